"""Measurement kinds: what one row of a campaign measures, as one object per kind.

A kind knows its rows, its residual from the model's predicted tool placement, its analytic
Jacobian rows (from the pose-error Jacobian of the tool in the base frame) and how many
unknown constant parameters it brings. :class:`Measurement` is the kind of an instrument
that measures the tool (a laser tracker, motion capture): the pose, the position of a point
or some rows of the pose error. The contact kinds (:mod:`calib.identification.contacts`)
measure nothing: a constraint holds. :func:`kind_of` turns the names the API and the
command line accept (``pose``, ``position``, ``x,y,rz``, ``plane``, ...) into a kind
(:mod:`calib.identification.kinds`); it is the one place where a measure's name is read.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from ..core.choices import CONTACT_MEASURES
from ..exceptions import InvalidArgumentError
from ..kinematics.so3 import rotation_vector

MAX_MARKER = 1e3
"""Largest marker coordinate [m]: a measured point on a robot's tool, not a kilometre away."""

ROW_NAMES = ("x", "y", "z", "rx", "ry", "rz")
"""The six rows of a pose error: position [m] then orientation [rad], in the base frame."""

POSE_ROWS = (0, 1, 2, 3, 4, 5)
"""Rows of a measured pose."""

POSITION_ROWS = (0, 1, 2)
"""Rows of a measured point."""


@runtime_checkable
class MeasureKind(Protocol):
    """What every measurement kind provides (see :class:`Measurement` and the contacts).

    Attributes:
        label: The name the kind is given by (``pose``, ``plane``, ...).
        marker: The point of the tool frame whose displacement the position rows of
            :meth:`jacobian_rows`'s pose-error Jacobian describe [m].
        row_names: One name per row.
    """

    @property
    def label(self) -> str: ...  # noqa: D102

    def __hash__(self) -> int: ...

    @property
    def marker(self) -> tuple[float, float, float]: ...  # noqa: D102

    @property
    def row_names(self) -> tuple[str, ...]: ...  # noqa: D102

    @property
    def n_rows(self) -> int: ...  # noqa: D102

    @property
    def is_contact(self) -> bool: ...  # noqa: D102

    def unknown_constants(self, n_markers: int = 1) -> int: ...  # noqa: D102

    def residual(  # noqa: D102
        self, R: np.ndarray, p: np.ndarray, measured: np.ndarray | None = None
    ) -> np.ndarray: ...

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray: ...  # noqa: D102

    def theoretical_count(  # noqa: D102
        self, sigma: np.ndarray, on_axes: tuple[int, ...], along: tuple[int, ...] | None = None
    ) -> int | None: ...


@dataclass(frozen=True)
class Measurement:
    """An instrument measures some rows of the tool pose error, at a point of the tool.

    Attributes:
        rows: Indices into ``(x, y, z, rx, ry, rz)``, sorted.
        marker: Measured point in the tool frame ``(3,)`` [m].
        label: ``pose``, ``position`` or the row names.
    """

    rows: tuple[int, ...]
    marker: tuple[float, float, float] = (0.0, 0.0, 0.0)
    label: str = "pose"

    @staticmethod
    def of(measure: str = "pose", marker=None) -> Measurement:
        """Build from ``pose``, ``position`` or comma-separated row names (``x,y,rz``).

        Raises:
            InvalidArgumentError: Unknown measure or a marker that is not 3 finite numbers.
        """
        rows: tuple[int, ...]
        if measure == "pose":
            rows = POSE_ROWS
        elif measure == "position":
            rows = POSITION_ROWS
        else:
            names = [s.strip() for s in str(measure).split(",") if s.strip()]
            if not names or any(s not in ROW_NAMES for s in names):
                raise InvalidArgumentError(
                    f"unknown measure '{measure}': choose pose, position or rows among "
                    f"{', '.join(ROW_NAMES)}"
                )
            rows = tuple(sorted({ROW_NAMES.index(s) for s in names}))
        return Measurement(rows, checked_marker(marker), measure)

    @property
    def marker_array(self) -> np.ndarray:
        """The marker as an array [m]."""
        return np.array(self.marker)

    @property
    def row_names(self) -> tuple[str, ...]:
        """The measured rows' names, e.g. ``('x', 'y', 'rz')``."""
        return tuple(ROW_NAMES[r] for r in self.rows)

    @property
    def n_rows(self) -> int:
        """Rows per configuration."""
        return len(self.rows)

    @property
    def is_pose(self) -> bool:
        """The whole pose is measured (position and orientation)."""
        return self.rows == POSE_ROWS

    @property
    def is_position(self) -> bool:
        """Exactly the position of the point is measured."""
        return self.rows == POSITION_ROWS

    @property
    def is_campaign(self) -> bool:
        """A kind a measured campaign (CSV, simulation, calibration) can hold: pose or position."""
        return self.is_pose or self.is_position

    @property
    def is_contact(self) -> bool:
        """False: an instrument measures the tool."""
        return False

    def unknown_constants(self, n_markers: int = 1) -> int:
        """Constant unknowns a calibration fits besides the robot.

        The measurement frame (6), each marker in the tool frame (3) and, for a measured
        pose, the measured frame's rotation in the tool frame (3).
        """
        return 6 + 3 * int(n_markers) + (3 if self.is_pose else 0)

    def residual(
        self, R: np.ndarray, p: np.ndarray, measured: np.ndarray | None = None
    ) -> np.ndarray:
        """Measured minus predicted, on the measured rows.

        Args:
            R: Predicted tool rotations in the base frame ``(m, 3, 3)``.
            p: Predicted tool origins in the base frame ``(m, 3)`` [m].
            measured: Measured pose per configuration ``(m, 4, 4)`` in the base frame.

        Returns:
            ``(m, n_rows)``: the point's displacement [m] and the rotation vector of
            ``R_measured R^T`` [rad] (in the base frame), on the measured rows.
        """
        if measured is None:
            raise InvalidArgumentError("a measured kind's residual needs the measured poses")
        M = np.asarray(measured, dtype=float)
        mk = self.marker_array
        point = p + np.einsum("mij,j->mi", R, mk)
        dp = M[:, :3, 3] + np.einsum("mij,j->mi", M[:, :3, :3], mk) - point
        dphi = rotation_vector(M[:, :3, :3] @ np.swapaxes(R, 1, 2))
        return np.concatenate([dp, dphi], axis=1)[:, list(self.rows)]

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The measured rows of the pose-error Jacobian ``W6`` ``(m, 6, k)`` at the marker."""
        return W6[:, list(self.rows)]

    def theoretical_count(
        self, sigma: np.ndarray, on_axes: tuple[int, ...], along: tuple[int, ...] | None = None
    ) -> int | None:
        """4R + 2P + 6 for the pose, 4R + 2P + 3 for a point (2 fewer on the last axis).

        None where the formula says nothing: other row subsets, or a point on a joint axis
        other than the last (a wrist centre).

        Args:
            sigma: The joints' types (0 revolute, 1 prismatic) in chain order ``(n,)``.
            on_axes: Joint rows (1..n) whose axis passes through the measured point.
            along: Revolute joint rows whose axis lies along the tool's z axis (unused here).
        """
        revolute, prismatic, n = count_joints(sigma)
        if self.is_pose:
            return 4 * revolute + 2 * prismatic + 6
        if self.is_position:
            if any(k != n for k in on_axes):
                return None
            return 4 * revolute + 2 * prismatic + 3 - (2 if on_axes else 0)
        return None


def count_joints(sigma: np.ndarray) -> tuple[int, int, int]:
    """Revolute joints R, prismatic joints P and joints n of a sigma vector."""
    sigma = np.asarray(sigma)
    revolute, prismatic = int(np.sum(sigma == 0)), int(np.sum(sigma == 1))
    return revolute, prismatic, revolute + prismatic


POSE = Measurement(POSE_ROWS)
"""The full pose at the tool origin."""


def checked_marker(marker) -> tuple[float, float, float]:
    """A marker as 3 floats [m] (None: the tool origin).

    Raises:
        InvalidArgumentError: Not 3 finite numbers within :data:`MAX_MARKER`.
    """
    if marker is None:
        return (0.0, 0.0, 0.0)
    mk = np.asarray(marker, dtype=float).ravel() if _numeric(marker) else None
    if (
        mk is None
        or mk.shape != (3,)
        or not np.all(np.isfinite(mk))
        or np.max(np.abs(mk)) > MAX_MARKER
    ):
        raise InvalidArgumentError(
            f"a marker is 3 finite numbers (x y z in metres, each within {MAX_MARKER:g} m), "
            f"got {marker!r}"
        )
    return (float(mk[0]), float(mk[1]), float(mk[2]))


def _numeric(value) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return True


CONTACT_NAMES = CONTACT_MEASURES
"""The contact kinds' names (:mod:`calib.identification.contacts`)."""


__all__ = [
    "CONTACT_NAMES",
    "MAX_MARKER",
    "POSE",
    "POSE_ROWS",
    "POSITION_ROWS",
    "ROW_NAMES",
    "MeasureKind",
    "Measurement",
    "checked_marker",
    "count_joints",
]
