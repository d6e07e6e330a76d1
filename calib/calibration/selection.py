"""Model selection: which identifiable parameters the data support.

All of it works on the model linearised at the registration (the nominal geometry with the
fitted measurement frame and markers), whose errors are millimetres: there the fit of any
subset of parameters is a linear least-squares problem, and its cross-validated error has a
closed form.

* **Leave-one-configuration-out error** (block PRESS): with ``H`` the hat matrix of the
  training rows, the prediction error of configuration i by the fit without it is
  ``(I - H_ii)^-1 e_i`` (the rows of one configuration leave together). Deterministic and
  exact for the linear model; for a ridge fit ``H = A (A^T A + L)^-1 A^T``.
* **Forward selection** (``auto``): starting from the registration (frame and markers, always
  free), the forward path adds, one at a time, the candidate that lowers the leave-one-out
  error most, until every candidate is in (each step is a rank-one update of the fit: no
  refactorisation). The model kept is a prefix of that path: the one of least error (a
  longer prefix preferred only if it lowers the error of every shorter one by ``MIN_GAIN``,
  2 %), then the shortest prefix whose error is within one standard error of it (paired
  over configurations). The whole path matters: parameters often lower the error together
  while neither does alone (on the TIAGo the error rises at steps 7 to 9, then falls by 3 to
  5 % at steps 10, 13 and 14), so stopping at the first step that gains less than 2 % stops
  early. Candidates are the base parameters of the complete set (the identifiable
  combinations not already carried by the frame and markers) and, only when compliance is
  asked for (``elastic``), the joint compliances.
* **Shrinkage**: the kept parameters are then pulled toward the nominal model by a Gaussian
  prior whose strength (on the unit-norm columns) is chosen by the same leave-one-out error
  (zero allowed).
* **Guard** against selection bias: the whole procedure is cross-validated once more, by
  ``OUTER_FOLDS`` folds (configuration i in fold i mod 10: no random draw); if it predicts
  the held-out folds no better than the registration alone, the registration is kept. Ten
  folds rather than five: each fold's procedure sees 90 % of the configurations, closer to
  the final fit (with 80 %, a fold that loses the only postures pinning a parameter down
  judges the procedure by an extrapolation the final fit does not make). The folds' forward
  paths run in one batch with the whole data's (:func:`paths`: each fold is the whole
  problem with its held-out rows zeroed), step by step.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np

__all__ = [
    "DEPENDENT",
    "MIN_GAIN",
    "OUTER_FOLDS",
    "REFRESH",
    "STRENGTHS",
    "Selection",
    "Step",
    "best_prefix",
    "block_loo",
    "forward",
    "path",
    "paths",
    "ridge_loo",
    "select",
    "shrinkage",
]

MIN_GAIN = 0.02
"""Relative decrease of the leave-one-out error a longer prefix of the path must bring."""

DEPENDENT = 1e-8
"""A unit-norm candidate whose part outside the fitted columns is shorter is dependent."""

REFRESH = 0.1
"""The inverse hat blocks ``(I - H_ii)^-1`` follow each step by Sherman-Morrison while every
``1 - q_i^T (I - H_ii)^-1 q_i`` of the added column exceeds this; otherwise (a leverage
near 1, where the update would lose digits) they are inverted afresh."""

OUTER_FOLDS = 10
"""Folds of the guard's cross-validation (configuration i goes to fold i mod OUTER_FOLDS)."""

STRENGTHS = tuple(10.0 ** np.arange(-4.0, 1.01, 0.25))
"""Prior strengths tried (on unit-norm columns), besides zero."""


@dataclass(frozen=True)
class Step:
    """One step of the forward selection.

    Attributes:
        name: Parameter added (``registration`` for the start).
        loo: Leave-one-configuration-out RMS error per point after the step [m].
    """

    name: str
    loo: float


@dataclass(frozen=True)
class Selection:
    """Outcome of the automatic choice.

    Attributes:
        kept: Parameters kept (MDH base values and compliances), in the order added.
        steps: The forward selection, registration first.
        strength: Prior strength on the unit-norm columns (0: none).
        registration_cv: Cross-validated RMS error per point of the registration alone [m].
        selection_cv: The same for the whole selection procedure [m].
        guarded: The guard rejected the selection (the registration is kept).
    """

    kept: tuple[str, ...]
    steps: tuple[Step, ...]
    strength: float
    registration_cv: float
    selection_cv: float
    guarded: bool

    def to_dict(self) -> dict:
        """JSON-ready form (metres)."""
        return {
            "kept": list(self.kept),
            "steps": [{"name": s.name, "loo": s.loo} for s in self.steps],
            "prior_strength": self.strength,
            "cv_registration": self.registration_cv,
            "cv_selection": self.selection_cv,
            "guarded": self.guarded,
        }


def block_loo(A: np.ndarray, e: np.ndarray, rows: int, lam: np.ndarray | None = None) -> float:
    """Leave-one-configuration-out RMS error per point of the linear fit ``A x ~ e``.

    Args:
        A: Columns, configuration-major rows ``(m rows, p)``.
        e: Residuals to explain ``(m rows,)``.
        rows: Rows per configuration (3 per point, 3 more for an orientation).
        lam: Ridge penalty per column ``(p,)`` (None: plain least squares).

    Returns:
        sqrt(sum of squared left-out errors / points) [units of e].
    """
    m = e.size // rows
    if A.shape[1] == 0:
        return float(np.sqrt(e @ e / (m * rows / 3)))
    if lam is None:
        Q, _ = np.linalg.qr(A)
        res = e - Q @ (Q.T @ e)
        Qb = Q.reshape(m, rows, -1)
        H = Qb @ np.swapaxes(Qb, 1, 2)
    else:
        G = np.linalg.inv(A.T @ A + np.diag(lam))
        res = e - A @ (G @ (A.T @ e))
        Ab = A.reshape(m, rows, -1)
        H = Ab @ G @ np.swapaxes(Ab, 1, 2)
    loo = np.linalg.solve(np.eye(rows) - H, res.reshape(m, rows, 1))
    return float(np.sqrt(np.sum(loo**2) / (m * rows / 3)))


def _loo_batch(H: np.ndarray, r: np.ndarray) -> np.ndarray:
    """Leave-one-configuration-out RMS errors of several fits at once.

    Args:
        H: Hat-matrix blocks of each fit's configurations ``(c, m, rows, rows)``.
        r: Residuals of each fit ``(c, m, rows)``.

    Returns:
        ``(c, m)`` squared left-out error of each configuration; inf where a configuration
        alone determines a parameter (leverage 1).
    """
    c, m, rows = r.shape
    M = np.eye(rows) - H
    try:
        loo = np.linalg.solve(M, r[..., None])
    except np.linalg.LinAlgError:
        loo = np.full((c, m, rows, 1), np.inf)
        for k in range(c):  # rare: find the singular fits one by one
            with contextlib.suppress(np.linalg.LinAlgError):
                loo[k] = np.linalg.solve(M[k], r[k, ..., None])
    return np.sum(loo**2, axis=(2, 3))


def _rms(sq: np.ndarray, rows: int) -> np.ndarray:
    """RMS error per point of squared errors per configuration ``(..., m)``."""
    return np.sqrt(np.sum(sq, axis=-1) / (sq.shape[-1] * rows / 3))


def path(
    A: np.ndarray, e: np.ndarray, rows: int, start: list[int], candidates: list[int]
) -> tuple[list[int], np.ndarray]:
    """The greedy forward path: each step adds the candidate of least leave-one-out error.

    Args:
        A: Columns, configuration-major rows ``(m rows, p)``.
        e: Residuals to explain ``(m rows,)``.
        rows: Rows per configuration.
        start: Columns always in.
        candidates: Columns to add, until none is left or independent of those in.

    Returns:
        The columns in the order added, and the squared left-out error of each configuration
        before the first and after each addition ``(len(order) + 1, m)``.
    """
    return paths(A, e, rows, start, candidates, np.ones((1, e.size // rows), dtype=bool))[0]


def paths(
    A: np.ndarray,
    e: np.ndarray,
    rows: int,
    start: list[int],
    candidates: list[int],
    train: np.ndarray,
) -> list[tuple[list[int], np.ndarray]]:
    """The forward paths (:func:`path`) of several subsets of the configurations at once.

    Each subset is the whole problem with the rows of the other configurations zeroed (a
    zero row changes neither the fit nor the hat blocks of the others), so every subset's
    path runs in the same batched arrays. The fit of the columns in is kept as an orthonormal
    basis, its residuals and its hat blocks; the candidates are kept orthogonal to it. Adding
    a column updates all of them by rank one: a step costs one batched inverse of
    ``rows x rows`` blocks and no refactorisation.

    Args:
        A: Columns, configuration-major rows ``(m rows, p)``.
        e: Residuals to explain ``(m rows,)``.
        rows: Rows per configuration.
        start: Columns always in.
        candidates: Columns to add, until none is left or independent of those in.
        train: Configurations of each subset ``(subsets, m)`` [bool].

    Returns:
        Per subset: the columns in the order added, and the squared left-out error of each of
        its configurations before the first and after each addition ``(steps + 1, m_subset)``.
    """
    state = _Batch(A, e, rows, start, candidates, train)
    errors, chosen = [state.start_errors()], []
    for _ in candidates:
        active = state.prune()
        if not np.any(active):
            break
        Cn, coef, denom, sq = state.candidate_errors()
        j = _pick(np.sum(sq, axis=2), state.alive)
        state.add(Cn, coef, denom, j, active)
        chosen.append(np.where(active, state.index[j], -1))
        errors.append(sq[np.arange(len(j)), j])
    return _split_paths(candidates, chosen, errors, train)


class _Batch:
    """Working state of :func:`paths`: every subset's fit as the columns are added.

    Attributes:
        m, rows: Configurations and rows per configuration.
        r: Residuals of each subset's fit ``(b, m rows)``.
        H: Hat blocks ``(b, m, rows, rows)``; ``Minv`` their ``(I - H_ii)^-1`` (None while
            one is singular).
        C: Candidates orthogonal to each fit ``(b, m rows, k)``; ``floor`` the norm under
            which one is dependent, ``alive`` those a subset may still add, ``index`` their
            positions in the candidate list (columns no subset can add are dropped).
        lost: Configurations of each subset that reached a leverage of 1 ``(b, m)``: their
            left-out error is infinite from then on (their blocks are left out of ``Minv``).
    """

    def __init__(self, A, e, rows, start, candidates, train):
        b, self.m = train.shape
        self.rows = rows
        w = np.repeat(train, rows, axis=1).astype(float)
        Q = np.linalg.qr(A[:, start] * w[:, :, None])[0]
        self.r = _residual(Q, e * w)
        self.H = _hat_blocks(Q, self.m, rows)
        C = A[:, candidates] * w[:, :, None]
        self.floor = DEPENDENT * np.linalg.norm(C, axis=1)
        for _ in range(2):  # twice is enough (Gram-Schmidt with reorthogonalisation)
            C = C - Q @ (np.swapaxes(Q, 1, 2) @ C)
        self.C, self.Minv = C, _inverse(self.H)
        self.alive = np.ones((b, len(candidates)), dtype=bool)
        self.index = np.arange(len(candidates))
        self.lost = np.zeros((b, self.m), dtype=bool)
        self.norms = np.zeros_like(self.floor)

    def start_errors(self) -> np.ndarray:
        """Squared left-out errors of the start ``(b, m)``."""
        return _loo_batch(self.H, self.r.reshape(len(self.r), self.m, self.rows))

    def prune(self) -> np.ndarray:
        """Mark the dependent candidates dead; the subsets with one alive ``(b,)``."""
        self.norms = np.sqrt(np.einsum("bnk,bnk->bk", self.C, self.C))
        self.alive &= self.norms > self.floor
        some = np.any(self.alive, axis=0)
        if not np.all(some):  # drop the columns no subset can add any more
            self.C, self.floor = self.C[:, :, some], self.floor[:, some]
            self.alive, self.norms, self.index = (
                self.alive[:, some],
                self.norms[:, some],
                self.index[some],
            )
        return np.any(self.alive, axis=1)

    def candidate_errors(self):
        """Unit candidates, their coefficients ``q^T r`` and :func:`_candidate_errors`."""
        Cn = self.C * (self.alive / np.where(self.alive, self.norms, 1.0))[:, None, :]
        coef = np.einsum("bnk,bn->bk", Cn, self.r)
        Cb = Cn.reshape(len(Cn), self.m, self.rows, -1)
        denom, sq = _candidate_errors(self.H, self.Minv, Cb, coef, self.r)
        sq[np.broadcast_to(self.lost[:, None, :], sq.shape)] = np.inf
        return Cn, coef, denom, sq

    def add(self, Cn, coef, denom, j, active) -> None:
        """Add candidate ``j[s]`` to each active subset s: rank-one updates of everything."""
        pick = np.arange(len(j)), j
        q = Cn[pick[0], :, j] * active[:, None]  # a finished subset adds nothing
        self.r = self.r - q * coef[pick][:, None]
        qb = q.reshape(len(q), self.m, self.rows)
        self.H = self.H + qb[:, :, :, None] * qb[:, :, None, :]
        self.C -= q[:, :, None] * np.einsum("bn,bnk->bk", q, self.C)[:, None, :]
        self.alive[pick] = False
        if self.Minv is None or denom is None:
            self.Minv = _inverse(self.H)
            return
        dj = denom[pick[0], :, j]  # (b, m): 1 - the leverage the column adds, by configuration
        newly = active[:, None] & (dj <= 1e-12) & ~self.lost
        self.lost |= newly
        if np.any(newly) or np.min(np.where(self.lost, 1.0, dj)) <= REFRESH:
            self.Minv = _inverse(self.H * ~self.lost[:, :, None, None])
            return
        aj = np.einsum("bmij,bmj->bmi", self.Minv, qb * (active[:, None] & ~self.lost)[:, :, None])
        self.Minv = self.Minv + aj[..., :, None] * (aj / dj[..., None])[..., None, :]


def _candidate_errors(H, Minv, Cb, coef, r):
    """Squared left-out errors of each subset's fit with each candidate added.

    With ``v_i = M_i^-1 r_i``, ``a_i = M_i^-1 q_i`` and ``g_i = q_i^T a_i``, the left-out error
    of configuration i after adding the orthonormal column q (coefficient ``q^T r``) is
    ``v_i + a_i (q_i^T v_i - q^T r) / (1 - g_i)`` (Sherman-Morrison, see :func:`_added_loo`).

    Args:
        H: Hat blocks of the current fits ``(b, m, rows, rows)``.
        Minv: Their ``(I - H_ii)^-1`` (None if one is singular).
        Cb: Candidate columns, orthonormal to the fits, by configuration ``(b, m, rows, c)``.
        coef: ``q^T r`` of each candidate ``(b, c)``.
        r: Residuals of the current fits ``(b, m rows)``.

    Returns:
        ``1 - g`` ``(b, m, c)`` (None without ``Minv``), and the squared left-out errors
        ``(b, c, m)``: inf where a configuration alone would determine the added column.
    """
    b, m, rows, _ = Cb.shape
    if Minv is None:  # a configuration of leverage 1 in some subset: each on its own
        Rb = r.reshape(b, m, rows, 1) - Cb * coef[:, None, None, :]
        return None, np.stack([_added_loo(H[k], Cb[k], Rb[k]) for k in range(b)])
    v = np.einsum("bmij,bmj->bmi", Minv, r.reshape(b, m, rows))
    loo = Minv @ Cb  # a, then the left-out errors in place
    denom = 1.0 - np.einsum("bmik,bmik->bmk", Cb, loo)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (np.einsum("bmik,bmi->bmk", Cb, v) - coef[:, None, :]) / denom
        loo *= s[:, :, None, :]
        loo += v[..., None]
        sq = np.einsum("bmik,bmik->bkm", loo, loo)
    sq[np.swapaxes(denom <= 1e-12, 1, 2) | ~np.isfinite(sq)] = np.inf
    return denom, sq


def _residual(Q: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``e - Q Q^T e`` of a stack of orthonormal bases ``(b, n, s)`` and vectors ``(b, n)``."""
    return e - np.einsum("bns,bs->bn", Q, np.einsum("bns,bn->bs", Q, e))


def _hat_blocks(Q: np.ndarray, m: int, rows: int) -> np.ndarray:
    """Diagonal blocks of ``Q Q^T`` per configuration ``(b, m, rows, rows)``."""
    Qb = Q.reshape(Q.shape[0], m, rows, -1)
    return Qb @ np.swapaxes(Qb, 2, 3)


def _pick(total: np.ndarray, alive: np.ndarray) -> np.ndarray:
    """Per subset, the live candidate of least total error ``(b,)``.

    The first live one when every live error is infinite (as :func:`numpy.argmin` of the live
    candidates alone would).
    """
    key = np.where(alive, total, np.inf)
    j = np.argmin(key, axis=1)
    stuck = np.isinf(key[np.arange(len(j)), j])
    return np.where(stuck, np.argmax(alive, axis=1), j)


def _split_paths(candidates, chosen, errors, train) -> list[tuple[list[int], np.ndarray]]:
    """Each subset's order (candidate columns) and errors on its own configurations."""
    steps = np.array(chosen, dtype=int).reshape(-1, train.shape[0])
    errs = np.array(errors)
    out = []
    for k, mask in enumerate(train):
        picked = [candidates[j] for j in steps[:, k] if j >= 0]
        out.append((picked, errs[: len(picked) + 1, k][:, mask]))
    return out


def _inverse(H: np.ndarray) -> np.ndarray | None:
    """``(I - H)^-1`` of each hat block, None if one is singular (a leverage of 1)."""
    try:
        return np.linalg.inv(np.eye(H.shape[-1]) - H)
    except np.linalg.LinAlgError:
        return None


def _added_loo(H: np.ndarray, Cb: np.ndarray, Rb: np.ndarray) -> np.ndarray:
    """Squared left-out errors ``(c, m)`` of the fit with each orthonormal column added.

    With ``M_i = I - H_ii`` and the added column's block ``q_i``, Sherman-Morrison gives
    ``(M_i - q_i q_i^T)^-1 r_i = b + a (q^T b) / (1 - q^T a)``, ``a = M_i^-1 q_i``,
    ``b = M_i^-1 r_i``: one inverse per configuration serves every candidate.

    Args:
        H: Hat blocks of the current fit ``(m, rows, rows)``.
        Cb: Candidate columns, orthonormal to the fit, by configuration ``(m, rows, c)``.
        Rb: Residuals after adding each candidate ``(m, rows, c)``.
    """
    rows = H.shape[1]
    try:
        Minv = np.linalg.inv(np.eye(rows) - H)
    except np.linalg.LinAlgError:  # a configuration of leverage 1 already: solve each
        Hc = H[None] + np.moveaxis(Cb[:, :, None, :] * Cb[:, None, :, :], 3, 0)
        return _loo_batch(Hc, np.moveaxis(Rb, 2, 0))
    return _sherman_morrison(Minv, Cb, Rb)[2]


def _sherman_morrison(
    Minv: np.ndarray, Cb: np.ndarray, Rb: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Left-out errors from the ``M^-1`` blocks ``(..., m, rows, rows)`` (:func:`_added_loo`).

    Returns:
        ``a = M^-1 q`` ``(..., m, rows, c)``, ``1 - q^T a`` ``(..., m, c)``, and the squared
        left-out errors ``(..., c, m)``: inf where a configuration alone would determine
        the added column.
    """
    a, b = Minv @ Cb, Minv @ Rb
    denom = 1.0 - np.sum(Cb * a, axis=-2)  # (..., m, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        loo = b + a * (np.sum(Cb * b, axis=-2) / denom)[..., None, :]
    sq = np.sum(loo**2, axis=-2)
    sq[(denom <= 1e-12) | ~np.isfinite(sq)] = np.inf
    return a, denom, np.swapaxes(sq, -1, -2)


def ridge_loo(A: np.ndarray, e: np.ndarray, rows: int, fixed: int) -> tuple[np.ndarray, float]:
    """Leave-one-out errors at the best prior strength (0 or one of ``STRENGTHS``), and it.

    The prior acts on the columns after the first ``fixed``. With those columns made
    orthogonal to the fixed ones (``B``, residuals ``r``) and ``B = U S V^T``, the hat matrix
    at strength ``s`` is ``P_fixed + U diag(S^2 / (S^2 + s)) U^T``: one SVD serves every
    strength (equal to :func:`block_loo` with ``lam = s`` on those columns).

    Args:
        A: Unit-norm columns ``(m rows, p)``, the first ``fixed`` free of prior.
        e: Residuals to explain.
        rows: Rows per configuration.
        fixed: Columns without prior.

    Returns:
        The squared left-out error of each configuration at the strength of least RMS error,
        and that strength (0: none; the smallest of equal errors).
    """
    m = e.size // rows
    Q = np.linalg.qr(A[:, :fixed])[0]
    B = A[:, fixed:] - Q @ (Q.T @ A[:, fixed:])
    r = e - Q @ (Q.T @ e)
    Qb = Q.reshape(m, rows, -1)
    H0 = Qb @ np.swapaxes(Qb, 1, 2)
    if B.shape[1] == 0:
        return _loo_batch(H0[None], r.reshape(1, m, rows))[0], 0.0
    U, sv, _ = np.linalg.svd(B, full_matrices=False)
    strengths = np.r_[0.0, STRENGTHS]
    w = sv**2 / (sv**2 + strengths[:, None])  # (strengths, k)
    Ub = U.reshape(m, rows, -1)
    outer = (Ub[:, :, None, :] * Ub[:, None, :, :]).reshape(-1, Ub.shape[2])  # (m rows^2, k)
    H = H0[None] + (outer @ w.T).T.reshape(len(w), m, rows, rows)
    res = r[None] - (w * (U.T @ r)) @ U.T
    sq = _loo_batch(H, res.reshape(-1, m, rows))
    best = int(np.argmin(np.sum(sq, axis=1)))
    return sq[best], float(strengths[best])


def best_prefix(sq: np.ndarray) -> int:
    """Length of the path's prefix kept, from its squared left-out errors ``(prefixes, m)``.

    The prefix of least error (a longer one preferred only if ``MIN_GAIN`` better than every
    shorter one), then the shortest prefix whose error is within one standard error of it
    (the standard error of the mean difference over configurations, paired): the minimum of
    a long path is partly chance, and a difference smaller than its own noise is not kept.
    """
    root = np.sqrt(np.mean(sq, axis=1)).tolist()
    best = 0
    for k, value in enumerate(root):
        if value < (1.0 - MIN_GAIN) * root[best]:
            best = k
    d = sq[:best] - sq[best]
    with np.errstate(invalid="ignore"):
        se = np.std(d, axis=1, ddof=1) / np.sqrt(sq.shape[1])
        close = np.all(np.isfinite(d), axis=1) & (np.mean(d, axis=1) <= se)
    return int(np.argmax(close)) if np.any(close) else best


def forward(
    A: np.ndarray, e: np.ndarray, rows: int, fixed: int, names: tuple[str, ...], forced=()
) -> tuple[list[int], list[Step], float]:
    """Forward selection of columns ``fixed..`` and their prior (see the module docstring).

    Args:
        A: Unit-norm columns; the first ``fixed`` are always in.
        e: Residuals to explain.
        rows: Rows per configuration.
        fixed: Number of columns always in (frame, markers).
        names: Names of the columns after the fixed ones.
        forced: Indices (into ``names``) always kept (``--free``).

    Returns:
        The kept indices (into ``names``) in the order added, the steps kept (each with its
        leave-one-out error), and the prior strength of the kept parameters.
    """
    train = np.ones((1, e.size // rows), dtype=bool)
    return _forwards(A, e, rows, fixed, names, forced, train)[0]


def _forwards(A, e, rows, fixed, names, forced, train) -> list[tuple[list[int], list[Step], float]]:
    """:func:`forward` on each subset of the configurations ``train`` ``(subsets, m)``."""
    sel = list(forced)
    start = list(range(fixed)) + [fixed + s for s in sel]
    rest = [fixed + u for u in range(len(names)) if u not in sel]
    Ab, eb = A.reshape(train.shape[1], rows, -1), e.reshape(train.shape[1], rows)
    out = []
    for mask, (order, errors) in zip(train, paths(A, e, rows, start, rest, train), strict=True):
        k = best_prefix(errors)
        loo = [float(v) for v in _rms(errors[: k + 1], rows)]
        steps = [Step("registration" if not sel else "+".join(names[s] for s in sel), loo[0])]
        steps += [Step(names[c - fixed], v) for c, v in zip(order[:k], loo[1:], strict=True)]
        At = Ab[mask].reshape(-1, A.shape[1])
        strength = ridge_loo(At[:, start + order[:k]], eb[mask].ravel(), rows, fixed)[1]
        out.append((sel + [c - fixed for c in order[:k]], steps, strength))
    return out


def shrinkage(A: np.ndarray, e: np.ndarray, rows: int, fixed: int) -> float:
    """Prior strength (0 or one of ``STRENGTHS``) of least leave-one-out error."""
    return ridge_loo(A, e, rows, fixed)[1]


def _solve(A, e, fixed, strength):
    lam = np.r_[np.zeros(fixed), np.full(A.shape[1] - fixed, strength)]
    return np.linalg.lstsq(A.T @ A + np.diag(lam), A.T @ e, rcond=None)[0]


def _guard_folds(m: int) -> np.ndarray:
    """Training configurations of the guard's folds ``(folds, m)``.

    Fold f leaves out the configurations i with i mod ``OUTER_FOLDS`` = f.
    """
    folds = np.arange(min(OUTER_FOLDS, m))
    return (np.arange(m) % OUTER_FOLDS)[None, :] != folds[:, None]


def _outer_cv(A, e, rows, fixed, train, outcomes) -> tuple[float, float]:
    """Pooled RMS error per point over the guard's held-out folds: registration, selection.

    Args:
        A: Unit-norm columns, configuration-major rows; the first ``fixed`` always in.
        e: Residuals to explain.
        rows: Rows per configuration.
        fixed: Number of columns always in (frame, markers).
        train: Training configurations of each fold ``(folds, m)``.
        outcomes: Each fold's procedure (:func:`forward` on its training configurations).
    """
    m = e.size // rows
    Ab, eb = A.reshape(m, rows, -1), e.reshape(m, rows)
    sse_reg = sse_sel = 0.0
    for mask, (sel, _, strength) in zip(train, outcomes, strict=True):
        At, et = Ab[mask].reshape(-1, A.shape[1]), eb[mask].ravel()
        Av, ev = Ab[~mask].reshape(-1, A.shape[1]), eb[~mask].ravel()
        x0 = _solve(At[:, :fixed], et, fixed, 0.0)
        sse_reg += float(np.sum((ev - Av[:, :fixed] @ x0) ** 2))
        cols = list(range(fixed)) + [fixed + s for s in sel]
        x = _solve(At[:, cols], et, fixed, strength)
        sse_sel += float(np.sum((ev - Av[:, cols] @ x) ** 2))
    points = m * rows / 3
    return float(np.sqrt(sse_reg / points)), float(np.sqrt(sse_sel / points))


def select(
    J: np.ndarray, e: np.ndarray, fixed: int, names: tuple[str, ...], forced=()
) -> tuple[Selection, np.ndarray]:
    """Choose the parameters the data support (see the module docstring).

    Args:
        J: Weighted Jacobian at the registration ``(m, rows, fixed + len(names))``: the
            frame and marker columns first, then the candidates.
        e: Weighted residuals measured - model at the registration ``(m, rows)``.
        fixed: Number of always-free columns (frame, markers).
        names: Candidate names.
        forced: Indices into ``names`` kept whatever the data say.

    Returns:
        The selection, and the prior weight of each kept parameter (in the units of x:
        ``sqrt(strength) * |column|``).
    """
    m, rows, p = J.shape
    A = J.reshape(m * rows, p)
    norms = np.linalg.norm(A, axis=0)
    A = A / np.where(norms > 0, norms, 1.0)
    ev = e.ravel()
    folds = _guard_folds(m)
    train = np.vstack([np.ones((1, m), dtype=bool), folds])  # the whole data, then each fold
    outcomes = _forwards(A, ev, rows, fixed, names, forced, train)
    sel, steps, strength = outcomes[0]
    reg_cv, sel_cv = _outer_cv(A, ev, rows, fixed, folds, outcomes[1:])
    guarded = bool(sel) and sel_cv >= reg_cv and not forced
    if guarded:
        sel, strength = [], 0.0
    kept = tuple(names[s] for s in sel)
    prior = np.sqrt(strength) * norms[[fixed + s for s in sel]]
    return Selection(kept, tuple(steps), strength, reg_cv, sel_cv, guarded), prior
