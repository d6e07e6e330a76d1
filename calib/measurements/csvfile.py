"""Measurement campaigns: the CSV format and its validation (simulation: :mod:`.simulation`).

The value read is :class:`~.data.Measurements`; its checks against the chain are in
:mod:`.limits`, the CSV records and numbers every calib CSV shares in :mod:`.csv_text` (their
names are re-exported here, where they were first).

CSV format (one header line, then one row per configuration; comma separated):

* one column per joint of the chain, named as the URDF joint, holding the URDF joint
  position [rad for revolute and continuous joints, m for prismatic ones]; a chain with
  mimic joints has one column per *independent* joint (:attr:`Chain.variable_names`: a
  mimic joint's position is computed from its master's, whose column it needs, in the
  chain or not; a mimic joint's own column may be there too, and must follow its master:
  :mod:`.joint_columns`);
* ``x, y, z``: the measured point in the measurement frame [m], each within
  ``MAX_COORDINATE`` (1 km) of its origin;
* for pose measurements also ``qx, qy, qz, qw``: the orientation of the tool frame in the
  measurement frame as a quaternion, scalar last (normalised on reading).

A joint named like a measurement column (``x``, ``qw``, ``tool``) is written
``joint:NAME``; on reading, ``joint:NAME`` is joint NAME's column, and a plain ``NAME`` is then
the measurement column (without ``joint:NAME``, a plain ``NAME`` is the joint's).

Columns may come in any order; blank lines are skipped. Errors name the row the way a
text editor or spreadsheet numbers it (the header is row 1) and the column by its name.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.checks import MAX_ROWS, check_size, read_only
from ..core.choices import MARKERS, ORIENTATION_FORMATS, UNITS, checked_points
from ..core.fileio import csv_text, read_failure, read_text_limited, write_atomic
from ..exceptions import DataError, InvalidArgumentError, warn_user
from ..kinematics.robot import Chain, check_robot
from ..kinematics.so3 import matrix_to_quaternion, rotation_matrix, rpy_to_matrix
from ..kinematics.tree import Tree
from . import marker_set
from .csv_text import NUMBER, csv_records, header_names, parse_number
from .data import (
    JOINT_PREFIX,
    MAX_COORDINATE,
    POSITION_COLUMNS,
    QUATERNION_COLUMNS,
    TOOL_COLUMN,
    Angles,
    DataWarning,
    Measurements,
)
from .joint_columns import check_followers, column_keys, follower_names, no_joint_of
from .limits import (
    LIMIT_MARGIN,
    LIMIT_TOL,
    check_against_chain,
    check_limits,
    check_tools,
    joint_bounds,
    tool_frames,
)
from .unseen import check_every_marker_seen, marker_cells

__all__ = [
    "DEFAULT_ORIENTATION_COLUMNS",
    "JOINT_PREFIX",
    "LIMIT_MARGIN",
    "LIMIT_TOL",
    "MAX_COORDINATE",
    "MAX_MEASUREMENTS_BYTES",
    "NAMED_ORIENTATION",
    "POSITION_COLUMNS",
    "QUATERNION_COLUMNS",
    "TOOL_COLUMN",
    "Angles",
    "Columns",
    "DataWarning",
    "Measurements",
    "check_against_chain",
    "check_limits",
    "csv_records",
    "joint_bounds",
    "measurements_csv",
    "parse_measurements",
    "parse_number",
    "read_data_text",
    "read_measurements",
    "tool_frames",
    "write_measurements",
]


MAX_MEASUREMENTS_BYTES = 256 << 20
"""Largest measurement or validation CSV read [B] (a million rows of 20 joints and a pose)."""


DEFAULT_ORIENTATION_COLUMNS = {
    "quat-xyzw": QUATERNION_COLUMNS,
    "quat-wxyz": ("qw", "qx", "qy", "qz"),
    "rotvec": ("rx", "ry", "rz"),
    "rpy": ("roll", "pitch", "yaw"),
}
"""Column names of each orientation format, in the order the format reads them."""

NAMED_ORIENTATION = ", or name its format and columns"
"""The last clause of the columns-ignored warning: an orientation read under other names (the
command line's ``--term`` reads the default names alone, and cuts it)."""


CHUNK = 4096
"""Rows of a measurement file parsed at once."""


@dataclass(frozen=True)
class Columns:
    """How a measurement CSV is read.

    Attributes:
        orientation: ``auto`` (from the column names: qx..qw, rx..rz or roll, pitch, yaw;
            none: position only), one of ``ORIENTATION_FORMATS``, or ``markers``: K >= 3
            points of one rigid set read as a pose, marker 1's position and the set's
            orientation (:mod:`!calib.measurements.marker_set`).
        orientation_columns: Column names of the orientation, in the format's order
            (default: the format's names, see ``DEFAULT_ORIENTATION_COLUMNS``).
        units: Unit of the position columns, ``m`` or ``mm``.
        points: The measured points to read, by their number in the file (1 for
            ``x1, y1, z1`` or ``x, y, z``), in this order: ``(1,)`` reads point 1 alone,
            ``(1, 3)`` points 1 and 3 as markers 1 and 2 (default None: every point). The
            other points' columns are not read.
    """

    orientation: str = "auto"
    orientation_columns: tuple[str, ...] | None = None
    units: str = "m"
    points: tuple[int, ...] | None = None

    def __post_init__(self) -> None:
        if self.points is not None:
            object.__setattr__(self, "points", checked_points(self.points))
        if self.orientation not in ("auto", MARKERS, *ORIENTATION_FORMATS):
            raise InvalidArgumentError(
                f"unknown orientation format '{self.orientation}': choose auto, markers or "
                f"{', '.join(ORIENTATION_FORMATS)}"
            )
        if self.units not in UNITS:
            raise InvalidArgumentError(f"unknown units '{self.units}': choose {', '.join(UNITS)}")
        cols = self.orientation_columns
        if cols is not None:
            if self.orientation in ("auto", MARKERS):
                raise InvalidArgumentError("orientation columns need an orientation format")
            want = len(DEFAULT_ORIENTATION_COLUMNS[self.orientation])
            if len(cols) != want or len(set(cols)) != len(cols):
                raise InvalidArgumentError(
                    f"{self.orientation} needs {want} distinct orientation columns, got "
                    f"{', '.join(cols)}"
                )


def _point_columns(names: list[str], src: str, line: int) -> list[str]:
    """Every position column of a header: ``x, y, z`` or ``x1, y1, z1, ..., xK, yK, zK``.

    ``names``: the cells' meanings, joints prefixed (see :func:`.joint_columns.column_keys`).
    """
    free = [n for n in names if not n.startswith(JOINT_PREFIX)]
    if all(f"{a}1" in free for a in POSITION_COLUMNS):
        k = 1
        while all(f"{a}{k + 1}" in free for a in POSITION_COLUMNS):
            k += 1
        return [f"{a}{i + 1}" for i in range(k) for a in POSITION_COLUMNS]
    if all(a in free for a in POSITION_COLUMNS):
        return list(POSITION_COLUMNS)
    missing = next(a for a in POSITION_COLUMNS if a not in free)
    raise DataError(
        src,
        "missing position column: expected x, y, z (one marker) or x1, y1, z1, ..., xK, yK, zK",
        row=line,
        column=missing,
    )


def _layout(names: list[str], chain: Chain | Tree, columns: Columns, src: str, line: int):
    """Position columns (K triples) and the orientation format and columns of a header.

    ``names``: the cells' meanings, joints prefixed (see :func:`.joint_columns.column_keys`).
    The position columns are those of the chosen points (``columns.points``).
    """
    free = [n for n in names if not n.startswith(JOINT_PREFIX)]
    pos = _chosen_points(_point_columns(names, src, line), columns.points, src, line)
    fmt: str | None
    fmt, cols = columns.orientation, columns.orientation_columns
    if fmt == MARKERS:
        if len(pos) < 3 * marker_set.MIN_MARKERS:
            raise DataError(
                src,
                f"orientation 'markers' needs x1..z{marker_set.MIN_MARKERS} or more points "
                f"of one rigid set, {'the header has' if columns.points is None else 'chosen:'} "
                f"{len(pos) // 3}",
                row=line,
            )
        return pos, fmt, ()
    if fmt == "auto":
        fmt = next(
            (
                f
                for f in ("quat-xyzw", "rotvec", "rpy")
                if any(c in free for c in DEFAULT_ORIENTATION_COLUMNS[f])
            ),
            None,
        )
    if fmt is not None:
        cols = cols or DEFAULT_ORIENTATION_COLUMNS[fmt]
        joints = set(chain.variable_names)  # a joint column without the prefix: not free
        taken = [c for c in cols if c in pos or (c in joints and c not in free)]
        if taken:
            raise InvalidArgumentError(
                f"orientation column '{taken[0]}' is also a "
                f"{'position' if taken[0] in pos else 'joint'} column: name other columns "
                f"(Columns' orientation_columns)"
            )
        for c in cols:
            if c not in free:
                raise DataError(
                    src,
                    f"missing orientation column ({fmt}: {', '.join(cols)})",
                    row=line,
                    column=c,
                )
    return pos, fmt, tuple(cols or ())


def _chosen_points(pos: list[str], points: tuple[int, ...] | None, src: str, line: int):
    """The position columns of the chosen points (all without a choice), in the choice's order.

    Raises:
        DataError: A chosen point is not in the file.
    """
    if points is None:
        return pos
    k = len(pos) // 3
    missing = next((p for p in points if p > k), None)
    if missing is not None:
        has = "x, y, z: one point" if k == 1 else f"x1, y1, z1 to x{k}, y{k}, z{k}: {k} points"
        raise DataError(src, f"point {missing} is not in the file (its header has {has})", row=line)
    return [pos[3 * (p - 1) + a] for p in points for a in range(3)]


def _joint_keys(chain: Chain | Tree) -> set[str]:
    """The keys of the joint columns read: the independent joints' and the followers'."""
    return {JOINT_PREFIX + n for n in (*chain.variable_names, *follower_names(chain))}


def _header(cells: list[str], chain: Chain | Tree, columns: Columns, src: str, line: int):
    """Validate the header: column names, position columns, orientation format and columns."""
    names = header_names(cells, src, line)
    keys = column_keys(names, (*chain.variable_names, *follower_names(chain)))
    for name in chain.variable_names:
        if JOINT_PREFIX + name not in keys:
            tools = ", ".join(chain.tool_frames)
            raise no_joint_of(chain, names, src, line) or DataError(
                src,
                f"missing joint column: the chain {chain.base_frame} -> {tools} moves that joint "
                "(its base and tool frames choose the joints read)",
                row=line,
                column=name,
            )
    pos, fmt, ori = _layout(keys, chain, columns, src, line)
    every = _point_columns(keys, src, line)  # the points not chosen are not "ignored"
    used = {*_joint_keys(chain), *pos, *every, *ori, TOOL_COLUMN}
    ignored = [n for n, k in zip(names, keys, strict=True) if k not in used]
    if ignored:
        warn_user(
            f"{src}: columns ignored (not joints of the chain, positions, orientation or tool): "
            f"{', '.join(ignored)}{_orientation_hint(ignored) if fmt is None else ''}",
            DataWarning,
        )
    return keys, pos, fmt, ori, names


def _orientation_hint(ignored: list[str]) -> str:
    """How to read an orientation under other names, when 3 ignored columns are named alike.

    Alike but for x, y and z (``phix1, phiy1, phiz1``); none for others (a log's time stamps).
    """
    triple = next((t for n in ignored for t in _axes_of(n) if set(t) <= set(ignored)), ())
    if not triple:
        return ""
    names = "; ".join(f"{f}: {' '.join(c)}" for f, c in DEFAULT_ORIENTATION_COLUMNS.items())
    return (
        f"; if 3 or 4 of them are an orientation, rename them as its format reads them ({names})"
        f"{NAMED_ORIENTATION}, e.g. --orientation rpy --orientation-columns {' '.join(triple)} "
        f"(Python: Columns(FORMAT, COLUMNS); formats: {', '.join(ORIENTATION_FORMATS)})"
    )


def _axes_of(name: str) -> list[tuple[str, ...]]:
    """The x, y and z columns ``name`` may be one of: each of its ``x`` (or ``X``) replaced.

    ``xsens_rx``: ``(xsens_rx, ysens_rx, zsens_rx)`` and ``(xsens_rx, xsens_ry, xsens_rz)``.
    """
    return [
        tuple(name[:i] + a + name[i + 1 :] for a in ("xyz" if c == "x" else "XYZ"))
        for i, c in enumerate(name)
        if c in "xX"
    ]


def _orientation(values: np.ndarray, fmt: str, src: str, lines: list[int]) -> np.ndarray:
    """Quaternions (x, y, z, w) from orientation columns in a format."""
    if fmt in ("quat-xyzw", "quat-wxyz"):
        quat = values if fmt == "quat-xyzw" else values[:, [1, 2, 3, 0]]
        big = np.max(np.abs(quat), axis=1)
        zero = big * np.linalg.norm(quat / np.where(big > 0, big, 1.0)[:, None], axis=1) < 1e-12
        if np.any(zero):
            raise DataError(src, "the quaternion has zero norm", row=lines[int(np.argmax(zero))])
        return quat
    if np.any(np.abs(values) > 1e3):
        i = int(np.argmax(np.any(np.abs(values) > 1e3, axis=1)))
        raise DataError(src, "an orientation angle beyond 1000 rad", row=lines[i])
    R = rotation_matrix(values) if fmt == "rotvec" else rpy_to_matrix(values)
    return matrix_to_quaternion(R)


def parse_measurements(
    text: str,
    chain: Chain | Tree,
    source: str = "<text>",
    columns: Columns | None = None,
    path: str | None = None,
) -> Measurements:
    """Parse and validate the text of a measurement CSV: joint positions and measured points.

    The format is :func:`read_measurements`'s.

    Args:
        text: The CSV content.
        chain: The chain the data belongs to (joint names and limits).
        source: Name of the data in messages (a file path).
        columns: How to read positions and orientations (default: metres, orientation
            format from the column names).
        path: The file read, resolved (:func:`read_measurements`), or None.

    Returns:
        The measurements, joints in chain order, positions in metres.

    Raises:
        DataError: Missing or duplicate column, a row of the wrong length, an empty,
            non-numeric or non-finite cell, a joint value far outside its limits, a measured
            coordinate beyond ``MAX_COORDINATE`` [m], a zero quaternion, or no data row.
    """
    check_robot(chain, "chain")
    columns = Columns() if columns is None else columns
    if not isinstance(columns, Columns):
        raise InvalidArgumentError(f"columns must be a Columns (or None), got {columns!r:.60}")
    header, values, lines, tools = _read_rows(text, chain, columns, source)
    check_size(len(values), MAX_ROWS, "rows", source)
    names, pos_cols, fmt, ori_cols, _ = header
    table = values
    col = {n: j for j, n in enumerate(names)}
    q = chain.joint_values(table[:, [col[JOINT_PREFIX + n] for n in chain.variable_names]])
    followers = {
        n: table[:, col[JOINT_PREFIX + n]] for n in follower_names(chain) if JOINT_PREFIX + n in col
    }
    check_followers(chain, q, followers, source, lines)
    check_limits(chain, q, source, np.array(lines), warn=False)
    position = table[:, [col[n] for n in pos_cols]] * UNITS[columns.units]
    _check_coordinates(position, pos_cols, lines, source, columns.units)
    check_every_marker_seen(position, pos_cols, source, lines if fmt == MARKERS else None)
    quat, angles = None, None
    if fmt == MARKERS:
        position, quat = _marker_set(position, source, lines)
    elif fmt is not None:
        ori = table[:, [col[n] for n in ori_cols]]
        quat = _orientation(ori, fmt, source, lines)
        angles = Angles(fmt, read_only(ori)) if fmt in ("rotvec", "rpy") else None
    data = Measurements(
        chain.joint_names,
        q,
        position,
        quat,
        source,
        tuple(lines),
        tuple(tools) or None,
        chain.coupling,
        angles,
        path,
    )
    check_tools(data, tool_frames(chain))
    _warn_repeats(data)
    return data


def _read_rows(text: str, chain: Chain | Tree, columns: Columns, source: str):
    """The header, the rows' numbers ``(m, cells)``, their line numbers and tool names.

    Rows are parsed :data:`CHUNK` at a time (no Python object per cell is kept).
    """
    header = None
    table: list[np.ndarray] = []
    lines: list[int] = []
    tools: list[str] = []
    chunk: list[tuple[int, list[str]]] = []
    for line, cells in csv_records(text, source):
        if header is None:
            header = _header(cells, chain, columns, source, line)
            continue
        chunk.append((line, cells))
        if len(chunk) == CHUNK:
            table.append(_chunk_values(chunk, header, chain, source, tools))
            lines += [n for n, _ in chunk]
            chunk = []
    if header is None:
        raise DataError(source, "empty file: expected a header line and measurement rows")
    if chunk:
        table.append(_chunk_values(chunk, header, chain, source, tools))
        lines += [n for n, _ in chunk]
    if not lines:
        raise DataError(source, "no measurement rows after the header")
    return header, np.concatenate(table), lines, tools


def _chunk_values(chunk, header, chain, source: str, tools: list[str]) -> np.ndarray:
    """The numbers of some rows ``(rows, cells)`` (0 in unused cells); their tools appended.

    Valid rows are parsed at once; otherwise row by row, which raises the first row's
    error (the same error, row and column as if every row were parsed alone).
    """
    keys, shown = header[0], header[4]
    used = {*_joint_keys(chain), *header[1], *header[3]}
    numbers = [j for j, k in enumerate(keys) if k in used]
    at = keys.index(TOOL_COLUMN) if TOOL_COLUMN in keys else None
    whole = [cells for _, cells in chunk if len(cells) == len(keys)]
    names = [] if at is None else [cells[at].strip() for cells in whole]
    texts = [cells[j].strip() for cells in whole for j in numbers]
    values = np.zeros((len(chunk), len(keys)))
    if len(whole) == len(chunk) and all(names) and all(map(NUMBER.fullmatch, texts)):
        parsed = np.fromiter(map(float, texts), dtype=float, count=len(texts))
        if np.all(np.isfinite(parsed)):
            values[:, numbers] = parsed.reshape(len(chunk), len(numbers))
            tools += names
            return values
    points = [keys.index(k) for k in header[1]]
    others = [j for j in numbers if keys[j] not in header[1]]
    for i, (line, cells) in enumerate(chunk):  # row by row: the first error, named
        if len(cells) != len(keys):
            raise DataError(source, f"expected {len(keys)} cells, found {len(cells)}", row=line)
        if at is not None and not cells[at].strip():
            raise DataError(source, "empty cell", row=line, column=TOOL_COLUMN)
        for j in others:
            values[i, j] = parse_number(cells[j], source, line, shown[j])
        values[i, points] = marker_cells(cells, points, [shown[j] for j in points], source, line)
    tools += [] if at is None else [cells[at].strip() for _, cells in chunk]
    return values


MM_HINT = ": millimetres? read them with Columns(units='mm')"
"""The way out of coordinates too large in metres: the command line says ``--units mm``."""


def _check_coordinates(
    position: np.ndarray, names, lines: list[int], source: str, units: str
) -> None:
    """Refuse a measured coordinate beyond :data:`MAX_COORDINATE` [m] (its row and column).

    Millimetres read as metres or centimetres are named when every coordinate would fit in
    millimetres (a tracker a few metres away writes thousands).
    """
    far = np.abs(position) > MAX_COORDINATE
    if np.any(far):
        i, j = (int(v) for v in np.argwhere(far)[0])
        in_mm = np.nanmax(np.abs(position)) * UNITS["mm"] / UNITS[units] <= MAX_COORDINATE
        raise DataError(
            source,
            f"{position[i, j]:.9g} m is not a plausible measurement (coordinates are within "
            f"{MAX_COORDINATE:g} m){MM_HINT if units != 'mm' and in_mm else ''}",
            row=lines[i],
            column=names[j],
        )


def _warn_repeats(data: Measurements) -> None:
    """Warn when rows repeat an earlier row's joint positions (and tool): not independent."""
    key = data.q
    if data.tool is not None:
        key = np.column_stack([key, np.unique(np.array(data.tool), return_inverse=True)[1]])
    _, first = np.unique(key, axis=0, return_index=True)
    repeats = data.m - len(first)
    if repeats:
        row = int(np.flatnonzero(~np.isin(np.arange(data.m), first))[0])
        line = data.rows[row] if data.rows else row + 2
        warn_user(
            f"{data.source}: {repeats} of {data.m} rows repeat the joint positions of an "
            f"earlier row (first: row {line}): repeated configurations are not independent "
            f"measurements, the reported uncertainty is overconfident",
            DataWarning,
        )


def _marker_set(position: np.ndarray, src: str, lines) -> tuple[np.ndarray, np.ndarray]:
    """Marker 1's position and the orientation of a rigid set of K >= 3 markers.

    A set that is not rigid is warned about, with the row and marker farthest off it (an
    outlier, or two markers' labels swapped in that row).
    """
    pose = marker_set.marker_set_pose(position.reshape(len(position), -1, 3))
    if pose.flat < marker_set.MIN_FLATNESS:
        raise DataError(src, "the markers lie on a line: their set has no orientation")
    if pose.spread > marker_set.SPREAD_WARNING:
        warn_user(
            f"{src}: the markers move up to {1e3 * pose.spread:.3g} mm relative to each "
            f"other (row {lines[pose.worst[0]]}, marker {pose.worst[1] + 1}): they are not one "
            "rigid set, its orientation is a least-squares fit",
            DataWarning,
        )
    return position[:, :3], matrix_to_quaternion(pose.rotations)


def read_measurements(
    path: str | Path, chain: Chain | Tree, columns: Columns | None = None
) -> Measurements:
    """Read and validate a measurement CSV file: joint positions and measured points.

    One header line, then one row per configuration, columns in any order: one column per
    independent joint of the chain, named as the URDF joint [rad or m]; the measured point
    ``x, y, z`` (``x1, y1, z1``, ``x2, ...`` for several) [m, or ``columns.units``]; for a
    pose, the tool frame's orientation in the measurement frame (``qx, qy, qz, qw`` scalar
    last, or the format ``columns`` names); a tree's file adds a ``tool`` column. A joint
    named like a measurement column is written ``joint:NAME``. The module
    ``calib.measurements.csvfile`` has the long form.

    Args:
        path: The CSV file.
        chain: The chain the data belongs to (joint names and limits).
        columns: How to read positions and orientations (see :class:`Columns`).

    Returns:
        The measurements, joints in chain order.

    Raises:
        DataError: The file is missing, unreadable, not UTF-8 or larger than
            :data:`!MAX_MEASUREMENTS_BYTES`, or its content is invalid (see
            :func:`!parse_measurements`).
    """
    text = read_data_text(path)
    return parse_measurements(text, chain, str(path), columns, str(Path(path).resolve()))


def read_data_text(path: str | Path, limit: int | None = None) -> str:
    """A data file's text, at most ``limit`` bytes [B] (default: :data:`MAX_MEASUREMENTS_BYTES`).

    Raises:
        DataError: The file is missing, unreadable, not UTF-8 or larger than ``limit``.
    """
    try:
        return read_text_limited(path, MAX_MEASUREMENTS_BYTES if limit is None else limit)
    except OSError as exc:
        raise DataError(str(path), read_failure(exc)) from None


_SIMULATION = ("Campaign", "SimulationTruth", "simulate")
"""Names that moved to :mod:`.simulation`, still found here (imported when asked for)."""


def __getattr__(name: str):
    if name in _SIMULATION:
        from . import simulation  # only when asked: reading a CSV does not need it

        return getattr(simulation, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def measurements_csv(data: Measurements) -> str:
    """The CSV text of measurements, full precision (``repr`` of every float)."""
    cells = (
        [*(repr(float(v)) for v in row), *(() if tool is None else (tool,))]
        for row, tool in itertools.zip_longest(data.table(), data.tool or ())
    )
    return csv_text(data.columns, cells)


def write_measurements(path: str | Path, data: Measurements) -> None:
    """Write measurements as CSV atomically (the file is complete or not written at all).

    Args:
        path: The CSV file to write (replaced if it exists).
        data: The measurements, written as :func:`read_measurements` reads them back.

    Raises:
        InvalidArgumentError: ``data`` is no :class:`Measurements`, or ``path`` no path.
        OutputError: The file cannot be written.
    """
    if not isinstance(data, Measurements):
        raise InvalidArgumentError(f"data must be Measurements, got {data!r:.60}")
    write_atomic(path, measurements_csv(data))
