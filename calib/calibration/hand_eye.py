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
(:func:`~.pixel_fit.refine_camera`), then Levenberg-Marquardt (``scipy.optimize.least_squares``)
on the camera's and the mounting's 12 steps composed into the start
(:func:`~.pixel_term.apply_step`), with the pixel term's analytic Jacobian at the moved state
(:func:`~.pixel_term.pixel_jacobian`): its columns are the derivatives by a step composed
there, so the fit's stationary points are those of the reprojection error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.robot import Chain
from ..measurements.pixels import PixelObservations, Target
from .pixel_fit import camera_from_rays, rays, refine_camera
from .pixel_term import (
    PixelCamera,
    PixelRows,
    PixelState,
    Unknowns,
    apply_step,
    check_in_front,
    pixel_jacobian,
    pixel_residuals,
    pixel_rows,
    target_points,
)
from .placements import Placements

__all__ = ["HandEye", "hand_eye"]

_MOUNT = Unknowns(mount=True)

MAX_EVALUATIONS = 200
"""Most residual evaluations of the fit."""


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
    fitted = _fit(state, chain, rows)
    r = pixel_residuals(fitted, chain, rows)
    rms = float(np.sqrt(np.mean(r**2)))
    return HandEye(fitted.camera, _rigid(points, fitted.target), fitted.target, rms)


def _fit(start: PixelState, chain: Chain, rows: PixelRows) -> PixelState:
    """Levenberg-Marquardt on the camera's and the mounting's 12 steps from ``start``."""
    from scipy.optimize import least_squares

    n = start.placements.y.size  # the joint placement columns, between the camera and mount
    free = np.r_[0:6, 6 + n : 12 + n]

    def moved(x: np.ndarray) -> PixelState:
        step = np.zeros(12 + n)
        step[free] = x
        return apply_step(start, step, _MOUNT)

    def residuals(x: np.ndarray) -> np.ndarray:
        return pixel_residuals(moved(x), chain, rows).ravel()

    def jacobian(x: np.ndarray) -> np.ndarray:
        J = pixel_jacobian(moved(x), chain, rows, _MOUNT)[1]
        return J.reshape(-1, J.shape[2])[:, free]

    found = least_squares(residuals, np.zeros(12), jacobian, method="lm", xtol=1e-15,
                          ftol=1e-15, gtol=1e-15, max_nfev=MAX_EVALUATIONS)  # fmt: skip
    return moved(found.x)
