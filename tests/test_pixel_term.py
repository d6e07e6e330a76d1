"""The pixel kind: residuals and Jacobian against Pinocchio and a textbook pinhole.

The reference (tests/pixel_scorer.py) places the camera and the target with Pinocchio's
forward kinematics of a model whose joint origins the test moves itself, and projects with
OpenCV's formula written out in numpy; its central differences are the Jacobian's check.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from pixel_scorer import link_points, moved_model, seen_pixels

from calib import load_chain
from calib.calibration.pixel_chain import PixelRows, PixelTermState, Unknowns, pixel_jacobian
from calib.calibration.placements import Placements
from calib.identification.pinhole import Pinhole

CAMERA = Pinhole(900.0, 905.0, 640.0, 480.0, np.array([0.1, -0.05, 1e-3, -1e-3, 0.01]))
SETUPS = {  # robot, camera link, tool: eye-to-hand, eye-in-hand (target in the cell), head
    "ur5": ("ur5", "world", "tool0"),
    "panda": ("panda", "panda_hand", "panda_link0"),
    "tiago": ("tiago", "xtion_rgb_frame", "arm_tool_link"),
}


def _pose(rng, scale: float = 1.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = pin.exp3(scale * rng.standard_normal(3)), scale * rng.normal(size=3)
    return T


def _setup(name: str, rng):
    """A moved robot, a camera 1.5 m in front of the tool's points, rows off the solution."""
    chain = load_chain(*SETUPS[name][:1], base=SETUPS[name][1], tool=SETUPS[name][2])
    pl = Placements.of((chain,))
    pl = pl.shifted(1e-2 * rng.standard_normal(pl.y.size)).rebased()
    q = chain.random_configurations(8, 2)
    point = np.arange(8) % 4
    target = 0.05 * rng.standard_normal((4, 3))
    return chain, pl, q, point, target


def _reference(chain, pl, q, point, target, C, dy, mount, dX, lens):
    """Pixels of the reference after moves of every unknown (Pinocchio + numpy); ``lens``:
    fx, fy, cx, cy, k1, k2, p1, p2, k3."""
    model = pl.model
    for j, name in enumerate(pl.joints):
        model = moved_model(model, name, pl.bases[j], dy[6 * j : 6 * j + 6])
    X = target @ pin.exp3(mount[3:]).T + mount[:3]
    X[3:] += dX.reshape(-1, 3)
    return seen_pixels(
        model,
        chain.base_frame,
        chain.tool_frame,
        chain.joint_names,
        q,
        X[point],
        C,
        np.array([[lens[0], 0, lens[2]], [0, lens[1], lens[3]], [0, 0, 1]]),
        lens[4:],
    )


@pytest.mark.parametrize("name", sorted(SETUPS))
def test_jacobian_matches_central_differences(name):
    """Every column (camera 6, every joint's 6 placement components, the mounting's 6, the
    free target points, the intrinsics) equals central differences of Pinocchio + a
    textbook pinhole."""
    rng = np.random.default_rng(4)
    chain, pl, q, point, target = _setup(name, rng)
    # a camera 1.5 m along the camera's z from the points' centre, looking at them
    centre = link_points(
        pl.model, chain.base_frame, chain.tool_frame, chain.joint_names, q, target[point]
    ).mean(axis=0)
    C = _pose(rng, 0.3)
    C[:3, 3] = centre - 1.5 * C[:3, 2]
    rows = PixelRows(q, point, np.zeros((8, 2)), tuple(range(8)))
    mdh = pl.chain_models((chain,))[0]
    state = PixelTermState(mdh, C, target, CAMERA, 1.0, Unknowns(True, True, True))
    r, J = pixel_jacobian(pl, state, chain, rows)
    assert J.shape == (8, 2, 6 + 6 * chain.n + 6 + 3 + 9)
    n = pl.y.size
    lens = CAMERA.parameters

    def pixels(x):
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = pin.exp3(x[3:6]), x[:3]
        parts = x[6 : 6 + n], x[6 + n : 12 + n], x[12 + n : 15 + n], lens + x[15 + n :]
        return _reference(chain, pl, q, point, target, C @ step, *parts)

    x0 = np.zeros(J.shape[2])
    assert np.max(np.abs(pixels(x0) - r)) < 1e-9  # the residual is the reference's pixels
    h = 1e-6
    num = np.stack([(pixels(e) - pixels(-e)) / (2 * h) for e in h * np.eye(J.shape[2])], axis=2)
    assert np.max(np.abs(J - num)) < 1e-6 * np.max(np.abs(num))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("cam", 5, "lens"), "link must be a non-empty text"),
        (("", "world", "lens"), "name must be a non-empty text"),
        (("cam", "world", None), "intrinsics must be read with calib.read_intrinsics"),
        (("cam", "world", "lens", np.eye(3)), "placement must be a rigid transform"),
        (("cam", "world", "lens", 2 * np.eye(4)), "placement must be a rigid transform"),
    ],
)
def test_a_camera_that_cannot_be_one_is_refused_where_it_is_made(args, message):
    """PixelCamera("cam", 5, None) was accepted and failed later, deep in the fit."""
    from pixel_setups import INTRINSICS

    import calib

    args = tuple(INTRINSICS if isinstance(a, str) and a == "lens" else a for a in args)
    with pytest.raises(calib.InvalidArgumentError, match=message):
        calib.PixelCamera(*args)
    calib.PixelCamera("cam", "world", INTRINSICS, np.eye(4))  # a good one is accepted
