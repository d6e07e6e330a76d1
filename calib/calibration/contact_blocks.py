"""Linear least squares of contacts with the objects' unknowns eliminated object by object.

Rationale and measurements: docs/developers/engine.md#contact_blocks
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BlockSolution", "BlockSystem", "block_factors", "block_lstsq", "dense"]


@dataclass(frozen=True, eq=False)
class BlockSystem:
    """``min |A x_o + B x_s + r|``, A block diagonal by object, given touch by touch.

    ``own`` ``(m, rows, o)``, ``shared`` ``(m, rows, s)``, ``residual``; ``index``: the objects.
    """

    own: np.ndarray
    shared: np.ndarray
    residual: np.ndarray
    index: np.ndarray
    objects: int


@dataclass(frozen=True, eq=False)
class BlockSolution:
    """The unknowns ``objects`` ``(K, o)``, ``shared`` ``(s,)`` and the extreme singular values."""

    objects: np.ndarray
    shared: np.ndarray
    smallest: float
    largest: float


def block_factors(system: BlockSystem, damping: np.ndarray | None = None) -> np.ndarray:
    """Each object's QR factor ``(K, w, w)`` of ``[A_k | B_k | r_k]`` and ``diag(damping[k])``."""
    Jo, Js, r, index, K = (system.own, system.shared, system.residual, system.index, system.objects)
    m, rows, o = Jo.shape
    s = Js.shape[2]
    w = o + s + 1
    blocks = np.concatenate([Jo, Js, r[:, :, None]], axis=2)  # (m, rows, w)
    counts = np.bincount(index, minlength=K)
    order = np.argsort(index, kind="stable")
    first = np.r_[0, np.cumsum(counts)[:-1]]
    position = np.empty(m, dtype=int)
    position[order] = np.arange(m) - first[index[order]]  # the touch's rank in its object
    least = np.maximum(counts, -(-w // rows))  # each object's touches: w rows at least,
    padded = (2 ** np.ceil(np.log2(np.maximum(least, 1)))).astype(int)  # a power of two
    factors = np.zeros((K, w, w))
    for size in np.unique(padded):
        objects = np.flatnonzero(padded == size)
        local = np.full(K, -1)
        local[objects] = np.arange(len(objects))
        mine = np.flatnonzero(local[index] >= 0)
        stack = np.zeros((len(objects), int(size), rows, w))
        stack[local[index[mine]], position[mine]] = blocks[mine]
        A = stack.reshape(len(objects), int(size) * rows, w)
        if damping is not None:
            extra = np.zeros((len(objects), o, w))
            extra[:, np.arange(o), np.arange(o)] = damping[objects]
            A = np.concatenate([A, extra], axis=1)
        R: np.ndarray = np.linalg.qr(A, mode="r")  # type: ignore[assignment]
        factors[objects, : R.shape[1]] = R
    return factors


def block_lstsq(
    system: BlockSystem, damping: np.ndarray | None = None, shared_rows: np.ndarray | None = None
) -> BlockSolution:
    """The least squares of ``system`` and extra rows: ``damping`` (objects), ``shared_rows``."""
    o, s, K = system.own.shape[2], system.shared.shape[2], system.objects
    F = block_factors(system, damping)
    R, S, y = F[:, :o, :o], F[:, :o, o : o + s], F[:, :o, -1]
    reduced = F[:, o:, o:].reshape(-1, s + 1)
    if shared_rows is not None:
        reduced = np.vstack([reduced, shared_rows])
    sv = [np.linalg.svd(R, compute_uv=False).ravel()] if o else []
    shared = np.zeros(s)
    if s:
        shared, _, _, singular = np.linalg.lstsq(reduced[:, :s], -reduced[:, s], rcond=None)
        sv.append(singular)
    values = np.concatenate(sv) if sv else np.ones(1)
    smallest, largest = float(np.min(values)), float(np.max(values))
    objects = np.zeros((K, o))
    if o and smallest > 0:
        rhs = -(y + S @ shared)
        objects = np.linalg.solve(R, rhs[:, :, None])[:, :, 0]
    return BlockSolution(objects, shared, smallest, largest)


def dense(own: np.ndarray, shared: np.ndarray, index: np.ndarray, K: int) -> np.ndarray:
    """The blocks as one matrix ``(m, rows, K o + s)``, the shared columns last."""
    m, rows, o = own.shape
    A = np.zeros((m, rows, K * o + shared.shape[2]))
    cols = np.asarray(index)[:, None] * o + np.arange(o)[None, :]
    A[np.arange(m)[:, None, None], np.arange(rows)[None, :, None], cols[:, None, :]] = own
    A[:, :, K * o :] = shared
    return A
