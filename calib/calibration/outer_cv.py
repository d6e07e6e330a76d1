"""The selection's guard: cross-validated errors of candidate models by fold, from moments.

Each fold's fit of a candidate model (its columns, its prior strength) is a ridge fit of the
fold's training rows; its error on the fold's held-out rows comes from the moments of those
rows (:func:`outer_cv`), so that no array larger than the data is made. Used by
:func:`~calib.calibration.selection.select`.
"""

from __future__ import annotations

import numpy as np

from .object_columns import object_moments

__all__ = ["outer_cv"]


def outer_cv(A, e, rows, fixed, train, models, objects=None) -> np.ndarray:
    """Held-out squared error of each candidate model's fits, by fold (module text).

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
    d = _solve(Gt, gt, use, lam) - x_all
    quad = np.einsum("cfi,fij,cfj->cf", d, Gh, d)
    sse = hh - 2.0 * np.einsum("cfi,fi->cf", d, gh) + quad
    return np.maximum(sse, 0.0)


def _solve(N: np.ndarray, b: np.ndarray, use: np.ndarray, lam: np.ndarray) -> np.ndarray:
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
