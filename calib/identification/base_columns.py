"""The base columns of an observation matrix: rank, preference, independent columns, regrouping.

The QR bookkeeping of the identifiability analysis (docs/method.md section 3): the numerical rank
from a pivoted QR, the paper's order of preference, the walk that keeps the independent columns
met first, and the regrouping matrix of the others.
"""

from __future__ import annotations

import math

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.mdh import MDHModel
from ..kinematics.tree_model import TreeMDH
from . import qr
from .parameters import Kind, Parameter, ParameterSet

__all__ = [
    "VERIFY_MARGIN",
    "checked_selection",
    "identify_base",
    "independent_columns",
    "numerical_rank",
    "pivoted_diagonal",
    "preference",
    "preference_order",
    "select_by_rank",
    "select_independent",
]


_SPECIAL_ANGLES = (0.0, math.pi / 2, -math.pi / 2, math.pi, -math.pi)


_EPS = float(np.finfo(float).eps)


def numerical_rank(diag: np.ndarray, n_rows: int) -> tuple[int, float]:
    """Rank from the |R_ii| of a pivoted QR: b = #{|R_ii| > tau}, tau = r eps |R_11|.

    Args:
        diag: |R_ii| in pivoting order (non-increasing).
        n_rows: Number of rows r of the observation matrix.

    Returns:
        The rank and the tolerance tau.
    """
    if diag.size == 0 or diag[0] == 0.0:
        return 0, 0.0
    tau = n_rows * _EPS * float(diag[0])
    return int((diag > tau).sum()), tau


def _triangular(W: np.ndarray) -> np.ndarray:
    """R factor of a tall W (min(r, c) x c): column norms and angles of W, cheaply."""
    return qr.triangular(W)


def pivoted_diagonal(W: np.ndarray) -> np.ndarray:
    """|R_ii| of the QR decomposition with column pivoting of W (non-increasing)."""
    return qr.pivoted_diagonal(_triangular(W))


def preference(mdh: MDHModel | TreeMDH, p: Parameter) -> int:
    """Rank of a parameter in the paper's order of preference (0 = kept first).

    0 joint offsets; 1 distances (d, r, b) with a non-zero nominal value; 2 angles (alpha,
    theta, gamma) whose nominal value is neither 0 nor 90 degrees (mod 90); 3 base parameters
    (row 0 and the rows placed from it: row 1 of a chain); 4 tool parameters (row n+1 of a
    chain, every tool row of a tree); 5 the rest.
    """
    k, kind = p.row, p.kind
    if 1 <= k <= mdh.n and (
        (kind is Kind.THETA and mdh.sigma[k] == 0) or (kind is Kind.R and mdh.sigma[k] == 1)
    ):
        return 0
    if k == 0 or mdh.antecedent[k] == 0:
        return 3
    if k in mdh.tool_rows:
        return 4
    value = float(getattr(mdh, kind.value)[k])
    if kind in (Kind.D, Kind.R, Kind.B) and abs(value) > 1e-9:
        return 1
    if (
        kind in (Kind.ALPHA, Kind.THETA, Kind.GAMMA)
        and min(abs(value - a) for a in _SPECIAL_ANGLES) > 1e-6
    ):
        return 2
    return 5


def preference_order(mdh: MDHModel | TreeMDH, params: ParameterSet) -> list[int]:
    """Column indices sorted by :func:`preference` (stable: set order within a class)."""
    key = (id(mdh), id(params))
    hit = _ORDERS.get(key)
    if hit is not None and hit[0] is mdh and hit[1] is params:
        return list(hit[2])
    ranks = [preference(mdh, p) for p in params.parameters]
    order = tuple(sorted(range(len(ranks)), key=ranks.__getitem__))
    if len(_ORDERS) >= 64:
        _ORDERS.clear()
    _ORDERS[key] = (mdh, params, order)  # holding both keeps their ids from being reused
    return list(order)


_ORDERS: dict[tuple[int, int], tuple[MDHModel | TreeMDH, ParameterSet, tuple[int, ...]]] = {}
"""Orders already computed, by model and set (both immutable): the structural step asks for
the same pair at every call."""


VERIFY_MARGIN = 2.0
"""Factor by which a column must clear the threshold for :func:`select_independent`'s one-QR
check to decide it (kept: distance above twice the threshold, dropped: under half of it).
The threshold is at least tau, ten times the round-off of a distance, so two ways of
computing a distance cannot disagree across this band; a column inside it takes the
restarting walk."""


def select_independent(R: np.ndarray, order: list[int], tau: float) -> list[int]:
    """Walk the columns in ``order`` and keep each one that is independent of those kept.

    A column is kept when its distance to the span of the kept ones exceeds ``tau``: this
    is what deleting the columns with |R_ii| <= tau of an unpivoted QR means. Householder
    QR stops revealing it after an exactly dependent column (that column's row is left
    unused), so after each dependent column the QR restarts on the residual block, which is
    an orthogonal image of the remaining columns' components orthogonal to the kept ones.

    The first QR's verdicts are tried first: they are the walk's result when one QR of the
    kept columns and the others (:func:`checked_selection`) proves it, which spares the
    restarts.

    Args:
        R: Triangular factor (or any matrix with the same column geometry as W).
        order: Column indices, most preferred first.
        tau: Distance under which a column is dependent.

    Returns:
        The kept column indices, in ``order``.
    """
    return _select(R, order, tau)[0]


def _select(
    R: np.ndarray, order: list[int], tau: float, first: np.ndarray | None = None
) -> tuple[list[int], np.ndarray | None]:
    """:func:`select_independent`, and the factor of :func:`checked_selection` (or None).

    ``first``: |diagonal| of an unpivoted QR of the columns in ``order`` (of W itself: its
    many rows leave more room to the round-off of dependent columns than R's), for the guess.
    """
    idx = list(order)
    if not idx or R.shape[0] == 0:
        return [], None
    T = None
    if first is None:
        T = qr.householder(R[:, idx])  # R on and above the diagonal, the reflectors below it
        first = np.abs(T.diagonal())
    guess = [idx[j] for j in np.flatnonzero(first > tau)]
    Rk = checked_selection(R, idx, guess, tau)
    if Rk is not None:
        return guess, Rk
    if T is None:
        T = qr.householder(R[:, idx])
    d = np.abs(T.diagonal())
    kept: list[int] = []
    while True:
        small = np.flatnonzero(d <= tau)
        j = int(small[0]) if small.size else len(d)
        kept += idx[:j]
        if j == len(d):  # all kept, or the rows are exhausted: the rest depends on the kept
            return kept, None
        # Column j depends on the kept ones; the rows j.. of the columns after it hold their
        # components orthogonal to the kept columns.
        idx = idx[j + 1 :]
        M = qr.upper(T[j:, j + 1 :], -1)  # R's part of that block (it starts below the diagonal)
        if not idx or M.shape[0] == 0:
            return kept, None
        T = qr.householder(M)
        d = np.abs(T.diagonal())


def checked_selection(
    R: np.ndarray, order: list[int], kept: list[int], tau: float
) -> np.ndarray | None:
    """Whether ``kept`` is the walk of :func:`select_independent`, by one QR.

    With the kept columns first (in ``order``), then the others (in index order), the
    triangular factor holds each kept column's distance to the kept ones before it (its
    diagonal) and, in each other column, its components along the kept columns and beyond:
    its distance to the kept columns met before it in ``order`` is the norm of the entries
    from that count down. The selection is proved when every kept distance exceeds ``tau``
    and every other one is under it, each by :data:`VERIFY_MARGIN`.

    Returns:
        The triangular factor of ``R[:, kept + others]``, or None if not proved.
    """
    chosen = set(kept)
    others = [i for i in range(R.shape[1]) if i not in chosen]
    if len(kept) > min(R.shape) or len(order) != R.shape[1]:
        return None
    Rk = qr.triangular(R[:, kept + others])
    b = len(kept)
    if (np.abs(Rk.diagonal()[:b]) <= VERIFY_MARGIN * tau).any():
        return None
    if others:
        count, before = 0, {}  # kept columns met before each other one
        for i in order:
            if i in chosen:
                count += 1
            else:
                before[i] = count
        start = np.array([before[i] for i in others])
        tail = np.where(np.arange(Rk.shape[0])[:, None] >= start, Rk[:, b:], 0.0)
        if (np.einsum("ij,ij->j", tail, tail) >= (tau / VERIFY_MARGIN) ** 2).any():
            return None
    return Rk


def select_by_rank(R: np.ndarray, order: list[int], tau: float) -> list[int]:
    """Keep each column, in ``order``, whose addition raises the numerical rank (slow, robust)."""
    kept: list[int] = []
    for i in order:
        cols = [*kept, i]
        if int(np.sum(pivoted_diagonal(R[:, cols]) > tau)) > len(kept):
            kept = cols
    return kept


def independent_columns(
    W: np.ndarray, order: list[int], n_rows: int | None = None
) -> tuple[np.ndarray, float, list[int], np.ndarray]:
    """Rank of W and the independent columns met first in an order of preference.

    Args:
        W: Observation matrix ``(r, c)``, or a smaller matrix with its column geometry.
        order: Column indices, most preferred first.
        n_rows: Rows r of the observation matrix (default: W's).

    Returns:
        |R_ii| of the pivoted QR, tau, the kept column indices (in ``order``) and a factor
        with W's column geometry: the triangular factor of W's columns in ``order``, its
        columns put back in W's order.
    """
    diag, tau, kept, R, _ = _independent_columns(W, order, n_rows)
    return diag, tau, kept, R


def _independent_columns(W: np.ndarray, order: list[int], n_rows: int | None):
    """:func:`independent_columns`, and the factor of :func:`checked_selection` (or None)."""
    if not np.isfinite(W).all():
        raise InvalidArgumentError(
            "the observation matrix has non-finite entries: check the marker and the configurations"
        )
    first = None
    if sorted(order) == list(range(W.shape[1])) and min(W.shape) > 0:
        # One QR of W's columns in order: its diagonal is the walk's first guess, and its
        # factor, columns put back, has W's column geometry.
        T = qr.householder(qr.fortran_columns(W, order), overwrite=True)
        k = min(W.shape)
        first = np.abs(T.diagonal())
        R = np.empty((k, W.shape[1]))
        R[:, order] = qr.upper(T[:k])
    else:
        R = _triangular(W)
    diag = qr.pivoted_diagonal(R)
    rank, tau = numerical_rank(diag, W.shape[0] if n_rows is None else n_rows)
    # Select with a threshold in the middle of the gap between the two clusters of |R_ii|:
    # dependencies that hold only to round-off of the URDF (1e-13) stay dependent whatever
    # the order in which the columns are visited.
    threshold = tau if rank in (0, len(diag)) else max(tau, math.sqrt(diag[rank - 1] * diag[rank]))
    kept, Rk = _select(R, order, threshold, first)
    if len(kept) != rank:
        # Nearly dependent columns (small tilts) amplify round-off in the residuals; fall back
        # to the definition: keep a column when it raises the pivoted-QR rank.
        kept, Rk = select_by_rank(R, order, tau), None
    return diag, tau, kept, R, Rk


def identify_base(
    mdh: MDHModel | TreeMDH, params: ParameterSet, W: np.ndarray, n_rows: int | None = None
) -> tuple[np.ndarray, float, list[int], list[int], np.ndarray]:
    """Rank, base columns and regrouping of an observation matrix (docs/method.md section 3).

    Args:
        mdh: Nominal model (for the order of preference).
        params: The parameters of W's columns.
        W: Observation matrix ``(r, c)``, or a smaller matrix with its column geometry.
        n_rows: Rows r of the observation matrix (default: W's).

    Returns:
        |R_ii| of the pivoted QR, tau, the kept column indices (preference order), the other
        column indices (set order), and B = R1^-1 R2 with base = kept + B @ others.
    """
    diag, tau, kept, R, Rk = _independent_columns(W, preference_order(mdh, params), n_rows)
    chosen = set(kept)
    others = [i for i in range(len(params)) if i not in chosen]
    if Rk is None:
        Rk = qr.triangular(R[:, kept + others])
    b = len(kept)
    B = qr.solve_upper(Rk[:b, :b], Rk[:b, b:])
    return diag, tau, kept, others, B
