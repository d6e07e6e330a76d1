"""Exchange shortcuts against brute force: bounds never below the gains of every exchange
(computed from a fresh information matrix), the kept traces equal fresh ones, and the design
found equals the one of a plain exchange that evaluates every swap from scratch."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CI, chain_of
from hypothesis import given
from hypothesis import strategies as st

from calib import InvalidArgumentError
from calib.design.design import candidate_configurations
from calib.design.exchange import (
    GREEDY_RIDGE,
    MAX_SWEEPS,
    MIN_DET_RATIO,
    MIN_IMPROVEMENT,
    ExchangeState,
    _best,
    optimal_subset,
)
from calib.design.observability import observation_model, reference


def _cost(J, design, L, ridge=0.0):
    """The criterion as a cost, from M formed and factored anew."""
    b = J.shape[2]
    W = J[list(design)].reshape(-1, b)
    M = ridge * np.eye(b) + W.T @ W
    if L is None:
        sign, logdet = np.linalg.slogdet(M)
        return -logdet if sign > 0 else np.inf
    return float(np.trace(L @ np.linalg.inv(M)))


def _swap(design, j, c):
    return [c if d == j else d for d in design]


def _weight(kind, b, rng):
    if kind == "D":
        return None
    if kind == "A":
        return np.eye(b)
    A = rng.standard_normal((b, max(1, b // 2)))  # rank-deficient, like a few reference points
    return A @ A.T


def _instance(seed, n, r, b, k):
    rng = np.random.default_rng(seed)
    J = rng.standard_normal((n, r, b)) * rng.uniform(0.2, 2.0, size=(1, 1, b))
    design = sorted(rng.choice(n, size=k, replace=False).tolist())
    return rng, J, design


@CI
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.integers(2, 7))
def test_bounds_never_below_the_gain_of_any_exchange(seed, r, b):
    """Every exchange of every design point, evaluated from scratch, against its bound."""
    k = -(-b // r) + 2
    rng, J, design = _instance(seed, 14 + k, r, b, k)
    others = [c for c in range(len(J)) if c not in design]
    for L in (_weight(kind, b, rng) for kind in ("D", "A", "I")):
        state = ExchangeState(J, design, L, 0.0)
        cost = _cost(J, design, L)
        tol = 1e-9 * max(1.0, abs(cost))
        for j in design:
            bound, coarse, gains = state.bounds(j), state.coarse_bounds(j), state.gains(j)
            if _cost(J, [d for d in design if d != j], None) - _cost(J, design, None) > -np.log(
                MIN_DET_RATIO
            ):  # det M_-j / det M below the ratio: j is never removed
                assert np.all(gains == -np.inf) and np.all(bound == -np.inf)
                assert np.all(coarse == -np.inf)
                continue
            np.testing.assert_allclose(
                state.bounds(j, others[::2]), bound[others[::2]], rtol=1e-9, atol=tol
            )  # rows gathered: same bounds
            assert np.all(coarse >= bound - tol)
            for c in others:
                fresh = cost - _cost(J, _swap(design, j, c), L)
                if np.isfinite(gains[c]):
                    assert gains[c] == pytest.approx(fresh, rel=1e-7, abs=tol)
                    assert bound[c] >= fresh - tol


@pytest.mark.parametrize("kind", ["D", "A", "I"])
def test_a_point_without_which_the_matrix_is_singular_is_never_removed(kind):
    """The branch the property above takes only when det M_-j / det M < MIN_DET_RATIO, which
    its random draws never meet: here design point 0 alone has a last column of size 1, the
    others of 1e-7 (det M_-0 / det M about 1e-14, not 0: the ratio decides, not a failed
    solve), so every exchange that removes it is refused: gains and bounds -inf."""
    rng, J, design = _instance(11, 18, 2, 4, 4)
    J[:, :, -1] *= 1e-7
    J[design[0], :, -1] = 1.0
    state = ExchangeState(J, design, _weight(kind, 4, rng), 0.0)
    assert np.all(state.gains(design[0]) == -np.inf)
    assert np.all(state.bounds(design[0]) == -np.inf)
    assert np.all(state.coarse_bounds(design[0]) == -np.inf)
    assert np.isfinite(state.gains(design[1])).any()  # another point can be exchanged


@CI
@given(st.integers(0, 2**31 - 1), st.integers(1, 4), st.integers(2, 7))
def test_add_bounds_never_below_the_gain_of_any_addition(seed, r, b):
    _, J, design = _instance(seed, 20, r, b, 3)
    ridge = 1e-3
    state = ExchangeState(J, design, None, ridge)
    cost = _cost(J, design, None, ridge)
    bound = state.add_bounds()
    for c in range(len(J)):
        fresh = cost - _cost(J, [*design, c], None, ridge)
        assert bound[c] >= fresh - 1e-9 * max(1.0, abs(cost))


@pytest.mark.parametrize("kind", ["D", "A", "I"])
def test_kept_traces_equal_fresh_ones_after_updates(kind):
    rng, J, design = _instance(7, 60, 3, 8, 6)
    L = _weight(kind, 8, rng)
    state = ExchangeState(J, design, L, 0.0)
    for add, remove in ((40, design[1]), (41, None), (42, 40), (43, design[4])):
        state.apply(add, remove)
    M = J[state.design].reshape(-1, 8).T @ J[state.design].reshape(-1, 8)
    Minv = np.linalg.inv(M)
    S = np.einsum("nrb,bc,nsc->nrs", J, Minv, J)
    np.testing.assert_allclose(state.trS, np.trace(S, axis1=1, axis2=2), rtol=1e-9)
    got_S, got_P = state.blocks(np.arange(len(J)))
    np.testing.assert_allclose(got_S.transpose(2, 0, 1), S, rtol=1e-9, atol=1e-12)
    if L is not None:
        P = np.einsum("nrb,bc,cd,de,nse->nrs", J, Minv, L, Minv, J)
        np.testing.assert_allclose(state.trP, np.trace(P, axis1=1, axis2=2), rtol=1e-9)
        np.testing.assert_allclose(got_P.transpose(2, 0, 1), P, rtol=1e-9, atol=1e-12)


@CI
@given(st.integers(0, 2**31 - 1), st.integers(1, 300), st.floats(-1.0, 1.0))
def test_branch_and_bound_finds_the_largest_gain(seed, n, floor):
    """Whatever the (valid) bounds, the candidate found is the argmax of the gains."""
    rng = np.random.default_rng(seed)
    gains = rng.standard_normal(n)
    bound = gains + rng.exponential(rng.uniform(0.0, 3.0), n) * (rng.random(n) < 0.8)
    bound[rng.random(n) < 0.1] = -np.inf  # not candidates (design points)
    gains[bound == -np.inf] = np.inf  # never looked at, or the test fails
    asked = []
    found = _best(bound, lambda s: asked.append(s) or gains[s], floor)
    valid = np.flatnonzero(np.isfinite(bound) & (gains > floor))
    if not valid.size:
        assert found is None
    else:
        assert found == valid[np.argmax(gains[valid])]
    seen = np.concatenate(asked) if asked else np.array([], dtype=int)
    assert len(set(seen.tolist())) == len(seen)  # each candidate evaluated at most once


# --- the design found against a plain exchange ---------------------------------------------


def _plain_optimal_subset(J, k, L):
    """Greedy start and modified Fedorov exchange evaluating every move from scratch."""
    n, _, b = J.shape
    ridge = GREEDY_RIDGE * float(np.mean(np.einsum("nrb,nrb->n", J, J))) / b
    design = []
    for _ in range(k):
        costs = [np.inf if c in design else _cost(J, [*design, c], None, ridge) for c in range(n)]
        design.append(int(np.argmin(costs)))
    greedy = list(design)
    exchanges = sweeps = 0
    while sweeps < MAX_SWEEPS:
        sweeps += 1
        made = 0
        for j in list(design):
            cost = _cost(J, design, L)
            need = MIN_IMPROVEMENT * max(abs(cost), 1.0)
            gains = [
                -np.inf if c in design else cost - _cost(J, _swap(design, j, c), L)
                for c in range(n)
            ]
            best = int(np.argmax(gains))
            if gains[best] > need:
                design, made = _swap(design, j, best), made + 1
        exchanges += made
        if not made:
            break
    return tuple(design), tuple(greedy), exchanges, sweeps


@pytest.fixture(scope="module")
def panda_small():
    chain = chain_of("panda")
    model = observation_model(chain, "position")
    J = model.jacobian(candidate_configurations(chain, 120, seed=11))
    ref = reference(model, candidate_configurations(chain, 50, seed=12))
    return J, ref.mean


@pytest.mark.parametrize("criterion", ["D", "A", "I"])
def test_design_equals_the_plain_exchange_on_the_panda(panda_small, criterion):
    J, L = panda_small
    weight = {"D": None, "A": np.eye(J.shape[2]), "I": L}[criterion]
    res = optimal_subset(J, 12, criterion, L)
    plain = _plain_optimal_subset(J, 12, weight)
    assert res.exchanges > 0
    assert (res.design, res.greedy, res.exchanges, res.sweeps) == plain


@pytest.mark.parametrize("seed", range(3))
@pytest.mark.parametrize("criterion", ["D", "A", "I"])
def test_design_equals_the_plain_exchange_on_random_instances(seed, criterion):
    rng, J, _ = _instance(100 + seed, 50, 2, 6, 1)
    L = _weight("I", 6, rng)
    weight = {"D": None, "A": np.eye(6), "I": L}[criterion]
    res = optimal_subset(J, 5, criterion, L)
    assert (res.design, res.greedy, res.exchanges, res.sweeps) == _plain_optimal_subset(
        J, 5, weight
    )


def test_candidates_without_a_finite_gain_are_refused():
    J = np.full((10, 2, 3), np.nan)
    with pytest.raises(InvalidArgumentError, match="not finite"):
        optimal_subset(J, 3, "D")
