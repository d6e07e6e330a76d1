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
  judges the procedure by an extrapolation the final fit does not make).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np

__all__ = [
    "DEPENDENT",
    "MIN_GAIN",
    "OUTER_FOLDS",
    "STRENGTHS",
    "Selection",
    "Step",
    "best_prefix",
    "block_loo",
    "forward",
    "path",
    "ridge_loo",
    "select",
    "shrinkage",
]

MIN_GAIN = 0.02
"""Relative decrease of the leave-one-out error a longer prefix of the path must bring."""

DEPENDENT = 1e-8
"""A unit-norm candidate whose part outside the fitted columns is shorter is dependent."""

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

    The fit of the columns in is kept as an orthonormal basis Q, its residuals and its hat
    blocks; a candidate's part orthogonal to Q updates all three by rank one, so a step costs
    one batched solve of ``rows x rows`` systems and no refactorisation.

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
    m = e.size // rows
    Q = np.linalg.qr(A[:, start])[0]
    r = e - Q @ (Q.T @ e)
    Qb = Q.reshape(m, rows, -1)
    H = Qb @ np.swapaxes(Qb, 1, 2)
    errors = [_loo_batch(H[None], r.reshape(1, m, rows))[0]]
    rest, order = list(candidates), []
    while rest:
        C = A[:, rest]
        for _ in range(2):  # twice is enough (Gram-Schmidt with reorthogonalisation)
            C = C - Q @ (Q.T @ C)
        norms = np.linalg.norm(C, axis=0)
        live = norms > DEPENDENT * np.linalg.norm(A[:, rest], axis=0)
        if not np.any(live):
            break
        rest = [u for u, keep in zip(rest, live, strict=True) if keep]
        C = C[:, live] / norms[live]
        rc = r[:, None] - C * (C.T @ r)
        Cb = C.reshape(m, rows, -1)
        sq = _added_loo(H, Cb, rc.reshape(m, rows, -1))
        j = int(np.argmin(np.sum(sq, axis=1)))
        order.append(rest.pop(j))
        errors.append(sq[j])
        Q, r = np.column_stack([Q, C[:, j]]), rc[:, j]
        H = H + Cb[:, :, j, None] * Cb[:, None, :, j]
    return order, np.array(errors)


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
    a, b = Minv @ Cb, Minv @ Rb
    denom = 1.0 - np.sum(Cb * a, axis=1)  # (m, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        loo = b + a * (np.sum(Cb * b, axis=1) / denom)[:, None, :]
    sq = np.sum(loo**2, axis=1).T
    sq[(denom <= 1e-12).T | ~np.isfinite(sq)] = np.inf
    return sq


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
    H = H0[None] + (Ub[None] * w[:, None, None, :]) @ np.swapaxes(Ub, 1, 2)[None]
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
    mean = np.mean(sq, axis=1)
    best = 0
    for k in range(len(mean)):
        if np.sqrt(mean[k]) < (1.0 - MIN_GAIN) * np.sqrt(mean[best]):
            best = k
    for k in range(best):
        d = sq[k] - sq[best]
        if np.all(np.isfinite(d)) and np.mean(d) <= np.std(d, ddof=1) / np.sqrt(d.size):
            return k
    return best


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
    sel = list(forced)
    start = list(range(fixed)) + [fixed + s for s in sel]
    rest = [fixed + u for u in range(len(names)) if u not in sel]
    order, errors = path(A, e, rows, start, rest)
    k = best_prefix(errors)
    loo = [float(v) for v in _rms(errors[: k + 1], rows)]
    steps = [Step("registration" if not sel else "+".join(names[s] for s in sel), loo[0])]
    steps += [Step(names[c - fixed], v) for c, v in zip(order[:k], loo[1:], strict=True)]
    strength = ridge_loo(A[:, start + order[:k]], e, rows, fixed)[1]
    return sel + [c - fixed for c in order[:k]], steps, strength


def shrinkage(A: np.ndarray, e: np.ndarray, rows: int, fixed: int) -> float:
    """Prior strength (0 or one of ``STRENGTHS``) of least leave-one-out error."""
    return ridge_loo(A, e, rows, fixed)[1]


def _procedure(A, e, rows, fixed, names, forced):
    """Selection and shrinkage: kept indices, steps, strength."""
    return forward(A, e, rows, fixed, names, forced)


def _solve(A, e, fixed, strength):
    lam = np.r_[np.zeros(fixed), np.full(A.shape[1] - fixed, strength)]
    return np.linalg.lstsq(A.T @ A + np.diag(lam), A.T @ e, rcond=None)[0]


def _outer_cv(A, e, rows, fixed, names, forced) -> tuple[float, float]:
    """Pooled RMS error per point over the guard's held-out folds: registration, selection."""
    m = e.size // rows
    Ab, eb = A.reshape(m, rows, -1), e.reshape(m, rows)
    sse_reg = sse_sel = 0.0
    for f in range(min(OUTER_FOLDS, m)):
        test = np.arange(f, m, OUTER_FOLDS)
        train = np.setdiff1d(np.arange(m), test)
        At, et = Ab[train].reshape(-1, A.shape[1]), eb[train].ravel()
        Av, ev = Ab[test].reshape(-1, A.shape[1]), eb[test].ravel()
        x0 = _solve(At[:, :fixed], et, fixed, 0.0)
        sse_reg += float(np.sum((ev - Av[:, :fixed] @ x0) ** 2))
        sel, _, strength = _procedure(At, et, rows, fixed, names, forced)
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
    sel, steps, strength = _procedure(A, ev, rows, fixed, names, forced)
    reg_cv, sel_cv = _outer_cv(A, ev, rows, fixed, names, forced)
    guarded = bool(sel) and sel_cv >= reg_cv and not forced
    if guarded:
        sel, strength = [], 0.0
    kept = tuple(names[s] for s in sel)
    prior = np.sqrt(strength) * norms[[fixed + s for s in sel]]
    return Selection(kept, tuple(steps), strength, reg_cv, sel_cv, guarded), prior
