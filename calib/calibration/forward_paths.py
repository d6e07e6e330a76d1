"""Forward paths of the selection (:mod:`.selection`), batched over subsets of configurations.

Each step by rank-one updates of the leave-one-configuration-out sums.
Rationale and measurements: docs/developers/engine.md#forward_paths
"""

from __future__ import annotations

import contextlib

import numpy as np

from .object_columns import FixedBasis, ObjectColumns

__all__ = [
    "DEPENDENT",
    "REFRESH",
    "SHRINK",
    "SMALL",
    "lu_errors",
    "paths",
    "residual",
    "spd_solve",
]

DEPENDENT = 1e-8
"""A unit-norm candidate whose part outside the fitted columns is shorter is dependent."""

REFRESH = 0.1
"""Least ``1 - q_i^T (I - H_ii)^-1 q_i`` for a Sherman-Morrison update (else inverted afresh)."""

SMALL = 8
"""Blocks of at most this many rows are solved by :func:`spd_solve` (larger: LAPACK)."""

SHRINK = 1e-2
"""A candidate's sums are computed afresh when its squared norm falls under this fraction."""


def lu_errors(M: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Squared leave-one-out errors ``(c, m)`` from ``M = I - H`` and ``r`` (LU; inf: singular)."""
    c, m, rows = r.shape
    try:  # a leverage of 1 or near it: LAPACK's LU (with pivoting) tells
        loo = np.linalg.solve(M, r[..., None])
    except np.linalg.LinAlgError:
        loo = np.full((c, m, rows, 1), np.inf)
        for k in range(c):  # rare: find the singular fits one by one
            with contextlib.suppress(np.linalg.LinAlgError):
                loo[k] = np.linalg.solve(M[k], r[k, ..., None])
    return np.sum(loo**2, axis=(2, 3))


def spd_solve(M: np.ndarray, y: np.ndarray, overwrite: bool = False) -> np.ndarray:
    """Solutions ``(n, systems)`` of small SPD systems ``M`` ``(n, n, systems)`` (no pivoting)."""
    n = len(y)  # overwrite: M and y (C-contiguous) worked on in place, not copied
    a, x = (M, y) if overwrite else (np.array(M, order="C"), np.array(y, order="C"))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for p in range(n - 1):
            f = a[p + 1 :, p] / a[p, p]
            a[p + 1 :, p + 1 :] -= f[:, None] * a[p, p + 1 :]
            x[p + 1 :] -= f * x[p]
        x[n - 1] /= a[n - 1, n - 1]
        for p in range(n - 2, -1, -1):
            x[p] -= np.einsum("js,js->s", a[p, p + 1 :], x[p + 1 :])
            x[p] /= a[p, p]
    return x


def paths(
    A: np.ndarray,
    e: np.ndarray,
    rows: int,
    start: list[int],
    candidates: list[int],
    train: np.ndarray,
    objects: ObjectColumns | None = None,
) -> list[tuple[list[int], np.ndarray]]:
    """The greedy forward paths of the subsets ``train`` ``(subsets, m)`` at once.

    Each step adds, in each subset, the candidate of least leave-one-out error to ``start``
    (and ``objects``). Per subset: the columns in the order added, and its configurations'
    squared left-out errors before the first and after each addition ``(steps + 1, m_subset)``.
    """
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        state = _Batch(A, e, rows, start, candidates, train, objects)
        errors, chosen = [np.where(state.lost, np.inf, state.vv)], []  # a copy: vv moves on
        for _ in candidates:
            active = state.prune()
            if not active.any():
                break
            j, stuck = _pick(state.totals(), state.alive)
            errors.append(state.errors_of(j, stuck))
            state.add(j, active)
            chosen.append(np.where(active, state.index[j], -1))
    return _split_paths(candidates, chosen, errors, train)


class _Batch:
    """Working state of :func:`paths`: every subset's fit as the columns are added.

    Arrays by configuration end with it, rows component-major: ``r`` ``(b, rows, m)``, ``C``
    the candidates ``(k, b, rows, m)``, ``S`` their sums ``D, N, K, 2 L`` (names of the page).
    """

    def __init__(self, A, e, rows, start, candidates, train, objects=None):
        b, m = train.shape
        self.m, self.rows, self.b = m, rows, np.arange(b)
        begin = _start if objects is None else _block_start
        self.r, self.H0, self.C, self.floor2 = begin(A, e, rows, start, candidates, train, objects)
        self.work = np.empty(self.C.shape)
        self.added: list[np.ndarray] = []
        self.alive = np.ones((len(candidates), b), dtype=bool)
        self.index = np.arange(len(candidates))
        self.lost, self.any_lost = np.zeros((b, m), dtype=bool), False
        self.S: list[np.ndarray] = []  # empty: to compute afresh
        self.nu2 = self.lim = np.zeros(self.alive.shape)
        self.Minv = self.v = self.vv = self.sq = np.zeros(0)
        self._invert(self.H0)

    def hat(self) -> np.ndarray:
        """Hat blocks of the current fits ``(b, rows, rows, m)`` (after a step)."""
        q = np.stack(self.added)
        return self.H0 + np.einsum("sbim,sbjm->bijm", q, q)

    def _invert(self, H: np.ndarray) -> None:
        """``Minv`` of the hat blocks ``H`` (leverage 1: lost from then on), then ``v``."""
        M = np.eye(self.rows) - np.moveaxis(H * ~self.lost[:, None, None, :], 3, 1)
        try:
            inv = np.linalg.inv(M)
        except np.linalg.LinAlgError:  # a leverage of 1
            singular = np.linalg.det(M) == 0.0
            self.lost |= singular
            self.any_lost = True
            M[singular] = np.eye(self.rows)
            inv = np.linalg.inv(M)
        self.Minv, self.S = np.ascontiguousarray(np.moveaxis(inv, 1, 3)), []
        self._set_v()

    def _set_v(self) -> None:
        """``v = M r`` and its squares by configuration."""
        self.v = np.einsum("bijm,bjm->bim", self.Minv, self.r)
        self.vv = np.einsum("bim,bim->bm", self.v, self.v)

    def prune(self) -> np.ndarray:
        """Mark the dependent candidates dead; the subsets with one alive ``(b,)``."""
        if not self.S or (self.nu2 < self.lim).any():
            Cf = self.C.reshape(len(self.C), len(self.b), -1)
            self.nu2, self.S = np.einsum("kbn,kbn->kb", Cf, Cf), []
            self.alive &= self.nu2 > self.floor2
        some = self.alive.any(axis=1)
        if not some.all():  # drop the columns no subset can add any more
            self.C, self.floor2 = self.C[some], self.floor2[some]
            self.alive, self.nu2, self.index = self.alive[some], self.nu2[some], self.index[some]
            self.S, self.lim = [x[some] for x in self.S], self.lim[some]
        return np.asarray(self.alive.any(axis=0))

    def totals(self) -> np.ndarray:
        """Summed squared left-out errors of each subset's fit with each candidate ``(k, b)``.

        Inf where the candidate is dead, one configuration would determine it or is ``lost``.
        """
        if not self.S:
            self._fresh(self.Minv)
        D, N, K, L2 = self.S
        P = N / D
        U = P * K
        U += L2
        P *= U
        P += self.vv
        self.sq, self.single = P, (1e-12 * self.nu2)[:, :, None] >= D
        total = np.einsum("kbm->kb", P)
        ok = ~self.single.any(axis=2)
        ok &= self.alive
        if self.any_lost:
            ok &= ~self.lost.any(axis=1)
        ok &= np.isfinite(total)
        return np.where(ok, total, np.inf)

    def errors_of(self, j: np.ndarray, stuck: bool) -> np.ndarray:
        """Squared left-out errors ``(b, m)`` of each subset's fit with its candidate j added."""
        sq = np.maximum(self.sq[j, self.b], 0.0)  # a square: round-off in the sums, not < 0
        sq[self.single[j, self.b] | self.lost] = np.inf
        if stuck:
            sq[~np.isfinite(sq)] = np.inf
        return sq

    def _fresh(self, Minv: np.ndarray) -> None:
        """The sums ``S`` computed afresh from ``M``, the candidates and ``v``."""
        MC = np.einsum("bijm,kbjm->kbim", Minv, self.C)
        rho = np.einsum("kbim,bim->kb", self.C, self.r)
        self.S = [
            self.nu2[:, :, None] - np.einsum("kbim,kbim->kbm", self.C, MC),
            np.einsum("bim,kbim->kbm", self.v, self.C) - rho[:, :, None],
            np.einsum("kbim,kbim->kbm", MC, MC),
            2.0 * np.einsum("bim,kbim->kbm", self.v, MC),
        ]
        lim = np.maximum(SHRINK * self.nu2, 2.0 * self.floor2)
        self.lim = np.where(self.alive, lim, -np.inf)

    def add(self, j: np.ndarray, active: np.ndarray) -> None:
        """Add candidate ``j[s]`` to each active subset s: rank-one updates of everything."""
        b = self.b
        q = self.C[j, b]
        q *= (active / np.sqrt(np.einsum("bim,bim->b", q, q) + ~active))[:, None, None]
        kappa = np.einsum("bim,bim->b", q, self.r)
        Cf = self.C.reshape(len(self.C), len(b), -1)
        beta = (np.swapaxes(Cf, 0, 1) @ q.reshape(len(b), -1, 1))[:, :, 0].T  # q^T c (k, b)
        self.alive[j, b] = False
        self.added.append(q)
        a = np.einsum("bijm,bjm->bim", self.Minv, q)
        d = 1.0 - np.einsum("bim,bim->bm", q, a)  # 1 - the leverage the column adds
        if self.any_lost or d.min() <= REFRESH:
            newly = active[:, None] & (d <= 1e-12) & ~self.lost
            self.lost |= newly
            self.any_lost = bool(self.lost.any())
            if newly.any() or np.where(self.lost, 1.0, d).min() <= REFRESH:
                self._update_columns(q, kappa, beta)
                self._invert(self.hat())
                return
            a *= ~self.lost[:, None, :]
            d[self.lost] = 1.0
        hav = np.array((a, self.r, self.v))
        hav *= a
        h, ar, av = hav.sum(axis=2)
        psi = ar - kappa[:, None]
        psi /= d
        self.lim[j, b] = -np.inf
        self._update_sums(self.Minv, a, d, h, psi, av, beta)
        self.nu2 -= beta * beta
        self._update_columns(q, kappa, beta)
        self.Minv += a[:, :, None] * (a / d[:, None])[:, None]
        if self.any_lost:
            self._set_v()
        else:  # v' = M' r' = v + psi a
            self.v += psi[:, None] * a
            av += av
            h *= psi
            av += h
            av *= psi
            self.vv += av

    def _update_columns(self, q: np.ndarray, kappa: np.ndarray, beta: np.ndarray) -> None:
        """Residuals and candidates made orthogonal to the added unit columns ``q``."""
        self.r -= q * kappa[:, None, None]
        work = np.multiply(beta[:, :, None, None], q, out=self.work[: len(self.C)])
        self.C -= work  # a buffer kept: a new array this large would be new pages each step

    def _update_sums(self, Minv, a, d, h, psi, av, beta) -> None:
        """The sums ``S`` after the columns q are added (engine.md#forward_paths's formulas)."""
        Y = np.einsum("bim,kbim->kbm", np.einsum("bjim,bjm->bim", Minv, a), self.C)
        W = np.einsum("bim,kbim->kbm", a, self.C)
        mu = psi * h
        mu += av
        D, N, K, L2 = self.S
        W -= beta[:, :, None]
        phi = W / d
        N += psi * W
        W *= phi
        D -= W
        t = phi * h
        t += Y
        t += Y
        t *= phi
        K += t
        Y *= psi
        phi *= mu
        Y += phi
        Y += Y
        L2 += Y


def _start(A, e, rows, start, candidates, train, objects=None):
    """Each subset's fit of ``start``: residuals, hat blocks, candidates orthogonal, floors."""
    b, m = train.shape
    Ap = np.swapaxes(A.reshape(m, rows, -1), 0, 1).reshape(m * rows, -1)
    w = np.tile(train, rows).astype(float)
    Q = np.linalg.qr(Ap[:, start] * w[:, :, None])[0]
    r = residual(Q, np.swapaxes(e.reshape(m, rows), 0, 1).ravel() * w).reshape(b, rows, m)
    Qb = Q.reshape(b, rows, m, -1)
    C = Ap[:, candidates] * w[:, :, None]
    floor2 = DEPENDENT**2 * np.einsum("bnk,bnk->kb", C, C)
    for _ in range(2):  # twice is enough (Gram-Schmidt with reorthogonalisation)
        C = C - Q @ (np.swapaxes(Q, 1, 2) @ C)
    C = np.ascontiguousarray(np.transpose(C, (2, 0, 1))).reshape(-1, b, rows, m)
    return r, np.einsum("bims,bjms->bijm", Qb, Qb), C, floor2


def _block_start(A, e, rows, start, candidates, train, objects: ObjectColumns):
    """:func:`_start` with the objects' columns in too, by block (:class:`FixedBasis`)."""
    m = train.shape[1]
    Ab = A.reshape(m, rows, -1)
    w = train.astype(float)
    basis = FixedBasis(objects, Ab[:, :, start], w)
    r = basis.project((e.reshape(m, rows)[None] * w[:, :, None])[..., None])[..., 0]
    C = Ab[None][:, :, :, candidates] * w[:, :, None, None]
    floor2 = DEPENDENT**2 * np.einsum("bmrk,bmrk->kb", C, C)
    C = np.ascontiguousarray(np.transpose(basis.project(C), (3, 0, 2, 1)))
    H0 = np.ascontiguousarray(np.transpose(basis.hat(), (0, 2, 3, 1)))
    return np.ascontiguousarray(np.swapaxes(r, 1, 2)), H0, C, floor2


def residual(Q: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``e - Q Q^T e`` of a stack of orthonormal bases ``(b, n, s)`` and vectors ``(b, n)``."""
    return e - np.einsum("bns,bs->bn", Q, np.einsum("bns,bn->bs", Q, e))


def _pick(total: np.ndarray, alive: np.ndarray) -> tuple[np.ndarray, bool]:
    """Per subset, the candidate of least total, or the first live one if all are inf (and if)."""
    b = np.arange(total.shape[1])
    j = total.argmin(axis=0)
    stuck = np.isinf(total[j, b])
    if not stuck.any():
        return j, False
    return np.where(stuck, alive.argmax(axis=0), j), True


def _split_paths(candidates, chosen, errors, train) -> list[tuple[list[int], np.ndarray]]:
    """Each subset's order (candidate columns) and errors on its own configurations."""
    steps = np.array(chosen, dtype=int).reshape(-1, train.shape[0])
    errs = np.array(errors)
    out = []
    for k, mask in enumerate(train):
        picked = [candidates[j] for j in steps[:, k] if j >= 0]
        out.append((picked, errs[: len(picked) + 1, k][:, mask]))
    return out
