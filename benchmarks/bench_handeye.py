"""Hand-eye alone (issue 32): calib's camera placement against OpenCV's calibrateHandEye.

The joint geometry is exact (the nominal robot is the truth); only the camera's placement on
its link and the board's mounting on its link are unknown. Two set-ups of tests/pixel_setups.py:
an eye-to-hand UR5 (camera in the cell, a 7 x 5 board of 4 cm on tool0) and an eye-in-hand
Panda (camera on panda_hand, a 6 x 5 board of 6 cm on the floor). For each seed: 20 images
where the whole board is seen from its front, Gaussian pixel noise of the level on u and v.

* calib: :func:`calib.calibration.hand_eye.hand_eye`, the reprojection error of every corner
  minimised over the camera (6) and the board's mounting (6); the camera placed in closed form,
  the board's mounting started from a guess 10 mm and 30 mrad off the truth (seeded).
* OpenCV: each image's board pose by ``cv2.solvePnP`` (as users do), then every method of
  ``cv2.calibrateHandEye`` (TSAI, PARK, HORAUD, ANDREFF, DANIILIDIS), run by handeye_peer.py
  in an OpenCV 4 venv (OpenCV 5.0 has no calibrateHandEye): ``OPENCV4_PYTHON``, default
  ``.opencv4-venv/bin/python`` (``python3 -m venv .opencv4-venv && .opencv4-venv/bin/pip
  install opencv-python-headless==4.10.0.84``).

Printed: per set-up, noise level and method, the median over the seeds of the camera
placement's rotation error [mrad] and translation error [mm] against the truth.

Run: .venv/bin/python benchmarks/bench_handeye.py   (CALIB_BENCH_SEEDS, default 10)
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from common import one_core, table

one_core()

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
from pixel_setups import INTRINSICS, SETUPS, look_at  # noqa: E402

from calib import load_chain  # noqa: E402
from calib.calibration.hand_eye import hand_eye  # noqa: E402
from calib.calibration.pixel_chain import PixelCamera  # noqa: E402
from calib.kinematics.mdh import from_chain  # noqa: E402
from calib.measurements.pixel_simulation import simulate_pixels  # noqa: E402
from calib.measurements.pixels import Target  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PEER = Path(__file__).resolve().parent / "handeye_peer.py"
SEEDS = int(os.environ.get("CALIB_BENCH_SEEDS", "10"))
NOISE_PX = (0.1, 0.5, 1.0, 2.0)
IMAGES = 20
METHODS = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")


def _pose(R: np.ndarray, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


FLIP = pin.utils.rotate("x", np.pi)  # the board's z (into the board) against its link's
CASES = {  # set-up, eye in hand, board (columns, rows, step [m]), board in its link
    "eye-to-hand UR5": ("ur5", False, (7, 5, 0.04), _pose(FLIP, (-0.12, 0.08, 0.01))),
    "eye-in-hand Panda": ("panda", True, (6, 5, 0.06), _pose(FLIP, (0.3, 0.09, 0.0))),
}


def _board(columns: int, rows: int, step: float) -> np.ndarray:
    return np.array([(i * step, j * step, 0.0) for j in range(rows) for i in range(columns)])


def _target(B: np.ndarray, M: np.ndarray) -> Target:
    """The board's corners in its link, their outward normal (the board's -z)."""
    normal = np.tile(-M[:3, 2], (len(B), 1))
    return Target(tuple(f"c{k}" for k in range(len(B))), B @ M[:3, :3].T + M[:3, 3], None, normal)


def _scene(name: str):
    """The chain, the true camera, and postures where it sees the whole board."""
    robot, _, link, tool, C, _, home = SETUPS[name]
    chain = load_chain(robot, base=link, tool=tool)
    if C is None:
        C = look_at(np.array([1.6, 0.3, 0.8]), [0, 0, 0.3])
    rng = np.random.default_rng(1)
    if home is None:
        q = chain.random_configurations(40_000, 1)
    else:
        q = home + 0.5 * rng.uniform(-1, 1, (40_000, chain.n))
    return chain, C, q


def _full_views(chain, C, target: Target, q: np.ndarray) -> np.ndarray:
    seen = simulate_pixels(chain, "cam", C, INTRINSICS, target, q)
    kept, count = np.unique(seen.q, axis=0, return_counts=True)
    return kept[count == len(target.point)]


def _peer_python() -> Path | None:
    python = Path(os.environ.get("OPENCV4_PYTHON", ROOT / ".opencv4-venv" / "bin" / "python"))
    return python if python.is_file() else None


def _opencv(python: Path, folder: Path, B, obs, chain, eye_in_hand: bool) -> dict:
    """Each OpenCV method's camera placement (4x4 in the camera's link)."""
    k = len(B)
    q = obs.q[::k]
    kin = from_chain(chain).kinematics(q)  # the target's link in the camera's link
    R, t = kin.R[:, -1], kin.p[:, -1]
    if eye_in_hand:  # the chain runs hand -> base: the gripper in the base is its inverse
        R, t = np.transpose(R, (0, 2, 1)), -np.einsum("nji,nj->ni", R, t)
    path = folder / "peer.npz"
    np.savez(
        path,
        object=B,
        pixels=obs.pixels.reshape(-1, k, 2),
        K=INTRINSICS.camera_matrix,
        dist=INTRINSICS.distortion,
        R_g2b=R,
        t_g2b=t,
        eye_in_hand=eye_in_hand,
    )
    out = subprocess.run([str(python), str(PEER), str(path)], capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"handeye_peer.py failed: {out.stderr.strip()[-300:]}")
    found = json.loads(out.stdout)
    return {m: np.array(found[m]) for m in METHODS} | {"version": found["opencv"]}


def _errors(T: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Rotation [mrad] and translation [mm] errors of a camera placement."""
    angle = np.linalg.norm(pin.log3(T[:3, :3].T @ truth[:3, :3]))
    return 1e3 * float(angle), 1e3 * float(np.linalg.norm(T[:3, 3] - truth[:3, 3]))


def _run(case: str, python: Path | None, folder: Path) -> tuple[list[list[str]], str]:
    name, eye_in_hand, (cols, rows, step), M = CASES[case]
    chain, C, q_all = _scene(name)
    B = _board(cols, rows, step)
    truth_target = _target(B, M)
    views = _full_views(chain, C, truth_target, q_all)
    errors: dict[tuple[float, str], list] = {}
    version = ""
    for seed in range(SEEDS):
        rng = np.random.default_rng([seed, 32])
        q = views[rng.choice(len(views), IMAGES, replace=False)]
        off = _pose(
            pin.exp3(rng.normal(size=3) * 0.03 / np.sqrt(3)), rng.normal(size=3) * 0.01 / np.sqrt(3)
        )
        guess = _target(B, M @ off)
        for noise in NOISE_PX:
            obs = simulate_pixels(
                chain, "cam", C, INTRINSICS, truth_target, q, noise_px=noise, seed=seed
            )
            if obs.m != IMAGES * len(B):  # a corner pushed out of the image by the noise
                continue
            camera = PixelCamera("cam", chain.base_frame, INTRINSICS, None)
            fit = hand_eye(chain, camera, guess, obs)
            errors.setdefault((noise, "calib"), []).append(_errors(fit.camera, C))
            if python is not None:
                peer = _opencv(python, folder, B, obs, chain, eye_in_hand)
                version = peer.pop("version")
                for method, T in peer.items():
                    errors.setdefault((noise, method), []).append(_errors(T, C))
    lines = [
        [
            case,
            f"{noise:g}",
            method,
            f"{np.median([e[0] for e in v]):.3f}",
            f"{np.median([e[1] for e in v]):.3f}",
            str(len(v)),
        ]
        for (noise, method), v in errors.items()
    ]
    return lines, version


def main() -> None:
    python = _peer_python()
    if python is None:
        print("no OpenCV 4 python (OPENCV4_PYTHON or .opencv4-venv): calib alone")
    rows, version = [], ""
    with tempfile.TemporaryDirectory() as folder:
        for case in CASES:
            lines, version = _run(case, python, Path(folder))
            rows += lines
    print(f"{IMAGES} images per seed, {SEEDS} seeds; OpenCV {version or '(not run)'}")
    print(
        table(
            ["set-up", "noise [px]", "method", "rotation [mrad]", "translation [mm]", "runs"], rows
        )
    )


if __name__ == "__main__":
    main()
