"""CPU-time medians [us] of the kinematics primitives and of the runs they serve, for one
source tree of calib (issue 22: the MDH conversion, kinematics, apply, Jacobian).

Run it on two trees alternately (the machine's load drifts):

    git worktree add /tmp/before <commit>
    for i in 1 2 3; do for r in /tmp/before .; do
        OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/compare_primitives.py $r
    done; done

Each line, process CPU time, medians after one warm-up call: TIAGo (8 joints) `from_chain`,
`idealized`, both in a row; TALOS (30 joints, 5 tools) `from_tree(...).idealized()`;
`ParameterSet.apply` (complete set); `kinematics` at m = 37 and 100; the position Jacobian
of the complete set with and without the kinematics given; then the TIAGo calibration (point
1, default options), `calib.analyze("ur5")` and `analyze_model` on the idealized TALOS tree
(m = 100, pose) [us].
"""

from __future__ import annotations

import dataclasses
import sys
import warnings
from pathlib import Path

ROOT = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
sys.path.insert(0, str(ROOT))

from common import cpu_median_ns  # noqa: E402 (the benchmarks' folder, not ROOT)

warnings.simplefilter("ignore")

import numpy as np  # noqa: E402

import calib  # noqa: E402
from calib import (  # noqa: E402
    Measurement,
    analyze,
    calibrate,
    from_chain,
    from_tree,
    load_chain,
    read_measurements,
)
from calib.identification.identifiability import analyze_model  # noqa: E402
from calib.identification.jacobian import identification_jacobian  # noqa: E402
from calib.identification.parameters import complete_parameters  # noqa: E402
from calib.kinematics.tree import load_tree  # noqa: E402

TIAGO = Path(__file__).resolve().parent.parent / "data" / "realdata" / "tiago"


def cpu_us(fn, repeats: int) -> float:
    """Median process CPU time of ``fn()`` [us], after one warm-up call."""
    return cpu_median_ns(fn, repeats) / 1e3


def primitives() -> dict[str, float]:
    chain = load_chain(TIAGO / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    mdh = from_chain(chain)
    tree = load_tree("talos")
    out = {
        "from_chain": cpu_us(lambda: from_chain(chain), 200),
        "idealized": cpu_us(mdh.idealized, 200),
        "both": cpu_us(lambda: from_chain(chain).idealized(), 200),
        "talos_tree": cpu_us(lambda: from_tree(tree).idealized(), 30),
    }
    pset = complete_parameters(mdh)
    delta = np.random.default_rng(0).normal(0.0, 1e-3, len(pset))
    out["apply"] = cpu_us(lambda: pset.apply(mdh, delta), 500)
    point = Measurement.of("position", (0.01, 0.02, 0.03))
    for m in (37, 100):
        q = chain.random_configurations(m, 0)
        kin = mdh.kinematics(q)
        out[f"kin{m}"] = cpu_us(lambda q=q: mdh.kinematics(q), 500)
        out[f"W{m}_kin"] = cpu_us(
            lambda q=q, kin=kin: identification_jacobian(mdh, pset, q, point, kin), 500
        )
        out[f"W{m}"] = cpu_us(lambda q=q: identification_jacobian(mdh, pset, q, point), 500)
    return out


def runs() -> dict[str, float]:
    chain = load_chain(TIAGO / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    four = read_measurements(TIAGO / "qualisys_2021-11-30_static_postures.csv", chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    tree = load_tree("talos")
    ideal = from_tree(tree).idealized()
    q = tree.random_configurations(100, 0)
    pose = Measurement.of("pose")
    return {
        "tiago_p1": cpu_us(lambda: calibrate(chain, one), 15),
        "analyze_ur5": cpu_us(lambda: analyze("ur5", measure="pose", params="paper"), 15),
        "talos_analyze_model": cpu_us(lambda: analyze_model(ideal, "paper", pose, q), 11),
    }


if __name__ == "__main__":
    if not Path(calib.__file__).is_relative_to(ROOT):
        sys.exit(f"calib imported from {calib.__file__}, not from {ROOT}")
    times = primitives() | runs()
    print(ROOT.name, " ".join(f"{k}={v:.0f}" for k, v in times.items()), flush=True)
