"""Measurements: the CSV of measured campaigns, simulated campaigns, marker sets.

:mod:`.csvfile` reads, checks and writes the measurement CSV, :mod:`.simulation` simulates
chain campaigns (their names are re-exported here, imported when first used:
``from calib.measurements import read_measurements`` works); :mod:`.tree_campaign`
simulates tree campaigns, :mod:`.marker_set` reads the markers of a pose measurement.

May import: :mod:`calib.identification`, :mod:`calib.kinematics` and the bottom modules.
"""

from ..lazy import attributes

_LAZY = {
    "Angles": "csvfile",
    "Campaign": "simulation",
    "Columns": "csvfile",
    "DEFAULT_ORIENTATION_COLUMNS": "csvfile",
    "DataWarning": "csvfile",
    "JOINT_PREFIX": "csvfile",
    "LIMIT_MARGIN": "csvfile",
    "LIMIT_TOL": "csvfile",
    "MAX_COORDINATE": "csvfile",
    "MAX_MEASUREMENTS_BYTES": "csvfile",
    "Measurements": "csvfile",
    "POSITION_COLUMNS": "csvfile",
    "QUATERNION_COLUMNS": "csvfile",
    "SimulationTruth": "simulation",
    "TOOL_COLUMN": "csvfile",
    "check_against_chain": "csvfile",
    "check_limits": "csvfile",
    "csv_records": "csvfile",
    "joint_bounds": "csvfile",
    "measurements_csv": "csvfile",
    "parse_measurements": "csvfile",
    "parse_number": "csvfile",
    "read_measurements": "csvfile",
    "simulate": "simulation",
    "tool_frames": "csvfile",
    "write_measurements": "csvfile",
}

__getattr__ = attributes(__name__, _LAZY)

TYPE_CHECKING = False  # True for type checkers; importing typing would cost start-up
if TYPE_CHECKING:  # what the lazy names are, for type checkers (tests/test_public.py)
    from .csvfile import (  # noqa: F401 (exported: __all__ is sorted(_LAZY))
        DEFAULT_ORIENTATION_COLUMNS,
        JOINT_PREFIX,
        LIMIT_MARGIN,
        LIMIT_TOL,
        MAX_COORDINATE,
        MAX_MEASUREMENTS_BYTES,
        POSITION_COLUMNS,
        QUATERNION_COLUMNS,
        TOOL_COLUMN,
        Angles,
        Columns,
        DataWarning,
        Measurements,
        check_against_chain,
        check_limits,
        csv_records,
        joint_bounds,
        measurements_csv,
        parse_measurements,
        parse_number,
        read_measurements,
        tool_frames,
        write_measurements,
    )
    from .simulation import Campaign, SimulationTruth, simulate  # noqa: F401

__all__ = sorted(_LAZY)
