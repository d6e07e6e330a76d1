"""Calibration from measurements: registration, model choice, fit, validation.

:func:`calibrate` fits a :class:`~.problem.Problem` (a robot and its terms) with the joint
engine (:mod:`.engine`), one module per step for every kind and shape
(docs/developers/architecture.md). May import: :mod:`calib.measurements`,
:mod:`calib.identification`, :mod:`calib.kinematics` and the bottom modules.
"""

from ..core.lazy import attributes
from .options import (
    DEFAULT_LEVEL,
    DEFAULT_MAX_ITERATIONS,
    LEVELS,
    LOSSES,
)

_LAZY = {
    "ErrorModel": "model",
    "State": "model",
    "Outlier": "outliers",
    "calibrate": "entry",
    "Problem": "problem",
    "Term": "problem",
    "residual_stats": "measured_view",
    "ResidualStats": "residuals",
    "Validation": "residuals",
    "Selection": "selection",
    "Step": "selection",
}
"""Names imported when first used: ``calib`` commands that do not calibrate skip the import."""


__getattr__ = attributes(__name__, _LAZY)

TYPE_CHECKING = False  # True for type checkers; importing typing would cost start-up
if TYPE_CHECKING:  # what the lazy names are, for type checkers (tests/test_public.py)
    from .entry import calibrate
    from .measured_view import residual_stats
    from .model import ErrorModel, State
    from .outliers import Outlier
    from .problem import Problem, Term
    from .residuals import ResidualStats, Validation
    from .selection import Selection, Step


__all__ = [
    "DEFAULT_LEVEL",
    "DEFAULT_MAX_ITERATIONS",
    "LEVELS",
    "LOSSES",
    "ErrorModel",
    "Outlier",
    "Problem",
    "ResidualStats",
    "Selection",
    "State",
    "Step",
    "Term",
    "Validation",
    "calibrate",
    "residual_stats",
]
