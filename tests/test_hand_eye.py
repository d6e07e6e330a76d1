"""Hand-eye alone: the camera and the board's mounting from pixels, the joints as nominal.

The truth is the simulation's input (a camera placement and a board mounting chosen here);
the pixels are projected by calib's simulation, whose pinhole equals cv2.projectPoints
(tests/test_pinhole.py).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from pixel_setups import INTRINSICS, look_at

from calib import load_chain
from calib.calibration.hand_eye import hand_eye
from calib.calibration.pixel_chain import PixelCamera
from calib.exceptions import InvalidArgumentError
from calib.measurements.pixel_simulation import simulate_pixels
from calib.measurements.pixels import Target


def _pose(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def _board(M: np.ndarray, columns: int, rows: int, step: float) -> Target:
    B = np.array([(i * step, j * step, 0.0) for j in range(rows) for i in range(columns)])
    normal = np.tile(-M[:3, 2], (len(B), 1))
    return Target(tuple(f"c{k}" for k in range(len(B))), B @ M[:3, :3].T + M[:3, 3], None, normal)


FLIP = pin.utils.rotate("x", np.pi)
CASES = {  # robot, camera link, board link, camera, board mounting, board, postures
    "eye-to-hand ur5": (
        "ur5",
        "world",
        "tool0",
        look_at(np.array([1.6, 0.3, 0.8]), [0, 0, 0.3]),
        _pose(FLIP, (-0.12, 0.08, 0.01)),
        (7, 5, 0.04),
        None,
    ),
    "eye-in-hand panda": (
        "panda",
        "panda_hand",
        "panda_link0",
        _pose(np.eye(3), (0, 0.05, 0.05)),
        _pose(FLIP, (0.3, 0.09, 0.0)),
        (6, 5, 0.06),
        np.array([0.8, 2.0, 0.0, -2.2, 0.0, -0.3, 0.0]),
    ),
}


@pytest.mark.parametrize("case", CASES)
def test_noise_free_pixels_give_the_true_camera_and_mounting(case):
    robot, link, tool, C, M, size, home = CASES[case]
    chain = load_chain(robot, base=link, tool=tool)
    truth = _board(M, *size)
    rng = np.random.default_rng(3)
    if home is None:
        q = chain.random_configurations(4000, 1)
    else:
        q = home + 0.5 * rng.uniform(-1, 1, (4000, chain.n))
    obs = simulate_pixels(chain, "cam", C, INTRINSICS, truth, q)
    kept, count = np.unique(obs.q, axis=0, return_counts=True)
    assert (count == len(truth.point)).sum() >= 15
    q = kept[count == len(truth.point)][:15]
    obs = simulate_pixels(chain, "cam", C, INTRINSICS, truth, q)
    off = _pose(pin.exp3(np.array([0.02, -0.01, 0.015])), (0.008, -0.005, 0.004))
    guess = _board(M @ off, *size)  # the mounting as guessed: 10 mm and 27 mrad off
    fit = hand_eye(chain, PixelCamera("cam", link, INTRINSICS, None), guess, obs)
    assert fit.rms_px < 1e-8
    assert np.max(np.abs(fit.camera - C)) < 1e-9
    assert np.max(np.abs(fit.target - truth.position)) < 1e-9
    moved = guess.position @ fit.mount[:3, :3].T + fit.mount[:3, 3]
    assert np.max(np.abs(moved - truth.position)) < 1e-9


def test_a_camera_off_the_chains_base_is_refused():
    chain = load_chain("ur5", base="world", tool="tool0")
    target = _board(np.eye(4), 3, 3, 0.05)
    camera = PixelCamera("cam", "tool0", INTRINSICS, None)
    obs = simulate_pixels(
        chain,
        "cam",
        look_at(np.array([1.6, 0.3, 0.8]), [0, 0, 0.3]),
        INTRINSICS,
        target,
        chain.random_configurations(200, 1),
    )
    with pytest.raises(
        InvalidArgumentError, match="camera cam: its chain must start at its link tool0, not world"
    ):
        hand_eye(chain, camera, target, obs)


def test_a_gross_outlier_is_set_aside_as_by_every_term():
    """Hand-eye alone is the joint engine's problem: a corner detected 40 px off is set aside
    (its line named), and the camera is found as without it."""
    robot, link, tool, C, M, size, _ = CASES["eye-to-hand ur5"]
    chain = load_chain(robot, base=link, tool=tool)
    truth = _board(M, *size)
    obs = simulate_pixels(chain, "cam", C, INTRINSICS, truth, chain.random_configurations(4000, 1))
    kept, count = np.unique(obs.q, axis=0, return_counts=True)
    q = kept[count == len(truth.point)][:15]
    obs = simulate_pixels(chain, "cam", C, INTRINSICS, truth, q, noise_px=0.3, seed=4)
    pixels = obs.pixels.copy()
    pixels[40] += (40.0, 0.0)  # row 41 (no file: rows count from 1)
    bad = dataclasses.replace(obs, pixels=pixels)
    guess = _board(
        M @ _pose(pin.exp3(np.array([0.02, -0.01, 0.015])), (0.008, -0.005, 0.004)), *size
    )
    fit = hand_eye(chain, PixelCamera("cam", link, INTRINSICS, None), guess, bad)
    clean = hand_eye(chain, PixelCamera("cam", link, INTRINSICS, None), guess, obs)
    assert fit.outliers == (41,) and clean.outliers == ()
    # 0.25 mm and 0.18 mrad measured (1.09 mm and 0.89 mrad with the outlier kept)
    assert np.max(np.abs(fit.camera[:3, 3] - C[:3, 3])) < 5e-4  # [m]
    assert np.linalg.norm(pin.log3(fit.camera[:3, :3].T @ C[:3, :3])) < 5e-4  # [rad]
    assert abs(fit.rms_px - 0.3) < 0.03  # the noise's (0.3 px per axis), the outlier out
