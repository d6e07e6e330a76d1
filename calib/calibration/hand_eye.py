"""Hand-eye calibration from pixels, the robot's joint geometry taken as exact.

The problem OpenCV's ``cv2.calibrateHandEye`` solves (``AX = XB``), solved instead by
minimising the reprojection error of every observed corner: a camera on one link of the robot
sees a target on another (eye-in-hand: the camera on the hand, the board in the cell;
eye-to-hand: the camera in the cell, the board on the hand), and only the camera's placement
on its link (6) and the target's mounting on its link (6) are unknown. The joint placements
stay nominal (for a robot already calibrated, or to compare with hand-eye solvers: issue 32's
"hand-eye alone"); :func:`calib.calibrate` of a pixel term fits them too.

Steps: the camera placed in closed form on the target as given
(:func:`~.pixel_fit.camera_from_rays`) unless a placement is given, refined alone
(:func:`~.pixel_fit.refine_camera`), then the pixel fit's Levenberg-Marquardt on the
camera's and the mounting's 12 columns of the pixel term's analytic Jacobian
(:func:`~.pixel_term.pixel_jacobian`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.robot import Chain
from ..measurements.pixels import PixelObservations, Target
from .pixel_fit import MAX_STEPS, PixelView, camera_from_rays, rays, refine_camera
from .pixel_fit import _solve as solve_columns
from .pixel_term import (
    PixelCamera,
    PixelState,
    Unknowns,
    check_in_front,
    pixel_residuals,
    pixel_rows,
    target_points,
)
from .placements import Placements

__all__ = ["HandEye", "hand_eye"]

_MOUNT = Unknowns(mount=True)


@dataclass(frozen=True, eq=False)
class HandEye:
    """A camera's placement and its target's mounting, fitted with the joints as nominal.

    Attributes:
        camera: The camera's optical frame in its link ``(4, 4)`` [m] (x right, y down, z
            forward).
        mount: The correction of the target: the fitted points are ``R X + t`` of the given
            ones ``X`` (in the target's link) ``(4, 4)`` [m].
        target: The target points fitted, in the target's link ``(k, 3)`` [m].
        rms_px: The reprojection error's RMS over u and v [px].
    """

    camera: np.ndarray
    mount: np.ndarray
    target: np.ndarray
    rms_px: float


def _rigid(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """The rigid motion ``(4, 4)`` taking the points ``before`` onto ``after`` (least squares)."""
    a, b = before.mean(axis=0), after.mean(axis=0)
    U, _, Vt = np.linalg.svd((before - a).T @ (after - b))
    R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, b - R @ a
    return T


def hand_eye(chain: Chain, camera: PixelCamera, target: Target, obs: PixelObservations) -> HandEye:
    """The camera's placement and the target's mounting, the robot's joints as nominal.

    Args:
        chain: From the camera's link to the target's link (the robot taken as exact).
        camera: The camera: its name (the observations' ``camera``), its link (the chain's
            base), its intrinsics, and its placement as a start or None (closed form).
        target: The target points in the chain's tool frame [m]: the board's corners placed
            by a guess of its mounting (the fit moves them rigidly).
        obs: The observations (the camera's rows are used).

    Raises:
        InvalidArgumentError: The camera's link is not the chain's base.
        DataError: A joint without its column, a point not in the target, no row of the
            camera, points behind the camera at the start.
    """
    if camera.link != chain.base_frame:
        raise InvalidArgumentError(
            f"camera {camera.name} is on {camera.link}; the chain starts at {chain.base_frame}"
        )
    rows = pixel_rows(chain, obs, target, camera.name)
    placements = Placements.of((chain,))
    lens, points = camera.intrinsics.camera, np.array(target.position)
    guess = camera.placement
    if guess is None:
        seen = target_points(PixelState(placements, np.eye(4), points, lens), chain, rows)[1]
        guess = camera_from_rays(seen, rays(lens, rows.pixels), obs.source)
    state = PixelState(placements, np.asarray(guess, float), points, lens)
    check_in_front(target_points(state, chain, rows)[0], rows, obs.source)
    state = refine_camera(state, chain, rows)
    n = placements.y.size  # the joint placement columns, between the camera's and the mount's
    free = (*range(6), *range(6 + n, 12 + n))
    view = PixelView(chain, rows)
    fitted = solve_columns((state,), (view,), free, _MOUNT, MAX_STEPS)[0]
    r = pixel_residuals(fitted, chain, rows)
    rms = float(np.sqrt(np.mean(r**2)))
    return HandEye(fitted.camera, _rigid(points, fitted.target), fitted.target, rms)
