"""Registration of contacts: planes, fixed points and fixed poses on the nominal model.

Rationale and measurements: docs/developers/engine.md#contact_registration
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..core.words import counted, noun
from ..exceptions import ContactGeometryError
from ..identification.contacts import (
    Contact,
    FixedPointContact,
    FixedPoseContact,
    PlaneContact,
    PlanePointContact,
)
from ..kinematics.so3 import rotation_matrix
from .contact_blocks import BlockSystem, block_lstsq, dense
from .contact_model import ContactFrames, plane_frames, row_weights
from .determined import ill_posed
from .registration import nearest_rotation
from .weighting import DEFAULT_WEIGHT

__all__ = ["MIN_TOUCHES", "refine", "register_contacts"]

MIN_TOUCHES = 3  # fewest touches of one plane, point or pose
ITERATIONS = 50  # most Gauss-Newton steps
STEP_TOLERANCE = 1e-13  # largest parameter step [m or rad] at which Gauss-Newton stops
CONDITION_LIMIT = 1e-9  # smallest singular value accepted, relative to the largest
MIN_SPREAD = 1e-6  # smallest RMS spread [rad] of the tool's orientations about any axis (a tip)


def _groups(ids: Sequence[str]) -> tuple[tuple[str, ...], np.ndarray]:
    """The distinct ids in order of appearance and each touch's index among them."""
    names = tuple(dict.fromkeys(str(i) for i in ids))
    index = np.array([names.index(str(i)) for i in ids], dtype=int)
    counts = np.bincount(index, minlength=len(names))
    for name, count in zip(names, counts, strict=True):
        if count < MIN_TOUCHES:
            raise ContactGeometryError(
                f"'{name}' has {counted(count, 'touches')}: at least {MIN_TOUCHES} are needed "
                "to fit it"
            )
    return names, index


def _tilt_to(b: np.ndarray) -> np.ndarray:
    """Rotation vector about an axis orthogonal to z that takes e_z to the unit vector b."""
    axis = np.array([-b[1], b[0], 0.0])
    s = np.linalg.norm(axis)
    return np.zeros(2) if s < 1e-300 else (axis * np.arctan2(s, b[2]) / s)[:2]


def _point_normals(x: np.ndarray, index: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Each plane's normal through its contact points ``x``, on the side of ``up`` ``(K, 3)``."""
    normals = []
    for k, u in enumerate(up):
        centred = x[index == k] - x[index == k].mean(axis=0)
        n = np.linalg.svd(centred, full_matrices=False)[2][-1]
        normals.append(n if n @ u >= 0 else -n)
    return np.array(normals)


def refine(
    frames: ContactFrames,
    rotations: np.ndarray,
    positions: np.ndarray,
    index: np.ndarray,
    weight: float = DEFAULT_WEIGHT,
) -> ContactFrames:
    """The frames at the least-squares minimum of the kind's weighted gap (Gauss-Newton).

    ContactGeometryError where the touches do not fix the unknowns.
    """
    w = row_weights(frames.kind, weight)
    x = np.zeros(frames.size)
    K = len(frames.ids)
    for _ in range(ITERATIONS):
        cur = frames.moved(x)
        R, p = cur.relative(rotations, positions, index)
        r = frames.kind.residual(R, p) * w
        Jo, Jc = cur.parts(R, p, index, x, w)
        sol = block_lstsq(BlockSystem(Jo, Jc, r, index, K))
        if not sol.smallest > CONDITION_LIMIT * sol.largest:
            names = frames.names()  # the unknowns of the undetermined directions
            found = ill_posed(dense(Jo, Jc, index, K).reshape(-1, frames.size), names)
            found = [d for d in found if d.condition >= 1 / CONDITION_LIMIT]
            named = [n for n in names if any(n in d.names for d in found)]
            which = f" (they cannot separate {', '.join(named)})" if named else ""
            objects = noun(len(frames.ids), f"{frames.kind.object_name}s")
            raise ContactGeometryError(
                f"the touches do not fix the {objects} and the contact frame"
                f"{which}: touch at several orientations, or at spots that span each "
                f"{frames.kind.object_name}"
            )
        step = np.r_[sol.objects.ravel(), sol.shared]
        x = x + step
        if np.max(np.abs(step)) < STEP_TOLERANCE:
            break
    return frames.moved(x)


def _planes(kind, R, p, guess, index, names, weight) -> ContactFrames:
    """Flush touches: the chordal fit of the normals, or the contact points' planes."""
    K = len(names)
    M = np.stack([np.sum(np.swapaxes(R[index == k], 1, 2), axis=0) for k in range(K)])
    U = np.linalg.svd(np.concatenate(list(M), axis=1), full_matrices=False)[0]
    z0 = guess[:3, 2]
    a = U[:, 0] if U[:, 0] @ z0 >= 0 else -U[:, 0]
    x = p + R @ guess[:3, 3]
    up = np.array([(R[index == k] @ z0).sum(axis=0) for k in range(K)])
    candidates = []
    for normals in (np.einsum("kji,j->ki", M, a), _point_normals(x, index, up)):
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        ak = np.einsum("kij,kj->i", M, normals)
        ak = ak / np.linalg.norm(ak)
        heights = np.array([np.mean(x[index == k] @ normals[k]) for k in range(K)])
        C = guess.copy()
        C[:3, :3] = guess[:3, :3] @ rotation_matrix(np.array([*_tilt_to(guess[:3, :3].T @ ak), 0]))
        planes = plane_frames(normals, heights, p + R @ C[:3, 3], index)
        frames = ContactFrames(kind, C, planes, names)
        cost = np.sum((frames.gaps(R, p, index) * row_weights(kind, weight)) ** 2)
        candidates.append((float(cost), frames))
    return min(candidates, key=lambda c: c[0])[1]


def _plane_points(kind, R, p, guess, index, names, weight) -> ContactFrames:
    """A tip's touches: each plane through the tip's points at the guessed tip."""
    x = p + R @ guess[:3, 3]
    normals = _point_normals(x, index, np.tile([0.0, 0.0, 1.0], (len(names), 1)))
    heights = [float(np.mean(x[index == k] @ n)) for k, n in enumerate(normals)]
    return ContactFrames(kind, guess, plane_frames(normals, np.array(heights), x, index), names)


def _points(kind, R, p, guess, index, names, weight) -> ContactFrames:
    """A tip at fixed points: the tip and the points by linear least squares."""
    K = len(names)
    count = np.bincount(index, minlength=K)[:, None]
    Rbar = np.zeros((K, 3, 3))
    np.add.at(Rbar, index, R)
    pbar = np.zeros((K, 3))
    np.add.at(pbar, index, p)
    Rbar, pbar = Rbar / count[:, :, None], pbar / count
    A = (R - Rbar[index]).reshape(-1, 3)
    tip, _, _, s = np.linalg.lstsq(A, -(p - pbar[index]).ravel(), rcond=None)
    if s[-1] < MIN_SPREAD * np.sqrt(len(p)):
        raise ContactGeometryError(
            "the touches do not fix the tip: touch each point at orientations about several axes"
        )
    C = guess.copy()
    C[:3, 3] = tip
    points = np.tile(np.eye(4), (K, 1, 1))
    points[:, :3, 3] = pbar + Rbar @ tip
    return ContactFrames(kind, C, points, names)


def _poses(kind, R, p, C, index, names, weight) -> ContactFrames:
    """Fixed poses: the mean position, the chordal mean rotation (the contact kept)."""
    Q = R @ C[:3, :3]
    x = p + R @ C[:3, 3]
    poses = np.tile(np.eye(4), (len(names), 1, 1))
    for k in range(len(names)):
        poses[k, :3, :3] = nearest_rotation(Q[index == k].sum(axis=0))
        poses[k, :3, 3] = x[index == k].mean(axis=0)
    return ContactFrames(kind, C, poses, names)


_Start = Callable[..., ContactFrames]

_STARTS: dict[type, tuple[_Start, bool]] = {
    PlaneContact: (_planes, True),
    PlanePointContact: (_plane_points, False),
    FixedPointContact: (_points, False),
    FixedPoseContact: (_poses, False),
}
"""Each kind's closed form, and whether its refinement weighs the angle rows by the weight
given (a plane-point has none; a pose's rotation is its rows' mean whatever their weight)."""


def register_contacts(
    kind: Contact,
    rotations: np.ndarray,
    positions: np.ndarray,
    ids: Sequence[str],
    contact: np.ndarray,
    weight: float = DEFAULT_WEIGHT,
    source: str | None = None,
) -> ContactFrames:
    """The objects and the contact frame registered from the tool's placements (nominal model).

    ``contact``: the contact frame's guess (a fixed pose's and a tip's rotation kept);
    ``weight`` [m/rad]; ``source``: the touches' file, which the errors name first.

    Raises:
        ContactGeometryError: Fewer than ``MIN_TOUCHES`` touches of an object, or a geometry
            that fixes nothing (one orientation and spots on a line for a plane; one
            orientation, or rotations about one axis only, for a tip).
        InvalidArgumentError: A weight that is not positive.
    """
    start, weighted = _STARTS[type(kind)]
    R, p, guess = (np.asarray(a, dtype=float) for a in (rotations, positions, contact))
    try:
        names, index = _groups(ids)
        frames = start(kind, R, p, guess, index, names, weight)
        if isinstance(kind, FixedPointContact):
            return frames  # the closed form is the least squares
        frames = refine(frames, R, p, index, weight if weighted else DEFAULT_WEIGHT)
    except ContactGeometryError as exc:
        if source is None:
            raise
        raise ContactGeometryError(f"{source}: {exc}") from None
    return frames.centred(R, p, index)
