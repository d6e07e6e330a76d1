"""Postures: the rows of a campaign recorded at the same joint values count once.

A posture recorded several times (the same configuration measured twice, a touch repeated)
adds rows but no new information about the geometry: only its noise averages. Whatever
counts or splits configurations (the selection's cross-validation folds, the holdout, the
equation counts of :mod:`calib.calibration.determined`) counts postures, so that a file whose
rows repeat is treated as if each posture were there once.
"""

from __future__ import annotations

import numpy as np

__all__ = ["POSTURE_TOL", "count", "posture_groups", "sample_postures"]

POSTURE_TOL = 1e-6
"""Rows whose joint values agree to this [rad or m] (after rounding to its multiples) are one
posture: well below any encoder's resolution, well above a CSV's round-off."""


def posture_groups(q: np.ndarray, key=None, tol: float = POSTURE_TOL) -> np.ndarray:
    """The posture of each row, numbered 0, 1, ... in order of first appearance.

    Args:
        q: Joint values ``(m, n)`` [rad or m].
        key: What else a row's posture is (``(m,)``, e.g. the plane a touch touches, or the
            tool a row measures), or None.
        tol: Joint values equal once rounded to multiples of this are the same [rad or m].

    Returns:
        ``(m,)`` posture index of each row; ``max + 1`` is the number of postures.
    """
    cells = _cells(q, key, tol)
    _, first, inverse = np.unique(cells, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first))  # group numbers in order of first appearance
    return order[inverse.reshape(-1)]


def _cells(q: np.ndarray, key, tol: float) -> np.ndarray:
    """Each row's joint values rounded to multiples of ``tol``, then its ``key``'s code."""
    q = np.asarray(q, dtype=float).reshape(len(q), -1)
    cells = np.round(q / tol)
    if key is not None:
        _, codes = np.unique(np.asarray(key), return_inverse=True)
        cells = np.c_[cells, codes.reshape(-1)]
    return cells


def count(q: np.ndarray, key=None) -> int:
    """Number of distinct postures among the rows (:func:`posture_groups`).

    The rows sorted (``lexsort``) and the changes between neighbours counted: the number
    :func:`posture_groups` numbers, without numbering them (a fifth of its time).
    """
    cells = _cells(q, key, POSTURE_TOL)
    if not cells.size:  # no row, or rows of no joint (one posture)
        return min(len(cells), 1)
    ordered = cells[np.lexsort(cells.T)]
    return 1 + int(np.count_nonzero((ordered[1:] != ordered[:-1]).any(axis=1)))


def sample_postures(groups: np.ndarray, count: int, seed: int, strata=None) -> np.ndarray:
    """Rows of about ``count`` whole postures drawn at random, each stratum in proportion.

    A posture's repeats are drawn together (they are one posture); every stratum (a tool,
    a plane: ``strata``) gives the same fraction of its rows, at least one posture.

    Args:
        groups: Posture of each row (:func:`posture_groups`).
        count: Rows wanted (about: whole postures are drawn).
        seed: Seed of the draw.
        strata: What else separates rows (``(m,)``), or None (one stratum).

    Returns:
        ``(m,)`` mask of the rows drawn, in the data's order.
    """
    groups = np.asarray(groups).reshape(-1)
    rng = np.random.default_rng(seed)
    codes = np.zeros(len(groups), dtype=int)
    if strata is not None:
        codes = np.unique(np.asarray(strata), return_inverse=True)[1].reshape(-1)
    sizes = np.bincount(groups)
    keep = np.zeros(len(groups), dtype=bool)
    for stratum in range(int(codes.max(initial=-1)) + 1):
        inside = codes == stratum
        drawn = rng.permutation(np.unique(groups[inside]))
        want = count * int(inside.sum()) / len(groups)
        take = max(1, int(np.searchsorted(np.cumsum(sizes[drawn]), want, side="right")))
        keep |= inside & np.isin(groups, drawn[:take])
    return keep
