"""Two source trees of calib timed in one process, call by call: the ratio a loaded machine keeps.

On a shared machine the load drifts between two runs, so two runs of
``calibration_stages.py`` one after the other can differ by more than the change measured.
Here both trees are imported into one process (each tree's ``calib/`` copied under another
package name) and each case alternates them call by call (A B, then B A), so that a drift
weighs on both alike. Each line: the CPU-time medians [ms] and the median of the paired ratios
B / A::

    mkdir -p /tmp/before && git archive <commit> | tar -x -C /tmp/before
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/paired_trees.py /tmp/before . [CASES] [N]

``CASES``: a comma-separated subset of point1, complete, ur10, four, plate, talos, tree,
ur5pos, ur5pos_c, ur5pose, ur5pose_c (those of ``calibration_stages.py`` and the UR5's 100
simulated configurations of ``bench_calibration.py``; ``_c``: ``params="complete"``);
``N``: pairs per case (default 15; a third of it, at least 5, for the slow cases).
``--processes`` (anywhere): each tree in a process of its own, still alternated call by call.
In one process the trees share one heap: a change to how much memory a call takes and gives
back (fresh pages, page faults) weighs on both trees alike and does not show.
"""

from __future__ import annotations

import dataclasses
import importlib
import multiprocessing
import shutil
import statistics
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from pathlib import Path

from common import one_core

one_core()
warnings.simplefilter("ignore")

DATA = Path(__file__).resolve().parent.parent / "data" / "realdata"
MARKER = (0.05, 0.02, 0.1)
SLOW = ("four", "plate", "talos")
"""Cases timed a third as often."""


def cases(package: str) -> dict[str, Callable[[], object]]:
    """Each case's calibration, by the package ``package`` (one tree's copy of calib)."""
    c = importlib.import_module(package)
    contacts = importlib.import_module(f"{package}.measurements.contact_campaign")
    tiago = DATA / "tiago"
    chain = c.load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    csv = tiago / "qualisys_2021-11-30_static_postures.csv"
    four = c.read_measurements(csv, chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    plate = c.read_measurements(csv, chain, c.Columns("markers"))
    ur10 = c.load_chain(DATA / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link")
    ur10_data = c.read_measurements(DATA / "ur10" / "calibration.csv", ur10)
    ur5 = c.load_chain("ur5")
    sims = {
        kind: c.simulate(ur5, configs=100, measure=kind, marker=MARKER, seed=0, noise_mm=0.1)
        for kind in ("position", "pose")
    }
    talos = c.load_robot("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
    touches = contacts.read_contacts(DATA / "talos_contact" / "left_train.csv", talos, "plane")
    hands = c.load_robot(
        "talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    )
    seen = c.simulate_tree(hands, 30, markers=[0.05, 0.02, 0.1], noise_mm=0.05, seed=1)
    cal = c.calibrate
    pos, pose = sims["position"].measurements, sims["pose"].measurements
    return {
        "point1": lambda: cal(chain, one),
        "complete": lambda: cal(chain, one, params="complete"),
        "ur10": lambda: cal(ur10, ur10_data, holdout=0.25),
        "four": lambda: cal(chain, four),
        "plate": lambda: cal(chain, plate),
        "talos": lambda: cal(talos, touches, marker=(0, 0, -0.12)),
        "tree": lambda: cal(hands, seen.measurements, holdout=0.25),
        "ur5pos": lambda: cal(ur5, pos, marker=MARKER),
        "ur5pos_c": lambda: cal(ur5, pos, marker=MARKER, params="complete"),
        "ur5pose": lambda: cal(ur5, pose, marker=MARKER),
        "ur5pose_c": lambda: cal(ur5, pose, marker=MARKER, params="complete"),
    }


def timed(f: Callable[[], object]) -> Callable[[], float]:
    """``f`` returning the process CPU time [s] it took."""

    def run() -> float:
        c0 = time.process_time()
        f()
        return time.process_time() - c0

    return run


def paired(a: Callable[[], float], b: Callable[[], float], n: int) -> tuple[float, float, float]:
    """CPU medians of ``a`` and ``b`` [ms] and the median of the ratios ``b / a``, ABBA order.

    ``a``, ``b``: each call returns the CPU time [s] it took (:func:`timed`, or a worker's).
    """
    a(), b()
    ta: list[float] = []
    tb: list[float] = []
    for i in range(n):
        for f, t in ((a, ta), (b, tb)) if i % 2 == 0 else ((b, tb), (a, ta)):
            t.append(f())
    ratio = statistics.median(y / x for x, y in zip(ta, tb, strict=True))
    return 1e3 * statistics.median(ta), 1e3 * statistics.median(tb), ratio


def _worker(path: str, package: str, conn) -> None:
    """A tree's process: runs the case named on ``conn``, answers its CPU time (None: stop)."""
    sys.path.insert(0, path)
    calls = {name: timed(f) for name, f in cases(package).items()}
    conn.send(list(calls))
    while (name := conn.recv()) is not None:
        conn.send(calls[name]())


def _remote(conn, name: str) -> Callable[[], float]:
    """A worker's case as a call returning its CPU time."""

    def run() -> float:
        conn.send(name)
        return conn.recv()

    return run


def main(argv: list[str]) -> None:
    """Time the cases of two trees (module text)."""
    apart = "--processes" in argv
    argv = [a for a in argv if a != "--processes"]
    trees = [Path(p).resolve() for p in argv[:2]]
    only = argv[2].split(",") if len(argv) > 2 else None
    repeats = int(argv[3]) if len(argv) > 3 else 15
    with tempfile.TemporaryDirectory() as tmp:
        for name, tree in zip(("calib_a", "calib_b"), trees, strict=True):
            skip = shutil.ignore_patterns("*.pyc")
            shutil.copytree(tree / "calib", Path(tmp) / name, ignore=skip)
        pipes, workers = [], []
        if apart:  # forked before any tree is imported: each process imports its own
            for package in ("calib_a", "calib_b"):
                ours, theirs = multiprocessing.Pipe()
                workers.append(multiprocessing.Process(target=_worker, args=(tmp, package, theirs)))
                workers[-1].start()
                pipes.append(ours)
            listed = [p.recv() for p in pipes]  # each worker's cases, once imported
            ca, cb = ({n: _remote(p, n) for n in k} for p, k in zip(pipes, listed, strict=True))
        else:
            sys.path.insert(0, tmp)
            ca, cb = ({n: timed(f) for n, f in cases(p).items()} for p in ("calib_a", "calib_b"))
        where = "one process per tree" if apart else "one process"
        print(f"A = {trees[0]}, B = {trees[1]} [ms of CPU time, medians; {where}]", flush=True)
        for name in ca:
            if only is None or name in only:
                n = max(5, repeats // 3) if name in SLOW else repeats
                ma, mb, ratio = paired(ca[name], cb[name], n)
                print(f"{name:10s} A {ma:7.1f}  B {mb:7.1f}  B/A {ratio:.3f}", flush=True)
        for p, w in zip(pipes, workers, strict=True):
            p.send(None)
            w.join()


if __name__ == "__main__":
    main(sys.argv[1:])
