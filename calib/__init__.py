"""calib: identifiable geometric parameters and calibration of serial robots from URDF.

Load a chain with :func:`load_chain`, convert it to modified DH with :func:`from_chain`,
and ask :func:`analyze` which parameters can be identified. Then :func:`simulate` or
:func:`read_measurements` a campaign, :func:`calibrate` the base parameters from it and
:func:`write_calibrated_urdf`.
"""

from .catalog import CatalogEntry, catalog
from .exceptions import (
    AmbiguousFrameError,
    CalibError,
    CalibrationRefusedError,
    ChainError,
    ConvergenceError,
    DataError,
    FrameNotFoundError,
    InvalidArgumentError,
    OutputError,
    RobotNotFoundError,
    UnsupportedJointError,
    URDFError,
)
from .identifiability import Identifiability, RankWarning, analyze, analyze_model
from .jacobian import Measurement, complete_jacobian, identification_jacobian
from .lazy import attributes
from .mdh import PARALLEL_TOL, MDHModel, from_chain, from_lines
from .measurements import (
    Campaign,
    Columns,
    DataWarning,
    Measurements,
    SimulationTruth,
    read_measurements,
    simulate,
    write_measurements,
)
from .parameters import Kind, Parameter, ParameterSet, complete_parameters, paper_parameters
from .robot import Chain, load_chain

_LAZY = {
    "CalibrationResult": "calibration",
    "ResidualStats": "calibration",
    "calibrate": "calibration",
    "residual_stats": "calibration",
    "calibrated_urdf": "urdf_export",
    "measurement_to_base": "urdf_export",
    "write_calibrated_urdf": "urdf_export",
}
"""Names imported when first used, so that ``calib analyze`` does not load the calibration."""


__getattr__ = attributes(__name__, _LAZY)


__version__ = "0.1.0"

__all__ = [
    "PARALLEL_TOL",
    "AmbiguousFrameError",
    "CalibError",
    "CalibrationRefusedError",
    "CalibrationResult",
    "Campaign",
    "CatalogEntry",
    "Chain",
    "ChainError",
    "Columns",
    "ConvergenceError",
    "DataError",
    "DataWarning",
    "FrameNotFoundError",
    "Identifiability",
    "InvalidArgumentError",
    "Kind",
    "MDHModel",
    "Measurement",
    "Measurements",
    "OutputError",
    "Parameter",
    "ParameterSet",
    "RankWarning",
    "ResidualStats",
    "RobotNotFoundError",
    "SimulationTruth",
    "URDFError",
    "UnsupportedJointError",
    "analyze",
    "analyze_model",
    "calibrate",
    "calibrated_urdf",
    "catalog",
    "complete_jacobian",
    "complete_parameters",
    "from_chain",
    "from_lines",
    "identification_jacobian",
    "load_chain",
    "measurement_to_base",
    "paper_parameters",
    "read_measurements",
    "residual_stats",
    "simulate",
    "write_calibrated_urdf",
    "write_measurements",
]
