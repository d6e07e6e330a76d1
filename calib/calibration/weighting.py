"""The orientation weight from the data: variance components of position and orientation.

Pose rows mix metres and radians, so the orientation rows carry a weight w [m/rad]. The
weighted least-squares fit is the maximum-likelihood one when w = sigma_p / sigma_o, the ratio
of the position error [m] to the orientation error [rad] per axis. Neither is known
beforehand, and the errors a calibration meets are mostly model errors, not the instrument's
specification. Both are estimated from the residuals of the registration (the nominal model
with its measurement frame, markers and measured-frame rotation fitted), the registration is
redone with the new weight, until the weight settles: an iterated estimation of the two
variance components (a feasible weighted least squares; Koch, *Parameter Estimation and
Hypothesis Testing in Linear Models*, Springer 1999, section 3.6).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = [
    "BOUNDS",
    "DEFAULT_WEIGHT",
    "ITERATIONS",
    "TINY",
    "TOLERANCE",
    "estimate_weight",
    "variance_ratio",
]

DEFAULT_WEIGHT = 1.0
"""Starting weight [m/rad] (1 mrad counts as 1 mm), kept when the data cannot tell."""

BOUNDS = (1e-3, 1e3)
"""Range of an estimated weight [m/rad]."""

TINY = 1e-9
"""Residual RMS [m or rad] below which a component is noise-free: the weight is not estimated."""

TOLERANCE = 0.01
"""Relative change of the weight at which the estimation stops."""

ITERATIONS = 10
"""Most registrations the estimation runs."""


def variance_ratio(residuals: np.ndarray, n_markers: int) -> float | None:
    """sigma_p / sigma_o [m/rad] of pose residuals ``(m, 3 K + 3)``, or None if one is ~0."""
    sp = math.sqrt(float(np.mean(residuals[:, : 3 * n_markers] ** 2)))
    so = math.sqrt(float(np.mean(residuals[:, 3 * n_markers :] ** 2)))
    if sp < TINY or so < TINY:
        return None
    return float(np.clip(sp / so, *BOUNDS))


def estimate_weight(residuals_at: Callable[[float], np.ndarray], n_markers: int) -> float:
    """The orientation weight [m/rad] at which the residuals' variance ratio settles.

    Args:
        residuals_at: Residuals ``(m, 3 K + 3)`` [m, rad] of a fit made with a weight.
        n_markers: K, the measured points per configuration.
    """
    weight = DEFAULT_WEIGHT
    for _ in range(ITERATIONS):
        new = variance_ratio(residuals_at(weight), n_markers)
        if new is None:
            return weight
        if abs(new - weight) <= TOLERANCE * weight:
            return new
        weight = new
    return weight
