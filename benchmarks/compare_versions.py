"""CPU-time medians of the structural step and of calibrations, for one source tree of calib.

Run it on two trees alternately (the machine's load drifts; wall time is too noisy for 5 %):

    git worktree add /tmp/before <commit>
    for i in 1 2 3; do for r in /tmp/before .; do
        OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/compare_versions.py $r
    done; done

Each line: UR5 kinematics, W + QR + base set, analyze_model (m=100, pose), analyze('ur5'),
then the TIAGo session (37 postures) calibrated from point 1, 4 points and the plate pose,
``auto`` and ``complete`` each [ms of process CPU time, medians].
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

import calib  # noqa: E402
from calib import (  # noqa: E402
    Columns,
    Measurement,
    analyze,
    calibrate,
    from_chain,
    load_chain,
    read_measurements,
)
from calib.identification.identifiability import (  # noqa: E402
    analyze_model,
    identify_base,
)
from calib.identification.jacobian import identification_jacobian  # noqa: E402
from calib.identification.parameters import paper_parameters  # noqa: E402

TIAGO = Path(__file__).resolve().parent.parent / "data" / "realdata" / "tiago"


def cpu_ms(fn, repeats: int) -> float:
    """Median process CPU time of ``fn()`` [ms], after one warm-up call."""
    return cpu_median_ns(fn, repeats) / 1e6


def structural() -> list[float]:
    chain = load_chain("ur5")
    mdh = from_chain(chain)
    q = chain.random_configurations(100, 0)
    pose = Measurement.of("pose")
    pset = paper_parameters(mdh)

    def w_and_qr():
        identify_base(mdh, pset, identification_jacobian(mdh, pset, q, pose))

    return [
        cpu_ms(lambda: mdh.kinematics(q), 400),
        cpu_ms(w_and_qr, 400),
        cpu_ms(lambda: analyze_model(mdh, "paper", pose, q), 200),
        cpu_ms(lambda: analyze("ur5", measure="pose", params="paper"), 40),
    ]


def calibrations() -> list[float]:
    chain = load_chain(TIAGO / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    csv = TIAGO / "qualisys_2021-11-30_static_postures.csv"
    four = read_measurements(csv, chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    plate = read_measurements(csv, chain, Columns("markers"))
    return [
        cpu_ms(lambda d=d, lv=lv: calibrate(chain, d, params=lv), 15)
        for d in (one, four, plate)
        for lv in ("auto", "complete")
    ]


if __name__ == "__main__":
    if not Path(calib.__file__).is_relative_to(ROOT):
        sys.exit(f"calib imported from {calib.__file__}, not from {ROOT}")
    print(ROOT.name, " ".join(f"{t:.2f}" for t in structural() + calibrations()))
