"""Model selection (``auto``): which identifiable parameters the data support.

On the model linearised at the registration: a forward path ordered by the
leave-one-configuration-out error (block PRESS), a prefix of it kept, shrunk toward the nominal
model by a ridge prior, guarded by ``OUTER_FOLDS`` folds against selection bias, against the
complete fit from ``RICH`` equations per parameter; a posture's repeats enter as one.

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
"""A prefix's mean squared left-out error under this fraction of the path's largest counts as
this floor: after a step that fits exactly, the steps' errors are round-off (about eps times
it), equal, and the shorter prefix is kept."""

OUTER_FOLDS = 10
"""Folds of the guard's cross-validation (configuration i goes to fold i mod OUTER_FOLDS)."""

RICH = 10
"""Equations (distinct postures times rows) per parameter of the complete fit from which the
complete fit with its cross-validated prior is a candidate: the lower cross-validated error
then chooses between it and the selection (with fewer, a fold's error is that of a few
postures, and the selection stays as careful as it was)."""

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
        complete_cv: The same for the complete fit (every candidate) with its prior strength
            chosen by the leave-one-out error [m].
        winner: The model delivered: ``registration``, ``selection`` or ``complete``.
        index: Each kept parameter's position among the candidates (``kept``'s order): two
            candidates may share a name (a joint two chains share, its MDH parameter in each
            chain's rows: two directions).
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
    """Leave-one-out errors at the best prior strength of several subsets of the configurations.

    The strength is 0 or one of ``STRENGTHS``, on the columns after the first ``fixed``;
    each subset has its own configurations and columns.

    Subset s fits the first ``fixed`` columns free and ``cols[s]`` under the prior, on its
    configurations ``train[s]`` (the others' rows zeroed, which changes neither the fit nor
    its own hat blocks). With the prior's columns made orthogonal to the fixed ones (``B``,
    residuals ``r``) and ``B = U S V^T``, the hat matrix at strength ``s`` is
    ``P_fixed + U diag(S^2 / (S^2 + s)) U^T``: one SVD per subset serves every strength
    (the block PRESS of the ridge fit ``A^T A + s`` on those columns), and the left-out errors of
    every subset at every strength are one batch of small solves. The subsets are taken a
    few at a time, and their configurations in blocks (:data:`BLOCK`): the memory is linear
    in the data. ``A``: unit-norm columns ``(m rows, p)``; ``train`` ``(subsets, m)``
    [bool]; ``objects``: objects' columns free too, by block (:mod:`.object_columns`), or
    None. Returns each subset's squared left-out errors at its strength of least RMS error
    ``(b, m)`` (zero on the configurations it leaves out), and those strengths ``(b,)`` (0:
    none; the smallest of equal errors).
    """
    per = _per_batch(A.shape[0] * A.shape[1], len(train))
    parts = [
        _ridge_batch(A, e, rows, fixed, train[i : i + per], cols[i : i + per], objects)
        for i in range(0, len(train), per)
    ]
    return np.concatenate([q[0] for q in parts]), np.concatenate([q[1] for q in parts])


BLOCK = 2_000_000
"""Numbers a batch of subsets (or a block of configurations) may hold in one working array:
the selection's memory is a few times ``8 BLOCK`` bytes beyond the data's own arrays."""


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
    """Squared left-out errors ``(b, strengths, m)`` of the hats ``Q Q^T + U diag(wt) U^T``.

    The configurations are taken in blocks (:data:`BLOCK`): each one's error needs its own
    rows and the fits' coefficients ``wt U^T r`` only. ``Q`` ``(b, n, fixed)``: the fixed
    columns' orthonormal basis (or ``hat``, their hat blocks ``(b, m, rows, rows)``); ``U``
    ``(b, n, width)``: the prior columns' left singular vectors, ``wt`` ``(b, strengths,
    width)`` their weights; ``r`` ``(b, n)``: the fixed columns' fit's residuals.
    """
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
    """The fixed columns' hat blocks ``(rows, rows, b, m)``.

    From their basis, or their hat blocks, by configuration ``(b, m, rows, .)``.
    """
    if is_hat:
        return np.transpose(Fb, (2, 3, 0, 1))
    Qc = np.transpose(Fb, (2, 0, 1, 3))
    return np.einsum("ibms,jbms->ijbm", Qc, Qc)


def _ridge_block(fixed, Ub, wt, coef, rb, rows) -> np.ndarray:
    """:func:`_ridge_errors` of a block of configurations (arrays by configuration).

    ``fixed``: the fixed columns' hat blocks ``(rows, rows, b, m)``.
    """
    b, m = Ub.shape[:2]
    S = wt.shape[1]
    Uc = np.ascontiguousarray(np.transpose(Ub, (2, 0, 3, 1)))  # (rows, b, width, m)
    M = _symmetric_hats(Uc, wt)  # (rows, rows, b, strengths, m): component-major
    M -= fixed[:, :, :, None]
    diag = np.arange(rows)
    M[diag, diag] += 1.0
    fitted = np.einsum("bsk,bmik->ibsm", coef, Ub)
    y = np.ascontiguousarray(np.transpose(rb, (2, 0, 1))[:, :, None, :] - fitted)
    if rows <= SMALL:
        x = spd_solve(M.reshape(rows, rows, -1), y.reshape(rows, -1))  # M kept for LAPACK
        sq = np.einsum("is,is->s", x, x).reshape(b, S, m)
        if np.isfinite(sq).all():
            return sq
    M[diag, diag] = 1.0 - (1.0 - M[diag, diag])  # I - (I - M): the digits LAPACK always had
    blocks = np.moveaxis(M.reshape(rows, rows, b * S, m), (0, 1), (2, 3))  # a view: no copy
    return lu_errors(blocks, np.moveaxis(y.reshape(rows, b * S, m), 0, 2)).reshape(b, S, m)


def _symmetric_hats(Uc: np.ndarray, wt: np.ndarray) -> np.ndarray:
    """``-U diag(wt) U^T`` of each configuration at each strength, component-major.

    Each entry on and above the diagonal once, mirrored below it (half the products).
    ``Uc`` ``(rows, b, width, m)``: the prior columns' left singular vectors by row of a
    configuration; ``wt`` ``(b, strengths, width)``. Returns ``(rows, rows, b, strengths, m)``.
    """
    rows = len(Uc)
    i, j = np.triu_indices(rows)
    upper = -(wt @ (Uc[i] * Uc[j]))  # (pairs, b, strengths, m)
    M = np.empty((rows, rows, *upper.shape[1:]))
    M[i, j] = upper
    M[j, i] = upper
    return M


def best_prefix(sq: np.ndarray) -> int:
    """Length of the path's prefix kept, from its squared left-out errors ``(prefixes, m)``.

    The prefix of least error (a longer one preferred only if ``MIN_GAIN`` better than every
    shorter one), then the shortest prefix whose error is within one standard error of it
    (the standard error of the mean difference over configurations, paired): the minimum of
    a long path is partly chance, and a difference smaller than its own noise is not kept.
    Errors under ``ROUNDOFF`` of the largest are equal (round-off after an exact step).
    """
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
    """The forward selection (see the module docstring) on each subset ``train`` ``(b, m)``.

    Each subset's kept candidates (into ``names``) and steps, and the whole path's order
    (all it reached) and steps; ``forced``: indices into ``names`` always kept (``--free``).

    ``repeats``: each posture's spread, the squared errors every model leaves on it (added
    to its left-out errors), and its rows in the file (:func:`_by_posture`).
    """
    sel = list(forced)
    start = list(range(fixed)) + [fixed + s for s in sel]
    rest = [fixed + u for u in range(len(names)) if u not in sel]
    spread, count = repeats
    out = []
    per = _per_batch(A.shape[0] * max(len(rest), 1), len(train))
    found = (  # a batch at a time: each path's errors (steps x configurations) then dropped
        p
        for i in range(0, len(train), per)
        for p in paths(A, e, rows, start, rest, train[i : i + per], objects)
    )
    for (order, errors), mask in zip(found, train, strict=True):
        errors = errors + spread[mask]
        k = best_prefix(errors)
        points = float(np.sum(count[mask])) * rows / 3  # the file's points they stand for
        loo = [float(v) for v in np.sqrt(np.sum(errors, axis=-1) / points)]  # RMS per point
        steps = [Step("registration" if not sel else "+".join(names[s] for s in sel), loo[0])]
        steps += [Step(names[c - fixed], v) for c, v in zip(order, loo[1:], strict=True)]
        whole = sel + [c - fixed for c in order]
        out.append((sel + [c - fixed for c in order[:k]], steps[: k + 1], whole, steps))
    return out


def _padded(A: np.ndarray, cols: list[list[int]]) -> tuple[np.ndarray, np.ndarray]:
    """Each list's columns of A zero-padded ``(lists, n, width)``, and which are real."""
    width = max(map(len, cols))
    out = np.zeros((len(cols), A.shape[0], width))
    for s, c in enumerate(cols):
        out[s, :, : len(c)] = A[:, c]
    return out, np.arange(width) < np.array([len(c) for c in cols])[:, None]


def _by_posture(J: np.ndarray, e: np.ndarray, groups) -> tuple[np.ndarray, np.ndarray, tuple]:
    """The rows of each posture once: its repeats' mean, times the square root of their count.

    For the linear model the fit and every left-out error of a posture are those of its
    repeats (a posture held out leaves with all of them), but for the spread of the repeats
    about their mean, which no model explains: it is returned, to be added to the errors.
    ``J`` ``(m, rows, p)`` -> ``(postures, rows, p)``, ``e`` ``(m, rows)`` -> ``(postures,
    rows)``, then each posture's spread (summed squares) with its count; ``groups``: each
    configuration's posture ``(m,)`` (from 0), or None.
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
    """The guard's candidates by fold: the registration, then the procedures ``fits``.

    ``fits``: the strengths the selection (then the complete fit) chose on the whole data
    and each fold, ``lists`` their columns, in that order.
    """
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
) -> tuple[Selection, np.ndarray]:
    """Choose the parameters the data support (see the module docstring).

    At the registration: ``J`` ``(m, rows, fixed + len(names))``, the ``fixed`` always-free
    columns (frame, markers) first, and ``e`` ``(m, rows)`` measured - model, both weighted.
    ``forced``: indices into ``names`` kept whatever the data say; ``groups``: each
    configuration's posture (:func:`~calib.measurements.postures.posture_groups`; repeats
    count once; None: each its own); ``objects``: always-free object columns by block
    (:mod:`.object_columns`), or None. Returns the selection and each kept parameter's
    prior weight (in the units of x: ``sqrt(strength) * |column|``).
    """
    points, rows = e.size / 3, J.shape[1]
    A, norms, ev, repeats, objects = _unit_columns(J, e, groups, objects)
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
    """Held-out squared error of each candidate model's fits, by fold (the selection's guard).

    Each fold's fit of a candidate model (its columns, its prior strength) is a ridge fit of the
    fold's training rows; its error on the fold's held-out rows comes from the moments of those
    rows, so that no array larger than the data is made.
    The held-out rows' moments (``A_h^T A_h``, ``A_h^T e_h``, ``|e_h|^2``) are taken about
    the whole data's least-squares fit (whose residuals are small: they keep their digits).
    ``A``: unit-norm columns, configuration-major rows, the first ``fixed`` always in;
    ``train`` ``(folds, m)``; ``models``: per candidate, per fold, its columns and prior
    strength; ``objects``: free by block (:func:`.object_columns.object_moments`), or None.
    Returns ``(candidates, folds)`` [units of e squared].
    """
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
    """Ridge normal equations of column subsets, solved as :func:`numpy.linalg.lstsq` would.

    Eigenvalues under ``eps p`` times the largest are dropped (``p`` the subset's columns).
    ``N`` ``(folds, p, p)`` and ``b`` ``(folds, p)``: each fold's normal equations; ``use``
    (the columns of each candidate's fit) and ``lam`` (the prior on each column):
    ``(candidates, folds, p)``. Returns ``(candidates, folds, p)``, zero off their columns.
    """
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
