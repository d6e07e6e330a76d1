"""QR factorisations of the small matrices of the analysis, called through LAPACK directly.

The same LAPACK routines NumPy and SciPy call (``dgeqrf``, ``dgeqp3``, ``dtrtrs``), so the
same numbers, without their per-call overhead (checks, copies, ``triu`` of the whole
result), which dominates for a 30 x 30 triangular factor: 2 us instead of 20 us.

The routines come from SciPy's LAPACK extension (``scipy.linalg._flapack``), loaded by itself:
importing the ``scipy.linalg`` package costs a start of ``calib analyze`` 0.15 s or more
(SciPy 1.17 imports its array-API layer, which imports ``numpy.f2py`` and ``numpy.testing``).
Where the extension cannot be loaded alone, ``scipy.linalg.lapack`` is imported as usual.
"""

from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
import sys
from pathlib import Path
from types import ModuleType

import numpy as np

__all__ = [
    "fortran_columns",
    "householder",
    "pivoted_diagonal",
    "solve_upper",
    "triangular",
    "upper",
]

_FLAPACK = "scipy.linalg._flapack"


@functools.cache
def _lapack() -> ModuleType:
    """SciPy's LAPACK wrappers (``dgeqrf``, ``dgeqp3``, ``dtrtrs``), loaded once."""
    if "scipy.linalg" not in sys.modules:
        try:
            return _load_flapack()
        except (ImportError, OSError):
            pass
    from scipy.linalg import lapack

    return lapack


def _load_flapack() -> ModuleType:
    """``scipy.linalg._flapack`` without ``scipy.linalg``'s ``__init__`` (ImportError if not)."""
    if _FLAPACK in sys.modules:
        return sys.modules[_FLAPACK]
    spec = importlib.util.find_spec("scipy")  # a top-level package: found, not imported
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("scipy not found")
    for folder in spec.submodule_search_locations:
        for suffix in importlib.machinery.EXTENSION_SUFFIXES:
            path = Path(folder, "linalg", "_flapack" + suffix)
            if path.is_file():
                ext = importlib.util.spec_from_file_location(_FLAPACK, path)
                if ext is None or ext.loader is None:
                    break
                module = importlib.util.module_from_spec(ext)
                ext.loader.exec_module(module)
                return module
    raise ImportError(f"{_FLAPACK} not found")


def triangular(W: np.ndarray) -> np.ndarray:
    """R factor of the QR decomposition of W ``(r, c)``: ``(min(r, c), c)``, upper triangular.

    As ``numpy.linalg.qr(W, mode="r")``.
    """
    k = min(W.shape)
    if k == 0:
        return np.zeros((k, W.shape[1]))
    return upper(householder(W)[:k])


def upper(M: np.ndarray, k: int = 0) -> np.ndarray:
    """``numpy.triu(M, k)`` (a new array), with the mask of each shape built once."""
    return np.where(_below(M.shape, k), 0.0, M)


@functools.lru_cache(maxsize=256)
def _below(shape: tuple[int, int], k: int) -> np.ndarray:
    return ~np.triu(np.ones(shape, dtype=bool), k)


def householder(W: np.ndarray, overwrite: bool = False) -> np.ndarray:
    """LAPACK's compact QR of W ``(r, c)``: R on and above the diagonal, reflectors below.

    ``triangular(W) == triu(householder(W)[:min(r, c)])``; ``W`` must not be empty.
    ``overwrite``: W may be factored in place (no copy if it is Fortran-ordered:
    :func:`fortran_columns`).
    """
    qr, _, _, info = _lapack().dgeqrf(W, overwrite_a=int(overwrite))
    if info != 0:
        return np.linalg.qr(W, mode="r")  # type: ignore[return-value]  # numpy's stubs: QRResult
    return qr


def fortran_columns(W: np.ndarray, order: list[int]) -> np.ndarray:
    """W's columns ``order`` in a new Fortran-ordered array (LAPACK's layout).

    :func:`householder` of it with ``overwrite`` copies nothing more (a 600,000 x 42
    Jacobian: 200 MB).
    """
    out = np.empty((W.shape[0], len(order)), order="F")
    for k, j in enumerate(order):
        out[:, k] = W[:, j]
    return out


def pivoted_diagonal(W: np.ndarray) -> np.ndarray:
    """|R_ii| of the QR decomposition with column pivoting of W (non-increasing).

    As ``abs(diag(scipy.linalg.qr(W, mode="r", pivoting=True)[0]))``.
    """
    if min(W.shape) == 0:
        return np.zeros(0)
    qr, _, _, _, info = _lapack().dgeqp3(W)
    if info != 0:
        import scipy.linalg

        qr = scipy.linalg.qr(W, mode="r", pivoting=True, check_finite=False)[0]
    return np.abs(np.diag(qr))


def solve_upper(R: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``R^-1 B`` for an upper triangular R ``(b, b)`` and B ``(b, k)``, by back substitution.

    As ``scipy.linalg.solve_triangular(R, B)``.
    """
    if R.size == 0 or B.size == 0:
        return np.zeros((R.shape[1], B.shape[1]))
    x, info = _lapack().dtrtrs(R, B, lower=0)
    if info != 0:  # a zero pivot: SciPy raises the usual error
        import scipy.linalg

        return scipy.linalg.solve_triangular(R, B, check_finite=False)
    return x
