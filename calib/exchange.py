"""Optimal subsets of candidate configurations: greedy start, then Fedorov-type exchange.

Each candidate c contributes the block ``J_c`` (``r x b``) to the information matrix
``M = ridge I + sum_{c in design} J_c^T J_c``. The state keeps ``M^-1`` and, for every
candidate, the r x r block ``S_c = J_c M^-1 J_c^T`` (and ``P_c = J_c M^-1 L M^-1 J_c^T`` for
a trace criterion), so that changing the design by a few blocks is a low-rank update: adding
candidate i and removing design point j is ``M' = M + R^T S R`` with ``R = [J_i; J_j]`` and
``S = diag(+1, -1)`` (per row), and with ``K = S + R M^-1 R^T`` (2r x 2r):

* ``det M' / det M = det(S) det(K)`` (matrix determinant lemma);
* ``M'^-1 = M^-1 - M^-1 R^T K^-1 R M^-1`` (Sherman-Morrison-Woodbury), so
  ``trace(L M'^-1) = trace(L M^-1) - trace(K^-1 R M^-1 L M^-1 R^T)``.

Every quantity an exchange needs is an r x r block formed from S, P and one matrix product
``J_c (M^-1 X)`` over all the candidates: evaluating one exchange costs O(r^2 b) per
candidate, vectorised, and applying it O(r^2 b) per candidate too; nothing is decomposed
again (``M^-1`` is recomputed from scratch once per sweep, against round-off).

Criteria: ``D`` maximises ``log det M``; ``A`` minimises ``trace M^-1`` (L = I) and ``I``
minimises ``trace(L M^-1)`` with L the mean information of the reference points (the mean
predicted position variance). The start is greedy on D (sequential D-optimal design, which
reaches full rank fastest); the exchange then visits the design points in turn and swaps
each for the candidate that improves the criterion most (Cook and Nachtsheim's modified
Fedorov exchange), sweep after sweep, until a whole sweep improves nothing.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from .exceptions import InvalidArgumentError

EXCHANGE_CRITERIA = ("D", "A", "I")
"""Criteria the exchange optimises."""

MIN_IMPROVEMENT = 1e-9
"""Relative improvement of the criterion below which an exchange is not made."""

MAX_SWEEPS = 30
"""Most exchange sweeps over the design."""

GREEDY_RIDGE = 1e-6
"""Ridge of the greedy start, relative to the mean diagonal of the candidates' information."""

MAX_CONDITION = 1e8
"""Largest condition number of W_b for a greedy start to count as identifying every parameter."""

MIN_DET_RATIO = 1e-10
"""Smallest det M' / det M of an accepted move: a nearly singular design is never entered."""


def _eye(r: int, n: int) -> np.ndarray:
    """Identity blocks ``(r, r, n)``."""
    out = np.zeros((r, r, n))
    out[np.arange(r), np.arange(r)] = 1.0
    return out


def solve_blocks(X: np.ndarray, E: np.ndarray | None = None):
    """``log det X`` and ``X^-1 E`` of many small symmetric positive definite matrices.

    Gauss-Jordan elimination without pivoting (stable on SPD matrices) on blocks stored
    component-major, ``(r, r, N)``: r steps of operations on whole arrays, no Python loop
    over the N matrices.

    Args:
        X: Matrices ``(r, r, N)``.
        E: Right-hand sides ``(r, p, N)``, or None (log-determinant only).

    Returns:
        ``log det X`` ``(N,)``, ``X^-1 E`` ``(r, p, N)`` (None without E), and whether X is
        positive definite ``(N,)`` (where it is not, the other two are meaningless).
    """
    r = X.shape[0]
    aug = np.array(X, dtype=float) if E is None else np.concatenate([X, E], axis=1)
    logdet = np.zeros(X.shape[2])
    ok = np.ones(X.shape[2], dtype=bool)
    for k in range(r):
        piv = aug[k, k].copy()
        ok &= piv > 0
        piv[~(piv > 0)] = 1.0
        logdet += np.log(piv)
        aug[k] /= piv
        f = aug[:, k].copy()
        f[k] = 0.0
        rows = slice(None) if E is not None else slice(k + 1, None)  # no back-substitution
        aug[rows] -= f[rows, None, :] * aug[k][None]
    return logdet, (None if E is None else aug[:, r:]), ok


def _gemm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A_c B`` for every block of A ``(N, r, b)`` and one matrix B ``(b, p)``: ``(N, r, p)``.

    One matrix product (BLAS) instead of N small ones.
    """
    N, r, b = A.shape
    return (A.reshape(N * r, b) @ B).reshape(N, r, -1)


def _blocks(A: np.ndarray) -> np.ndarray:
    """``(N, r, p)`` to component-major ``(r, p, N)``."""
    return np.ascontiguousarray(A.transpose(1, 2, 0))


def _outer(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A_c B_c^T`` for component-major blocks ``(r, p, N)`` and ``(s, p, N)``: ``(r, s, N)``."""
    return np.einsum("ipn,jpn->ijn", A, B)


def _times(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A_c B`` for component-major blocks ``(r, p, N)`` and one matrix ``(p, s)``."""
    return np.einsum("rpn,ps->rsn", A, B)


class ExchangeState:
    """Information matrix of a design and the low-rank update quantities of every candidate.

    Kept: ``M^-1``, ``log det M`` and, for every candidate c, ``S_c = J_c M^-1 J_c^T`` and,
    for a trace criterion, ``P_c = J_c M^-1 L M^-1 J_c^T`` (r x r blocks stored
    component-major, ``(r, r, N)``). Products with ``J_c M^-1`` are formed as ``J_c (M^-1
    X)``: one matrix product over all candidates.

    Args:
        J: Candidate blocks ``(N, r, b)`` (scaled Jacobian rows).
        design: Indices of the design's candidates.
        L: Weight matrix of a trace criterion ``(b, b)``, or None for D.
        ridge: Multiple of the identity added to M.
    """

    def __init__(self, J: np.ndarray, design: Iterable[int], L: np.ndarray | None, ridge: float):
        self.J = np.ascontiguousarray(J, dtype=float)
        self.L = L
        self.ridge = ridge
        self.design = [int(i) for i in design]
        self.refresh()

    def refresh(self) -> None:
        """Recompute M^-1, S, P and log det M from scratch (no accumulated round-off)."""
        b = self.J.shape[2]
        Jd = self.J[self.design].reshape(-1, b)
        M = self.ridge * np.eye(b) + Jd.T @ Jd
        sign, logdet = np.linalg.slogdet(M)
        if sign <= 0:
            raise InvalidArgumentError("the design's information matrix is singular")
        Minv = np.linalg.inv(M)
        self.Minv = 0.5 * (Minv + Minv.T)
        self.logdet = float(logdet)
        G = _gemm(self.J, self.Minv)
        self.S = np.einsum("nrb,nsb->rsn", G, self.J, optimize=True)
        self.P = None
        if self.L is not None:
            self.P = np.einsum("nrb,nsb->rsn", _gemm(G, self.L), G, optimize=True)

    def value(self) -> float:
        """The criterion, as a cost: ``-log det M`` or ``trace(L M^-1)``."""
        return -self.logdet if self.L is None else float(np.sum(self.L * self.Minv))

    def _removal(self, j: int):
        """``G_j = J_j M^-1``, ``W = (I - S_j)^-1`` and ``log det(I - S_j)`` (or None)."""
        r = self.J.shape[1]
        lw, W, ok = solve_blocks((np.eye(r) - self.S[:, :, j])[:, :, None], np.eye(r)[:, :, None])
        if not ok[0] or lw[0] < np.log(MIN_DET_RATIO):
            return None
        return self.J[j] @ self.Minv, W[:, :, 0], float(lw[0])

    def bounds(self, j: int) -> np.ndarray:
        """Upper bounds of :meth:`gains` for removing design point ``j``, from ``(N,)`` traces.

        ``M_-j^-1 <= M^-1 / (1 - l)``, l the largest eigenvalue of ``S_j``, so ``log det(I
        + D_c) <= r log(1 + trace(S_c) / (r (1 - l)))``; for a trace criterion ``trace((I +
        D_c)^-1 E_c) <= trace(E_c) <= (sqrt(trace P_c) + sqrt(w trace(S_j) trace(S_c)))^2``
        with w the largest eigenvalue of ``W P_j W`` (Cauchy-Schwarz in the M^-1 inner
        product). A candidate whose bound does not exceed the improvement asked for cannot
        be the exchange, so :meth:`gains` need not look at it.
        """
        removal = self._removal(j)
        if removal is None:
            return np.full(len(self.J), -np.inf)
        Gj, W, lw = removal
        r = self.J.shape[1]
        trS = np.einsum("iin->n", self.S)
        if self.P is None:
            x = 1.0 / (1.0 - float(np.max(np.linalg.eigvalsh(self.S[:, :, j]))))
            return lw + r * np.log1p(x * trS / r)
        Pj = self.P[:, :, j]
        w = float(np.max(np.linalg.eigvalsh(W @ Pj @ W)))
        trP = np.einsum("iin->n", self.P)
        cross = np.sqrt(np.maximum(w * float(np.trace(self.S[:, :, j])) * trS, 0.0))
        first = (np.sqrt(np.maximum(trP, 0.0)) + cross) ** 2
        # E_c <= mu D_c with mu the largest eigenvalue of L M_-j^-1, and trace((I + D)^-1 D)
        # is concave in the eigenvalues of D: at most r t / (r + t), t = trace(D_c).
        Minv_j = self.Minv + Gj.T @ W @ Gj
        mu = float(np.max(np.linalg.eigvals(self.L @ Minv_j).real))
        t = trS / (1.0 - float(np.max(np.linalg.eigvalsh(self.S[:, :, j]))))
        return -float(np.trace(W @ Pj)) + np.minimum(first, mu * r * t / (r + t))

    def gains(self, j: int | None, subset: np.ndarray | None = None) -> np.ndarray:
        """Decrease of the cost if each candidate is added, and design point ``j`` removed.

        Removing j first: ``M_-j^-1 = M^-1 + G_j^T W G_j`` with ``W = (I - S_j)^-1``; then
        candidate c sees ``D_c = J_c M_-j^-1 J_c^T = S_c + A_c S_cj^T`` (``S_cj = J_c M^-1
        J_j^T``, ``A_c = S_cj W``) and ``det M' / det M = det(I - S_j) det(I + D_c)``. For a
        trace criterion ``trace(L M'^-1) = trace(L M^-1) + trace(W P_j) - trace((I +
        D_c)^-1 E_c)`` with ``E_c = J_c M_-j^-1 L M_-j^-1 J_c^T = P_c + A_c T_cj^T + T_cj
        A_c^T + A_c P_j A_c^T`` (``T_cj = J_c M^-1 L M^-1 J_j^T``). All blocks are r x r.

        Args:
            j: Candidate index of the design point to remove, or None (only add).
            subset: Candidates to evaluate (default: all).

        Returns:
            One gain per candidate of ``subset``; -inf where the move would make M (nearly)
            singular.
        """
        r = self.J.shape[1]
        Jc, S, P = self.J, self.S, self.P
        if subset is not None:  # copies of the subset only
            Jc, S = self.J[subset], self.S[:, :, subset]
            P = None if self.P is None else self.P[:, :, subset]
        n = len(Jc)
        D, E, base, trace_base = S, P, 0.0, 0.0
        if j is not None:
            removal = self._removal(j)
            if removal is None:
                return np.full(n, -np.inf)
            Gj, W, base = removal
            Scj = _blocks(_gemm(Jc, Gj.T))
            A = _times(Scj, W)
            D = S + _outer(A, Scj)
            if P is not None:
                Pj = self.P[:, :, j]
                Tcj = _blocks(_gemm(Jc, self.Minv @ self.L @ Gj.T))
                AT = _outer(A, Tcj)
                E = P + AT + AT.transpose(1, 0, 2) + _outer(_times(A, Pj), A)
                trace_base = -float(np.trace(W @ Pj))
        logdet, Y, ok = solve_blocks(_eye(r, n) + D, E)
        ok &= logdet + base > np.log(MIN_DET_RATIO)  # det M' / det M
        gain = logdet + base if Y is None else np.einsum("iin->n", Y) + trace_base
        return np.where(ok & np.isfinite(gain), gain, -np.inf)

    def apply(self, add: int, remove: int | None) -> None:
        """Add candidate ``add`` (and remove design point ``remove``) by a low-rank update.

        With ``R`` the rows changed, ``K = diag(+-1) + R M^-1 R^T``, ``C = K^-1``, ``Q_c =
        J_c M^-1 R^T`` and ``U_c = Q_c C``: ``M'^-1 = M^-1 - (R M^-1)^T C (R M^-1)``,
        ``S'_c = S_c - U_c Q_c^T``, and with ``T_c = J_c M^-1 L M^-1 R^T``, ``P'_c = P_c -
        U_c T_c^T - T_c U_c^T + U_c (R M^-1 L M^-1 R^T) U_c^T``; ``log det`` grows by
        ``log |det K|``.
        """
        r = self.J.shape[1]
        rows = [add] if remove is None else [add, remove]
        R = self.J[rows].reshape(-1, self.J.shape[2])
        GR = R @ self.Minv  # R M^-1
        K = np.diag(np.repeat([1.0, -1.0][: len(rows)], r)) + GR @ R.T
        _, logabs = np.linalg.slogdet(K)
        self.logdet += float(logabs)
        C = np.linalg.inv(K)
        Q = _gemm(self.J, GR.T)
        U = _blocks(_gemm(Q, C))
        if self.P is not None:
            ML = self.Minv @ self.L
            T = _blocks(_gemm(self.J, ML @ GR.T))
            UT = _outer(U, T)
            self.P = self.P - UT - UT.transpose(1, 0, 2) + _outer(_times(U, GR @ self.L @ GR.T), U)
        self.S = self.S - _outer(U, _blocks(Q))
        self.Minv -= GR.T @ C @ GR
        if remove is None:
            self.design.append(add)
        else:
            self.design[self.design.index(remove)] = add


@dataclass(frozen=True)
class ExchangeResult:
    """Outcome of :func:`optimal_subset`.

    Attributes:
        design: Candidate indices chosen (in the order of the design).
        greedy: The greedy start.
        exchanges: Exchanges made.
        sweeps: Sweeps over the design.
    """

    design: tuple[int, ...]
    greedy: tuple[int, ...]
    exchanges: int
    sweeps: int


def greedy_start(J: np.ndarray, k: int, progress: Callable | None = None) -> list[int]:
    """K candidates chosen one by one, each maximising ``log det M`` (with a small ridge).

    Args:
        J: Candidate blocks ``(N, r, b)``.
        k: Number to choose (at most N).
        progress: Wraps an iterable to show progress (or None).

    Returns:
        Candidate indices, in the order chosen.
    """
    scale = float(np.mean(np.einsum("nrb,nrb->n", J, J))) / J.shape[2]
    state = ExchangeState(J, [], None, GREEDY_RIDGE * max(scale, 1e-300))
    steps = range(k) if progress is None else progress(range(k))
    for _ in steps:
        gain = state.gains(None)
        gain[state.design] = -np.inf
        state.apply(int(np.argmax(gain)), None)
    return state.design


def _sweep(state: ExchangeState, progress: Callable | None) -> int:
    """One pass over the design points; returns the number of exchanges made.

    For each design point, only the candidates whose :meth:`ExchangeState.bounds` exceed
    the improvement asked for are evaluated: the exchange found is the best one all the same.
    """
    made = 0
    order = list(state.design)
    for j in order if progress is None else progress(order):
        if j not in state.design:
            continue
        need = MIN_IMPROVEMENT * max(abs(state.value()), 1.0)
        bound = state.bounds(j)
        bound[state.design] = -np.inf
        subset = np.flatnonzero(bound > need)
        if not subset.size:
            continue
        gain = state.gains(j, subset)
        best = int(np.argmax(gain))
        if gain[best] > need:
            state.apply(int(subset[best]), j)
            made += 1
    return made


def optimal_subset(
    J: np.ndarray,
    k: int,
    criterion: str = "D",
    L: np.ndarray | None = None,
    progress: Callable | None = None,
) -> ExchangeResult:
    """Choose K of N candidates optimising a criterion: greedy start, then exchanges.

    Args:
        J: Candidate blocks ``(N, r, b)``.
        k: Design size K (``K r >= b``, K <= N).
        criterion: ``D``, ``A`` or ``I``.
        L: For ``I``: the reference information ``(b, b)``.
        progress: Wraps an iterable to show progress (or None).

    Returns:
        The chosen candidates and counts.

    Raises:
        InvalidArgumentError: A bad criterion or size, or candidates that cannot identify
            every parameter.
    """
    N, r, b = J.shape
    if criterion not in EXCHANGE_CRITERIA:
        raise InvalidArgumentError(
            f"unknown criterion '{criterion}': choose {', '.join(EXCHANGE_CRITERIA)}"
        )
    if k > N:
        raise InvalidArgumentError(f"{k} configurations asked from only {N} candidates")
    if k * r < b:
        raise InvalidArgumentError(
            f"{k} configurations give {k * r} rows for {b} parameters: choose at least "
            f"{-(-b // r)} configurations"
        )
    if criterion == "I" and (L is None or L.shape != (b, b)):
        raise InvalidArgumentError("criterion I needs the reference information matrix")
    greedy = greedy_start(J, k, progress)
    weight = {"D": None, "A": np.eye(b), "I": L}[criterion]
    if np.linalg.cond(J[greedy].reshape(-1, b)) > MAX_CONDITION:
        raise InvalidArgumentError(
            f"the candidates do not identify the {b} parameters with {k} configurations "
            f"(a joint that never moves, or too few distinct candidates?)"
        )
    state = ExchangeState(J, greedy, weight, 0.0)
    exchanges = sweeps = 0
    while sweeps < MAX_SWEEPS:
        sweeps += 1
        made = _sweep(state, progress)
        exchanges += made
        state.refresh()
        if not made:
            break
    return ExchangeResult(tuple(state.design), tuple(greedy), exchanges, sweeps)


__all__ = ["EXCHANGE_CRITERIA", "ExchangeResult", "ExchangeState", "greedy_start", "optimal_subset"]
