"""identification.qr calls LAPACK directly: the same numbers as NumPy's and SciPy's own wrappers."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg

from calib.identification import qr


def _matrices():
    rng = np.random.default_rng(7)
    tall = rng.standard_normal((40, 12))
    deficient = tall.copy()
    deficient[:, 5] = deficient[:, 1] - 2 * deficient[:, 3]  # rank 11
    wide = rng.standard_normal((5, 9))
    return [tall, deficient, wide, np.zeros((6, 4)), tall[:, :1], np.asfortranarray(tall)]


@pytest.mark.parametrize("W", _matrices(), ids=lambda W: f"{W.shape}")
def test_factorisations_equal_numpy_and_scipy(W):
    assert np.array_equal(qr.triangular(W), np.linalg.qr(W, mode="r"))
    R = np.linalg.qr(W, mode="r")
    expected = np.abs(np.diag(scipy.linalg.qr(R, mode="r", pivoting=True)[0]))
    assert np.array_equal(qr.pivoted_diagonal(R), expected)
    for k in (-1, 0, 2):
        assert np.array_equal(qr.upper(W, k), np.triu(W, k))
    T = qr.householder(W)
    assert np.array_equal(np.triu(T[: min(W.shape)]), qr.triangular(W))


def test_empty_matrices():
    assert qr.triangular(np.zeros((0, 3))).shape == (0, 3)
    assert qr.pivoted_diagonal(np.zeros((3, 0))).shape == (0,)
    assert qr.solve_upper(np.zeros((0, 0)), np.zeros((0, 4))).shape == (0, 4)


def test_back_substitution_equals_scipy():
    rng = np.random.default_rng(3)
    R = np.triu(rng.standard_normal((8, 8))) + 4 * np.eye(8)
    B = rng.standard_normal((8, 5))
    x = qr.solve_upper(R, B)
    assert np.array_equal(x, scipy.linalg.solve_triangular(R, B))
    assert np.allclose(R @ x, B, atol=1e-12)


def test_householder_in_place_of_fortran_columns_is_the_copy_s():
    W = np.random.default_rng(8).normal(size=(500, 9))
    order = [4, 0, 8, 2, 1, 3, 7, 5, 6]
    A = qr.fortran_columns(W, order)
    assert A.flags.f_contiguous and np.array_equal(A, W[:, order])
    T = qr.householder(A, overwrite=True)
    assert np.shares_memory(T, A)  # factored in place: no copy
    assert np.array_equal(T, qr.householder(W[:, order]))  # the same numbers, to the bit
