"""Registration: the measurement frame and the markers in closed form, from the nominal model.

Horn's / Umeyama's rigid motion and each marker's least squares, alternated.
Rationale and references: docs/developers/engine.md#registration
"""

from __future__ import annotations

from itertools import accumulate

import numpy as np
import scipy.linalg

from ..kinematics.mdh import Kinematics, MDHModel
from .model import State, registration_state

__all__ = ["ITERATIONS", "nearest_rotation", "register", "register_points", "rigid_fit"]

ITERATIONS = 50
"""Most alternations between the frame and the markers."""


def rigid_fit(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t minimising ``sum |B_i - (R A_i + t)|^2`` (points ``(N, 3)``)."""
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    R = _rotation((A - ca).T @ (B - cb))
    return R, cb - R @ ca


def _rotation(H: np.ndarray) -> np.ndarray:
    """The rotation R maximising ``trace(R H)``: docs/developers/engine.md#_rotation."""
    U, _, Vt, info = _gesdd(H)
    if info != 0:
        U, _, Vt = np.linalg.svd(H)  # raises LinAlgError
    V = Vt.T
    R = V @ U.T
    if _det(R) < 0.0:
        R = (V * _FLIP) @ U.T
    return R


_gesdd = scipy.linalg.lapack.dgesdd
_FLIP = np.array([1.0, 1.0, -1.0])


def _det(M: np.ndarray) -> float:
    """Determinant of a 3x3 matrix."""
    (a, b, c), (d, e, f), (g, h, i) = M.tolist()
    return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)


def nearest_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation nearest to a 3x3 matrix in the Frobenius norm (maximising ``trace(R^T M)``)."""
    return _rotation(np.ascontiguousarray(M.T))


class _Moments:
    """The sums over one tool's configurations that the alternation needs, computed once.

    ``Rt`` ``(m, 3, 3)``, ``pt`` ``(m, 3)`` [m]: the tool's rotations and origins in the base
    frame; ``points`` ``(m, K, 3)`` [m]; ``cb``: their centre [m] (several tools: every
    tool's), or None: of these.
    How: docs/developers/engine.md#registration.
    """

    def __init__(self, Rt, pt, points: np.ndarray, cb: np.ndarray | None = None) -> None:
        m, K = points.shape[:2]
        self.m, self.K, self.slices = m, K, [slice(None)]  # the markers: all of them
        self.count = m * K  # points
        self.cb = points.reshape(-1, 3).mean(axis=0) if cb is None else cb
        Y = points - self.cb  # (m, K, 3)
        self.G = np.ascontiguousarray(np.einsum("iaj,ikb->kjab", Rt, Y).reshape(3 * K, 9))
        self.P = pt.T @ Y.sum(axis=1)
        self.p_mean = pt.mean(axis=0)
        self.R_mean = Rt.mean(axis=0)
        self.back = np.einsum("iba,ib->a", Rt, pt) / m  # mean of R_i^T p_i

    def sums(self, mk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`rigid_fit`'s cross-covariance (markers ``(3 K,)``) and the points' centroid."""
        # One marker: NumPy's sum of one row is 0.0 + it, and dividing by 1 changes nothing.
        mean = mk + 0.0 if self.K == 1 else mk.reshape(-1, 3).sum(axis=0) / self.K
        return self.P + (mk @ self.G).reshape(3, 3), self.p_mean + self.R_mean @ mean

    def markers(self, R: np.ndarray, ca: np.ndarray) -> np.ndarray:
        """Each marker's least squares with the frame (R, t = cb - R ca) held ``(3 K,)``."""
        # R^T (y_ik - t) = R^T Y_ik + ca, and (R^T Y_ik) summed against R_i^T is G : R
        new = self.G @ R.T.ravel()  # one marker: (3,) as the markers are, else (K, 3)
        new = (new if self.K == 1 else new.reshape(self.K, 3)) / self.m
        return (new + (self.R_mean.T @ ca - self.back)).ravel()


class _Partial(_Moments):
    """:class:`_Moments` of points some markers of which were not seen (NaN) in some rows.

    ``seen`` ``(m, K)``: the sums run over the points seen (the rows of a marker not seen
    are left out; docs/developers/engine.md#registration).
    """

    def __init__(self, Rt, pt, points: np.ndarray, cb: np.ndarray | None = None) -> None:
        m, K = points.shape[:2]
        seen = ~np.isnan(points[..., 0])
        w = seen.astype(float)
        self.m, self.K, self.slices = m, K, [slice(None)]
        self.n, self.count = w.sum(axis=0), float(w.sum())  # per marker, in all
        self.cb = points[seen].mean(axis=0) if cb is None else cb
        Y = np.where(seen[..., None], points - self.cb, 0.0)  # (m, K, 3)
        self.G = np.ascontiguousarray(np.einsum("iaj,ikb->kjab", Rt, Y).reshape(3 * K, 9))
        self.P = pt.T @ Y.sum(axis=1)
        self.p_mean = w.sum(axis=1) @ pt / self.count
        self.RW = np.einsum("ik,iab->kab", w, Rt)  # sum of the rotations seeing each marker
        self.back = np.einsum("ik,iba,ib->ka", w, Rt, pt)  # sum of their R_i^T p_i

    def sums(self, mk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cross-covariance and the centroid of the points seen (markers ``(3 K,)``)."""
        mean = np.einsum("kab,kb->a", self.RW, mk.reshape(-1, 3)) / self.count
        return self.P + (mk @ self.G).reshape(3, 3), self.p_mean + mean

    def markers(self, R: np.ndarray, ca: np.ndarray) -> np.ndarray:
        """Each marker's least squares over the rows that see it, the frame held ``(3 K,)``."""
        new = (self.G @ R.T.ravel()).reshape(self.K, 3)
        return ((new + np.swapaxes(self.RW, 1, 2) @ ca - self.back) / self.n[:, None]).ravel()


def _moments(Rt, pt, points: np.ndarray, cb: np.ndarray | None = None) -> _Moments:
    """The sums of one tool's points: :class:`_Partial` if a marker was not seen in some row."""
    return _Partial(Rt, pt, points, cb) if np.isnan(points).any() else _Moments(Rt, pt, points, cb)


class _Tools:
    """:class:`_Moments` of several tools measured in one frame (centred on every tool's mean)."""

    def __init__(self, Rt: list, pt: list, points: list) -> None:
        every = np.concatenate([p.reshape(-1, 3) for p in points])
        cb = (every[~np.isnan(every[:, 0])] if np.isnan(every).any() else every).mean(axis=0)
        self.tools = [_moments(*t, cb) for t in zip(Rt, pt, points, strict=True)]
        self.cb, self.sizes = cb, [t.count for t in self.tools]
        ends = accumulate(3 * t.K for t in self.tools)
        self.slices = [slice(end - 3 * t.K, end) for t, end in zip(self.tools, ends, strict=True)]

    def sums(self, mk: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The cross-covariance of every tool's points (markers ``(3 sum K,)``), their centroid."""
        each = [t.sums(mk[c]) for t, c in zip(self.tools, self.slices, strict=True)]
        H = np.sum([h for h, _ in each], axis=0)
        return H, np.average([ca for _, ca in each], axis=0, weights=self.sizes)

    def markers(self, R: np.ndarray, ca: np.ndarray) -> np.ndarray:
        """Each tool's markers' least squares with the frame held ``(3 sum K,)``."""
        return np.concatenate([t.markers(R, ca) for t in self.tools])


def register_points(
    Rt: list, pt: list, points: list, markers: list, held: list | None = None
) -> tuple[np.ndarray, list]:
    """Closed-form frame ``(4, 4)`` and markers ``(K_c, 3)`` [m] of tools measured in one frame.

    Per tool: ``Rt``, ``pt`` the tool's poses in the base frame, ``points`` ``(m_c, K_c, 3)``
    [m] (NaN: a marker not seen in a row), ``markers``: the guess; ``held``: coordinates
    kept at the guess (or None).
    """
    sums = _moments(Rt[0], pt[0], points[0]) if len(Rt) == 1 else _Tools(Rt, pt, points)
    flat = np.concatenate([np.asarray(m, dtype=float).ravel() for m in markers])
    keep = [(c.start or 0) + k for c, h in zip(sums.slices, held or (), strict=False) for k in h]
    for _ in range(ITERATIONS):
        H, ca = sums.sums(flat)
        new = sums.markers(_rotation(H), ca)  # t is not needed until the end
        if keep:
            new[keep] = flat[keep]
        # every marker moved by less than 1e-12 (a NaN never): max(|new - flat|) < 1e-12
        done = all(abs(a - b) < 1e-12 for a, b in zip(new.tolist(), flat.tolist(), strict=True))
        flat = new
        if done:
            break
    H, ca = sums.sums(flat)
    R = _rotation(H)
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = R, sums.cb - R @ ca
    return frame, [flat[c].reshape(-1, 3) for c in sums.slices]


def register(
    mdh: MDHModel,
    q: np.ndarray,
    points: np.ndarray,
    rotations: np.ndarray | None = None,
    markers: np.ndarray | None = None,
    kin: Kinematics | None = None,
    held: tuple[int, ...] = (),
) -> State:
    """The nominal geometry with the frame, markers (and measured frame's rotation) registered.

    ``q`` ``(m, n)`` [rad or m]; ``points`` ``(m, K, 3)`` [m]; ``markers``: their guess ``(K,
    3)`` [m] (zeros); ``kin``: ``mdh.kinematics(q)``, if made; ``held``: kept at the guess.
    """
    if kin is None:
        kin = mdh.kinematics(q)
    Rt, pt = kin.R[:, -1], kin.p[:, -1]
    K = points.shape[1]
    mk = np.zeros((K, 3)) if markers is None else np.array(markers, dtype=float).reshape(K, 3)
    frame, (mk,) = register_points([Rt], [pt], [points], [mk], [held])
    tool = None
    if rotations is not None:
        R = np.ascontiguousarray(frame[:3, :3])
        tool = nearest_rotation(np.sum(np.swapaxes(Rt, 1, 2) @ R.T @ rotations, axis=0))
    return registration_state(mdh, frame, mk, tool)
