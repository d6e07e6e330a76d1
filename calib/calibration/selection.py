"""Model selection (``auto``): which identifiable parameters the data support.

Rationale and measurements: docs/developers/engine.md#selection
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .forward_paths import SMALL, lu_errors, paths, residual, spd_solve
from .object_columns import FixedBasis, ObjectColumns, object_moments, posture_sums

__all__ = [
    "MIN_GAIN",
    "OUTER_FOLDS",
    "ROUNDOFF",
    "STRENGTHS",
    "Selection",
    "Step",
    "best_prefix",
    "ridge_strengths",
    "select",
]

MIN_GAIN = 0.02
"""Relative decrease of the leave-one-out error a longer prefix of the path must bring."""

ROUNDOFF = 1e-13
"""Fraction of the path's largest mean squared left-out error under which errors are equal."""

OUTER_FOLDS = 10
"""Folds of the guard's cross-validation (configuration i in fold i mod OUTER_FOLDS)."""

RICH = 10
"""Equations per parameter from which the complete fit is a candidate against the selection."""

STRENGTHS = tuple(10.0 ** np.arange(-4.0, 1.01, 0.25))
"""Prior strengths tried (on unit-norm columns), besides zero."""


@dataclass(frozen=True)
class Step:
    """One step of the forward selection: the parameter added, the RMS left-out error [m]."""

    name: str
    loo: float


@dataclass(frozen=True)
class Selection:
    """Outcome of the automatic choice.

    ``kept``: parameters kept, in the order added (``index``: their positions among the
    candidates, whose names two chains sharing a joint may repeat); ``strength``: the prior's on
    the unit-norm columns (0: none); ``*_cv``: cross-validated RMS errors per point [m] of the
    registration, the selection and the complete fit; ``guarded``: the guard kept the
    registration; ``winner``: ``registration``, ``selection`` or ``complete``.
    """

    kept: tuple[str, ...]
    steps: tuple[Step, ...]
    strength: float
    registration_cv: float
    selection_cv: float
    guarded: bool
    complete_cv: float = float("nan")
    winner: str = "selection"
    index: tuple[int, ...] = ()

    def to_dict(self) -> dict:
        """JSON-ready form (metres)."""
        return {
            "kept": list(self.kept),
            "steps": [{"name": s.name, "loo": s.loo} for s in self.steps],
            "prior_strength": self.strength,
            "cv_registration": self.registration_cv,
            "cv_selection": self.selection_cv,
            "guarded": self.guarded,
            "cv_complete": None if np.isnan(self.complete_cv) else self.complete_cv,
            "winner": self.winner,
        }


def ridge_strengths(
    A: np.ndarray,
    e: np.ndarray,
    rows: int,
    fixed: int,
    train: np.ndarray,
    cols: list[list[int]],
    objects: ObjectColumns | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Leave-one-out errors ``(b, m)`` at the best prior strength ``(b,)`` of several subsets.

    Subset s fits the first ``fixed`` columns free and ``cols[s]`` under the prior, on its
    configurations ``train[s]`` (``(b, m)`` bool). ``A``: unit-norm columns ``(m rows, p)``;
    ``objects``: free too, by block, or None. The errors are zero on the configurations a
    subset leaves out; a strength 0 is no prior. How: docs/developers/engine.md#selection
    """
    per = _per_batch(A.shape[0] * A.shape[1], len(train))
    parts = [
        _ridge_batch(A, e, rows, fixed, train[i : i + per], cols[i : i + per], objects)
        for i in range(0, len(train), per)
    ]
    return np.concatenate([q[0] for q in parts]), np.concatenate([q[1] for q in parts])


BLOCK = 2_000_000
"""Numbers a batch of subsets (or a block of configurations) may hold in one working array."""


def _per_batch(size: int, subsets: int) -> int:
    """Subsets taken together when each holds ``size`` numbers (at least one)."""
    return max(1, min(subsets, BLOCK // max(size, 1)))


def _ridge_batch(A, e, rows, fixed, train, cols, objects=None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`ridge_strengths` of a few subsets at once."""
    b = len(train)
    w = np.repeat(train, rows, axis=1).astype(float)
    B, real = _padded(A, cols)  # zero columns pad: their singular values are 0, unused
    B *= w[:, :, None]
    hat = Q = None
    if objects is None:
        Q = np.linalg.qr(A[:, :fixed] * w[:, :, None])[0]
        r = residual(Q, e * w)
        B -= Q @ (np.swapaxes(Q, 1, 2) @ B)
    else:  # the objects' columns by block
        m = train.shape[1]
        basis = FixedBasis(objects, A[:, :fixed].reshape(m, rows, -1), train.astype(float))
        r = basis.project((e * w).reshape(b, m, rows, 1)).reshape(b, -1)
        B = basis.project(B.reshape(b, m, rows, -1)).reshape(B.shape)
        hat = basis.hat()
    U, sv = np.linalg.svd(B, full_matrices=False)[:2]
    del B
    width, strengths = U.shape[2], np.r_[0.0, STRENGTHS]
    s2 = np.broadcast_to(sv[:, None, :] ** 2, (b, len(strengths), width))
    with np.errstate(invalid="ignore"):  # 0 / 0 where a column is dependent, as it should
        wt = np.divide(s2, s2 + strengths[:, None], out=np.zeros(s2.shape), where=real[:, None])
    sq = np.where(train[:, None, :], _ridge_errors(Q, U, wt, r, rows, hat), 0.0)  # not inf * 0
    best = np.argmin(np.sum(sq, axis=2), axis=1)
    return sq[np.arange(b), best], strengths[best]


def _ridge_errors(Q, U, wt, r, rows, hat=None) -> np.ndarray:
    """Squared left-out errors ``(b, strengths, m)`` of the hats ``Q Q^T + U diag(wt) U^T``."""
    b, n, width = U.shape
    m, S = n // rows, wt.shape[1]
    coef = wt * np.einsum("bnk,bn->bk", U, r)[:, None]  # (b, strengths, width)
    Ub, rb = U.reshape(b, m, rows, width), r.reshape(b, m, rows)
    Fb = Q.reshape(b, m, rows, -1) if hat is None else hat  # the fixed columns by configuration
    step = max(1, BLOCK // (rows * b * (rows * S + width + Fb.shape[3])))
    out = np.empty((b, S, m))
    for c in range(0, m, step):
        part = slice(c, c + step)
        fixed = _fixed_hat(Fb[:, part], hat is not None)
        out[:, :, part] = _ridge_block(fixed, Ub[:, part], wt, coef, rb[:, part], rows)
    return out


def _fixed_hat(Fb: np.ndarray, is_hat: bool) -> np.ndarray:
    """The fixed columns' hat blocks ``(rows, rows, b, m)``, from their basis or hat blocks."""
    if is_hat:
        return np.transpose(Fb, (2, 3, 0, 1))
    Qc = np.transpose(Fb, (2, 0, 1, 3))
    return np.einsum("ibms,jbms->ijbm", Qc, Qc)


def _ridge_block(fixed, Ub, wt, coef, rb, rows) -> np.ndarray:
    """:func:`_ridge_errors` of a block of configurations (arrays by configuration)."""
    b, m = Ub.shape[:2]
    S = wt.shape[1]
    Uc = np.ascontiguousarray(np.transpose(Ub, (2, 0, 3, 1)))  # (rows, b, width, m)
    system = (Uc, wt, fixed, coef, Ub, rb)
    if rows <= SMALL:  # solved in place (no copies this large), made again for LAPACK
        M, y = _system(*system)
        x = spd_solve(M.reshape(rows, rows, -1), y.reshape(rows, -1), overwrite=True)
        sq = np.einsum("is,is->s", x, x).reshape(b, S, m)
        if np.isfinite(sq).all():
            return sq
    M, y = _system(*system)
    diag = np.arange(rows)
    M[diag, diag] = 1.0 - (1.0 - M[diag, diag])  # I - (I - M): the digits LAPACK always had
    blocks = np.moveaxis(M.reshape(rows, rows, b * S, m), (0, 1), (2, 3))  # a view: no copy
    return lu_errors(blocks, np.moveaxis(y.reshape(rows, b * S, m), 0, 2)).reshape(b, S, m)


def _system(Uc, wt, fixed, coef, Ub, rb) -> tuple[np.ndarray, np.ndarray]:
    """``I - hat`` ``(rows, rows, b, strengths, m)`` and the residuals ``(rows, b, s, m)``."""
    M = _symmetric_hats(Uc, wt)  # component-major
    M -= fixed[:, :, :, None]
    diag = np.arange(len(Uc))
    M[diag, diag] += 1.0
    fitted = np.einsum("bsk,bmik->ibsm", coef, Ub)
    return M, np.ascontiguousarray(np.transpose(rb, (2, 0, 1))[:, :, None, :] - fitted)


def _symmetric_hats(Uc: np.ndarray, wt: np.ndarray) -> np.ndarray:
    """``-U diag(wt) U^T`` of each configuration at each strength ``(rows, rows, b, s, m)``."""
    rows = len(Uc)
    i, j = np.triu_indices(rows)
    upper = -(wt @ (Uc[i] * Uc[j]))  # (pairs, b, strengths, m)
    M = np.empty((rows, rows, *upper.shape[1:]))
    M[i, j] = upper
    M[j, i] = upper
    return M


def best_prefix(sq: np.ndarray) -> int:
    """Length of the path's prefix kept, from its squared left-out errors ``(prefixes, m)``."""
    mse = sq.mean(axis=1)
    floor = ROUNDOFF * mse[np.isfinite(mse)].max(initial=0.0)
    root = np.sqrt(np.maximum(mse, floor)).tolist()
    best = 0
    for k, value in enumerate(root):
        if value < (1.0 - MIN_GAIN) * root[best]:
            best = k
    if best == 0:
        return 0
    d = sq[:best] - sq[best]
    with np.errstate(invalid="ignore", divide="ignore"):
        gap = d.mean(axis=1)
        dev = d - gap[:, None]
        se = np.sqrt(np.einsum("kn,kn->k", dev, dev) / (d.shape[1] - 1) / d.shape[1])
        close = np.isfinite(d).all(axis=1) & (gap <= se)
    return int(np.argmax(close)) if close.any() else best


def _paths_of(A, e, rows, fixed, names, forced, train, repeats, objects):
    """Per subset ``train``: the kept candidates and steps, then the whole path's order, steps."""
    sel = list(forced)
    start = list(range(fixed)) + [fixed + s for s in sel]
    rest = [fixed + u for u in range(len(names)) if u not in sel]
    spread, count = repeats
    out: list[tuple[list[int], list[Step], list[int], list[Step]]] = []
    per = _per_batch(A.shape[0] * max(len(rest), 1), len(train))
    found = (  # a batch at a time: each path's errors (steps x configurations) then dropped
        p
        for i in range(0, len(train), per)
        for p in paths(A, e, rows, start, rest, train[i : i + per], objects)
    )
    for (order, errors), mask in zip(found, train, strict=True):
        errors = errors + spread[mask]
        k = best_prefix(errors)
        whole = sel + [c - fixed for c in order]
        steps = [] if out else _steps(errors, count[mask], rows, names, sel, whole)  # folds' unread
        out.append((whole[: len(sel) + k], steps[: k + 1], whole, steps))
    return out


def _steps(errors, count, rows, names, sel, whole) -> list[Step]:
    """A path's steps: the start's RMS left-out error per point, then each addition's."""
    points = float(np.sum(count)) * rows / 3  # the file's points they stand for
    loo = [float(v) for v in np.sqrt(np.sum(errors, axis=-1) / points)]  # RMS per point
    steps = [Step("registration" if not sel else "+".join(names[s] for s in sel), loo[0])]
    added = whole[len(sel) :]
    return steps + [Step(names[c], v) for c, v in zip(added, loo[1:], strict=True)]


def _padded(A: np.ndarray, cols: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
    """Each list's columns of A zero-padded ``(lists, n, width)``, and which are real."""
    width = max(map(len, cols))
    out = np.zeros((len(cols), A.shape[0], width))
    for s, c in enumerate(cols):
        out[s, :, : len(c)] = A[:, c]
    return out, np.arange(width) < np.array([len(c) for c in cols])[:, None]


def _by_posture(J: np.ndarray, e: np.ndarray, groups) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The rows of each posture once (times the root of its count), and its spread and count.

    ``J`` ``(m, rows, p)`` -> ``(postures, rows, p)``, ``e`` ``(m, rows)`` -> ``(postures,
    rows)``; ``groups``: each configuration's posture ``(m,)`` (from 0), or None (each its own).
    """
    m = len(e)
    if groups is None or int(np.max(groups, initial=-1)) + 1 == m:
        return J, e, (np.zeros(m), np.ones(m))  # numbered by first appearance: same order
    count = np.bincount(groups).astype(float)
    root = np.sqrt(count)
    Js, es = posture_sums(J, groups), posture_sums(e, groups)
    spread = np.zeros(len(count))
    np.add.at(spread, groups, np.sum((e - (es / root[:, None])[groups]) ** 2, axis=1))
    return Js, es, (spread, count)


def _unit_columns(J, e, groups, objects):
    """The rows of each posture once (:func:`_by_posture`), the columns of unit norm.

    Returns the columns ``(postures rows, p)``, their norms, the residuals ``(postures
    rows,)``, the postures' spread and counts, and the objects (by posture) or None.
    """
    if objects is not None:
        objects = objects.by_posture(groups, len(e)).unit()
    J, e, repeats = _by_posture(J, e, groups)
    A = J.reshape(-1, J.shape[2])
    norms = np.linalg.norm(A, axis=0)
    return A / np.where(norms > 0, norms, 1.0), norms, e.ravel(), repeats, objects


def _guard_models(fixed: int, lists, fits, folds: int) -> list[list[tuple[list[int], float]]]:
    """The guard's candidates by fold: the registration, then the procedures ``fits``."""
    frame, n = list(range(fixed)), len(fits[0])
    models = [[(frame, 0.0)] * folds]
    for k, fit in enumerate(fits):
        cols = lists[k * n + 1 : (k + 1) * n]
        models.append([(frame + c, s) for c, s in zip(cols, fit[1:], strict=True)])
    return models


def select(
    J: np.ndarray,
    e: np.ndarray,
    fixed: int,
    names: tuple[str, ...],
    forced=(),
    groups: np.ndarray | None = None,
    objects: ObjectColumns | None = None,
    measured: np.ndarray | None = None,
) -> tuple[Selection, np.ndarray]:
    """Choose the parameters the data support; and each kept one's prior weight.

    ``J`` ``(m, rows, fixed + len(names))`` (the always-free columns first) and ``e`` ``(m,
    rows)``, weighted, at the registration; ``forced``: indices into ``names`` always kept;
    ``groups``: each configuration's posture (repeats count once; None: each its own);
    ``objects``: always-free object columns by block, or None; ``measured``: each
    configuration's rows measured (partial marker rows: those of a marker not seen are 0 in
    ``J`` and ``e``, no equation), None: all. The prior weights are in the units of x
    (``sqrt(strength) * |column|``).
    """
    points, rows = (e.size if measured is None else float(np.sum(measured))) / 3, J.shape[1]
    A, norms, ev, repeats, objects = _unit_columns(J, e, groups, objects)
    if measured is not None:  # each posture counts the points it measured
        per = measured if groups is None else np.bincount(groups, weights=measured)
        repeats = (repeats[0], per / rows)
    m = len(ev) // rows
    # the guard's folds' training configurations: fold f leaves out those i mod OUTER_FOLDS = f
    folds = (np.arange(m) % OUTER_FOLDS)[None, :] != np.arange(min(OUTER_FOLDS, m))[:, None]
    train = np.vstack([np.ones((1, m), dtype=bool), folds])  # the whole data, then each fold
    outcomes = _paths_of(A, ev, rows, fixed, names, forced, train, repeats, objects)
    unknowns = A.shape[1] + (0 if objects is None else objects.objects * objects.own.shape[2])
    rich = m * rows >= RICH * unknowns  # else the complete fit is no candidate (as before)
    every = [o[2] + [u for u in range(len(names)) if u not in o[2]] for o in outcomes]
    every = every if rich else []  # each path's order, then the candidates it never reached
    lists = [[fixed + u for u in c] for c in [o[0] for o in outcomes] + every]
    subsets = np.vstack([train] * (2 if rich else 1))
    both = ridge_strengths(A, ev, rows, fixed, subsets, lists, objects)[1].tolist()
    fits = [both[k : k + len(train)] for k in range(0, len(both), len(train))]
    models = _guard_models(fixed, lists, fits, len(folds))
    folded = outer_cv(A, ev, rows, fixed, folds, models, objects)
    cv = [*np.sqrt((folded.sum(axis=1) + repeats[0].sum()) / points).tolist(), float("nan")]
    reg_cv, sel_cv, full_cv = cv[:3]
    low = np.sqrt(ROUNDOFF) * max(float(np.sqrt(np.sum(e * e) / points)), *cv[: 2 + rich])
    reg, chosen, full = (max(v, low) for v in cv[:3])  # round-off after an exact fit: equal
    sel, steps, _, path_steps = outcomes[0]
    strength, winner = fits[0][0], "selection"
    if rich and full < chosen:
        sel, steps, strength, winner = every[0], path_steps, fits[1][0], "complete"
    guarded = bool(sel) and not forced and min(chosen, full if rich else chosen) >= reg
    if guarded or not sel:
        winner, sel, strength = "registration", [], 0.0
    kept = tuple(names[s] for s in sel)
    prior = np.sqrt(strength) * norms[[fixed + s for s in sel]]
    index = tuple(int(s) for s in sel)
    out = Selection(kept, tuple(steps), strength, reg_cv, sel_cv, guarded, full_cv, winner, index)
    return out, prior


def outer_cv(A, e, rows, fixed, train, models, objects=None) -> np.ndarray:
    """Held-out squared error ``(candidates, folds)`` of each candidate's ridge fit by fold."""
    if objects is None:
        x_all = np.linalg.lstsq(A, e, rcond=None)[0]
        ec = e - A @ x_all
        held = ((A[h], ec[h]) for h in (np.repeat(~mask, rows) for mask in train))
        moments = [(Ah.T @ Ah, Ah.T @ eh, eh @ eh) for Ah, eh in held]
        Gh, gh, hh = (np.array(v) for v in zip(*moments, strict=True))
        Gt = A.T @ A - Gh
        gt = A.T @ ec - gh + Gt @ x_all  # training moments, about 0
    else:
        x_all, Gt, gt, Gh, gh, hh = object_moments(A, e, rows, train, objects)
    p = A.shape[1]
    use = np.zeros((len(models), len(train), p), dtype=bool)
    lam = np.zeros(use.shape)
    for c, model in enumerate(models):
        for f, (cols, strength) in enumerate(model):
            use[c, f, cols] = True
            lam[c, f, cols[fixed:]] = strength
    d = _ridge_solve(Gt, gt, use, lam) - x_all
    quad = np.einsum("cfi,fij,cfj->cf", d, Gh, d)
    sse = hh - 2.0 * np.einsum("cfi,fi->cf", d, gh) + quad
    return np.maximum(sse, 0.0)


def _ridge_solve(N: np.ndarray, b: np.ndarray, use: np.ndarray, lam: np.ndarray) -> np.ndarray:
    """Ridge normal equations of column subsets ``use`` (prior ``lam``), as lstsq would solve."""
    both = use[..., :, None] & use[..., None, :]
    M = np.where(both, N[None], 0.0)
    diag = np.arange(N.shape[1])
    top = np.max(np.abs(M[..., diag, diag]), axis=-1, keepdims=True)
    M[..., diag, diag] += lam + np.where(use, 0.0, top)  # the padding: eigenvalue top, no rhs
    ev, V = np.linalg.eigh(M)
    ev_abs = np.abs(ev)
    tol = np.finfo(float).eps * use.sum(axis=-1, keepdims=True) * ev_abs.max(axis=-1, keepdims=True)
    y = np.einsum("cfji,cfj->cfi", V, np.where(use, b[None], 0.0))
    y = np.divide(y, ev, out=np.zeros_like(y), where=ev_abs > tol)
    return np.einsum("cfij,cfj->cfi", V, y)
