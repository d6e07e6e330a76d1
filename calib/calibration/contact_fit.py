"""The fit and the structural check of one chain touching many objects, object by object.

Rationale and measurements: docs/developers/engine.md#contact_fit
"""

from __future__ import annotations

import numpy as np

from ..identification.base_columns import independent_columns
from .contact_blocks import BlockSystem, block_factors, block_lstsq
from .contact_model import ContactState
from .engine_model import ChainsData, ChainsModel, ChainsState
from .solve import TOLERANCE, Fit, solved

__all__ = ["BLOCK_UNKNOWNS", "block_fit", "block_structural", "by_block"]

BLOCK_UNKNOWNS = 90  # objects' unknowns (30 planes) from which the fit and the check go by block
ACCEPT = 1e-4  # smallest ratio of the actual to the predicted reduction of an accepted step


def by_block(model: ChainsModel, start: ChainsState) -> bool:
    """One chain touching with ``BLOCK_UNKNOWNS`` objects' unknowns or more: by block."""
    if len(start.states) != 1 or not isinstance(start.states[0], ContactState):
        return False
    K, o = model.object_blocks()
    return K * o >= BLOCK_UNKNOWNS


def _cost(f: np.ndarray, prior: np.ndarray | None, x: np.ndarray) -> float:
    return float(np.sum(f**2) + (0.0 if prior is None else np.sum((prior * x) ** 2)))


def _scales(own, shared, index, K, prior_s) -> tuple[np.ndarray, np.ndarray]:
    """Column norms of the objects' ``(K, o)`` and the shared unknowns (1 for a zero one)."""
    Do = np.zeros((K, own.shape[2]))
    np.add.at(Do, index, np.sum(own**2, axis=1))
    Ds = np.sum(shared**2, axis=(0, 1)) + (0.0 if prior_s is None else prior_s**2)
    Do, Ds = np.sqrt(Do), np.sqrt(Ds)
    return np.where(Do > 0, Do, 1.0), np.where(Ds > 0, Ds, 1.0)


def block_fit(
    model: ChainsModel,
    start: ChainsState,
    data: ChainsData,
    *,
    prior: np.ndarray | None = None,
    max_iterations: int = 100,
) -> Fit:
    """Levenberg-Marquardt from x = 0 with the objects eliminated by block (:func:`.solve.fit`)."""
    K, o = model.object_blocks()
    split = K * o
    prior_s = None if prior is None else prior[split:]

    def gaps(x: np.ndarray) -> np.ndarray:
        return -model.apply(start, x).residuals(data)

    x = np.zeros(model.size())
    f = gaps(x)
    cost, lam, nu = _cost(f, prior, x), 1e-3, 2.0
    evals, jacobians, status = 1, 0, 0
    while evals < max_iterations and status == 0:
        own, shared, index = model.blocks(start, x, data)
        jacobians += 1
        Do, Ds = _scales(own, shared, index, K, prior_s)
        while evals < max_iterations:
            extra = [np.c_[np.sqrt(lam) * np.diag(Ds), np.zeros(len(Ds))]]
            if prior_s is not None:
                extra.append(np.c_[np.diag(prior_s), prior_s * x[split:]])
            system = BlockSystem(own, shared, f, index, K)
            sol = block_lstsq(system, np.sqrt(lam) * Do, np.vstack(extra))
            step = np.r_[sol.objects.ravel(), sol.shared]
            linear = f + np.einsum("mro,mo->mr", own, sol.objects[index]) + shared @ sol.shared
            predicted = cost - _cost(linear, prior, x + step)
            trial = gaps(x + step)
            evals += 1
            new = _cost(trial, prior, x + step)
            scaled = np.linalg.norm(np.r_[(Do.ravel() * step[:split]), Ds * step[split:]])
            size = np.linalg.norm(np.r_[(Do.ravel() * x[:split]), Ds * x[split:]])
            if predicted > 0 and (cost - new) / predicted > ACCEPT and np.isfinite(new):
                rho = (cost - new) / predicted
                small = cost - new <= TOLERANCE * cost and predicted <= TOLERANCE * cost
                x, f, cost = x + step, trial, new
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                status = 2 if scaled <= TOLERANCE * size else (1 if small else 0)
                break
            if scaled <= TOLERANCE * size or predicted <= TOLERANCE * cost:
                status = 2  # no smaller step lowers the cost: a minimum
                break
            lam, nu = lam * nu, nu * 2.0
    return _result(model, start, data, x, f, status, (jacobians, evals))


_MESSAGES = {
    0: "the number of evaluations exceeded max_iterations",
    1: "both actual and predicted relative reductions are at most the tolerance",
    2: "the relative step is at most the tolerance",
}


def _result(model, start, data, x, f, status, counts) -> Fit:
    """The :class:`~calib.calibration.solve.Fit` of :func:`block_fit`."""
    J = model.jacobian(start, x, data).reshape(len(f.ravel()), -1)
    state = model.apply(start, x)
    return solved(model, start, state, x, J, f.ravel(), status, _MESSAGES[status], counts)


def block_structural(model: ChainsModel, start: ChainsState, data: ChainsData) -> list[int]:
    """The columns the touches determine (:func:`~.choice.structural`), by block."""
    K, o = model.object_blocks()
    own, shared, index = model.blocks(start, np.zeros(model.size()), data)
    F = block_factors(BlockSystem(own, shared, np.zeros(own.shape[:2]), index, K))
    R = F[:, :o, :o]
    diag = np.abs(np.diagonal(R, axis1=1, axis2=2))
    scale = max(float(np.max(np.abs(F))), 1e-300)
    if o and np.min(diag) <= 1e-10 * scale:
        return []
    reduced = F[:, o:-1, o:-1].reshape(-1, shared.shape[2])
    rows = own.shape[0] * own.shape[1]
    kept = independent_columns(reduced, list(range(shared.shape[2])), rows)[2]
    return list(range(K * o)) + [K * o + c for c in kept]
