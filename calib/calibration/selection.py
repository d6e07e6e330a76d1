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
  free), add the candidate that lowers the leave-one-out error most, as long as it lowers it
  by at least ``MIN_GAIN`` (2 %). Candidates are the base parameters of the complete set
  (the identifiable combinations not already carried by the frame and markers) and, where
  the URDF gives masses, the joint compliances.
* **Shrinkage**: the kept parameters are then pulled toward the nominal model by a Gaussian
  prior whose strength (on the unit-norm columns) is chosen by the same leave-one-out error
  (zero allowed).
* **Guard** against selection bias: the whole procedure is cross-validated once more, by
  ``OUTER_FOLDS`` folds (configuration i in fold i mod 5: no random draw); if it predicts
  the held-out folds no better than the registration alone, the registration is kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_GAIN = 0.02
"""Relative decrease of the leave-one-out error a parameter must bring to be kept."""

OUTER_FOLDS = 5
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


def forward(
    A: np.ndarray, e: np.ndarray, rows: int, fixed: int, names: tuple[str, ...], forced=()
) -> tuple[list[int], list[Step]]:
    """Forward selection of columns ``fixed..`` by the leave-one-out error.

    Args:
        A: Unit-norm columns; the first ``fixed`` are always in.
        e: Residuals to explain.
        rows: Rows per configuration.
        fixed: Number of columns always in (frame, markers).
        names: Names of the columns after the fixed ones.
        forced: Indices (into ``names``) always kept (``--free``).

    Returns:
        The kept indices (into ``names``) in the order added, and the steps.
    """
    sel = list(forced)
    cols = list(range(fixed))
    best = block_loo(A[:, cols + [fixed + s for s in sel]], e, rows)
    steps = [Step("registration" if not sel else "+".join(names[s] for s in sel), best)]
    rest = [u for u in range(len(names)) if u not in sel]
    while rest:
        scores = [block_loo(A[:, cols + [fixed + s for s in (*sel, u)]], e, rows) for u in rest]
        j = int(np.argmin(scores))
        if scores[j] >= best * (1.0 - MIN_GAIN):
            break
        best = scores[j]
        sel.append(rest.pop(j))
        steps.append(Step(names[sel[-1]], best))
    return sel, steps


def shrinkage(A: np.ndarray, e: np.ndarray, rows: int, fixed: int) -> float:
    """Prior strength (0 or one of ``STRENGTHS``) of least leave-one-out error."""
    p = A.shape[1]
    if p == fixed:
        return 0.0
    best, strength = block_loo(A, e, rows), 0.0
    for s in STRENGTHS:
        lam = np.r_[np.zeros(fixed), np.full(p - fixed, s)]
        score = block_loo(A, e, rows, lam)
        if score < best:
            best, strength = score, float(s)
    return strength


def _procedure(A, e, rows, fixed, names, forced):
    """Selection then shrinkage: kept indices, steps, strength."""
    sel, steps = forward(A, e, rows, fixed, names, forced)
    cols = list(range(fixed)) + [fixed + s for s in sel]
    return sel, steps, shrinkage(A[:, cols], e, rows, fixed)


def _solve(A, e, fixed, strength):
    lam = np.r_[np.zeros(fixed), np.full(A.shape[1] - fixed, strength)]
    return np.linalg.lstsq(A.T @ A + np.diag(lam), A.T @ e, rcond=None)[0]


def _outer_cv(A, e, rows, fixed, names, forced) -> tuple[float, float]:
    """Pooled RMS error per point over contiguous held-out blocks: registration, selection."""
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
