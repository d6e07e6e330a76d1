"""Speed of the identifiability analysis (issue: W + QR < 1 ms, `analyze ur5` < 20 ms).

Also the structural step against FIGAROH 1.0.2's ``calculate_base_kinematics_regressor``,
measured in the same run: FIGAROH runs in its own venv (``FIGAROH_PYTHON``, default
``.figaroh-venv/bin/python``, which ``bash .ci/run bench`` creates), see figaroh_peer.py.

Run: .venv/bin/python benchmarks/bench_identifiability.py [figaroh | startup]   (only that part)
"""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import ROOT, compile_calib, median_ms, one_core, process_cpu_times, table

one_core()

import warnings  # noqa: E402

import numpy as np  # noqa: E402

from calib import Measurement, analyze, from_chain, from_tree, load_chain  # noqa: E402
from calib.identification.identifiability import (  # noqa: E402
    analyze_model,
    identify_base,
)
from calib.identification.jacobian import identification_jacobian  # noqa: E402
from calib.identification.parameters import paper_parameters  # noqa: E402
from calib.kinematics.mdh import from_lines  # noqa: E402
from calib.kinematics.tree import load_tree  # noqa: E402

warnings.simplefilter("ignore")


def w_and_qr(mdh, q, measurement):
    params = paper_parameters(mdh)
    W = identification_jacobian(mdh, params, q, measurement)
    return identify_base(mdh, params, W)


def structural_step(chain, mdh, params, measurement):
    """Random configurations, W, QR, base set: what FIGAROH's step does (m = 100)."""
    q = chain.random_configurations(100, 0)
    return identify_base(mdh, params, identification_jacobian(mdh, params, q, measurement))


ROUNDS = 20
"""Alternating pairs of batches (calib's, then FIGAROH's) per chain."""

CALIB_BATCH, PEER_BATCH = 50, 5
"""Calls per batch: about the same wall time each (calib's step is ~10x to 20x shorter)."""


def figaroh_peer(chains: dict) -> subprocess.Popen | None:
    """FIGAROH's step, running in its own venv and waiting for batches, or None without it."""
    python = Path(os.environ.get("FIGAROH_PYTHON", ROOT / ".figaroh-venv" / "bin" / "python"))
    if not python.exists():
        return None
    args = [str(python), str(Path(__file__).with_name("figaroh_peer.py"))]
    for name, chain in chains.items():
        args += [name, str(chain.urdf_path), chain.tool_frame]
    return subprocess.Popen(
        args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True
    )


def peer_batch(peer: subprocess.Popen, name: str, repeats: int) -> list[float]:
    """Times [ms] of ``repeats`` FIGAROH steps on chain ``name``."""
    peer.stdin.write(f"{name} {repeats}\n")
    peer.stdin.flush()
    return json.loads(peer.stdout.readline())


def calib_batch(step, repeats: int) -> list[float]:
    """Times [ms] of ``repeats`` calls of ``step`` after one warm-up call."""
    step()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        step()
        times.append(1e3 * (time.perf_counter() - t0))
    return times


def versus_figaroh() -> None:
    """The structural step, UR5 and Panda, position, m = 100, against FIGAROH 1.0.2.

    Measured in alternating pairs of batches (calib, FIGAROH, calib, FIGAROH, ...) of about
    the same wall time, so that both see the same load of a shared machine. The ratio is
    the median over the pairs of (FIGAROH's batch median / calib's batch median).
    """
    position = Measurement.of("position")
    chains = {name: load_chain(name) for name in ("ur5", "panda")}
    peer = figaroh_peer(chains)
    n_peer = json.loads(peer.stdout.readline()) if peer else {}
    rows = []
    for name, chain in chains.items():
        mdh = from_chain(chain).idealized()
        params = paper_parameters(mdh)
        step = lambda c=chain, m=mdh, p=params: structural_step(c, m, p, position)  # noqa: E731
        ours, theirs, ratios = [], [], []
        for _ in range(ROUNDS if peer else 1):
            a = calib_batch(step, CALIB_BATCH)
            ours += a
            if peer:
                b = peer_batch(peer, name, PEER_BATCH)
                theirs += b
                ratios.append(statistics.median(b) / statistics.median(a))
        ms = statistics.median(ours)
        rows.append(
            [
                name,
                f"{ms:.3f}",
                len(step()[2]),
                f"{statistics.median(theirs):.2f}" if peer else "-",
                n_peer.get(name, "-"),
                f"{statistics.median(ratios):.1f}x" if peer else "-",
                f"{min(ratios):.1f}x to {max(ratios):.1f}x" if peer else "-",
            ]
        )
    if peer:
        peer.stdin.close()
        peer.wait()
    print(
        f"\nStructural step (random configurations, W, QR, base set), position, m = 100; "
        f"{ROUNDS} alternating pairs of batches ({CALIB_BATCH} calib calls, {PEER_BATCH} "
        f"FIGAROH calls):"
    )
    if peer is None:
        print("FIGAROH not measured: no venv (bash .ci/run bench creates .figaroh-venv)")
    header = [
        "chain",
        "calib [ms]",
        "base",
        "FIGAROH 1.0.2 [ms]",
        "base",
        "calib faster (target >= 12x)",
        "range over pairs",
    ]
    print(table(header, rows))


STARTS = (
    ("python -c pass (interpreter start, for reference)", ["--python"], "-"),
    ("python -c 'import numpy' (reference)", ["--python", "import numpy"], "-"),
    ("python -c 'import pinocchio' (reference: numpy too)", ["--python", "import pinocchio"], "-"),
    (
        "python -c 'import pinocchio, numpy.random' (reference)",
        ["--python", "import pinocchio, numpy.random"],
        "-",
    ),
    (
        "the same and calib's CLI modules (every import of `calib analyze`)",
        ["--python", "import pinocchio, numpy.random, calib.cli.commands"],
        "-",
    ),
    ("`calib --version`", ["--version"], "< 100"),
    ("`calib list`", ["list"], "< 100"),
    ("`calib analyze ur5`", ["analyze", "ur5"], "< 250"),
)
"""Whole processes timed by :func:`start_up`: label, arguments, target [ms]."""


def start_up(rounds: int = 15) -> None:
    """Whole ``calib`` processes (interpreter start and imports included), with the targets.

    Taken in rounds (one process of each command per round, so that a busy spell of the
    machine weighs on all alike), after calib's bytecode caches are written. Wall and CPU
    medians; then where the CPU time of ``calib analyze ur5`` goes (differences of the
    references' medians).
    """
    compile_calib()
    times: dict[str, list[tuple[float, float]]] = {label: [] for label, _, _ in STARTS}
    for _ in range(rounds):
        for label, args, _ in STARTS:
            times[label] += process_cpu_times(args, 1)
    wall = {k: 1e3 * statistics.median(w for w, _ in v) for k, v in times.items()}
    cpu = {k: 1e3 * statistics.median(c for _, c in v) for k, v in times.items()}
    rows = [
        [
            label,
            f"{wall[label]:.0f}",
            f"{1e3 * min(w for w, _ in times[label]):.0f}",
            f"{cpu[label]:.0f}",
            target,
        ]
        for label, _, target in STARTS
    ]
    print(f"\nWhole processes ({rounds} rounds):")
    print(table(["command", "median [ms]", "min [ms]", "cpu median [ms]", "target [ms]"], rows))
    steps = [label for label, _, _ in STARTS]
    order = [steps[0], steps[1], steps[2], steps[3], steps[4], steps[-1]]
    parts = [
        "interpreter",
        "numpy",
        "pinocchio (beyond numpy)",
        "numpy.random",
        "calib's modules (and the standard library they import)",
        "the command: parser, catalog, URDF load, analysis, output",
    ]
    split = [[parts[0], f"{cpu[order[0]]:.0f}"]]
    pairs = zip(parts[1:], order[:-1], order[1:], strict=True)
    split += [[p, f"{cpu[b] - cpu[a]:.0f}"] for p, a, b in pairs]
    print("\nWhere the CPU time of `calib analyze ur5` goes (differences of medians):")
    print(table(["part", "cpu [ms]"], split))


def random_chain(n: int, seed: int):
    rng = np.random.default_rng(seed)
    points = np.cumsum(rng.uniform(-0.2, 0.2, (n, 3)), axis=0)
    dirs = rng.normal(size=(n, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    tool = np.eye(4)
    tool[:3, 3] = points[-1] + 0.1
    return from_lines(points, dirs, np.zeros(n, dtype=int), tool)


def tree_against_chain() -> None:
    """A whole humanoid (TALOS: 30 joints, 5 tools) against a 7-joint chain (Panda)."""
    pose = Measurement.of("pose")
    chain = load_chain("panda")
    chain_mdh = from_chain(chain).idealized()
    q_chain = chain.random_configurations(100, 0)
    tree = load_tree("talos")
    tree_mdh = from_tree(tree).idealized()
    q_tree = tree.random_configurations(100, 0)
    t_chain = median_ms(lambda: analyze_model(chain_mdh, "paper", pose, q_chain), 100)
    t_tree = median_ms(lambda: analyze_model(tree_mdh, "paper", pose, q_tree), 50)
    rows = [
        ["panda chain: 7 joints, 1 tool, analyze_model, m=100, pose", f"{t_chain:.3f}"],
        [
            f"talos tree: {tree.n} joints, {tree.n_tools} tools, analyze_model, m=100, pose",
            f"{t_tree:.3f}",
        ],
        ["ratio tree / chain (target < 10)", f"{t_tree / t_chain:.1f}"],
    ]
    print("\nA whole humanoid against a 7-joint chain (W, QR, base set, complete model):")
    print(table(["case", "median [ms]"], rows))


def main() -> None:
    pose = Measurement.of("pose")
    rows = []
    for name in ("ur5", "panda"):
        chain = load_chain(name)
        mdh = from_chain(chain)
        q = chain.random_configurations(100, 0)
        rows.append(
            [
                f"{name}: W + QR + base set, m=100, pose",
                f"{median_ms(lambda mdh=mdh, q=q: w_and_qr(mdh, q, pose), 300):.3f}",
            ]
        )
        rows.append(
            [
                f"{name}: analyze_model (+ complete model), m=100",
                f"{median_ms(lambda mdh=mdh, q=q: analyze_model(mdh, 'paper', pose, q), 200):.3f}",
            ]
        )
    rows.append(
        [
            "calib.analyze('ur5') in-process (load+convert+all)",
            f"{median_ms(lambda: analyze('ur5', measure='pose', params='paper'), 50):.3f}",
        ]
    )
    print(table(["case", "median [ms]"], rows))
    start_up()

    print("\nGrowth with m (ur5, pose, W + QR + base set):")
    chain = load_chain("ur5")
    mdh = from_chain(chain)
    grow = []
    for m in (10, 100, 1000, 10000):
        q = chain.random_configurations(m, 0)
        repeats = 30 if m >= 1000 else 200
        t = median_ms(lambda q=q: w_and_qr(mdh, q, pose), repeats)
        grow.append([m, f"{t:.3f}"])
    print(table(["m", "median [ms]"], grow))

    print("\nGrowth with chain length (random revolute chains, m=100, pose):")
    grow = []
    for n in (6, 12, 18, 24, 30):
        mdh = random_chain(n, n)
        q = np.random.default_rng(0).uniform(-np.pi, np.pi, (100, n))
        grow.append(
            [n, 4 * n + 6, f"{median_ms(lambda mdh=mdh, q=q: w_and_qr(mdh, q, pose), 100):.3f}"]
        )
    print(table(["joints", "parameters", "median [ms]"], grow))
    tree_against_chain()
    versus_figaroh()


if __name__ == "__main__":
    if sys.argv[1:] == ["figaroh"]:  # only the comparison with FIGAROH
        versus_figaroh()
    elif sys.argv[1:] == ["startup"]:  # only the whole processes
        start_up()
    else:
        main()
