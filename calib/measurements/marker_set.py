"""The pose of a rigid set of markers: several measured points become one measured frame.

A motion-capture system often tracks a plate of markers as one rigid body and reports its
points (the TIAGo data of ``../shared/realdata`` is such a set: the distances between its four
points are constant to 1e-12 m). Their positions then carry one pose per configuration, and
fitting the K points with equal weights gives the set's orientation a weight fixed by the
plate's size, not by how well it is measured. Read as a pose (``--orientation markers``),
the position of marker 1 and the orientation of the set are fitted with a weight estimated
from the data (:mod:`calib.calibration.weighting`).

The orientation is that of the set's mean shape, found by Procrustes alignment (Kabsch;
Umeyama 1991, IEEE TPAMI 13(4)) of each configuration's points onto it. The set's frame is
named by the markers' order, so that every file of the same set agrees: x from marker 1
towards marker 2, z normal to the best plane of the points (on the side of
(p2 - p1) x (pK - p1)), y = z x x. A constant rotation between that frame and the tool is part
of every calibration (the measured-frame rotation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "ITERATIONS",
    "MIN_FLATNESS",
    "MIN_MARKERS",
    "SPREAD_WARNING",
    "MarkerSetPose",
    "marker_set_pose",
]

MIN_MARKERS = 3
"""Points a set needs to have an orientation."""

MIN_FLATNESS = 1e-3
"""Smallest second over largest singular value of the centred shape: below, the points are
(nearly) on a line and the rotation about it is not measured."""

SPREAD_WARNING = 1e-3
"""Non-rigid displacement [m] above which the markers are warned not to be one rigid body."""

ITERATIONS = 5
"""Procrustes passes (mean shape, then alignments); the shape settles in two or three."""


@dataclass(frozen=True)
class MarkerSetPose:
    """Orientations of a marker set and how rigid it is.

    Attributes:
        rotations: Orientation of the set's frame per configuration ``(m, 3, 3)``.
        spread: Largest distance of a marker from the rigid set fitted to it [m].
        flat: Smallest over largest singular value of the centred shape (0: collinear points).
        worst: (configuration, marker) of ``spread``, both counted from 0.
    """

    rotations: np.ndarray
    spread: float
    flat: float
    worst: tuple[int, int] = (0, 0)


def _kabsch(shape: np.ndarray, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotations ``(m, 3, 3)`` and translations ``(m, 3)``: ``points ~ R shape + t``."""
    centre = points.mean(axis=1)
    H = np.einsum("ki,mkj->mij", shape - shape.mean(axis=0), points - centre[:, None])
    U, _, Vt = np.linalg.svd(H)
    d = np.sign(np.linalg.det(np.swapaxes(Vt, 1, 2) @ np.swapaxes(U, 1, 2)))
    D = np.zeros((len(points), 3, 3))
    D[:, 0, 0] = D[:, 1, 1] = 1.0
    D[:, 2, 2] = np.where(d == 0, 1.0, d)
    R = np.swapaxes(Vt, 1, 2) @ D @ np.swapaxes(U, 1, 2)
    return R, centre - np.einsum("mij,j->mi", R, shape.mean(axis=0))


def marker_set_pose(points: np.ndarray) -> MarkerSetPose:
    """Orientation of a set of K >= 3 markers at each configuration.

    Args:
        points: Measured points ``(m, K, 3)`` [m].

    Returns:
        The orientations of the set's frame, the largest non-rigid displacement and the
        shape's flatness.
    """
    points = np.asarray(points, dtype=float)
    shape = points[0] - points[0].mean(axis=0)
    for _ in range(ITERATIONS):
        R, t = _kabsch(shape, points)
        aligned = np.einsum("mji,mkj->mki", R, points - t[:, None])
        shape = aligned.mean(axis=0)
        shape -= shape.mean(axis=0)
    R, t = _kabsch(shape, points)
    fitted = np.einsum("mij,kj->mki", R, shape) + t[:, None]
    s = np.linalg.svd(shape, compute_uv=False)
    off = np.linalg.norm(points - fitted, axis=2)
    worst = np.unravel_index(np.argmax(off), off.shape)
    return MarkerSetPose(
        rotations=R @ _set_frame(shape),
        spread=float(off[worst]),
        flat=float(s[-2] / s[0]) if s[0] > 0 else 0.0,
        worst=(int(worst[0]), int(worst[1])),
    )


def _set_frame(shape: np.ndarray) -> np.ndarray:
    """The set's frame (columns x, y, z) in the shape's coordinates, named by marker order."""
    normal = np.linalg.svd(shape - shape.mean(axis=0))[2][2]
    if normal @ np.cross(shape[1] - shape[0], shape[-1] - shape[0]) < 0:
        normal = -normal
    x = shape[1] - shape[0]
    x = x - (x @ normal) * normal
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(normal, x), normal])
