"""A pixel term's registration: the camera's placement (closed form, then least squares).

The start given, or the perspective-n-point problem in closed form (:func:`camera_from_rays`
of the pixels' :func:`rays`), refined on the camera's 6 alone (:func:`refine_camera`); for
the outlier rule, the term fitted alone (:func:`fit_alone`). Both least squares are the
engine's (:func:`~.solve.fit`), x moving the start as the joint engine moves a pixel term's
unknowns (its columns exact: :func:`~.pixel_term.exact_columns`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError
from ..identification.pinhole import Pinhole
from ..kinematics.robot import Chain
from .pixel_term import (
    KNOWN,
    PixelRows,
    PixelState,
    Unknowns,
    exact_columns,
    free_columns,
    move_own,
    pixel_columns,
    pixel_jacobian,
)
from .registration import nearest_rotation
from .solve import fit

__all__ = [
    "MAX_EVALUATIONS",
    "PixelView",
    "camera_from_rays",
    "fit_alone",
    "rays",
    "refine_camera",
]

UNDISTORT_ITERATIONS = 20
"""Newton steps that invert the distortion (each pixel's ray)."""

MAX_EVALUATIONS = 200
"""Most residual evaluations of a fit."""


def rays(camera: Pinhole, pixels: np.ndarray) -> np.ndarray:
    """The normalised coordinates ``(a, b)`` ``(m, 2)`` of the ray of each pixel.

    Newton's method on ``pinhole((a, b, 1)) = pixel`` from the undistorted guess.
    """
    ab = (pixels - [camera.cx, camera.cy]) / [camera.fx, camera.fy]
    for _ in range(UNDISTORT_ITERATIONS):
        seen = camera.projection(np.column_stack([ab, np.ones(len(ab))]), derivatives=True)
        J = np.asarray(seen.d_point)[:, :, :2]
        step = np.linalg.solve(J, (pixels - seen.pixels)[..., None])[..., 0]
        ab = ab + step
        if np.max(np.abs(step), initial=0.0) < 1e-15:
            break
    return ab


def camera_from_rays(points: np.ndarray, ab: np.ndarray, source: str) -> np.ndarray:
    """The camera's placement in the points' frame ``(4, 4)`` from their rays, in closed form.

    The direct linear transform of the normalised points (centred, mean distance sqrt(3)),
    its sign chosen so the points are in front, its rotation the nearest one (SVD).

    Raises:
        DataError: Fewer than 6 points, or points on one plane or line (no unique solution).
    """
    if len(points) < 6:
        raise DataError(source, f"{len(points)} observations cannot place a camera (at least 6)")
    centre = points.mean(axis=0)
    scale = np.sqrt(3) / max(float(np.mean(np.linalg.norm(points - centre, axis=1))), 1e-12)
    P = np.column_stack([(points - centre) * scale, np.ones(len(points))])
    A = np.zeros((2 * len(P), 12))
    A[0::2, 0:4], A[0::2, 8:12] = -P, ab[:, :1] * P
    A[1::2, 4:8], A[1::2, 8:12] = -P, ab[:, 1:] * P
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    if s[-2] < 1e-6 * s[0]:
        raise DataError(
            source, "the points seen lie on one plane or line: give the camera's placement"
        )
    normalise = np.eye(4)
    normalise[:3, :3] *= scale
    normalise[:3, 3] = -scale * centre
    M = Vt[-1].reshape(3, 4) @ normalise
    if np.median(np.column_stack([points, np.ones(len(points))]) @ M[2]) < 0:
        M = -M
    seen = np.eye(4)  # the points' frame in the camera
    seen[:3, :3] = nearest_rotation(M[:, :3])
    seen[:3, 3] = M[:, 3] / np.linalg.svd(M[:, :3], compute_uv=False).mean()
    return np.linalg.inv(seen)


@dataclass(frozen=True, eq=False)
class PixelView:
    """One camera's rows on its chain (a camera's link to the target's tool).

    Attributes:
        chain: The camera's link to the tool.
        rows: Its observations.
    """

    chain: Chain
    rows: PixelRows


@dataclass(frozen=True, eq=False)
class _Steps:
    """The columns ``free`` of :func:`~.pixel_term.pixel_jacobian` as the solver's model.

    x moves the start: the joint placements shifted, the camera, the mounting, the points and
    the lens as a pixel term's own unknowns (:func:`~.pixel_term.move_own`); the Jacobian is
    by x itself (:func:`~.pixel_term.exact_columns`), as the joint engine's.
    """

    free: tuple[int, ...]
    what: Unknowns

    n_markers = 0  # rows in pixels, unweighted
    pose = False

    def size(self) -> int:
        """Number of free columns."""
        return len(self.free)

    def _steps(self, start: PixelState, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The joint placements' change and the own unknowns (with the mounting's 6)."""
        dx = np.zeros(pixel_columns(start, self.what))
        dx[list(self.free)] = x
        n = start.placements.y.size
        return dx[6 : 6 + n], np.r_[dx[:6], dx[6 + n :]]

    def apply(self, start: PixelState, x: np.ndarray) -> PixelState:
        """The camera's state at x."""
        dy, own = self._steps(start, x)
        what = Unknowns(True, self.what.targets, self.what.intrinsics)
        camera, target, lens = move_own(start.camera, start.target, start.lens, own, what)
        return PixelState(start.placements.shifted(dy), camera, target, lens)

    def jacobian(self, start: PixelState, x: np.ndarray, view: PixelView, torque=None):
        """d(pixel)/dx ``(m, 2, free)`` [px per unit]."""
        state, own = self.apply(start, x), self._steps(start, x)[1]
        n, point = state.placements.y.size, view.rows.point
        robot = any(6 <= c < 6 + n for c in self.free)  # else no joint placement column
        J = pixel_jacobian(state, view.chain, view.rows, self.what, robot)[1]
        J = exact_columns(J, self.what, start.target, own, n, point)
        return J[:, :, list(self.free)]


def _solve(state: PixelState, view: PixelView, free, what: Unknowns) -> PixelState:
    """The engine's least squares (:func:`~.solve.fit`) on the columns ``free``."""
    steps = _Steps(tuple(free), what)
    return fit(steps, state, view, None, 1.0, max_iterations=MAX_EVALUATIONS).state


def refine_camera(state: PixelState, chain: Chain, rows: PixelRows) -> PixelState:
    """The camera's placement by least squares on the current robot (its 6 unknowns alone)."""
    return _solve(state, PixelView(chain, rows), tuple(range(6)), KNOWN)


def fit_alone(state: PixelState, view: PixelView, what: Unknowns) -> PixelState:
    """A registered camera's term fitted alone: the unknowns its rows determine.

    The columns chosen once (:func:`~.pixel_term.free_columns` at ``state``), then the
    engine's least squares on them.
    """
    J = pixel_jacobian(state, view.chain, view.rows, what)[1]
    free = free_columns(J.reshape(-1, J.shape[2]), state.placements, what)
    return _solve(state, view, free, what)
