"""Which columns of a CSV header hold a robot's joints: the one reading every file shares.

Measurement, contact and configuration files name their joint columns alike:

* a joint named like another column of the file (``x``, ``qw``, ``tool``, ``plane``,
  ``point``) is written ``joint:NAME``; on reading, ``joint:NAME`` is joint NAME's column and a
  plain ``NAME`` is then the other column (without ``joint:NAME``, a plain ``NAME`` is the
  joint's);
* a robot through mimic joints needs the columns of its independent joints
  (:attr:`~calib.kinematics.robot.CoupledJoints.variable_names`, what ``calib simulate``
  writes); a follower's column may be there too (``calib design`` writes every joint), and
  each of its values must then be what its mimic tag gives from its leader, within
  :data:`FOLLOWER_TOL`.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core.words import counted
from ..exceptions import DataError
from ..kinematics.robot import CoupledJoints, Robot
from .csv_text import csv_records, parse_number
from .data import JOINT_PREFIX

__all__ = [
    "FOLLOWER_TOL",
    "check_followers",
    "column_keys",
    "follower_names",
    "logged_joints",
    "no_joint_of",
]

FOLLOWER_TOL = 1e-6
"""Largest difference between a follower's column and its mimic relation [rad or m] (the
files calib writes hold them to round-off)."""


def column_keys(names: Sequence[str], joints: Sequence[str]) -> list[str]:
    """Each header cell's meaning: ``joint:NAME`` for a joint's column, else the cell.

    A joint's column is ``joint:NAME``, or plain ``NAME`` when the header has no ``joint:NAME``
    (then a plain ``NAME`` is another column: ``x``, ``qw``, ``tool``, ``plane``).
    """
    joint_set = set(joints)
    prefixed = {n[len(JOINT_PREFIX) :] for n in names if n.startswith(JOINT_PREFIX)} & joint_set
    return [JOINT_PREFIX + n if n in joint_set and n not in prefixed else n for n in names]


def logged_joints(
    text: str, source: str, joints: Sequence[str], lines: Sequence[int]
) -> dict[str, np.ndarray]:
    """The columns of some joints in a file's text, at its rows ``lines``: those it logs.

    What reading a campaign ignores (joints off its chain), read again. A joint is left out
    when the file has no column of it, or a row of ``lines`` holds no number in it.

    Raises:
        DataError: Text that is no CSV.
    """
    records = csv_records(text, source)
    header: list[str] = next(records, (0, []))[1]
    keys = column_keys([c.strip() for c in header], joints)
    at = {j: keys.index(JOINT_PREFIX + j) for j in joints if JOINT_PREFIX + j in keys}
    wanted = set(lines)
    cells = {line: row for line, row in records if line in wanted}
    out = {}
    for joint, k in at.items():
        try:
            out[joint] = np.array([parse_number(cells[n][k], source, n, joint) for n in lines])
        except (KeyError, IndexError, DataError):  # a row not there, or no number: not logged
            continue
    return out


def no_joint_of(robot: Robot, header: Sequence[str], source: str, row: int) -> DataError | None:
    """The error of a header with no column of the robot's joints (another robot's file), or None.

    A file of another robot or chain (the candidates of a Panda read for a UR10, the right
    arm's touches for the left arm) lacks every joint, not one: the error says so and shows
    the file's columns, instead of naming the first joint missing.
    """
    keys = column_keys(header, (*robot.variable_names, *follower_names(robot)))
    if any(JOINT_PREFIX + n in keys for n in robot.variable_names):
        return None
    ends = f"{robot.chains[0].base_frame} -> {', '.join(robot.tool_frames)}"
    joints = counted(len(robot.variable_names), "joints")
    theirs = ", ".join(header[:6]) + (", ..." if len(header) > 6 else "")
    return DataError(
        source,
        f"no joint column of {robot.name} {ends} (its {joints}: {robot.variable_names[0]}, "
        f"...); the file's columns: {theirs}: a file of another robot or chain?",
        row=row,
    )


def follower_names(robot: CoupledJoints) -> tuple[str, ...]:
    """The joints that follow another (mimic), whose columns are optional."""
    return () if robot.coupling is None else tuple(m.name for m in robot.coupling.mimic)


def check_followers(
    robot: CoupledJoints,
    q: np.ndarray,
    given: dict[str, np.ndarray],
    source: str,
    lines: Sequence[int],
) -> None:
    """Refuse a follower's column that does not follow its leader.

    Args:
        robot: The chain or tree.
        q: Joint positions ``(m, n)`` computed from the independent joints.
        given: The follower columns the file has, by joint name ``(m,)`` each.
        source: The file, for messages.
        lines: Each row's line number in the file.

    Raises:
        DataError: A value farther than :data:`FOLLOWER_TOL` from its mimic relation,
            naming its row and column and the relation.
    """
    if robot.coupling is None:
        return
    for mimic in robot.coupling.mimic:
        if mimic.name not in given:
            continue
        off = np.abs(given[mimic.name] - q[:, mimic.joint])
        if np.any(off > FOLLOWER_TOL):
            i = int(np.argmax(off))
            raise DataError(
                source,
                f"joint {mimic.name} = {given[mimic.name][i]:.9g} does not follow "
                f"{mimic.master}: its mimic tag gives {mimic.multiplier:g} * {mimic.master} + "
                f"{mimic.offset:g} = {q[i, mimic.joint]:.9g}",
                row=lines[i],
                column=mimic.name,
            )
