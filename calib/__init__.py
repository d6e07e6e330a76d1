"""calib: identifiable geometric parameters and calibration of serial robots from URDF.

Load a chain with :func:`load_chain`, convert it to modified DH with :func:`from_chain`,
and ask :func:`analyze` which parameters can be identified.
"""

from .catalog import CatalogEntry, catalog
from .exceptions import (
    AmbiguousFrameError,
    CalibError,
    ChainError,
    ConvergenceError,
    DataError,
    FrameNotFoundError,
    InvalidArgumentError,
    RobotNotFoundError,
    UnsupportedJointError,
    URDFError,
)
from .identifiability import Identifiability, RankWarning, analyze, analyze_model
from .jacobian import Measurement, complete_jacobian, identification_jacobian
from .mdh import PARALLEL_TOL, MDHModel, from_chain, from_lines
from .parameters import Kind, Parameter, ParameterSet, complete_parameters, paper_parameters
from .robot import Chain, load_chain

__version__ = "0.1.0"

__all__ = [
    "PARALLEL_TOL",
    "AmbiguousFrameError",
    "CalibError",
    "CatalogEntry",
    "Chain",
    "ChainError",
    "ConvergenceError",
    "DataError",
    "FrameNotFoundError",
    "Identifiability",
    "InvalidArgumentError",
    "Kind",
    "MDHModel",
    "Measurement",
    "Parameter",
    "ParameterSet",
    "RankWarning",
    "RobotNotFoundError",
    "URDFError",
    "UnsupportedJointError",
    "analyze",
    "analyze_model",
    "catalog",
    "complete_jacobian",
    "complete_parameters",
    "from_chain",
    "from_lines",
    "identification_jacobian",
    "load_chain",
    "paper_parameters",
]
