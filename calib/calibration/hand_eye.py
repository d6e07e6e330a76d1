"""Hand-eye calibration from pixels, the robot's joint geometry taken as exact.

OpenCV's ``cv2.calibrateHandEye`` problem by every corner's reprojection error.
Rationale and measurements: docs/developers/engine.md#hand_eye
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from ..kinematics.robot import Chain
from ..measurements.pixels import PixelObservations, Target
from .engine import calibrate_contact_chains
from .pixel_chain import PixelCamera, PixelData, Unknowns
from .pixel_chain_result import PixelChain
from .pixel_fit import MAX_EVALUATIONS
from .registration import rigid_fit

__all__ = ["HandEye", "hand_eye"]


@dataclass(frozen=True, eq=False)
class HandEye:
    """A camera's placement and its target's mounting, fitted with the joints as nominal.

    Attributes:
        camera: The camera's optical frame in its link ``(4, 4)`` [m] (x right, y down, z
            forward).
        mount: The correction of the target: the fitted points are ``R X + t`` of the given
            ones ``X`` (in the target's link) ``(4, 4)`` [m].
        target: The target points fitted, in the target's link ``(k, 3)`` [m].
        rms_px: The reprojection error's RMS over u and v [px] (the rows kept).
        outliers: The rows set aside (their file lines), if any.
    """

    camera: np.ndarray
    mount: np.ndarray
    target: np.ndarray
    rms_px: float
    outliers: tuple[int, ...] = ()


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
            camera, points behind the camera at the start, a usual mistake in the joints.
    """
    data = PixelData(camera, target, obs, Unknowns(mount=True))
    fitted = calibrate_contact_chains(
        [chain], [data], params="frames", max_iterations=MAX_EVALUATIONS
    )
    part = cast(PixelChain, fitted.chains[0])  # a pixel term's part
    points = np.asarray(target.position, dtype=float)
    R, t = rigid_fit(points, part.state.target)
    mount = np.eye(4)
    mount[:3, :3], mount[:3, 3] = R, t
    rms = float(part.pixels["train"]["reprojection_rms_px"]) / np.sqrt(2)  # of |(u, v)|: per axis
    return HandEye(
        part.state.camera, mount, part.state.target, rms, tuple(o.row for o in part.outliers)
    )
