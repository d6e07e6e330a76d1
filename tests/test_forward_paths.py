"""The selection's fast paths (issue 22) against brute force.

Every expected value is recomputed by refits from scratch (:func:`numpy.linalg.lstsq` with the
held-out rows removed), or by LAPACK: the forward paths with their rank-one updated sums
(including the steps that recompute them afresh), the batched prior strengths, the batched
guard and the vectorised block solver.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_calibration import greedy_check, path, refit_loo

import calib.calibration.forward_paths as fp
from calib.calibration.forward_paths import lu_errors, paths, spd_solve
from calib.calibration.selection import (
    OUTER_FOLDS,
    STRENGTHS,
    best_prefix,
    ridge_strengths,
    select,
)


def count_calls(monkeypatch, name):
    """Count the calls of a method of the paths' state."""
    calls = []
    method = getattr(fp._Batch, name)

    def counted(*args, **kwargs):
        calls.append(1)
        return method(*args, **kwargs)

    monkeypatch.setattr(fp._Batch, name, counted)
    return calls


def test_paths_through_nearly_collinear_candidates(monkeypatch):
    """Candidates nearly carried by others shrink by orders of magnitude as those enter:
    their sums are computed afresh (SHRINK), and the path is still the brute-force one."""
    rng = np.random.default_rng(5)
    m, rows, fixed = 16, 3, 3
    base = rng.normal(size=(m * rows, fixed + 4))
    near = base[:, [3, 4]] @ np.array([[1.0, 0.3], [0.5, 1.0]]) + 1e-3 * rng.normal(
        size=(m * rows, 2)
    )
    A = np.hstack([base, near])
    A /= np.linalg.norm(A, axis=0)
    e = A[:, [0, 3, 7]] @ np.array([1.0, 0.5, -0.4]) + 0.05 * rng.normal(size=m * rows)
    fresh = count_calls(monkeypatch, "_fresh")
    order, errors = path(A, e, rows, list(range(fixed)), list(range(fixed, A.shape[1])))
    assert len(fresh) > 1  # the premise: the shrinking candidates were recomputed
    greedy_check(A, e, rows, fixed, order, errors)


def test_paths_through_a_configuration_of_high_leverage(monkeypatch):
    """A column mostly seen by one configuration drives its leverage near 1: the inverse
    blocks are inverted afresh (REFRESH) and the path is still the brute-force one."""
    rng = np.random.default_rng(8)
    m, rows, fixed, cand = 12, 3, 3, 5
    A = rng.normal(size=(m * rows, fixed + cand))
    A[:, fixed] *= 0.02
    A[0:rows, fixed] = rng.normal(size=rows)  # column `fixed`: almost only configuration 0
    A /= np.linalg.norm(A, axis=0)
    e = A[:, [0, fixed, fixed + 2]] @ np.array([1.0, 0.8, 0.3]) + 0.1 * rng.normal(size=m * rows)
    refreshed = count_calls(monkeypatch, "_set_v")
    order, errors = path(A, e, rows, list(range(fixed)), list(range(fixed, fixed + cand)))
    assert len(refreshed) > 1  # the premise: M was inverted afresh after the start
    greedy_check(A, e, rows, fixed, order, errors)


def test_paths_of_twelve_rows_and_of_folds_with_forced_columns():
    """Four points (12 rows: LAPACK blocks) and subsets with two start columns beyond the
    fixed ones: each subset's path is its brute-force greedy path."""
    rng = np.random.default_rng(2)
    m, rows, fixed, cand = 9, 12, 4, 5
    A = rng.normal(size=(m * rows, fixed + cand))
    A /= np.linalg.norm(A, axis=0)
    e = A[:, [1, 5, 7]] @ np.array([1.0, -0.5, 0.2]) + 0.1 * rng.normal(size=m * rows)
    train = np.ones((3, m), dtype=bool)
    train[1, ::3] = False
    train[2, [1, 2, 6]] = False
    out = paths(A, e, rows, list(range(fixed)), list(range(fixed, fixed + cand)), train)
    for mask, (order, errors) in zip(train, out, strict=True):
        assert errors.shape == (cand + 1, mask.sum())
        greedy_check(A, e, rows, fixed, order, errors, mask)


def test_ridge_strengths_are_each_subsets_best_refit_loo():
    """Each subset's prior strength, on its own configurations and columns (some none), is
    the one of least brute-force left-out error."""
    rng = np.random.default_rng(4)
    m, rows, fixed, p = 12, 3, 3, 9
    A = rng.normal(size=(m * rows, p))
    A /= np.linalg.norm(A, axis=0)
    e = A @ (0.1 * rng.normal(size=p)) + rng.normal(size=m * rows)
    train = np.ones((4, m), dtype=bool)
    train[1, ::4] = False
    train[2, [0, 5, 7]] = False
    cols = [[3, 4, 5, 6, 7, 8], [5, 3], [], [8, 6, 4]]
    sq, strengths = ridge_strengths(A, e, rows, fixed, train, cols)
    for s, (mask, c) in enumerate(zip(train, cols, strict=True)):
        keep = np.repeat(mask, rows)
        At = A[keep][:, list(range(fixed)) + c]
        brute = {
            t: refit_loo(At, e[keep], rows, np.r_[np.zeros(fixed), np.full(len(c), t)])
            for t in (0.0, *STRENGTHS)
        }
        best = min(brute, key=lambda t: brute[t].sum())
        assert strengths[s] == best
        assert np.allclose(sq[s, mask], brute[best], rtol=1e-9)
        assert np.all(sq[s, ~mask] == 0.0)


def brute_forward(A, e, rows, fixed):
    """The forward selection by refits from scratch: the greedy path of least summed left-out
    error (:func:`refit_loo`), its prefix by :func:`best_prefix`, and the prior strength of
    least refit error. Returns the kept candidates (into those after ``fixed``) and the
    strength."""
    cols, order = list(range(fixed)), []
    errors = [refit_loo(A[:, cols], e, rows)]
    while len(cols) < A.shape[1]:
        rest = [c for c in range(fixed, A.shape[1]) if c not in cols]
        sse = {c: refit_loo(A[:, [*cols, c]], e, rows) for c in rest}
        best = min(sse, key=lambda c: sse[c].sum())
        cols.append(best)
        order.append(best - fixed)
        errors.append(sse[best])
    kept = order[: best_prefix(np.array(errors))]
    At = A[:, list(range(fixed)) + [fixed + k for k in kept]]
    lam = {t: np.r_[np.zeros(fixed), np.full(len(kept), t)] for t in (0.0, *STRENGTHS)}
    return kept, min(lam, key=lambda t: refit_loo(At, e, rows, lam[t]).sum())


def test_guard_errors_are_refits_of_each_folds_procedure():
    """select()'s two cross-validated errors: each fold runs the forward selection (by refits
    from scratch) on its own configurations, its ridge fit (and the registration's) predicts
    the held-out ones."""
    rng = np.random.default_rng(9)
    m, rows, fixed, cand = 23, 3, 3, 6
    J = rng.normal(size=(m, rows, fixed + cand)) * rng.uniform(0.5, 3.0, size=fixed + cand)
    x = np.r_[rng.normal(size=fixed), 0.6, 0.0, -0.4, 0.0, 0.2, 0.0]
    e = J @ x + 0.3 * rng.normal(size=(m, rows))
    names = tuple(f"p{i}" for i in range(cand))
    selection, _ = select(J, e, fixed, names)
    A = J.reshape(m * rows, -1)
    A = A / np.linalg.norm(A, axis=0)
    ev = e.ravel()
    sse_reg = sse_sel = 0.0
    for f in range(OUTER_FOLDS):
        held = np.repeat(np.arange(m) % OUTER_FOLDS == f, rows)
        At, et, Av = A[~held], ev[~held], A[held]
        x0 = np.linalg.lstsq(At[:, :fixed], et, rcond=None)[0]
        sse_reg += np.sum((ev[held] - Av[:, :fixed] @ x0) ** 2)
        kept, strength = brute_forward(At, et, rows, fixed)
        cols = list(range(fixed)) + [fixed + k for k in kept]
        lam = np.r_[np.zeros(fixed), np.full(len(kept), strength)]
        aug = np.vstack([At[:, cols], np.diag(np.sqrt(lam))])
        xs = np.linalg.lstsq(aug, np.r_[et, np.zeros(len(cols))], rcond=None)[0]
        sse_sel += np.sum((ev[held] - Av[:, cols] @ xs) ** 2)
    assert np.isclose(selection.registration_cv, np.sqrt(sse_reg / m), rtol=1e-9)
    assert np.isclose(selection.selection_cv, np.sqrt(sse_sel / m), rtol=1e-9)


def test_the_selection_gives_each_kept_candidate_by_position():
    """Two candidates of one name (a joint two chains share, one MDH parameter in each chain's
    rows): both kept, told apart by their positions (``index``), not their names."""
    rng = np.random.default_rng(4)
    m, rows, fixed = 40, 3, 2
    J = rng.normal(size=(m, rows, fixed + 4))
    e = J @ np.r_[0.0, 0.0, 1.0, 0.0, 0.0, -1.0] + 0.01 * rng.normal(size=(m, rows))
    selection, _ = select(J, e, fixed, ("a", "d7", "b", "d7"))
    assert sorted(selection.index) == [0, 3] and sorted(selection.kept) == ["a", "d7"]


@pytest.mark.parametrize("n", [3, 6])
def test_spd_solve_equals_lapack(n):
    rng = np.random.default_rng(n)
    X = rng.normal(size=(50, n, 2 * n))
    M = np.eye(n) + X @ np.swapaxes(X, 1, 2) / n
    y = rng.normal(size=(50, n))
    want = np.linalg.solve(M, y[..., None])[..., 0]
    got = spd_solve(np.moveaxis(M, 0, 2), y.T)
    assert np.allclose(got.T, want, rtol=1e-12, atol=0)


def test_spd_solve_in_place_gives_the_same_numbers_in_the_right_hand_side():
    """overwrite=True works on the arrays given (no copies of large blocks): the solution
    is written over y, bit for bit the one of the copying solve."""
    rng = np.random.default_rng(7)
    X = rng.normal(size=(40, 3, 6))
    M = np.ascontiguousarray(np.moveaxis(np.eye(3) + X @ np.swapaxes(X, 1, 2) / 3, 0, 2))
    y = rng.normal(size=(3, 40))
    want = np.linalg.solve(np.moveaxis(M, 2, 0), y.T[..., None])[..., 0].T
    copied = spd_solve(M, y)
    got = spd_solve(M, y, overwrite=True)
    assert got is y and np.array_equal(got, copied)
    assert np.allclose(got, want, rtol=1e-12, atol=0)


def test_lu_errors_of_a_singular_block_are_infinite_for_its_fit():
    """A configuration of leverage exactly 1 makes its fit's errors infinite (as LAPACK's
    singular solve said before); the other fits keep their exact errors."""
    rng = np.random.default_rng(1)
    H = np.zeros((2, 4, 3, 3))
    H[:, :] = 0.2 * np.eye(3)
    H[1, 2] = np.diag([1.0, 0.0, 0.0])  # fit 1, configuration 2: leverage 1 along x
    r = rng.normal(size=(2, 4, 3))
    sq = lu_errors(np.eye(3) - H, r)
    assert np.all(np.isinf(sq[1]))
    assert np.allclose(sq[0], np.sum((r[0] / 0.8) ** 2, axis=1), rtol=1e-12)


@pytest.mark.parametrize("rows", [1, 3])
def test_paths_from_a_configuration_of_leverage_one(rows):
    """A start column only one configuration sees: its hat block is exactly singular from
    the start (LAPACK's inverse refuses it). Its left-out error is infinite at every step,
    so is every candidate's total (the path takes them in their order); the other
    configurations' errors are those of brute-force refits, in every subset."""
    rng = np.random.default_rng(3)
    m, cand = 9, 4
    A = rng.normal(size=(m * rows, 1 + cand))
    A[:, 0] = 0.0
    A[rows * 4, 0] = 0.7  # configuration 4 alone
    A /= np.linalg.norm(A, axis=0)
    e = rng.normal(size=m * rows)
    train = np.ones((2, m), dtype=bool)
    train[1, 7] = False
    out = paths(A, e, rows, [0], list(range(1, 1 + cand)), train)
    for mask, (order, errors) in zip(train, out, strict=True):
        assert order == list(range(1, 1 + cand))
        keep = np.repeat(mask, rows)
        lost = np.flatnonzero(mask) == 4
        assert np.all(np.isinf(errors[:, lost]))
        for k in range(cand + 1):
            want = refit_loo(A[keep][:, : k + 1], e[keep], rows)
            assert np.allclose(errors[k, ~lost], want[~lost], rtol=1e-9)


def test_ridge_strengths_with_columns_seen_by_one_configuration():
    """Two prior columns each seen by one configuration's single row: the vectorised solve
    meets a singular block and LAPACK takes over on the untouched matrices (it once took
    over on matrices the first solve had overwritten, and every error came out NaN)."""
    rng = np.random.default_rng(6)
    m, rows, fixed, p = 10, 3, 2, 6
    A = rng.standard_normal((m * rows, p))
    A[:, 5], A[:, 4] = 0.0, 0.0
    A[rows * 6, 5], A[rows * 6 + 1, 4] = 1.0, 1.0
    e = A @ rng.standard_normal(p) * 1e-3 + 1e-4 * rng.standard_normal(m * rows)
    sq, strength = ridge_strengths(
        A, e, rows, fixed, np.ones((1, m), dtype=bool), [list(range(fixed, p))]
    )
    assert np.isfinite(sq).all() and strength[0] > 0
    brute = {
        t: refit_loo(A, e, rows, np.r_[np.zeros(fixed), np.full(p - fixed, t)]) for t in STRENGTHS
    }
    assert strength[0] == min(brute, key=lambda t: brute[t].sum())
    assert np.allclose(sq[0], brute[strength[0]], rtol=1e-9)


@pytest.mark.parametrize("seed", range(6))
def test_a_step_that_fits_exactly_has_errors_of_zero_not_below(seed):
    """Noise-free residuals in the span of the start and one candidate: at the step that adds
    it every left-out error is zero up to round-off (brute-force refits agree), never below
    (the rank-one sums gave squares of -1e-17: NaN in the selection's square roots, and the
    exact step was never kept); every subset keeps it."""
    rng = np.random.default_rng(seed)
    m, rows, fixed, cand = 14, 3, 4, 5
    A = rng.normal(size=(m * rows, fixed + cand))
    A /= np.linalg.norm(A, axis=0)
    e = A[:, [0, fixed + 1]] @ np.array([1.0, 0.4])
    train = np.ones((3, m), dtype=bool)
    train[1, ::4] = False
    train[2, [0, 5]] = False
    out = paths(A, e, rows, list(range(fixed)), list(range(fixed, fixed + cand)), train)
    for mask, (order, errors) in zip(train, out, strict=True):
        k = order.index(fixed + 1) + 1
        tiny = 1e-12 * errors[0].mean()
        keep = np.repeat(mask, rows)
        assert refit_loo(A[keep][:, [*range(fixed), fixed + 1]], e[keep], rows).max() < tiny
        assert np.all(errors >= 0.0)
        assert errors[k].max() < tiny
        with np.errstate(invalid="raise"):
            assert best_prefix(errors) >= k


def exact_prefix(A, e, rows, fixed, order):
    """Brute force: the shortest prefix of ``order`` whose least squares (with the ``fixed``
    start) leaves only round-off of ``e``, and the relative residual of the prefix before."""
    norms = []
    for k in range(len(order) + 1):
        B = A[:, [*range(fixed), *order[:k]]]
        norms.append(np.linalg.norm(e - B @ np.linalg.lstsq(B, e, rcond=None)[0]))
        if norms[-1] <= 1e-12 * np.linalg.norm(e):
            return k, norms[-2] / np.linalg.norm(e) if k else 1.0
    raise AssertionError("no prefix fits exactly")


@pytest.mark.parametrize(
    ("m", "rows", "fixed", "cand", "true", "corr"),
    [(14, 3, 4, 5, 1, 0.0), (14, 3, 4, 5, 2, 0.0), (20, 6, 6, 12, 2, 10.0), (16, 1, 3, 6, 2, 0.0)],
)
def test_the_selection_stops_at_the_step_that_fits_exactly(m, rows, fixed, cand, true, corr):
    """Noise-free residuals in the span of the start and a few candidates: every subset's
    path keeps the shortest prefix whose least squares fits them exactly (brute force), not
    a column more: after it the steps' errors are round-off (some kept one more in 7 of 40)."""
    for seed in range(20):
        rng = np.random.default_rng(seed)
        A = rng.normal(size=(m * rows, fixed + cand))
        A[:, fixed:] += corr * A[:, [fixed - 1]]  # candidates close to the start: ill-conditioned
        A /= np.linalg.norm(A, axis=0)
        cols = [0, *(fixed + rng.choice(cand, size=true, replace=False))]
        e = A[:, cols] @ (rng.normal(size=true + 1) * 10.0 ** rng.uniform(-3, 1, size=true + 1))
        train = np.ones((3, m), dtype=bool)
        train[1, ::4] = False
        train[2, [0, 5]] = False
        out = paths(A, e, rows, list(range(fixed)), list(range(fixed, fixed + cand)), train)
        for mask, (order, errors) in zip(train, out, strict=True):
            keep = np.repeat(mask, rows)
            k, before = exact_prefix(A[keep], e[keep], rows, fixed, order)
            assert before > 1e-6  # the premises: the shorter prefixes leave a real error,
            assert fixed + k < keep.sum() - rows  # and the left-out fits are not square
            assert best_prefix(errors) == k, (seed, mask.sum())


@pytest.mark.parametrize(
    ("m", "rows", "fixed", "cand", "true", "corr"),
    [(40, 6, 6, 12, 2, 10.0), (60, 3, 4, 10, 2, 0.0), (60, 3, 4, 10, 0, 0.0)],
)
def test_a_noise_free_fit_is_won_by_the_fewest_parameters_that_fit_it(
    m, rows, fixed, cand, true, corr
):
    """Noise-free residuals in the span of the start and ``true`` candidates, enough rows
    for the complete fit to compete: its cross-validated error and the selection's are both
    round-off, so the fewer parameters win: the registration where it fits exactly (true 0),
    else the selection, whose columns fit exactly (brute force: least squares). Before
    (round-off against round-off), the complete fit won 25, 1 and 3 of the 40 seeds."""
    names = tuple(f"c{i}" for i in range(cand))
    for seed in range(40):
        rng = np.random.default_rng([seed, 48])
        J = rng.normal(size=(m, rows, fixed + cand))
        J[:, :, fixed:] += corr * J[:, :, [fixed - 1]]  # close to the start: ill-conditioned
        cols = [*range(fixed), *(fixed + rng.choice(cand, size=true, replace=False))]
        size = rng.normal(size=len(cols)) * 10.0 ** rng.uniform(-3, 1, size=len(cols))
        A, e = J.reshape(m * rows, -1), (J[:, :, cols] @ size).ravel()
        if true:  # as at the registration: nothing left along the start's columns
            e -= A[:, :fixed] @ np.linalg.lstsq(A[:, :fixed], e, rcond=None)[0]
        selection = select(J, e.reshape(m, rows), fixed, names)[0]
        assert m * rows >= 10 * (fixed + cand) and np.isfinite(selection.complete_cv)
        start = A[:, :fixed]
        kept = A[:, [*range(fixed), *(fixed + np.array(selection.index, dtype=int))]]
        alone, left = (
            np.linalg.norm(e - B @ np.linalg.lstsq(B, e, rcond=None)[0]) for B in (start, kept)
        )
        assert (alone > 1e-6 * np.linalg.norm(e)) == bool(true)  # the premise: real or none
        assert left <= 1e-10 * np.linalg.norm(e), (
            seed,
            selection.winner,
        )  # ill-conditioned: its round-off
        winner = "selection" if true else "registration"
        assert selection.winner == winner, (seed, selection.complete_cv, selection.selection_cv)
