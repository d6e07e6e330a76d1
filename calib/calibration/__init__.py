"""Calibration from measurements: registration, model choice, fit, validation.

One module per step, in the order :func:`calibrate` runs them: :mod:`.registration`
(measurement frame and markers in closed form), :mod:`.diagnosis` (the usual data mistakes),
:mod:`.outliers` (robust fitting), :mod:`.selection` (which parameters the data support),
:mod:`.solve` (the nonlinear fit), :mod:`.validation` (held-out errors and the checks), on the
model of :mod:`.model`; :mod:`.pipeline` chains them and :mod:`.result` holds the outcome.
"""

from .model import ErrorModel, State
from .outliers import Outlier
from .pipeline import (
    DEFAULT_LEVEL,
    DEFAULT_MAX_ITERATIONS,
    LEVELS,
    calibrate,
    residual_stats,
)
from .result import CalibrationResult, ResidualStats, Validation
from .selection import Selection, Step
from .solve import LOSSES

__all__ = [
    "DEFAULT_LEVEL",
    "DEFAULT_MAX_ITERATIONS",
    "LEVELS",
    "LOSSES",
    "CalibrationResult",
    "ErrorModel",
    "Outlier",
    "ResidualStats",
    "Selection",
    "State",
    "Step",
    "Validation",
    "calibrate",
    "residual_stats",
]
