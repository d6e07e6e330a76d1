"""Three camera set-ups on one truth each: eye-to-hand UR5, eye-in-hand Panda, TIAGo's head.

Each is a nominal chain from the camera's link to the target's tool, a true robot (every
joint's origin moved by ~1 mm / 1 mrad, :func:`calib.measurements.true_robot.true_robot`), a
true camera a few mm and mrad from its nominal placement, and postures at which the true
camera sees at least 6 target points. The numbers are the test's own (not calib's output).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from calib import load_chain
from calib.identification.pinhole import Pinhole
from calib.kinematics.robot import Chain
from calib.measurements.intrinsics import Intrinsics
from calib.measurements.pixel_simulation import simulate_pixels
from calib.measurements.pixels import Target
from calib.measurements.true_robot import true_robot

INTRINSICS = Intrinsics(
    1280, 960, Pinhole(900.0, 905.0, 640.0, 480.0, np.array([0.1, -0.05, 1e-3, -1e-3, 0.01]))
)


def look_at(eye, at, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """An optical frame at ``eye`` whose z looks at ``at`` (x right, y down) ``(4, 4)``."""
    z = np.asarray(at, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = np.column_stack([x, np.cross(z, x), z]), eye
    return T


def grid(nx: int, ny: int, step: float, corner=(0.0, 0.0)) -> Target:
    """A flat board of points ``p0 ...`` in its link's xy plane [m]."""
    xy = [(corner[0] + i * step, corner[1] + j * step, 0.0) for i in range(nx) for j in range(ny)]
    return Target(tuple(f"p{i}" for i in range(len(xy))), np.array(xy))


@dataclass(frozen=True, eq=False)
class Setup:
    """A camera set-up: the nominal chain, the truth, the camera and the postures."""

    name: str
    camera: str
    link: str
    nominal: Chain
    truth: Chain
    true_urdf: Path
    placement: np.ndarray  # nominal camera in the link
    true_placement: np.ndarray
    target: Target
    q: np.ndarray


def _hand():
    T = np.eye(4)
    T[:3, 3] = (0.0, 0.05, 0.05)
    return T


SETUPS = {  # robot, camera, link, tool, nominal placement (None: the URDF's), target, home
    "ur5": (
        "ur5",
        "cam",
        "world",
        "tool0",
        look_at(np.array([1.6, 0.3, 0.8]), [0, 0, 0.3]),
        grid(4, 3, 0.03),
        None,
    ),
    "panda": (
        "panda",
        "cam",
        "panda_hand",
        "panda_link0",
        _hand(),
        grid(6, 5, 0.06, (0.3, -0.15)),
        np.array([0.8, 2.0, 0.0, -2.2, 0.0, -0.3, 0.0]),
    ),
    "tiago": (
        "tiago",
        "xtion_optical_frame",
        "xtion_link",
        "arm_tool_link",
        None,
        grid(4, 3, 0.03),
        None,
    ),
}


def setup(name: str, folder: Path, postures: int = 600) -> Setup:
    """The set-up ``name`` with its true URDF written in ``folder``."""
    robot, camera, link, tool, C, target, home = SETUPS[name]
    nominal = load_chain(robot, base=link, tool=tool)
    if C is None:  # TIAGo's optical frame, read by Pinocchio
        model = nominal.model
        data = model.createData()
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        C = data.oMf[model.getFrameId(link)].inverse() * data.oMf[model.getFrameId(camera)]
        C = C.homogeneous
    path = folder / f"true_{name}.urdf"
    true_robot([nominal], path, seed=3)
    truth = load_chain(str(path), base=link, tool=tool)
    true_C = C.copy()
    true_C[:3, 3] += (0.003, -0.002, 0.001)
    true_C[:3, :3] = true_C[:3, :3] @ pin.exp3(np.array([0.002, -0.001, 0.003]))
    rng = np.random.default_rng(1)
    if home is None:
        q = nominal.random_configurations(20 * postures, 1)
    else:
        q = home + 0.3 * rng.uniform(-1, 1, (20 * postures, nominal.n))
    seen = simulate_pixels(truth, camera, true_C, INTRINSICS, target, q)
    kept, count = np.unique(seen.q, axis=0, return_counts=True)
    order = np.sort([np.flatnonzero((q == k).all(axis=1))[0] for k in kept[count >= 6]])
    return Setup(name, camera, link, nominal, truth, path, C, true_C, target, q[order[:postures]])


def calibrated(chains, cameras, target, obs, validate=None, what=None, **options):
    """The joint fit of one pixel term per camera (``calib.calibrate`` of a Problem).

    ``chains`` and ``cameras``: one each, or tuples of one per camera.
    """
    from calib import Problem, Term, calibrate
    from calib.calibration.pixel_chain import PixelData, Unknowns

    chains = chains if isinstance(chains, tuple) else (chains,)
    cameras = cameras if isinstance(cameras, tuple) else (cameras,)
    what = Unknowns() if what is None else what
    terms = tuple(
        Term(
            c,
            PixelData(cam, target, obs, what),
            None if validate is None else PixelData(cam, target, validate, what),
        )
        for c, cam in zip(chains, cameras, strict=True)
    )
    return calibrate(Problem(terms, params="complete", **options))


def pixels(result, part: str = "train", term: int = 0) -> dict:
    """A pixel term's reprojection errors [px] of ``part`` (``train_registration`` ...)."""
    return result.chains[term].pixels[part]
