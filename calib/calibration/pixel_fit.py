"""Fit a pixel term: the camera's placement (closed form, then least squares), then the robot.

1. The camera's starting placement: given (a ``--camera`` guess or the URDF's optical link),
   or a closed form of the perspective-n-point problem (:func:`camera_from_rays`: the pixels
   undistorted into rays, the direct linear transform on normalised points, the rotation
   projected onto SO(3));
2. refined by least squares on the camera's 6 unknowns alone, on the nominal robot;
3. the unknowns the rows determine chosen once (pivoted QR of the Jacobian's scaled columns,
   :func:`~.pixel_term.free_columns`), then Levenberg-Marquardt on them, each step composed
   into the robot's placements (the first-order directions stay exact).
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
    check_in_front,
    column_names,
    free_columns,
    pixel_jacobian,
    pixel_residuals,
    target_points,
)
from .placements import Placements

__all__ = [
    "PixelFit",
    "PixelView",
    "camera_from_rays",
    "fit_pixels",
    "rays",
    "refine_camera",
    "stacked_rows",
    "target_residuals",
]

UNDISTORT_ITERATIONS = 20
"""Newton steps that invert the distortion (each pixel's ray)."""

MAX_STEPS = 60
"""Most Levenberg-Marquardt steps of a fit."""


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
    U, S, Wt = np.linalg.svd(M[:, :3])
    R = U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Wt))]) @ Wt
    seen = np.eye(4)  # the points' frame in the camera
    seen[:3, :3], seen[:3, 3] = R, M[:, 3] / S.mean()
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


def _solve(states, views, free, what: Unknowns, steps: int) -> tuple[PixelState, ...]:
    """Levenberg-Marquardt on the joint columns ``free``; the states of least squared error."""
    r, J = stacked_rows(states, views, what)
    cost, damping = float(np.sum(r**2)), 1e-6
    size, m = J.shape[2], len(r)
    for _ in range(steps):
        A = J.reshape(-1, size)[:, free]
        g, H = A.T @ r.ravel(), A.T @ A
        while True:
            step = np.linalg.solve(H + damping * np.diag(np.diag(H) + 1e-30), -g)
            dx = np.zeros(size)
            dx[list(free)] = step
            trial = _moved(states, dx, what)
            r_t = _residuals(trial, views)
            cost_t = float(np.sum(r_t**2)) if np.all(np.isfinite(r_t)) else np.inf
            if cost_t <= cost or damping > 1e12:
                break
            damping *= 10
        if cost_t > cost:
            break
        done = cost - cost_t <= 1e-14 * cost or cost_t < 1e-26 * m
        states, cost, damping = trial, cost_t, max(damping / 10, 1e-9)
        if done:
            break
        r, J = stacked_rows(states, views, what)
    return states


def target_residuals(state: PixelState, chain, rows: PixelRows) -> np.ndarray:
    """Reprojection errors ``(m, 2)`` [px]."""
    return pixel_residuals(state, chain, rows)


def refine_camera(state: PixelState, chain: Chain, rows: PixelRows) -> PixelState:
    """The camera's placement by least squares on the current robot (its 6 unknowns alone)."""
    return _solve((state,), (PixelView(chain, rows),), tuple(range(6)), KNOWN, MAX_STEPS)[0]


@dataclass(frozen=True, eq=False)
class PixelFit:
    """A fitted pixel problem: one or several cameras seeing one target.

    Attributes:
        starts: Each camera's state after its registration (nominal robot).
        states: Each camera's fitted state (one robot and target: the same in each).
        free: The joint columns fitted (indices into :attr:`names`).
        names: Every joint column's name.
    """

    starts: tuple[PixelState, ...]
    states: tuple[PixelState, ...]
    free: tuple[int, ...]
    names: tuple[str, ...]

    @property
    def start(self) -> PixelState:
        """The first camera's registered state."""
        return self.starts[0]

    @property
    def state(self) -> PixelState:
        """The first camera's fitted state."""
        return self.states[0]


def _names(states, cameras: tuple[str, ...], what: Unknowns) -> tuple[str, ...]:
    """The joint columns' names: each camera's under its name."""
    layout, size = _layout(states, what)
    names = [""] * size
    for state, name, index in zip(states, cameras, layout, strict=True):
        for i, local in zip(index, column_names(state, what), strict=True):
            names[i] = local.replace("camera.", f"{name}.", 1)
    return tuple(names)


def fit_pixels(
    placements: Placements,
    target: np.ndarray,
    guesses: tuple[np.ndarray | None, ...],
    views: tuple[PixelView, ...],
    lenses: tuple[Pinhole, ...],
    cameras: tuple[str, ...],
    what: Unknowns = KNOWN,
    source: str = "<observations>",
) -> PixelFit:
    """Register each camera, choose the determined unknowns, fit them together.

    Args:
        placements: The robot (zero errors on every camera chain's joints).
        target: The target points in the tool frame ``(k, 3)`` [m].
        guesses: Each camera's optical frame in its chain's base link ``(4, 4)`` [m], or
            None: placed in closed form (:func:`camera_from_rays`).
        views: Each camera's chain and rows.
        lenses: Each camera's intrinsics (the start, with ``what.intrinsics``).
        cameras: Each camera's name.
        what: The optional unknowns (mounting, target points, intrinsics).
        source: The observations' file, for messages.

    Raises:
        DataError: Too few observations, or points behind a camera once it is placed.
    """
    starts = []
    for guess, view, lens in zip(guesses, views, lenses, strict=True):
        chain, rows = view.chain, view.rows
        if guess is None:
            state = PixelState(placements, np.eye(4), target, lens)
            p_link = target_points(state, chain, rows)[1]
            guess = camera_from_rays(p_link, rays(lens, rows.pixels), source)
        state = PixelState(placements, guess, target, lens)
        check_in_front(target_points(state, chain, rows)[0], rows, source)
        starts.append(refine_camera(state, chain, rows))
    J = stacked_rows(tuple(starts), views, what)[1]
    free = free_columns(J.reshape(-1, J.shape[2]), placements, what, len(views))
    fitted = _solve(tuple(starts), views, free, what, MAX_STEPS)
    return PixelFit(tuple(starts), fitted, free, _names(tuple(starts), cameras, what))
