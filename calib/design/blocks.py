"""Many small matrices at once: the linear algebra of the exchange (:mod:`.exchange`).

The candidates' blocks are stored component-major, ``(r, p, N)`` (one array per entry, N
candidates along the last axis), so that each operation is a few whole-array steps, with no
Python loop over the candidates; or candidate-major ``(N, r, p)`` for one BLAS product with a
common matrix (:func:`gemm`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["component_major", "dots", "eye_blocks", "gemm", "outer", "solve_blocks", "times"]


def eye_blocks(r: int, n: int) -> np.ndarray:
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


def gemm(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A_c B`` for every block of A ``(N, r, b)`` and one matrix B ``(b, p)``: ``(N, r, p)``.

    One matrix product (BLAS) instead of N small ones.
    """
    N, r, b = A.shape
    return (A.reshape(N * r, b) @ B).reshape(N, r, -1)


def component_major(A: np.ndarray) -> np.ndarray:
    """``(N, r, p)`` to component-major ``(r, p, N)``."""
    return np.ascontiguousarray(A.transpose(1, 2, 0))


def outer(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A_c B_c^T`` for component-major blocks ``(r, p, N)`` and ``(s, p, N)``: ``(r, s, N)``."""
    return np.einsum("ipn,jpn->ijn", A, B)


def times(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``A_c B`` for component-major blocks ``(r, p, N)`` and one matrix ``(p, s)``."""
    return np.einsum("rpn,ps->rsn", A, B)


def dots(A: np.ndarray, B: np.ndarray, r: int) -> np.ndarray:
    """``<A_c, B_c>_F`` of the p x r blocks of N candidates stored ``(p, r N)``: ``(N,)``.

    Column ``s N + c`` holds column s of candidate c's block.
    """
    return np.einsum("ij,ij->j", A, B).reshape(r, -1).sum(axis=0)
