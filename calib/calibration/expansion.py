"""The residuals the selection explains: the expansion of the model it works on.

The selection (:mod:`.selection`) works on the model linearised at the registration. Where
the second-order terms of that expansion dominate what the complete linear fit leaves
(little noise), the expansion moves to the complete fit (:func:`explained`).
"""

from __future__ import annotations

import numpy as np

from .model import ErrorModel, State

__all__ = ["NONLINEAR", "explained"]


def explained(wide: ErrorModel, reg: State, data, torque, J, cols, e, w) -> np.ndarray:
    """The residuals the selection explains with the Jacobian at the registration.

    Those at the registration leave the model's second-order terms (about the squared
    errors of the geometry, micrometres for millimetre errors), which no linear fit
    removes: with little noise they hide the parameters whose effect is smaller (and the
    complete fit is no longer exact). One step of the complete model (its linear fit ``x``,
    the residuals ``r(x)`` there) moves the expansion to where the complete model fits,
    ``r(x) + J x``, when those terms are most of what the linear fit leaves (the complete
    linear fit of the moved residuals leaves under ``NONLINEAR`` times what it left).
    Otherwise (noise or what the model lacks dominate, or few data where the complete fit
    is far from the others) the residuals at the registration are kept.

    Args:
        wide: The model of every candidate; ``cols`` its columns in ``J``.
        reg: The registration (x = 0).
        data: The training data.
        torque: Their gravity torques (or None).
        J: Weighted Jacobian of the columns ``(m, rows, len(cols))``.
        cols: Columns of ``wide`` in ``J``.
        e: Weighted residuals at the registration ``(m, rows)``.
        w: Row weights.
    """
    A = J.reshape(-1, J.shape[2])
    x = np.linalg.lstsq(A, e.ravel(), rcond=None)[0]
    step = np.zeros(wide.size())
    step[cols] = x
    moved = wide.apply(reg, step).residuals(data, torque) * w + J @ x
    if not np.all(np.isfinite(moved)):
        return e
    left = [v - A @ np.linalg.lstsq(A, v, rcond=None)[0] for v in (e.ravel(), moved.ravel())]
    return moved if left[1] @ left[1] < NONLINEAR * (left[0] @ left[0]) else e


NONLINEAR = 0.5
"""The selection's expansion moves to the complete fit (:func:`_explained`) when the complete
linear fit leaves less than this fraction of its squared residuals there."""
