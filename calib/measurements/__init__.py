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

__all__ = sorted(_LAZY)
