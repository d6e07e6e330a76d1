"""Does the default selection converge to the complete fit as the data grow? (issue 30)

Simulated campaigns (every complete parameter off by 1 mm / 1 mrad, 0.05 mm / 0.05 mrad noise,
a marker at (10, 20, 50) mm in the tool frame) of m configurations are calibrated with the
default (``auto``) and with ``params='complete'``; both are scored on 500 unseen noise-free
configurations of the same true robot (position RMS). The table prints the median over seeds
of the held-out ratio auto / complete (1.00: the default loses nothing), and the median
held-out RMS of each [um].

Run: .venv/bin/python benchmarks/bench_selection_consistency.py [m ...]
(CALIB_BENCH_SEEDS, default 3; CALIB_BENCH_CASES, default all: ur5,panda,tiago,ur5-pose)
"""

from __future__ import annotations

import os
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import one_core

one_core()

import numpy as np  # noqa: E402

from calib import load_chain, simulate  # noqa: E402
from calib.calibration import calibrate, residual_stats  # noqa: E402

SEEDS = int(os.environ.get("CALIB_BENCH_SEEDS", "3"))
CASES = {
    "ur5": ("ur5", "position"),
    "panda": ("panda", "position"),
    "tiago": ("tiago", "position"),
    "ur5-pose": ("ur5", "pose"),
}
MARKER = (0.01, 0.02, 0.05)


def held_out(robot: str, measure: str, m: int, seed: int) -> tuple[float, float]:
    """Held-out position RMS [m] of auto and complete on one campaign."""
    chain = load_chain(robot)
    data = simulate(chain, m, measure, MARKER, noise_mm=0.05, seed=seed).measurements
    q = chain.random_configurations(500, 1000 + seed)
    test = simulate(chain, q, measure, MARKER, noise_mm=0.0, seed=seed).measurements
    out = []
    for params in ("auto", "complete"):
        result = calibrate(chain, data, params=params)
        out.append(residual_stats(result, test).position_rms)
    return out[0], out[1]


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [30, 100, 300, 1000]
    names = os.environ.get("CALIB_BENCH_CASES", ",".join(CASES)).split(",")
    print("case        m   auto/complete  auto [um]  complete [um]   (median of", SEEDS, "seeds)")
    for name in names:
        robot, measure = CASES[name]
        for m in sizes:
            runs = [held_out(robot, measure, m, s) for s in range(SEEDS)]
            ratio = statistics.median(a / c for a, c in runs)
            a = 1e6 * statistics.median(r[0] for r in runs)
            c = 1e6 * statistics.median(r[1] for r in runs)
            print(f"{name:9s} {m:5d}   {ratio:12.3f}  {a:9.1f}  {c:13.1f}", flush=True)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
