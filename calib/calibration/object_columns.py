"""The selection's object columns by block: each object's unknowns eliminated on its touches.

Rationale and measurements: docs/developers/engine.md#object_columns
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["UNDETERMINED", "FixedBasis", "ObjectColumns", "object_moments", "posture_sums"]

UNDETERMINED = 1e-14
"""Relative Gram eigenvalue under which an object's direction is undetermined (1e-7 singular)."""


@dataclass(frozen=True, eq=False)
class ObjectColumns:
    """Each configuration's rows ``own`` ``(m, rows, o)`` on its object ``index`` (of K)."""

    own: np.ndarray
    index: np.ndarray
    objects: int

    def by_posture(self, groups: np.ndarray | None, m: int) -> ObjectColumns:
        """The rows of each posture once, as :func:`~.selection._by_posture` takes them."""
        if groups is None or int(np.max(groups, initial=-1)) + 1 == m:
            return self
        index = np.zeros(int(np.max(groups)) + 1, dtype=int)
        index[groups] = self.index
        return ObjectColumns(posture_sums(self.own, groups), index, self.objects)

    def unit(self) -> ObjectColumns:
        """The same columns, each object's of unit norm (a zero column left as it is)."""
        norms = np.sqrt(self.sums(np.sum(self.own**2, axis=1)[None])[0])  # (K, o)
        scale = 1.0 / np.where(norms > 0, norms, 1.0)
        return ObjectColumns(self.own * scale[self.index][:, None, :], self.index, self.objects)

    def sums(self, X: np.ndarray) -> np.ndarray:
        """Per subset, the sums of ``X`` ``(b, m, ...)`` over each object's: ``(b, K, ...)``."""
        order = np.argsort(self.index, kind="stable")
        starts = np.searchsorted(self.index[order], np.arange(self.objects))
        return np.add.reduceat(X[:, order], starts, axis=1)

    def transform(self, w: np.ndarray) -> np.ndarray:
        """Each subset's ``W_k`` ``(b, K, o, o)``: ``F_k W_k`` orthonormal (0: undetermined)."""
        o = self.own.shape[2]
        F = self.own[None] * w[:, :, None, None]
        W = np.broadcast_to(np.eye(o), (len(w), self.objects, o, o))
        U = F
        for _ in range(2):  # twice: orthonormal to round-off (Cholesky QR, twice)
            G = self.sums(np.einsum("bmri,bmrj->bmij", U, U))  # (b, K, o, o)
            ev, V = np.linalg.eigh(G)
            top = ev[..., -1:]
            keep = ev > UNDETERMINED * np.where(top > 0, top, np.inf)
            inv = np.divide(
                1.0, np.sqrt(np.where(keep, ev, 1.0)), where=keep, out=np.zeros(ev.shape)
            )
            W = W @ np.einsum("bkij,bkj,bklj->bkil", V, inv, V)
            U = np.einsum("bmri,bmij->bmrj", F, W[:, self.index])
        return W

    def basis(self, w: np.ndarray) -> np.ndarray:
        """Each configuration's rows of its object's basis, per subset ``(b, m, rows, o)``."""
        W = self.transform(w)[:, self.index]
        return np.einsum("bmri,bmij->bmrj", self.own[None] * w[:, :, None, None], W)

    def project(self, U: np.ndarray, X: np.ndarray) -> np.ndarray:
        """``X`` ``(b, m, rows, k)`` minus its projection onto :meth:`basis`'s ``U``."""
        coef = self.sums(np.einsum("bmro,bmrk->bmok", U, X))  # (b, K, o, k)
        return X - np.einsum("bmro,bmok->bmrk", U, coef[:, self.index])


def posture_sums(X: np.ndarray, groups: np.ndarray) -> np.ndarray:
    """Each posture's rows of ``X`` ``(m, ...)`` summed over the root of their count."""
    root = np.sqrt(np.bincount(groups).astype(float))
    out = np.zeros((len(root), *X.shape[1:]))
    np.add.at(out, groups, X)
    return out / root.reshape(-1, *[1] * (X.ndim - 1))


def object_moments(
    A: np.ndarray, e: np.ndarray, rows: int, train: np.ndarray, objects: ObjectColumns
) -> tuple[np.ndarray, ...]:
    """The guard's moments of each fold, objects eliminated (as :func:`~.selection.outer_cv`'s).

    How: docs/developers/engine.md#object_columns
    """
    m = train.shape[1]
    D = A.reshape(m, rows, -1)
    every = FixedBasis(objects, D[:, :, :0], np.ones((1, m)))
    Dp = every.project(D[None])[0].reshape(m * rows, -1)
    x_all = np.linalg.lstsq(Dp, every.project(e.reshape(1, m, rows, 1)).ravel(), rcond=None)[0]
    e = e.reshape(m, rows) - D @ x_all
    X = np.concatenate([D, e[:, :, None]], axis=2)
    out: list[list[np.ndarray]] = [[], [], [], [], []]
    for mask in train:  # one fold at a time: arrays of the data's size
        w = mask[None].astype(float)
        W = objects.transform(w)[0, objects.index]  # (m, o, o)
        Xt = X * mask[:, None, None]
        U = np.einsum("mri,mij->mrj", objects.own * mask[:, None, None], W)
        coef = objects.sums(np.einsum("mro,mrk->mok", U, Xt)[None])[0]  # (K, o, k)
        fitted = np.einsum("mri,mij,mjk->mrk", objects.own, W, coef[objects.index])
        Xt = (Xt - fitted * mask[:, None, None]).reshape(-1, X.shape[2])
        Xh = ((X - fitted) * ~mask[:, None, None]).reshape(-1, X.shape[2])
        normal, held = Xt.T @ Xt, Xh.T @ Xh
        for k, v in enumerate(
            (normal[:-1, :-1], normal[:-1, -1], held[:-1, :-1], held[:-1, -1], held[-1, -1])
        ):
            out[k].append(v)
    Gt, gt, Gh, gh, hh = (np.array(v) for v in out)
    return x_all, Gt, gt + Gt @ x_all, Gh, gh, hh


class FixedBasis:
    """Each subset's basis of the fixed columns: the objects' (by block), then the dense ``D``."""

    def __init__(self, objects: ObjectColumns, D: np.ndarray, w: np.ndarray) -> None:
        self.objects = objects
        self.U = objects.basis(w)
        b, (m, rows, f) = len(w), D.shape
        Dw = self._objects_out(D[None] * w[:, :, None, None])
        self.Q = np.zeros((b, m, rows, 0))
        if f:
            self.Q = np.linalg.qr(Dw.reshape(b, m * rows, f))[0].reshape(b, m, rows, f)

    def _objects_out(self, X: np.ndarray) -> np.ndarray:
        return self.objects.project(self.U, self.objects.project(self.U, X))

    def project(self, X: np.ndarray) -> np.ndarray:
        """``X`` ``(b, m, rows, k)`` minus its projection onto each subset's fixed columns."""
        X = self._objects_out(X)
        for _ in range(2):  # twice (Gram-Schmidt with reorthogonalisation)
            X = X - np.einsum("bmrf,bfk->bmrk", self.Q, np.einsum("bmrf,bmrk->bfk", self.Q, X))
        return X

    def hat(self) -> np.ndarray:
        """Each configuration's hat block of the fixed columns ``(b, m, rows, rows)``."""
        return np.einsum("bmri,bmsi->bmrs", self.U, self.U) + np.einsum(
            "bmri,bmsi->bmrs", self.Q, self.Q
        )
