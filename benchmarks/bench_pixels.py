"""The pixel kind's cost (issue 32): 20,000 pixel observations calibrated in process.

Three set-ups of tests/pixel_setups.py (an eye-to-hand UR5, an eye-in-hand Panda seeing a
board in the cell, TIAGo's head camera seeing its hand), each on its true robot (joint origins
moved by ~1 mm / 1 mrad), 0.5 px of noise (seed 7), postures drawn until about 20,000 pixels
are seen; ``calib.calibrate`` of a Problem of one pixel term, 20 % of the postures held out:
the camera placed in closed form, then the joint placements fitted (the joint engine). One
BLAS thread; each case ``CALIB_BENCH_REPEATS``
times (default 5) after a warm-up: the median wall and CPU times, and the held-out
reprojection error.

Run: .venv/bin/python benchmarks/bench_pixels.py   (CALIB_BENCH_REPEATS, default 5)
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from common import median_times_ms, one_core, table

one_core()

import numpy as np  # noqa: E402
from pixel_setups import INTRINSICS, calibrated, pixels, setup  # noqa: E402

from calib.calibration.pixel_chain import PixelCamera  # noqa: E402
from calib.measurements.pixel_simulation import simulate_pixels  # noqa: E402

REPEATS = int(os.environ.get("CALIB_BENCH_REPEATS", "5"))
M = 20_000


def case(name: str, folder: Path):
    s = setup(name, folder, postures=2000)
    obs = simulate_pixels(s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q)
    per = obs.m / len(s.q)
    q = s.q[: int(np.ceil(M / per))]
    obs = simulate_pixels(
        s.truth, s.camera, s.true_placement, INTRINSICS, s.target, q, noise_px=0.5, seed=7
    )
    camera = PixelCamera(s.camera, s.link, INTRINSICS, None)
    return s, obs, camera


def main() -> None:
    rows = []
    with tempfile.TemporaryDirectory() as folder:
        for name in ("ur5", "panda", "tiago"):
            s, obs, camera = case(name, Path(folder))

            def run(s=s, obs=obs, camera=camera):
                return calibrated(s.nominal, camera, s.target, obs, holdout=0.2, seed=1)

            result = run()
            wall, cpu = median_times_ms(run, REPEATS)
            held = pixels(result, "held_out")
            rows.append(
                [
                    name,
                    obs.m,
                    result.unknowns,
                    f"{wall / 1e3:.2f} / {cpu / 1e3:.2f}",
                    f"{held['reprojection_rms_px']:.3f}",
                ]
            )
    print(table(["set-up", "pixels", "determined", "wall / CPU [s]", "held-out rms [px]"], rows))


if __name__ == "__main__":
    main()
