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
apart; the others are in :mod:`calib.exceptions`). The names calib had before it
(``calibrate_tree``, ``tree_jacobian``, ``load_tree``: ``load_robot`` with several tools,
...) are still attributes of ``calib``, as are the camera's pieces (``Unknowns``, ``Pinhole``,
``Intrinsics``, ``Target``, ``PixelObservations``, ``hand_eye``), and every
module has its own ``__all__``; those that left it (``_MOVED``) warn.
"""

import sys
import types

from .core.lazy import attributes, moved
from .exceptions import CalibError, CalibrationRefusedError, DataError, InvalidArgumentError
from .kinematics.catalog import CatalogEntry, catalog  # light (the standard library only)

_LAZY = {
    "RankWarning": "identification.identifiability",
    "analyze": "calibration.analysis",
    "ProblemAnalysis": "calibration.analysis",
    "analyze_model": "identification.identifiability",
    "Measurement": "identification.jacobian",
    "complete_jacobian": "identification.jacobian",
    "identification_jacobian": "identification.jacobian",
    "PARALLEL_TOL": "kinematics.mdh",
    "from_chain": "kinematics.mdh",
    "from_lines": "kinematics.mdh",
    "Campaign": "measurements.simulation",
    "Columns": "measurements.csvfile",
    "DataWarning": "measurements.data",
    "Measurements": "measurements.data",
    "SimulationTruth": "measurements.simulation",
    "read_measurements": "measurements.csvfile",
    "simulate": "measurements.simulation",
    "write_measurements": "measurements.csvfile",
    "Kind": "identification.parameters",
    "Parameter": "identification.parameters",
    "ParameterSet": "identification.parameters",
    "complete_parameters": "identification.parameters",
    "paper_parameters": "identification.parameters",
    "Chain": "kinematics.robot",
    "load_chain": "kinematics.robot",
    "Tree": "kinematics.tree",
    "load_robot": "kinematics.tree",
    "load_tree": "kinematics.tree",
    "tree_complete_jacobian": "identification.tree_jacobian",
    "tree_jacobian": "identification.tree_jacobian",
    "tree_parameters": "identification.tree_jacobian",
    "TreeMDH": "kinematics.tree_model",
    "from_tree": "kinematics.tree_model",
    "Problem": "calibration.problem",
    "Term": "calibration.problem",
    "Result": "calibration.delivery",
    "ContactData": "measurements.contact_campaign",
    "read_contacts": "measurements.contact_campaign",
    "simulate_contacts": "measurements.contact_campaign",
    "design": "design.design",
    "cross_validate": "design.folds",
    "ResidualStats": "calibration",
    "calibrate": "calibration",
    "residual_stats": "calibration",
    "calibrated_urdf": "kinematics.urdf_export",
    "measurement_to_base": "kinematics.urdf_export",
    "write_calibrated_urdf": "kinematics.urdf_export",
    "ContactChainsCalibration": "calibration.engine_result",
    "calibrate_contact_chains": "calibration.engine",
    "calibrate_tree": "calibration.entry",
    "TreeCampaign": "measurements.tree_campaign",
    "simulate_tree": "measurements.tree_campaign",
    "calibrated_tree_urdf": "kinematics.tree_export",
    "write_calibrated_tree_urdf": "kinematics.tree_export",
    "ElasticModel": "kinematics.elastic",
    "load_calibrated": "kinematics.elastic",
    "PixelCamera": "calibration.pixel_chain",
    "Unknowns": "calibration.pixel_chain",
    "PixelData": "calibration.pixel_chain",
    "hand_eye": "calibration.hand_eye",
    "Pinhole": "identification.pinhole",
    "Intrinsics": "measurements.intrinsics",
    "read_intrinsics": "measurements.intrinsics",
    "PixelObservations": "measurements.pixels",
    "Target": "measurements.pixels",
    "read_observations": "measurements.pixels",
    "read_target": "measurements.pixels",
    "simulate_pixels": "measurements.pixel_simulation",
}
"""Names imported when first used (all but the light catalog and errors), so that
``import calib`` loads nothing heavy: ``calib --version`` and ``calib list`` start without
numpy, Pinocchio or SciPy."""


_lazy = attributes(__name__, _LAZY)

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
}
"""Names that left ``__all__`` (46 -> 36 names, session 51): the errors a user rarely catches
by their own class (every one is a :class:`CalibError`) and the types of what ``analyze``
and ``from_chain`` return. ``calib.URDFError`` still works with a ``DeprecationWarning``
naming ``calib.exceptions.URDFError``, until calib 0.2."""

_moved = moved(__name__, _MOVED, "0.2")


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
    from .calibration import ResidualStats, calibrate, residual_stats
    from .calibration.analysis import ProblemAnalysis, analyze
    from .calibration.delivery import Result
    from .calibration.engine import calibrate_contact_chains
    from .calibration.engine_result import ContactChainsCalibration
    from .calibration.entry import calibrate_tree
    from .calibration.hand_eye import hand_eye
    from .calibration.pixel_chain import PixelCamera, PixelData, Unknowns
    from .calibration.problem import Problem, Term
    from .design.design import design
    from .design.folds import cross_validate
    from .identification.identifiability import RankWarning, analyze_model
    from .identification.jacobian import Measurement, complete_jacobian, identification_jacobian
    from .identification.parameters import (
        Kind,
        Parameter,
        ParameterSet,
        complete_parameters,
        paper_parameters,
    )
    from .identification.pinhole import Pinhole
    from .identification.tree_jacobian import tree_complete_jacobian, tree_jacobian, tree_parameters
    from .kinematics.elastic import ElasticModel, load_calibrated
    from .kinematics.mdh import PARALLEL_TOL, from_chain, from_lines
    from .kinematics.robot import Chain, load_chain
    from .kinematics.tree import Tree, load_robot, load_tree
    from .kinematics.tree_export import calibrated_tree_urdf, write_calibrated_tree_urdf
    from .kinematics.tree_model import TreeMDH, from_tree
    from .kinematics.urdf_export import calibrated_urdf, measurement_to_base, write_calibrated_urdf
    from .measurements.contact_campaign import ContactData, read_contacts, simulate_contacts
    from .measurements.csvfile import Columns, read_measurements, write_measurements
    from .measurements.data import DataWarning, Measurements
    from .measurements.intrinsics import Intrinsics, read_intrinsics
    from .measurements.pixel_simulation import simulate_pixels
    from .measurements.pixels import PixelObservations, Target, read_observations, read_target
    from .measurements.simulation import Campaign, SimulationTruth, simulate
    from .measurements.tree_campaign import TreeCampaign, simulate_tree


class _Package(types.ModuleType):
    """calib itself: a function named as its own module (``tree_jacobian``) keeps the name.

    Importing a submodule binds it on its package; eager imports used to rebind the function
    right after, lazy ones cannot, so the binding of such a submodule is skipped (it stays in
    ``sys.modules``) and the name resolves to the function (see ``__getattr__``).
    """

    def __setattr__(self, name: str, value: object) -> None:
        if isinstance(value, types.ModuleType) and _LAZY.get(name) == name:
            return
        super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package


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
