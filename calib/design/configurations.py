"""Joint configurations as CSV: what ``calib design`` writes and ``--configs-file`` reads.

One header line with the chain's joint names (URDF names, any order; ``joint:NAME`` for a joint
named like another column; a chain through mimic joints needs its independent joints, and
its followers' columns, if there, must follow them: :mod:`calib.measurements.joint_columns`),
then one row per configuration: joint positions [rad for revolute and continuous joints, m
for prismatic ones]. Other columns are ignored, so a measurement CSV is a configurations
file too; blank lines are skipped; numbers follow the measurement CSV's strict grammar, and a
value far outside its joint limits is an error naming its row and column (as in
:mod:`calib.measurements.csvfile`).

A tree's measurement file (a ``tool`` column) holds one row per tool at each configuration:
consecutive rows with the same joint positions are one configuration there. A camera's
observations (OBS.csv: ``camera``, ``point``, ``u``, ``v`` columns) hold one row per pixel:
each posture counts once there, in the order it first appears (the cameras' rows follow one
another).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..core.fileio import csv_text
from ..exceptions import DataError, warn_user
from ..kinematics.robot import Chain
from ..kinematics.standing import JointReadings
from ..kinematics.tree import Tree
from ..measurements.csvfile import csv_records, parse_number, read_data_text
from ..measurements.data import JOINT_PREFIX, TOOL_COLUMN, DataWarning
from ..measurements.joint_columns import (
    check_followers,
    column_keys,
    follower_names,
    no_joint_of,
)
from ..measurements.limits import check_limits
from ..measurements.pixels import OBSERVATION_COLUMNS
from ..measurements.unseen import left_blank

_MAX_CONFIGS_BYTES = 256 << 20
"""Largest configurations file read [B] (a million configurations of 20 joints fit)."""


def parse_configurations(text: str, chain: Chain | Tree, source: str = "<text>") -> np.ndarray:
    """Joint positions ``(m, n)`` from CSV text, columns in chain order.

    The joint columns are read as in every calib file
    (:mod:`calib.measurements.joint_columns`): ``joint:NAME`` for a joint named like another
    column, the independent joints of a robot through mimic joints, and its followers' columns
    (optional) checked against their leaders. With a ``tool`` column, consecutive rows of equal
    joint positions count once.

    Raises:
        DataError: A missing or duplicate joint column, a bad cell, a follower that does not
            follow, a value far outside its joint limits, or no row.
    """
    records = csv_records(text, source)
    first = next(records, None)
    if first is None:
        raise DataError(source, "empty file: expected a header line of joint names and rows")
    line, cells = first
    header = [c.strip() for c in cells]
    keys = column_keys(header, (*chain.variable_names, *follower_names(chain)))
    for name in (*chain.variable_names, *follower_names(chain)):
        if keys.count(JOINT_PREFIX + name) > 1:
            raise DataError(source, "duplicate column", row=line, column=name)
    leaders = _leaders(chain, keys)
    for name in leaders:
        if JOINT_PREFIX + name not in keys:
            missing = DataError(source, "missing joint column", row=line, column=name)
            raise no_joint_of(chain, header, source, line) or missing
    read = [*leaders, *(n for n in follower_names(chain) if JOINT_PREFIX + n in keys)]
    read = list(dict.fromkeys(read))
    cols = [keys.index(JOINT_PREFIX + n) for n in read]
    rows: list[list[float]] = []
    lines: list[int] = []
    for line, cells in records:
        if len(cells) != len(header):
            raise DataError(source, f"expected {len(header)} cells, found {len(cells)}", row=line)
        rows.append([parse_number(cells[c], source, line, header[c]) for c in cols])
        lines.append(line)
    if not rows:
        raise DataError(source, "no configuration rows after the header")
    table = np.array(rows)
    v = len(leaders)
    leading = table[:, :v]
    if leaders == chain.joint_names and chain.coupling is not None:
        leading = chain.coupling.variables(leading)  # each variable from a joint it drives
    q = chain.joint_values(leading)
    given = dict(zip(read, table.T, strict=True))
    check_followers(
        chain, q, {n: given[n] for n in follower_names(chain) if n in given}, source, lines
    )
    check_limits(chain, q, source, np.array(lines), warn=False)
    if TOOL_COLUMN in header:  # a tree's measurements: one row per tool and configuration
        q = q[np.r_[True, np.any(q[1:] != q[:-1], axis=1)]]
    elif set(OBSERVATION_COLUMNS) <= set(header):  # pixels: one row per point seen
        q = q[np.sort(np.unique(q, axis=0, return_index=True)[1])]
    return q


def _leaders(chain: Chain | Tree, keys: list[str]) -> tuple[str, ...]:
    """The joints whose columns give a configuration.

    Every joint when the file has them all (``calib design`` writes those; a master outside
    the chain is then read from a joint it drives), else the independent joints (``calib
    simulate`` writes those).
    """
    if all(JOINT_PREFIX + n in keys for n in chain.joint_names):
        return tuple(chain.joint_names)
    return tuple(chain.variable_names)


def read_configurations(path: str | Path, chain: Chain | Tree) -> np.ndarray:
    """Read a configurations CSV file: the joint positions of each configuration.

    The file has one header line naming the chain's joints (URDF names, any order; other columns are
    ignored, so a measurement CSV is a configurations file too), then one row of joint positions per
    configuration. A tree's measurement file (a ``tool`` column) and a camera's observations
    (OBS.csv) give each configuration once. The module ``calib.design.configurations`` has the whole
    format.

    Args:
        path: The CSV file (what ``calib design`` writes).
        chain: The chain or tree the configurations are for (joint names and limits).

    Returns:
        The joint positions ``(m, n)``, joints in chain order [rad for revolute and
        continuous joints, m for prismatic ones].

    Raises:
        DataError: The file is missing or unreadable, a joint column is missing or
            duplicated, a cell is not a number, a row has the wrong length, there is no row,
            or a value is far outside its joint limits.
    """
    return read_chains_configurations(path, (chain,))[0]


def read_chains_configurations(
    path: str | Path, chains: Sequence[Chain | Tree]
) -> list[np.ndarray]:
    """Each chain's joint positions ``(m, n)`` from one configurations file, read once.

    Raises:
        DataError: The file is missing, unreadable or invalid for a chain.
    """
    text = read_data_text(path, _MAX_CONFIGS_BYTES)
    return [parse_configurations(text, chain, str(path)) for chain in chains]


def read_readings(path: str | Path, names: tuple[str, ...]) -> JointReadings | None:
    """The columns of ``names`` (joints off the chain) a configurations file has, or None.

    Raises:
        DataError: The file is unreadable, or a cell of those columns is not a number.
    """
    src = str(path)
    records = list(csv_records(read_data_text(path, _MAX_CONFIGS_BYTES), src))
    header = [c.strip() for c in records[0][1]] if records else []
    found = tuple(n for n in names if header.count(n) == 1)
    if 0 < len(found) < len(names):  # none: the model's own warning says so
        missing = [n for n in names if n not in found]
        warn_user(
            f"{src}: no column for {len(missing)} of the {len(names)} joints off the chain the "
            f"fit read ({', '.join(missing[:3])}{', ...' if len(missing) > 3 else ''}): they are "
            f"at their neutral positions",
            DataWarning,
        )
    if not found:
        return None
    cols = [header.index(n) for n in found]
    values = [
        [parse_number(cells[c], src, line, header[c]) for c in cols]
        for line, cells in records[1:]
        if len(cells) == len(header)
    ]
    return JointReadings(found, np.array(values, dtype=float).reshape(-1, len(found)))


def recorded_off_chain(path: str | Path, chain: Chain) -> JointReadings | None:
    """The joints off the chain a configurations file records, or None (no such column).

    Its columns named like a one-degree-of-freedom joint of the URDF that is not on the chain
    (a recorded touch's other arm, legs and head); the URDF's other joints are not read.

    Raises:
        DataError: The file is unreadable, or a cell of those columns is not a number.
    """
    model = chain.model
    header = _header(path)
    names = tuple(
        n
        for n in header
        if n not in chain.joint_names
        and model.existJointName(n)
        and model.joints[model.getJointId(n)].nv == 1
    )
    return read_readings(path, names) if names else None


def _header(path: str | Path) -> list[str]:
    """The cells of a file's header line (none for an empty file)."""
    first = next(csv_records(read_data_text(path, _MAX_CONFIGS_BYTES), str(path)), None)
    return [] if first is None else [c.strip() for c in first[1]]


def points_in_file(path: str | Path, chain: Chain | Tree) -> int:
    """The number of points a measurement file's header measures (0: a configurations file).

    K for ``x1, y1, z1`` to ``xK, yK, zK``, 1 for ``x, y, z``, 0 without them; the chain's
    joint columns are not read as points.

    Raises:
        DataError: The file is unreadable.
    """
    joints = set(chain.joint_names)
    free = {c for c in _header(path) if c not in joints and not c.startswith(JOINT_PREFIX)}
    k = 0
    while all(f"{a}{k + 1}" in free for a in "xyz"):
        k += 1
    return k or int(all(a in free for a in "xyz"))


def markers_seen(path: str | Path, chain: Chain | Tree) -> np.ndarray | None:
    """Which of a measurement file's points each row sees ``(m, K)``, None: every one.

    A point's ``x, y, z`` cells all empty (or ``NaN``) in a row: not seen there (an occluded marker,
    :mod:`calib.measurements.unseen`); a file of a tree's tools (a ``tool`` column) or of no
    point: None.

    Raises:
        DataError: The file is unreadable.
    """
    k = points_in_file(path, chain)
    records = csv_records(read_data_text(path, _MAX_CONFIGS_BYTES), str(path))
    header = [c.strip() for c in next(records)[1]]
    if not k or TOOL_COLUMN in header:
        return None
    names = [f"{a}{i + 1}" for i in range(k) for a in "xyz"] if "x1" in header else list("xyz")
    index = [header.index(n) for n in names]
    seen = [
        [not all(map(left_blank, (cells[j] for j in index[3 * i : 3 * i + 3]))) for i in range(k)]
        for _, cells in records
    ]
    return None if all(map(all, seen)) else np.array(seen)


def configurations_csv(
    chain: Chain | Tree, q: np.ndarray, readings: JointReadings | None = None
) -> str:
    """CSV text of configurations ``(m, n)``: the chain's joint names, full precision.

    With ``readings``, the joints off the chain follow, a row per configuration.
    """
    q = np.atleast_2d(q)
    if readings is not None:
        q = np.hstack([q, readings.values])
    header = [*chain.joint_names, *(() if readings is None else readings.names)]
    return csv_text(header, ([repr(float(v)) for v in row] for row in q))


__all__ = [
    "configurations_csv",
    "markers_seen",
    "parse_configurations",
    "points_in_file",
    "read_chains_configurations",
    "read_configurations",
    "read_readings",
    "recorded_off_chain",
]
