"""Optimal subsets of candidate configurations: greedy start, then Fedorov-type exchange.

Each candidate c contributes the block ``J_c`` (``r x b``) to the information matrix
``M = ridge I + sum_{c in design} J_c^T J_c``. Changing the design by a few blocks is a
low-rank update: adding candidate i and removing design point j is ``M' = M + R^T S R`` with
``R = [J_i; J_j]`` and ``S = diag(+1, -1)`` (per row), and with ``K = S + R M^-1 R^T`` (2r x
2r):

* ``det M' / det M = det(S) det(K)`` (matrix determinant lemma);
* ``M'^-1 = M^-1 - M^-1 R^T K^-1 R M^-1`` (Sherman-Morrison-Woodbury), so
  ``trace(L M'^-1) = trace(L M^-1) - trace(K^-1 R M^-1 L M^-1 R^T)``.

The gain of an exchange is then a function of r x r blocks (``S_c = J_c M^-1 J_c^T``, ``P_c
= J_c M^-1 L M^-1 J_c^T`` and their cross terms with j), O(r^2 b) per candidate. The state
keeps ``M^-1`` and only the traces of ``S_c`` and ``P_c`` for every candidate; one matrix
product over the candidates per design point turns them into an upper bound of every
candidate's gain, and the exact gains are evaluated only for the candidates whose bound
exceeds the best gain found so far (branch and bound), which are few: the exchange made is
the best one all the same. Nothing is decomposed again (``M^-1`` is recomputed from scratch
once per sweep, against round-off).

Criteria: ``D`` maximises ``log det M``; ``A`` minimises ``trace M^-1`` (L = I) and ``I``
minimises ``trace(L M^-1)`` with L the mean information of the reference points (the mean
predicted position variance). The start is greedy on D (sequential D-optimal design, which
reaches full rank fastest); the exchange then visits the design points in turn and swaps
each for the candidate that improves the criterion most (Cook and Nachtsheim's modified
Fedorov exchange), sweep after sweep, until a whole sweep improves nothing.
:func:`least_i` bounds from below the I of every set of K of the candidates.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.checks import check_count, least_configurations, real_array, shown
from ..core.choices import EXCHANGE_CRITERIA
from ..core.progress import steps
from ..exceptions import InvalidArgumentError
from .blocks import component_major, dots, eye_blocks, gemm, outer, solve_blocks, times

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

FIRST_CHUNK = 128
"""Candidates evaluated first for an exchange (those of highest bound); then twice as many."""

GATHER = 0.25
"""Fraction of the candidates below which their rows are gathered for the bounds (above it,
one product over all the candidates is cheaper)."""


class ExchangeState:
    """Information matrix of a design and the low-rank update quantities of every candidate.

    Kept: ``M^-1``, ``log det M`` and, for every candidate c, ``trace S_c`` and, for a trace
    criterion, ``trace P_c`` ``(N,)``, with ``S_c = J_c M^-1 J_c^T`` and ``P_c = J_c M^-1 L
    M^-1 J_c^T``: the traces bound the gains (:meth:`bounds`); the r x r blocks themselves
    are formed only for the candidates whose exchange is evaluated (:meth:`gains`). The
    candidates' rows are also kept transposed, ``(b, r N)`` (column ``s N + c`` is row s of
    ``J_c``), so that ``X J_c^T`` for every candidate is one matrix product.

    Args:
        J: Candidate blocks ``(N, r, b)`` (scaled Jacobian rows).
        design: Indices of the design's candidates.
        L: Weight matrix of a trace criterion ``(b, b)``, or None for D.
        ridge: Multiple of the identity added to M.
    """

    def __init__(self, J: np.ndarray, design: Iterable[int], L: np.ndarray | None, ridge: float):
        self.J = np.ascontiguousarray(J, dtype=float)
        self.Jt = np.ascontiguousarray(self.J.transpose(2, 1, 0).reshape(self.J.shape[2], -1))
        self.L = L
        self.ridge = ridge
        self.design = [int(i) for i in design]
        self.excluded = np.zeros(len(self.J), dtype=bool)  # rejected by the checks
        self.refresh()

    def refresh(self) -> None:
        """Recompute M^-1, log det M and the traces from scratch (no accumulated round-off)."""
        b = self.J.shape[2]
        Jd = self.J[self.design].reshape(-1, b)
        M = self.ridge * np.eye(b) + Jd.T @ Jd
        sign, logdet = np.linalg.slogdet(M)
        if sign <= 0:
            raise InvalidArgumentError("the design's information matrix is singular")
        Minv = np.linalg.inv(M)
        self.Minv = 0.5 * (Minv + Minv.T)
        self.logdet = float(logdet)
        self._removed: tuple[int | None, Any] = (None, None)
        G = self.Minv @ self.Jt  # M^-1 J_c^T of every candidate
        self.trS = dots(G, self.Jt, self.J.shape[1])
        self.trP = None if self.L is None else dots(self.L @ G, G, self.J.shape[1])

    def value(self) -> float:
        """The criterion, as a cost: ``-log det M`` or ``trace(L M^-1)``."""
        return -self.logdet if self.L is None else float(np.sum(self.L * self.Minv))

    def blocks(self, subset: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """``S_c`` and ``P_c`` (None for D) of the candidates of ``subset``, ``(r, r, n)``."""
        Js = self.J[subset]
        return self._blocks_of(Js, gemm(Js, self.Minv))

    def _blocks_of(self, Js: np.ndarray, G: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """``S_c`` and ``P_c`` from the rows ``Js`` and ``G = Js M^-1``, ``(n, r, b)``."""
        S = component_major(np.matmul(G, Js.transpose(0, 2, 1)))
        if self.L is None:
            return S, None
        return S, component_major(np.matmul(gemm(G, self.L), G.transpose(0, 2, 1)))

    def _removal(self, j: int):
        """``G_j = J_j M^-1``, ``W = (I - S_j)^-1``, ``log det(I - S_j)`` and ``P_j`` (or None).

        Kept until M changes: the bounds and every chunk of gains of j share them.
        """
        if self._removed[0] != j:
            self._removed = (j, self._removal_of(j))
        return self._removed[1]

    def _removal_of(self, j: int):
        r = self.J.shape[1]
        Gj = self.J[j] @ self.Minv
        Sj = Gj @ self.J[j].T
        lw, W, ok = solve_blocks((np.eye(r) - Sj)[:, :, None], np.eye(r)[:, :, None])
        if not ok[0] or lw[0] < np.log(MIN_DET_RATIO):
            return None
        Pj = None if self.L is None else Gj @ self.L @ Gj.T
        return Gj, W[:, :, 0], float(lw[0]), Pj

    def coarse_bounds(self, j: int) -> np.ndarray:
        """Looser upper bounds of :meth:`gains` for removing ``j``, from the kept traces alone.

        No product over the candidates: ``M_-j^-1 <= M^-1 / (1 - l)``, l the largest
        eigenvalue of ``S_j``, so ``trace D_c <= trace S_c / (1 - l)``; for a trace criterion
        ``sqrt(trace E_c) <= sqrt(trace P_c) + sqrt(w l trace S_c)`` with w the largest
        eigenvalue of ``W P_j W`` (triangle inequality, ``|S_cj|_F^2 <= l trace S_c``). Then
        as in :meth:`bounds`. No coarse bound is below the bound of :meth:`bounds`.
        """
        removal = self._removal(j)
        if removal is None:
            return np.full(len(self.J), -np.inf)
        Gj, W, lw, Pj = removal
        r = self.J.shape[1]
        lj = float(np.max(np.linalg.eigvalsh(Gj @ self.J[j].T)))
        if self.L is None or self.trP is None:  # D (trP is None exactly when L is)
            return lw + r * np.log1p(self.trS / (r * (1.0 - lj)))
        w = float(np.max(np.linalg.eigvalsh(W @ Pj @ W)))
        cross = np.sqrt(np.maximum(w * lj * self.trS, 0.0))
        return (np.sqrt(np.maximum(self.trP, 0.0)) + cross) ** 2 - float(np.trace(W @ Pj))

    def bounds(self, j: int, subset: np.ndarray | None = None) -> np.ndarray:
        """Upper bounds of :meth:`gains` for removing design point ``j``, one per candidate.

        One matrix product over the candidates gives the exact traces of the blocks of
        :meth:`gains` (``J_c^T`` times a few rows): for D, with ``W = R^T R``, ``trace D_c =
        trace S_c + |R G_j J_c^T|_F^2``, and ``log det(I + D_c) <= r log(1 + trace(D_c) /
        r)`` (arithmetic-geometric mean of the eigenvalues of ``I + D_c``); for a trace
        criterion, with ``V_c = W G_j J_c^T = A_c^T`` and ``P_j = F^T F``, ``trace E_c =
        trace P_c + 2 <V_c, G_j L M^-1 J_c^T> + |F V_c|_F^2``, and ``trace((I + D_c)^-1 E_c)
        <= trace E_c``. A candidate whose bound does not exceed a gain already found cannot
        be the best exchange, so :meth:`gains` need not look at it.

        Args:
            j: Candidate index of the design point to remove.
            subset: Candidates to bound (default: all).
        """
        every = slice(None) if subset is None else subset
        removal = self._removal(j)
        if removal is None:
            return np.full(len(self.trS[every]), -np.inf)
        Gj, W, lw, Pj = removal
        r = self.J.shape[1]
        if self.L is None or self.trP is None:  # D (trP is None exactly when L is)
            Y = self._products(np.linalg.cholesky(W).T @ Gj, subset)  # R S_cj^T
            return lw + r * np.log1p((self.trS[every] + dots(Y, Y, r)) / r)
        e, U = np.linalg.eigh(Pj)
        F = np.sqrt(np.maximum(e, 0.0))[:, None] * U.T
        V = W @ Gj
        Y = self._products(np.vstack([V, Gj @ self.L @ self.Minv, F @ V]), subset)
        cross = dots(Y[:r], Y[r : 2 * r], r)  # Y: V_c, T_cj^T and F V_c
        return self.trP[every] + 2.0 * cross + dots(Y[2 * r :], Y[2 * r :], r) - np.trace(W @ Pj)

    def _products(self, rows: np.ndarray, subset: np.ndarray | None) -> np.ndarray:
        """``rows J_c^T`` of the candidates of ``subset`` (default: all), ``(p, r n)``.

        Column ``s n + i`` is column s of the i-th candidate's block (as
        :func:`~.blocks.dots` reads).
        """
        if subset is None:
            return rows @ self.Jt
        Js = self.J[subset]
        m, r, b = Js.shape
        Y = (Js.reshape(m * r, b) @ rows.T).reshape(m, r, -1)
        return Y.transpose(2, 1, 0).reshape(-1, r * m)

    def add_bounds(self) -> np.ndarray:
        """Upper bounds of ``gains(None)`` for D ``(N,)``.

        ``log det(I + S_c) <= r log(1 + trace S_c / r)`` (arithmetic-geometric mean).
        """
        r = self.J.shape[1]
        return r * np.log1p(self.trS / r)

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
        Js = self.J[np.arange(len(self.J)) if subset is None else subset]
        n, r, b = Js.shape
        removal = None if j is None else self._removal(j)
        if j is not None and removal is None:
            return np.full(n, -np.inf)
        right = [self.Minv]
        if removal is not None:  # S_cj, then T_cj, from the same product
            right.append(removal[0].T)
            if self.L is not None:
                right.append(self.Minv @ self.L @ removal[0].T)
        X = gemm(Js, np.hstack(right))
        D, E = self._blocks_of(Js, X[:, :, :b])
        base = trace_base = 0.0
        if removal is not None:
            _, W, base, Pj = removal
            Scj = component_major(X[:, :, b : b + r])
            A = times(Scj, W)
            D = D + outer(A, Scj)
            if E is not None:
                Tcj = component_major(X[:, :, b + r :])
                AT = outer(A, Tcj)
                E = E + AT + AT.transpose(1, 0, 2) + outer(times(A, Pj), A)
                trace_base = -float(np.trace(W @ Pj))
        logdet, Y, ok = solve_blocks(eye_blocks(r, n) + D, E)
        ok &= logdet + base > np.log(MIN_DET_RATIO)  # det M' / det M
        gain = logdet + base if Y is None else np.einsum("iin->n", Y) + trace_base
        return np.where(ok & np.isfinite(gain), gain, -np.inf)

    def apply(self, add: int, remove: int | None) -> None:
        """Add candidate ``add`` (and remove design point ``remove``) by a low-rank update.

        With ``R`` the rows changed, ``K = diag(+-1) + R M^-1 R^T``, ``C = K^-1`` and, for
        every candidate, ``Q_c = J_c M^-1 R^T``, ``U_c = Q_c C`` and ``T_c = J_c M^-1 L M^-1
        R^T`` (one matrix product): ``M'^-1 = M^-1 - (R M^-1)^T C (R M^-1)``, ``trace S'_c =
        trace S_c - <U_c, Q_c>`` and ``trace P'_c = trace P_c - 2 <U_c, T_c> + <U_c H,
        U_c>`` with ``H = R M^-1 L M^-1 R^T``; ``log det`` grows by ``log |det K|``.
        """
        r = self.J.shape[1]
        rows = [add] if remove is None else [add, remove]
        R = self.J[rows].reshape(-1, self.J.shape[2])
        GR = R @ self.Minv  # R M^-1
        K = np.diag(np.repeat([1.0, -1.0][: len(rows)], r)) + GR @ R.T
        _, logabs = np.linalg.slogdet(K)
        self.logdet += float(logabs)
        C = np.linalg.inv(K)
        C = 0.5 * (C + C.T)
        p = len(R)
        left = GR if self.L is None else np.vstack([GR, GR @ self.L @ self.Minv])
        QT = left @ self.Jt  # Q_c^T (then T_c^T) of every candidate, (p or 2p, r N)
        Ut = C @ QT[:p]
        self.trS -= dots(Ut, QT[:p], r)
        if self.L is not None:
            H = GR @ self.L @ GR.T
            self.trP -= 2.0 * dots(Ut, QT[p:], r) - dots(H @ Ut, Ut, r)
        self.Minv -= GR.T @ C @ GR
        self._removed = (None, None)
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


Check = Callable[[np.ndarray], np.ndarray]
"""Whether each candidate of an index array may be measured (e.g. collision-free)."""


class CandidatesExhaustedError(InvalidArgumentError):
    """Every candidate left was rejected by the checks before the design was complete."""


def _checked(state: ExchangeState, pick: Callable[[], int | None], check: Check | None):
    """The best candidate ``pick`` finds that passes ``check``, or None.

    A rejected candidate is excluded from the state for good and the next best is sought:
    the candidates are checked in order of merit, and only those picked.
    """
    while True:
        best = pick()
        if best is None or check is None or bool(check(np.array([best]))[0]):
            return best
        state.excluded[best] = True


def greedy_start(
    J: np.ndarray, k: int, progress: Callable | None = None, check: Check | None = None
) -> list[int]:
    """K candidates chosen one by one, each maximising ``log det M`` (with a small ridge).

    Each step evaluates only the candidates whose :meth:`ExchangeState.add_bounds` exceed
    the best gain found (:func:`_best`): the candidate added is the best one all the same.

    Args:
        J: Candidate blocks ``(N, r, b)``.
        k: Number to choose (at most N).
        progress: Progress bars (:mod:`calib.core.progress`; e.g. ``tqdm.tqdm``), or None.
        check: Whether candidates may be measured (or None: all may); only those picked are
            asked, best first, a rejected one replaced by the next best.

    Returns:
        Candidate indices, in the order chosen.

    Raises:
        CandidatesExhaustedError: The checks leave fewer than k candidates.
    """
    scale = float(np.mean(np.einsum("nrb,nrb->n", J, J))) / J.shape[2]
    state = ExchangeState(J, [], None, GREEDY_RIDGE * max(scale, 1e-300))
    picks = steps(progress, range(k), "design: greedy start", k)

    def pick() -> int | None:
        bound = state.add_bounds()
        bound[state.design] = -np.inf
        bound[state.excluded] = -np.inf
        return _best(bound, lambda subset: state.gains(None, subset), -np.inf)

    for _ in picks:
        best = _checked(state, pick, check)  # None: every candidate left rejected
        if best is None:
            raise CandidatesExhaustedError(f"the checks leave fewer than {k} candidates")
        state.apply(int(best), None)
    return state.design


def _sweep(
    state: ExchangeState, progress: Callable | None, check: Check | None = None, sweep: int = 1
) -> int:
    """One pass over the design points; returns the number of exchanges made.

    For each design point, only the candidates whose :meth:`ExchangeState.bounds` exceed the
    best gain found so far are evaluated (:func:`_best`): the exchange made is the best one
    all the same (among those ``check`` accepts).
    """
    made = 0
    order = list(state.design)
    for j in steps(progress, order, f"design: exchange, sweep {sweep}", len(order)):
        if j not in state.design:
            continue
        need = MIN_IMPROVEMENT * max(abs(state.value()), 1.0)
        best = _checked(state, lambda: _best_exchange(state, j, need), check)  # noqa: B023
        if best is not None:
            state.apply(best, j)
            made += 1
    return made


def _best_exchange(state: ExchangeState, j: int, need: float) -> int | None:
    """The candidate whose exchange with design point j gains most, if more than ``need``.

    The coarse bounds (no product over the candidates) leave some candidates; the bounds of
    these (their rows gathered if they are few) order the branch and bound.
    """
    coarse = state.coarse_bounds(j)
    coarse[state.design] = -np.inf
    coarse[state.excluded] = -np.inf
    live = np.flatnonzero(coarse > need)
    if not live.size:
        return None
    few = live.size < GATHER * len(coarse)
    bound = state.bounds(j, live) if few else state.bounds(j)[live]
    best = _best(bound, lambda subset: state.gains(j, live[subset]), need)
    return None if best is None else int(live[best])


def _best(bound: np.ndarray, gains: Callable, floor: float) -> int | None:
    """The candidate of largest gain above ``floor``, evaluating as few as the bounds allow.

    Branch and bound: ``gains`` is called on the ``FIRST_CHUNK`` candidates of highest
    bound, then on twice as many of the rest, ..., and a candidate is dropped as soon as its
    bound does not exceed the best gain found; since no gain exceeds its bound, the best
    candidate is never dropped.

    Args:
        bound: Upper bound of each candidate's gain ``(N,)`` (-inf: not a candidate).
        gains: The exact gains of an array of candidates.
        floor: Gain to exceed.

    Returns:
        The candidate, or None if no gain exceeds the floor.
    """
    best, best_gain, size = None, floor, FIRST_CHUNK
    live = np.flatnonzero(bound > floor)
    top_bound = bound[live]
    while live.size:
        top = np.arange(live.size)
        if live.size > size:
            top = np.argpartition(top_bound, live.size - size)[live.size - size :]
        chunk = np.sort(live[top])
        gain = gains(chunk)
        i = int(np.argmax(gain))
        if gain[i] > best_gain:
            best, best_gain = int(chunk[i]), float(gain[i])
        keep = top_bound > best_gain
        keep[top] = False
        live, top_bound, size = live[keep], top_bound[keep], 2 * size
    return best


def _not_identified(J: np.ndarray, k: int) -> InvalidArgumentError:
    """The error of k configurations that do not identify the parameters, with its cause.

    Too few of them (every candidate together identifies the parameters), or candidates
    that never can.
    """
    N, _, b = J.shape
    if np.linalg.cond(J.reshape(-1, b)) <= MAX_CONDITION:
        why = f"all {N} together do: choose more configurations"
    else:
        why = "a joint that never moves, or too few distinct candidates?"
    return InvalidArgumentError(
        f"the candidates do not identify the {b} parameters with {k} configurations ({why})"
    )


def optimal_subset(
    J: np.ndarray,
    k: int,
    criterion: str = "D",
    L: np.ndarray | None = None,
    progress: Callable | None = None,
    check: Check | None = None,
) -> ExchangeResult:
    """Choose K of N candidates optimising a criterion: greedy start, then exchanges.

    Args:
        J: Candidate blocks ``(N, r, b)``.
        k: Design size K (``K r >= b``, K <= N).
        criterion: ``D``, ``A`` or ``I``.
        L: For ``I``: the reference information ``(b, b)``.
        progress: Progress bars (:mod:`calib.core.progress`; e.g. ``tqdm.tqdm``), or None.
        check: Whether candidates may be measured (or None): asked only about the
            candidates the greedy start or an exchange picks, best first (a rejected one is
            excluded and the next best taken); the result is the design of the candidates
            it accepts.

    Returns:
        The chosen candidates and counts.

    Raises:
        InvalidArgumentError: A bad criterion or size, or candidates that cannot identify
            every parameter.
        CandidatesExhaustedError: The checks leave fewer than k candidates.
    """
    N, r, b = J.shape
    if not isinstance(criterion, str) or criterion not in EXCHANGE_CRITERIA:
        raise InvalidArgumentError(
            f"unknown criterion {shown(criterion)}: choose {', '.join(EXCHANGE_CRITERIA)}"
        )
    if k > N:
        raise InvalidArgumentError(f"{k} configurations asked from only {N} candidates")
    if k * r < b:
        raise InvalidArgumentError(
            f"{k} configurations give {k * r} rows for {b} parameters: choose at least "
            f"{least_configurations(b, r)} configurations"
        )
    if criterion == "I" and (L is None or L.shape != (b, b)):
        raise InvalidArgumentError("criterion I needs the reference information matrix")
    if not np.all(np.isfinite(J)):
        raise InvalidArgumentError("the candidates' Jacobian is not finite")
    greedy = greedy_start(J, k, progress, check)
    weight = {"D": None, "A": np.eye(b), "I": L}[criterion]
    if np.linalg.cond(J[greedy].reshape(-1, b)) > MAX_CONDITION:
        raise _not_identified(J, k)
    state = ExchangeState(J, greedy, weight, 0.0)
    exchanges = sweeps = 0
    while sweeps < MAX_SWEEPS:
        sweeps += 1
        made = _sweep(state, progress, check, sweeps)
        exchanges += made
        state.refresh()
        if not made:
            break
    return ExchangeResult(tuple(state.design), tuple(greedy), exchanges, sweeps)


def least_i(
    J: np.ndarray, k: int, L: np.ndarray, tolerance: float = 1e-3, iterations: int = 5000
) -> float:
    """A certified lower bound of I over every set of ``k`` of the candidates.

    No design of ``k`` of these candidates predicts a lower error, whatever the algorithm:
    the bound says how much a design can buy over random sets. Relaxation: weights
    ``w >= 0`` summing to k, ``M(w) = sum_c w_c J_c^T J_c`` and ``f(w) = trace(L M(w)^-1)``,
    convex; every set is a 0/1 point of it. Multiplicative updates
    ``w_c <- w_c sqrt(g_c k / f)`` with ``g_c = -df/dw_c = trace(J_c M^-1 L M^-1 J_c^T)``
    (``sum_c w_c g_c = f``) lower f; by convexity, ``f(any set) >= 2 f(w) - k max_c g_c``,
    the certificate kept.

    Args:
        J: Scaled rows of the candidates ``(N, r, b)`` (:meth:`ObservationModel.jacobian`).
        k: Set size K.
        L: Reference information ``(b, b)`` (:attr:`Reference.mean`): I^2 = trace(L M^-1).
        tolerance: Stop when the certificate is within this fraction of f.
        iterations: Most updates (the bound is valid, if weaker, when they run out).

    Returns:
        The bound of I [per unit noise] (0 if no certificate is positive).

    Raises:
        InvalidArgumentError: A bad k, or candidates that cannot identify the parameters.
    """
    k = check_count(k, "the number of configurations")
    J = real_array(J, "the candidates' rows J", (None, None, None))
    L = real_array(L, "the reference information L", (J.shape[2], J.shape[2]))
    if not len(J):
        raise InvalidArgumentError("J has no candidate")
    n, r, b = J.shape
    A = J.reshape(n * r, b)
    w = np.full(n, k / n)
    best = 0.0
    for _ in range(check_count(iterations, "the number of iterations")):
        S = A * np.repeat(np.sqrt(w), r)[:, None]
        try:
            Mi = np.linalg.inv(S.T @ S)
        except np.linalg.LinAlgError:
            raise InvalidArgumentError("the candidates cannot identify the parameters") from None
        g = np.sum((A @ (Mi @ L @ Mi)) * A, axis=1).reshape(n, r).sum(axis=1)
        f = float(w @ g)
        best = max(best, 2.0 * f - k * float(g.max()))
        if best >= (1.0 - tolerance) * f:
            break
        w = w * np.sqrt(np.maximum(g, 0.0) * k / f)
        w *= k / w.sum()
    return float(np.sqrt(best))


__all__ = [
    "EXCHANGE_CRITERIA",
    "CandidatesExhaustedError",
    "Check",
    "ExchangeResult",
    "ExchangeState",
    "greedy_start",
    "least_i",
    "optimal_subset",
]
