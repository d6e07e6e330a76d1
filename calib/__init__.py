"""calib: identifiable geometric parameters and calibration of serial robots from URDF.

Load a chain with :func:`load_chain`, convert it to modified DH with :func:`from_chain`,
and ask :func:`analyze` which parameters can be identified. Then :func:`simulate` or
:func:`read_measurements` a campaign, :func:`calibrate` the base parameters from it and
:func:`write_calibrated_urdf`.

A whole robot (several tools sharing joints) is a tree: :func:`load_tree`, :func:`from_tree`
(Khalil-Kleinfinger's tree notation), :func:`tree_parameters`, :func:`tree_jacobian`;
:func:`analyze` takes a tree too; :func:`simulate_tree`, :func:`calibrate_tree` and
:func:`write_calibrated_tree_urdf` calibrate it from rows that name their tool.
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
from .tree import Tree, load_robot, load_tree
from .tree_jacobian import tree_complete_jacobian, tree_jacobian, tree_parameters
from .tree_model import TreeMDH, from_tree

_LAZY = {
    "CalibrationResult": "calibration",
    "ResidualStats": "calibration",
    "calibrate": "calibration",
    "residual_stats": "calibration",
    "calibrated_urdf": "urdf_export",
    "measurement_to_base": "urdf_export",
    "write_calibrated_urdf": "urdf_export",
    "TreeCalibrationResult": "calibration.tree_pipeline",
    "calibrate_tree": "calibration.tree_pipeline",
    "TreeCampaign": "tree_campaign",
    "simulate_tree": "tree_campaign",
    "calibrated_tree_urdf": "tree_export",
    "write_calibrated_tree_urdf": "tree_export",
    "ElasticModel": "elastic",
    "load_calibrated": "elastic",
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
    "ElasticModel",
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
    "Tree",
    "TreeCalibrationResult",
    "TreeCampaign",
    "TreeMDH",
    "URDFError",
    "UnsupportedJointError",
    "analyze",
    "analyze_model",
    "calibrate",
    "calibrate_tree",
    "calibrated_tree_urdf",
    "calibrated_urdf",
    "catalog",
    "complete_jacobian",
    "complete_parameters",
    "from_chain",
    "from_lines",
    "from_tree",
    "identification_jacobian",
    "load_calibrated",
    "load_chain",
    "load_robot",
    "load_tree",
    "measurement_to_base",
    "paper_parameters",
    "read_measurements",
    "residual_stats",
    "simulate",
    "simulate_tree",
    "tree_complete_jacobian",
    "tree_jacobian",
    "tree_parameters",
    "write_calibrated_tree_urdf",
    "write_calibrated_urdf",
    "write_measurements",
]
