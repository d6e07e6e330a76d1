"""A pixel term's registration: the camera's placement (closed form, then least squares).

1. The camera's starting placement: given (a ``--camera`` guess or the URDF's optical link),
   or a closed form of the perspective-n-point problem (:func:`camera_from_rays`: the pixels
   undistorted into rays, the direct linear transform on normalised points, the rotation
   projected onto SO(3));
2. refined by least squares on the camera's 6 unknowns alone, on the nominal robot;
3. for the outlier rule, the term fitted alone (:func:`fit_alone`): the unknowns the rows
   determine chosen once (pivoted QR of the Jacobian's scaled columns,
   :func:`~.pixel_term.free_columns`).

Both least squares are the engine's (:func:`~.solve.fit`), x a step composed into the
start (the robot's placements rebased: the first-order directions stay exact).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError
from ..identification.pinhole import Pinhole
from ..kinematics.robot import Chain
from .pixel_term import (
    GAUGE_POINTS,
    KNOWN,
    PixelRows,
    PixelState,
    Unknowns,
    apply_step,
    free_columns,
    pixel_jacobian,
    pixel_residuals,
)
from .registration import nearest_rotation
from .solve import fit

__all__ = [
    "PixelView",
    "camera_from_rays",
    "fit_alone",
    "rays",
    "refine_camera",
    "stacked_rows",
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


def _layout(states: tuple[PixelState, ...], what: Unknowns) -> tuple[list[np.ndarray], int]:
    """Each camera's columns (:func:`~.pixel_term.pixel_jacobian`'s) in the joint columns.

    Joint columns: each camera's 6, the joint placements, the mounting, the target points,
    each camera's intrinsics. Returns the index of each camera's columns and their count.
    """
    C, n = len(states), states[0].placements.y.size
    k = len(states[0].target)
    shared = np.arange(6 * C, 6 * C + n + 6 + (3 * (k - GAUGE_POINTS) if what.targets else 0))
    start = int(shared[-1]) + 1
    out = []
    for c, state in enumerate(states):
        lens = 4 + len(state.lens.distortion) if what.intrinsics else 0
        out.append(np.concatenate([np.arange(6 * c, 6 * c + 6), shared, start + np.arange(lens)]))
        start += lens
    return out, start


def stacked_rows(states, views, what: Unknowns):
    """All cameras' residuals ``(M, 2)`` and joint Jacobian ``(M, 2, size)``."""
    layout, size = _layout(states, what)
    rs, Js = [], []
    for state, view, index in zip(states, views, layout, strict=True):
        r, J = pixel_jacobian(state, view.chain, view.rows, what)
        full = np.zeros((len(r), 2, size))
        full[:, :, index] = J
        rs.append(r)
        Js.append(full)
    return np.concatenate(rs), np.concatenate(Js)


def _moved(states, dx: np.ndarray, what: Unknowns) -> tuple[PixelState, ...]:
    layout = _layout(states, what)[0]
    return tuple(apply_step(s, dx[i], what) for s, i in zip(states, layout, strict=True))


def _residuals(states, views) -> np.ndarray:
    return np.concatenate(
        [pixel_residuals(s, v.chain, v.rows) for s, v in zip(states, views, strict=True)]
    )


@dataclass(frozen=True, eq=False)
class _Cameras:
    """Every camera's state: a fit's start or its state at x (:func:`~.solve.fit`'s)."""

    states: tuple[PixelState, ...]

    def residuals(self, views: tuple[PixelView, ...], torque=None) -> np.ndarray:
        """``observed - pixel`` of every camera's rows ``(M, 2)`` [px]."""
        return -_residuals(self.states, views)


@dataclass(frozen=True, eq=False)
class _Steps:
    """The cameras' joint columns ``free`` as a model of the engine's solver (:func:`~.solve.fit`).

    x is a step composed into the start (:func:`~.pixel_term.apply_step`); the Jacobian's
    columns are the derivatives by a step composed at x: the same stationary points.
    """

    free: tuple[int, ...]
    what: Unknowns

    n_markers = 0  # rows in pixels, unweighted
    pose = False

    def size(self) -> int:
        """Number of free columns."""
        return len(self.free)

    def apply(self, start: _Cameras, x: np.ndarray) -> _Cameras:
        """Every camera's state at x."""
        dx = np.zeros(_layout(start.states, self.what)[1])
        dx[list(self.free)] = x
        return _Cameras(_moved(start.states, dx, self.what))

    def jacobian(self, start: _Cameras, x: np.ndarray, views, torque=None) -> np.ndarray:
        """d(pixel)/dx ``(M, 2, free)`` [px per unit]."""
        J = stacked_rows(self.apply(start, x).states, views, self.what)[1]
        return J[:, :, list(self.free)]


def _solve(states, views, free, what: Unknowns) -> tuple[PixelState, ...]:
    """The engine's least squares (:func:`~.solve.fit`) on the joint columns ``free``."""
    return fit(_Steps(tuple(free), what), _Cameras(tuple(states)), tuple(views), None, 1.0,
               max_iterations=MAX_EVALUATIONS).state.states  # fmt: skip


def refine_camera(state: PixelState, chain: Chain, rows: PixelRows) -> PixelState:
    """The camera's placement by least squares on the current robot (its 6 unknowns alone)."""
    return _solve((state,), (PixelView(chain, rows),), tuple(range(6)), KNOWN)[0]


def fit_alone(state: PixelState, view: PixelView, what: Unknowns) -> PixelState:
    """A registered camera's term fitted alone: the unknowns its rows determine.

    The columns chosen once (:func:`~.pixel_term.free_columns` at ``state``), then the
    engine's least squares on them.
    """
    J = stacked_rows((state,), (view,), what)[1]
    free = free_columns(J.reshape(-1, J.shape[2]), state.placements, what)
    return _solve((state,), (view,), free, what)[0]
