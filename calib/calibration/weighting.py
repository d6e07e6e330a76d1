"""The orientation weight w = sigma_p / sigma_o [m/rad] from the data (variance components).

Rationale and measurements: docs/developers/engine.md#weighting
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = ["DEFAULT_WEIGHT", "estimate_weight", "pose_angles", "variance_ratio"]

DEFAULT_WEIGHT = 1.0  # [m/rad] (1 mrad counts as 1 mm), kept when the data cannot tell
BOUNDS = (1e-3, 1e3)  # range of an estimated weight [m/rad]
TINY = 1e-9  # residual RMS [m or rad] of a noise-free component: the weight is not estimated
TOLERANCE = 0.01  # relative change of the weight that stops the estimation (measured chains)
ITERATIONS = 10  # most registrations the estimation runs (measured chains)


def variance_ratio(residuals: np.ndarray, angle: np.ndarray) -> float | None:
    """sigma_p / sigma_o [m/rad] of residuals ``(m, rows)`` [m, rad], or None if one is ~0.

    A marker not seen in a row (NaN) has no rows.
    """
    lengths = residuals[:, ~angle] ** 2
    if np.isnan(lengths).any():
        lengths = lengths[~np.isnan(lengths)]
    sp = math.sqrt(float(np.mean(lengths)))
    so = math.sqrt(float(np.mean(residuals[:, angle] ** 2)))
    if sp < TINY or so < TINY:
        return None
    return float(np.clip(sp / so, *BOUNDS))


def pose_angles(n_markers: int) -> np.ndarray:
    """Which rows of pose residuals ``(m, 3 K + 3)`` are angles: the last 3 (bool)."""
    return np.arange(3 * n_markers + 3) >= 3 * n_markers


def estimate_weight(
    residuals_at: Callable[[float], np.ndarray],
    angle: np.ndarray,
    rounds: int = ITERATIONS,
    tolerance: float = TOLERANCE,
) -> float:
    """The orientation weight [m/rad] at which the variance ratio of ``residuals_at(w)`` settles.

    ``residuals_at(w)``: ``(m, rows)`` [m, rad] of a fit at weight w; ``angle`` ``(rows,)``:
    which rows are angles; ``tolerance``: the relative change that stops it (0: ``rounds``
    fits). Residuals without both lengths and angles: ``DEFAULT_WEIGHT``.
    """
    weight = DEFAULT_WEIGHT
    angle = np.asarray(angle, dtype=bool)
    if angle.all() or not angle.any():
        return weight
    for _ in range(rounds):
        new = variance_ratio(residuals_at(weight), angle)
        if new is None:
            return weight
        if abs(new - weight) <= tolerance * weight:
            return new
        weight = new
    return weight
