"""Measurements: the CSV of measured campaigns, simulated campaigns, marker sets.

:mod:`.data` holds the measurements (one value), :mod:`.csvfile` reads and writes them as
CSV, :mod:`.limits` checks them against their chain or tree, :mod:`.simulation` simulates
chain campaigns (their names are re-exported here, imported when first used:
``from calib.measurements import read_measurements`` works); :mod:`.tree_campaign`
simulates tree campaigns, :mod:`.marker_set` reads the markers of a pose measurement;
:mod:`.intrinsics` reads and writes a camera's intrinsics file, :mod:`.pixels` the pixel
observations and targets of cameras.

May import: :mod:`calib.identification`, :mod:`calib.kinematics` and the bottom modules.
"""

from ..core.lazy import attributes

_LAZY = {
    "Angles": "data",
    "Campaign": "simulation",
    "Columns": "csvfile",
    "DEFAULT_ORIENTATION_COLUMNS": "csvfile",
    "DataWarning": "data",
    "Intrinsics": "intrinsics",
    "JOINT_PREFIX": "data",
    "LIMIT_MARGIN": "limits",
    "LIMIT_TOL": "limits",
    "MAX_COORDINATE": "data",
    "MAX_MEASUREMENTS_BYTES": "csvfile",
    "Measurements": "data",
    "POSITION_COLUMNS": "data",
    "PixelObservations": "pixels",
    "QUATERNION_COLUMNS": "data",
    "SimulationTruth": "simulation",
    "TOOL_COLUMN": "data",
    "Target": "pixels",
    "check_against_chain": "limits",
    "check_limits": "limits",
    "csv_records": "csvfile",
    "joint_bounds": "limits",
    "measurements_csv": "csvfile",
    "parse_intrinsics": "intrinsics",
    "parse_measurements": "csvfile",
    "parse_number": "csvfile",
    "parse_observations": "pixels",
    "parse_target": "pixels",
    "read_intrinsics": "intrinsics",
    "read_measurements": "csvfile",
    "read_observations": "pixels",
    "read_target": "pixels",
    "simulate": "simulation",
    "tool_frames": "limits",
    "write_intrinsics": "intrinsics",
    "write_measurements": "csvfile",
    "write_observations": "pixels",
    "write_target": "pixels",
}

__getattr__ = attributes(__name__, _LAZY)

TYPE_CHECKING = False  # True for type checkers; importing typing would cost start-up
if TYPE_CHECKING:  # what the lazy names are, for type checkers (tests/test_public.py)
    from .csvfile import (  # noqa: F401 (exported: __all__ is sorted(_LAZY))
        DEFAULT_ORIENTATION_COLUMNS,
        MAX_MEASUREMENTS_BYTES,
        Columns,
        csv_records,
        measurements_csv,
        parse_measurements,
        parse_number,
        read_measurements,
        write_measurements,
    )
    from .data import (  # noqa: F401
        JOINT_PREFIX,
        MAX_COORDINATE,
        POSITION_COLUMNS,
        QUATERNION_COLUMNS,
        TOOL_COLUMN,
        Angles,
        DataWarning,
        Measurements,
    )
    from .intrinsics import (  # noqa: F401
        Intrinsics,
        parse_intrinsics,
        read_intrinsics,
        write_intrinsics,
    )
    from .limits import (  # noqa: F401
        LIMIT_MARGIN,
        LIMIT_TOL,
        check_against_chain,
        check_limits,
        joint_bounds,
        tool_frames,
    )
    from .pixels import (  # noqa: F401
        PixelObservations,
        Target,
        parse_observations,
        parse_target,
        read_observations,
        read_target,
        write_observations,
        write_target,
    )
    from .simulation import Campaign, SimulationTruth, simulate  # noqa: F401

__all__ = sorted(_LAZY)
