"""The pinhole camera's cost (issue 32): pixels of 20,000 points, with and without derivatives.

One BLAS thread, in process; each case ``CALIB_BENCH_REPEATS`` times (default 21) after a
warm-up: the median wall and CPU times. Points in the camera frame within a 90 degree field of
view (seed 0), each distortion model; OpenCV's ``projectPoints`` on the same points for scale
(with its Jacobian, which also has the rotation's and translation's columns), when OpenCV is
installed (the test extra).

Run: .venv/bin/python benchmarks/bench_pinhole.py   (CALIB_BENCH_REPEATS, default 21)
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import median_times_ms, one_core, table

one_core()

import numpy as np  # noqa: E402

from calib.identification.pinhole import DISTORTION_COUNTS, Pinhole  # noqa: E402

REPEATS = int(os.environ.get("CALIB_BENCH_REPEATS", "21"))
M = 20_000
LENS = np.array(
    [-0.28, 0.07, 1e-3, -8e-4, 0.012, 0.09, -0.015, 0.004, 1.5e-3, -4e-4, -1e-3, 3e-4, 0.02, -0.015]
)


def points(m: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    z = rng.uniform(0.3, 2.0, m)
    return np.column_stack([rng.uniform(-0.45, 0.45, (m, 2)) * z[:, None], z])


def opencv(cv2, cam: Pinhole, p: np.ndarray):
    """OpenCV's pixels and Jacobian of points in the camera frame (no rotation, no translation)."""
    zero = np.zeros(3)
    return cv2.projectPoints(p, zero, zero, cam.camera_matrix, cam.distortion)


def main() -> None:
    try:
        import cv2
    except ImportError:
        cv2 = None
    p = points(M)
    rows = []
    for k in DISTORTION_COUNTS:
        cam = Pinhole(612.5, 608.25, 321.7, 238.4, LENS[:k])
        pixels = median_times_ms(lambda cam=cam: cam.projection(p), REPEATS)
        both = median_times_ms(lambda cam=cam: cam.projection(p, derivatives=True), REPEATS)
        row = [k, f"{pixels[0]:.2f} / {pixels[1]:.2f}", f"{both[0]:.2f} / {both[1]:.2f}"]
        if cv2 is not None:
            ocv = median_times_ms(lambda cam=cam: opencv(cv2, cam, p), REPEATS)
            row.append(f"{ocv[0]:.2f} / {ocv[1]:.2f}")
        rows.append(row)
    header = ["coefficients", "pixels [ms]", "pixels + derivatives [ms]"]
    header += ["cv2.projectPoints + Jacobian [ms]"] if cv2 is not None else []
    print(f"{M} points, medians of {REPEATS} (wall / CPU), one BLAS thread")
    print(table(header, rows))


if __name__ == "__main__":
    main()
