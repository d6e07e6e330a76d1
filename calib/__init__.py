"""calib: identifiable geometric parameters and calibration of robots from URDF.

Load a robot with :func:`load_robot` (a chain between two frames, or a tree of several
tools), ask :func:`analyze` which parameters can be identified, :func:`design` the postures to
measure, :func:`simulate` (or :func:`simulate_contacts`) a campaign or read one
(:func:`read_measurements`, :func:`read_contacts`; a camera's: :func:`read_intrinsics`,
:func:`read_target`, :func:`read_observations`, :func:`simulate_pixels`, a
:class:`PixelCamera` and its :class:`PixelData`), then :func:`calibrate` a :class:`Problem`
of one or more :class:`Term` (a chain and what was recorded on it): the :class:`Result` writes
the calibrated URDF. :func:`load_calibrated` reads it back with its report. ``analyze(problem)``
counts what a problem's terms determine together.

``calib.__all__`` (and ``dir(calib)``) is the public face: what a user calls, or catches
(:class:`CalibError`, which every error derives from, and the three an ordinary script tells
apart; the others are in :mod:`calib.exceptions`). Everything else is public one level down,
at its module's path (``calib.identification.tree_jacobian.tree_jacobian``,
``calib.calibration.hand_eye.hand_eye``, ...), and every module lists its own in ``__all__``;
the names calib resolved before at its top level (``_MOVED``) still do, with a warning, until
calib 0.2.
"""

from .core.lazy import attributes as _attributes
from .core.lazy import moved as _moved_names
from .exceptions import CalibError, CalibrationRefusedError, DataError, InvalidArgumentError
from .kinematics.catalog import catalog  # light (the standard library only)

_LAZY = {
    "RankWarning": "identification.identifiability",
    "analyze": "calibration.analysis",
    "Measurement": "identification.jacobian",
    "from_chain": "kinematics.mdh",
    "Columns": "measurements.csvfile",
    "DataWarning": "measurements.data",
    "Measurements": "measurements.data",
    "read_measurements": "measurements.csvfile",
    "simulate": "measurements.simulation",
    "write_measurements": "measurements.csvfile",
    "Chain": "kinematics.robot",
    "load_chain": "kinematics.robot",
    "Tree": "kinematics.tree",
    "load_robot": "kinematics.tree",
    "from_tree": "kinematics.tree_model",
    "Problem": "calibration.problem",
    "Term": "calibration.problem",
    "Result": "calibration.delivery",
    "ContactData": "measurements.contact_campaign",
    "read_contacts": "measurements.contact_campaign",
    "simulate_contacts": "measurements.contact_campaign",
    "design": "design.design",
    "cross_validate": "design.folds",
    "calibrate": "calibration",
    "load_calibrated": "kinematics.elastic",
    "PixelCamera": "calibration.pixel_chain",
    "PixelData": "calibration.pixel_chain",
    "read_intrinsics": "measurements.intrinsics",
    "read_observations": "measurements.pixels",
    "read_target": "measurements.pixels",
    "simulate_pixels": "measurements.pixel_simulation",
}
"""Names imported when first used (all but the light catalog and errors), so that
``import calib`` loads nothing heavy: ``calib --version`` and ``calib list`` start without
numpy, Pinocchio or SciPy."""


_lazy = _attributes(__name__, _LAZY)

_MOVED = {
    "AmbiguousFrameError": "exceptions",
    "ChainError": "exceptions",
    "ConvergenceError": "exceptions",
    "FrameNotFoundError": "exceptions",
    "OutputError": "exceptions",
    "RobotNotFoundError": "exceptions",
    "URDFError": "exceptions",
    "UnsupportedJointError": "exceptions",
    "Identifiability": "identification.identifiability",
    "MDHModel": "kinematics.mdh",
    "ResidualStats": "calibration",
    "residual_stats": "calibration",
    "ProblemAnalysis": "calibration.analysis",
    "calibrate_contact_chains": "calibration.engine",
    "ContactChainsCalibration": "calibration.engine_result",
    "calibrate_tree": "calibration.entry",
    "hand_eye": "calibration.hand_eye",
    "Unknowns": "calibration.pixel_chain",
    "analyze_model": "identification.identifiability",
    "complete_jacobian": "identification.jacobian",
    "identification_jacobian": "identification.jacobian",
    "Kind": "identification.parameters",
    "Parameter": "identification.parameters",
    "ParameterSet": "identification.parameters",
    "complete_parameters": "identification.parameters",
    "paper_parameters": "identification.parameters",
    "Pinhole": "identification.pinhole",
    "tree_complete_jacobian": "identification.tree_jacobian",
    "tree_jacobian": "identification.tree_jacobian",
    "tree_parameters": "identification.tree_jacobian",
    "CatalogEntry": "kinematics.catalog",
    "ElasticModel": "kinematics.elastic",
    "PARALLEL_TOL": "kinematics.mdh",
    "from_lines": "kinematics.mdh",
    "load_tree": "kinematics.tree",
    "calibrated_tree_urdf": "kinematics.tree_export",
    "write_calibrated_tree_urdf": "kinematics.tree_export",
    "TreeMDH": "kinematics.tree_model",
    "calibrated_urdf": "kinematics.urdf_export",
    "measurement_to_base": "kinematics.urdf_export",
    "write_calibrated_urdf": "kinematics.urdf_export",
    "Intrinsics": "measurements.intrinsics",
    "PixelObservations": "measurements.pixels",
    "Target": "measurements.pixels",
    "Campaign": "measurements.simulation",
    "SimulationTruth": "measurements.simulation",
    "TreeCampaign": "measurements.tree_campaign",
    "simulate_tree": "measurements.tree_campaign",
}
"""Names calib's top level resolved outside ``__all__``, each with the module it lives in:
``calib.URDFError`` still works with a ``DeprecationWarning`` naming
``calib.exceptions.URDFError``, until calib 0.2. The ten first left ``__all__`` (46 -> 36
names); the others are the names calib had before it (``calibrate_tree``, which is
:func:`calibrate`; ``tree_jacobian``, ``load_tree``: :func:`load_robot` with several tools,
...), the camera's pieces and the types of what the public calls return (``Campaign``,
``ProblemAnalysis``, ...), all silent attributes until session 51."""

_ALIASES = {"calibrate_tree": "calibrate"}
"""Moved names that are another name of a public one: their warning names that one."""

_moved = _moved_names(__name__, _MOVED, "0.2", _ALIASES)


def __getattr__(name: str) -> object:
    """The lazy names, the moved ones (warned) and the callable package ``design``."""
    if name == "design":
        import importlib

        return importlib.import_module(".design", __name__)
    if name in _MOVED:
        return _moved(name)
    return _lazy(name)


TYPE_CHECKING = False  # True for type checkers; importing typing would cost start-up
if TYPE_CHECKING:  # what the lazy names are, for type checkers (tests/test_public.py)
    from .calibration import calibrate
    from .calibration.analysis import analyze
    from .calibration.delivery import Result
    from .calibration.pixel_chain import PixelCamera, PixelData
    from .calibration.problem import Problem, Term
    from .design.design import design
    from .design.folds import cross_validate
    from .identification.identifiability import RankWarning
    from .identification.jacobian import Measurement
    from .kinematics.elastic import load_calibrated
    from .kinematics.mdh import from_chain
    from .kinematics.robot import Chain, load_chain
    from .kinematics.tree import Tree, load_robot
    from .kinematics.tree_model import from_tree
    from .measurements.contact_campaign import ContactData, read_contacts, simulate_contacts
    from .measurements.csvfile import Columns, read_measurements, write_measurements
    from .measurements.data import DataWarning, Measurements
    from .measurements.intrinsics import read_intrinsics
    from .measurements.pixel_simulation import simulate_pixels
    from .measurements.pixels import read_observations, read_target
    from .measurements.simulation import simulate
del TYPE_CHECKING  # not a name of calib


__version__ = "0.1.0"

__all__ = [
    "CalibError",
    "CalibrationRefusedError",
    "Chain",
    "Columns",
    "ContactData",
    "DataError",
    "DataWarning",
    "InvalidArgumentError",
    "Measurement",
    "Measurements",
    "PixelCamera",
    "PixelData",
    "Problem",
    "RankWarning",
    "Result",
    "Term",
    "Tree",
    "analyze",
    "calibrate",
    "catalog",
    "cross_validate",
    "design",
    "from_chain",
    "from_tree",
    "load_calibrated",
    "load_chain",
    "load_robot",
    "read_contacts",
    "read_intrinsics",
    "read_measurements",
    "read_observations",
    "read_target",
    "simulate",
    "simulate_contacts",
    "simulate_pixels",
    "write_measurements",
]


def __dir__() -> list[str]:
    """The public face (``__all__``): what ``dir(calib)`` and tab completion list."""
    return sorted([*__all__, "__version__"])
