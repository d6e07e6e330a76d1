"""Measurements: joint positions and what was measured at them, one value.

The value a campaign is read into (:mod:`.csvfile`) or simulated as (:mod:`.simulation`):
joints, measured points and orientations, tools, and the names of their CSV columns.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..core.checks import read_only
from ..core.words import counted
from ..exceptions import InvalidArgumentError
from ..identification.measures import POSE, POSITION, Measurement, Observed
from ..kinematics.mimic import Coupling
from ..kinematics.so3 import (
    matrix_to_quaternion,
    quaternion_to_matrix,
    rotation_matrix,
    rpy_to_matrix,
)

__all__ = [
    "JOINT_PREFIX",
    "MAX_COORDINATE",
    "POSITION_COLUMNS",
    "QUATERNION_COLUMNS",
    "TOOL_COLUMN",
    "Angles",
    "DataWarning",
    "Measurements",
]


POSITION_COLUMNS = ("x", "y", "z")
"""Columns of the measured point [m] (one marker); markers 1..K use ``x1, y1, z1, ...``."""


MAX_COORDINATE = 1e3
"""Largest magnitude [m] of a measured coordinate: a point near a robot, not a kilometre away.

Larger values (a unit mix-up, a corrupt file) are rejected: squared in the residuals they
would overflow to infinity.
"""


QUATERNION_COLUMNS = ("qx", "qy", "qz", "qw")
"""Columns of the measured orientation, a quaternion with the scalar last."""


TOOL_COLUMN = "tool"
"""Column naming the tool frame a row measures (several tools of a tree; optional)."""


JOINT_PREFIX = "joint:"
"""A header cell ``joint:NAME`` is the column of joint NAME: how a joint named like a
measurement column (``x``, ``qw``, ``tool``) is told apart from that column."""


class DataWarning(UserWarning):
    """Data that are usable but unusual (readings past a joint limit, ignored columns)."""


def _unit_quaternions(quat: np.ndarray) -> np.ndarray:
    """Normalised quaternions; raise on a zero or non-finite one (overflow-safe norm)."""
    if not np.all(np.isfinite(quat)):
        raise InvalidArgumentError("quaternions must be finite and non-zero")
    # The norm of the quaternion scaled by its largest component first: (1e300, 0, 0,
    # 1e300) is a rotation too, and its plain norm overflows.
    big = np.max(np.abs(quat), axis=1)
    unit = quat / np.where(big > 0, big, 1.0)[:, None]
    if np.any(big * np.linalg.norm(unit, axis=1) < 1e-12):
        raise InvalidArgumentError("quaternions must be finite and non-zero")
    return unit / np.linalg.norm(unit, axis=1)[:, None]


def _finite_or_unseen(pos: np.ndarray) -> bool:
    """Every coordinate finite, but markers not seen: NaN in all 3 of a row's coordinates."""
    nan = np.isnan(pos)
    if not nan.any():
        return bool(np.all(np.isfinite(pos)))
    triples = nan.reshape(len(pos), -1, 3)
    whole = bool(np.all(triples == triples[..., :1]))
    return whole and bool(np.all(np.isfinite(pos[~nan])))


@dataclass(frozen=True, eq=False)
class Angles:
    """Orientation columns of a file in an angle format, as read (before any conversion).

    Kept so that the usual mistakes of such columns (degrees, the order of roll, pitch and
    yaw) can be tried on them (:mod:`!calib.calibration.diagnosis`).

    Attributes:
        format: ``rotvec`` or ``rpy``.
        values: The three columns ``(m, 3)`` [rad as read].
    """

    format: str
    values: np.ndarray

    def quaternions(self) -> np.ndarray:
        """The orientations they give, quaternions x, y, z, w ``(m, 4)``."""
        fn = rotation_matrix if self.format == "rotvec" else rpy_to_matrix
        return matrix_to_quaternion(fn(self.values))


@dataclass(frozen=True, eq=False)
class Measurements:
    """Measured tool points (and orientations) at joint configurations, a value object.

    Attributes:
        joint_names: URDF joint of each column of ``q``, base to tool.
        q: Joint positions ``(m, n)`` [rad or m].
        position: Measured points in the measurement frame ``(m, 3 K)`` [m]: x, y, z of
            marker 1, then of marker 2, ...; every coordinate within ``MAX_COORDINATE``. A
            marker not seen in a row (occluded) is NaN in its 3 coordinates there
            (:attr:`seen`): its rows are left out of every fit and error.
        quaternion: Measured tool orientation ``(m, 4)`` (qx, qy, qz, qw; unit norm), or
            None for position-only data.
        source: Where the data came from (a file path), for messages.
        rows: Row of each configuration in the source file (the header is row 1), or None.
        tool: The tool frame each row measures (the CSV's ``tool`` column), or None: the
            only tool.
        coupling: The chain's mimic relation, or None: the CSV then holds the independent
            joints (``coupling.names``) and ``q`` follows from them.
        angles: The orientation columns as read when they are angles (rpy, rotation
            vector), or None.
        path: The file read, resolved when it was read (absolute, links followed), or None
            (not read from a file): what ``Result.write`` never overwrites, wherever the
            working directory is then.
    """

    joint_names: tuple[str, ...]
    q: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray | None = None
    source: str = "<measurements>"
    rows: tuple[int, ...] | None = None
    tool: tuple[str, ...] | None = None
    coupling: Coupling | None = None
    angles: Angles | None = None
    path: str | None = None

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        m = q.shape[0]
        pos = np.asarray(self.position, dtype=float)
        if q.ndim != 2 or q.shape[1] != len(self.joint_names) or m == 0:
            raise InvalidArgumentError(
                f"joint positions must have shape (m >= 1, {len(self.joint_names)}), got "
                f"{np.shape(self.q)}"
            )
        if pos.ndim == 3 and pos.shape[0] == m and pos.shape[2] == 3:
            pos = pos.reshape(m, -1)
        if pos.ndim != 2 or pos.shape[0] != m or pos.shape[1] % 3 or pos.shape[1] == 0:
            raise InvalidArgumentError(
                f"positions must have shape ({m}, 3 K) or ({m}, K, 3), got "
                f"{np.shape(self.position)}"
            )
        if not (np.all(np.isfinite(q)) and _finite_or_unseen(pos)):
            raise InvalidArgumentError(
                "measurements contain NaN or infinity (a marker not seen: NaN in its x, y and z)"
            )
        blind = np.all(np.isnan(pos), axis=1)
        if np.any(blind):
            raise InvalidArgumentError(
                f"configuration {int(np.argmax(blind)) + 1} sees no marker: every row "
                "measures at least one"
            )
        if np.any(np.abs(pos) > MAX_COORDINATE):
            i, j = (int(v) for v in np.argwhere(np.abs(pos) > MAX_COORDINATE)[0])
            raise InvalidArgumentError(
                f"measured {POSITION_COLUMNS[j % 3]} = {pos[i, j]:.9g} (configuration {i + 1}) "
                f"is not a plausible measurement in metres: coordinates are within "
                f"{MAX_COORDINATE:g} m"
            )
        if self.quaternion is not None:
            quat = np.asarray(self.quaternion, dtype=float)
            if quat.shape != (m, 4):
                raise InvalidArgumentError(
                    f"quaternions must have shape ({m}, 4), got {quat.shape}"
                )
            object.__setattr__(self, "quaternion", read_only(_unit_quaternions(quat)))
        if self.angles is not None and (
            self.quaternion is None or np.shape(self.angles.values) != (m, 3)
        ):
            raise InvalidArgumentError(f"angles must give 3 values per orientation ({m})")
        if self.rows is not None and len(self.rows) != m:
            raise InvalidArgumentError(f"rows must give one row number per configuration ({m})")
        if self.tool is not None:
            if len(self.tool) != m or not all(isinstance(t, str) and t for t in self.tool):
                raise InvalidArgumentError(f"tool must give one tool frame name per row ({m})")
            object.__setattr__(self, "tool", tuple(self.tool))
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "q", read_only(q))
        object.__setattr__(self, "position", read_only(pos))
        if self.rows is not None:
            object.__setattr__(self, "rows", tuple(int(r) for r in self.rows))

    def __repr__(self) -> str:
        """One line (the arrays are in the attributes)."""
        tools = "" if self.tool is None else f", tools {', '.join(dict.fromkeys(self.tool))}"
        return (
            f"<Measurements {self.source}: {self.m} rows of {len(self.joint_names)} joints, "
            f"{self.kind.label}, {counted(self.n_markers, 'markers')}{tools}>"
        )

    @property
    def m(self) -> int:
        """Number of configurations (rows)."""
        return self.q.shape[0]

    @property
    def n_markers(self) -> int:
        """Number of points K measured per configuration."""
        return self.position.shape[1] // 3

    @cached_property
    def seen(self) -> np.ndarray:
        """Whether each marker was seen in each row ``(m, K)`` (read only)."""
        seen = ~np.isnan(self.position[:, ::3])
        seen.setflags(write=False)
        return seen

    @cached_property
    def partial(self) -> bool:
        """Whether some marker was not seen in some row (partial marker rows)."""
        return not bool(self.seen.all())

    def seen_rows(self, width: int) -> np.ndarray | None:
        """Which of ``width`` residual rows per row were measured ``(m, width)``, None: all.

        A marker's 3 rows are those of :attr:`seen`; the rows past them (orientation): all.
        """
        if not self.partial:
            return None
        rows = np.ones((self.m, width), dtype=bool)
        rows[:, : self.position.shape[1]] = np.repeat(self.seen, 3, axis=1)
        return rows

    @property
    def points(self) -> np.ndarray:
        """The measured points as ``(m, K, 3)`` [m]."""
        return self.position.reshape(self.m, self.n_markers, 3)

    @property
    def kind(self) -> Measurement:
        """What was measured, the pose when orientations are present, else the position."""
        return POSITION if self.quaternion is None else POSE

    @property
    def measure(self) -> str:
        """``pose`` when orientations are present, else ``position``."""
        return self.kind.label

    @property
    def observed(self) -> Observed:
        """The measured points and orientations, as a measurement kind compares them."""
        return Observed(self.points, self.rotations)

    @property
    def rotations(self) -> np.ndarray | None:
        """Measured tool orientations as rotation matrices ``(m, 3, 3)``, or None."""
        if self.quaternion is None:
            return None
        return quaternion_to_matrix(self.quaternion)

    def row_of(self, i: int) -> int:
        """Row of configuration i in the source (file row, or i + 1 without a file)."""
        return self.rows[i] if self.rows is not None else i + 1

    def file_rows(self) -> np.ndarray:
        """Every configuration's row in the source ``(m,)`` (:meth:`row_of` of each)."""
        return np.arange(1, self.m + 1) if self.rows is None else np.asarray(self.rows)

    def position_only(self) -> Measurements:
        """The same data without the orientations."""
        return dataclasses.replace(self, quaternion=None, angles=None)

    def subset(self, index: np.ndarray) -> Measurements:
        """The configurations ``index`` (an integer array or a boolean mask)."""
        index = np.arange(self.m)[index]
        quat = None if self.quaternion is None else self.quaternion[index]
        rows = tuple(self.file_rows()[index].tolist())
        tool = None if self.tool is None else tuple(self.tool[int(i)] for i in index)
        return Measurements(
            self.joint_names,
            self.q[index],
            self.position[index],
            quat,
            self.source,
            rows,
            tool,
            self.coupling,
            None if self.angles is None else Angles(self.angles.format, self.angles.values[index]),
            self.path,
        )

    @property
    def tools(self) -> tuple[str, ...]:
        """The tool frames the rows measure, in order of first appearance (() if not named)."""
        return () if self.tool is None else tuple(dict.fromkeys(self.tool))

    @property
    def joint_columns(self) -> tuple[str, ...]:
        """Names of the joint columns, the joints or the independent ones (mimic joints)."""
        return self.joint_names if self.coupling is None else self.coupling.names

    @property
    def position_columns(self) -> tuple[str, ...]:
        """Names of the position columns, ``x, y, z`` or ``x1, y1, z1, ..., zK``."""
        if self.n_markers == 1 and not set(POSITION_COLUMNS) & set(self.joint_columns):
            return POSITION_COLUMNS
        return tuple(f"{a}{k + 1}" for k in range(self.n_markers) for a in POSITION_COLUMNS)

    @property
    def columns(self) -> tuple[str, ...]:
        """CSV header of this data (the ``tool`` column last, if rows name their tool).

        A joint named as one of the measurement columns is written ``joint:NAME``.
        """
        quat = QUATERNION_COLUMNS if self.quaternion is not None else ()
        tool = (TOOL_COLUMN,) if self.tool is not None else ()
        measured = (*self.position_columns, *quat, *tool)
        joints = [JOINT_PREFIX + n if n in measured else n for n in self.joint_columns]
        return (*joints, *measured)

    def table(self) -> np.ndarray:
        """The values in the order of :attr:`columns`, ``(m, len(columns))``."""
        q = self.q if self.coupling is None else self.coupling.variables(self.q)
        parts = [q, self.position]
        if self.quaternion is not None:
            parts.append(self.quaternion)
        return np.hstack(parts)
