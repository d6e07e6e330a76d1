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
from functools import cached_property
from typing import Protocol, runtime_checkable

import numpy as np

from ..core.checks import shown
from ..core.choices import CONTACT_MEASURES
from ..exceptions import InvalidArgumentError
from ..kinematics.so3 import inverse_right_jacobian, rotation_vector
from .planar import Layout

MAX_MARKER = 1e3
"""Largest marker coordinate [m]: a measured point on a robot's tool, not a kilometre away."""

ROW_NAMES = ("x", "y", "z", "rx", "ry", "rz")
"""The six rows of a pose error: position [m] then orientation [rad], in the base frame."""

POSE_ROWS = (0, 1, 2, 3, 4, 5)
"""Rows of a measured pose."""

POSITION_ROWS = (0, 1, 2)
"""Rows of a measured point."""

ROTATION_ROWS = (3, 4, 5)
"""Rows of a measured orientation."""

_XYZ = (0, 1, 2)


ROWS_BLOCK = 4096
"""Configurations whose rotation rows :meth:`Measurement.jacobian_rows` turns at once."""


@runtime_checkable
class MeasureKind(Protocol):
    """What every measurement kind provides (see :class:`Measurement` and the contacts).

    Attributes:
        label: The name the kind is given by (``pose``, ``plane``, ...).
        marker: The point of the tool frame whose displacement the position rows of
            :meth:`~calib.Measurement.jacobian_rows`'s pose-error Jacobian describe [m].
        row_names: One name per row.
    """

    @property
    def label(self) -> str:
        """The name the kind is given by (``pose``, ``position``, ``x,y,rz``, ``plane``)."""

    def __hash__(self) -> int: ...

    @property
    def marker(self) -> tuple[float, float, float]:
        """The point of the tool frame the position rows describe [m]."""

    @property
    def row_names(self) -> tuple[str, ...]:
        """One name per row (``x``, ``rz``, a contact's gap rows)."""

    @property
    def n_rows(self) -> int:
        """Rows per configuration."""

    @property
    def is_contact(self) -> bool:
        """True for a contact (a constraint holds, nothing is measured)."""

    def unknown_constants(self, n_markers: int = 1) -> int:
        """Constant unknowns the kind brings besides the robot (a frame, markers, a plane)."""

    def residual(
        self, R: np.ndarray, p: np.ndarray, measured: np.ndarray | None = None
    ) -> np.ndarray:
        """Measured minus predicted [m, rad] (a contact: its gap) ``(m, n_rows)``.

        Args:
            R: Predicted tool rotations in the base frame ``(m, 3, 3)``.
            p: Predicted tool origins in the base frame ``(m, 3)`` [m].
            measured: What was measured (None for a contact).
        """

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The residual's Jacobian rows ``(m, n_rows, k)``.

        Args:
            W6: The tool's pose-error Jacobian at the marker ``(m, 6, k)`` [m, rad].
            R: The tool rotations in the base frame ``(m, 3, 3)``.
        """

    def theoretical_count(
        self, sigma: np.ndarray, on_axes: tuple[int, ...], layout: Layout | None = None
    ) -> int | None:
        """:meth:`theory`'s count, None where the formula says nothing."""

    def theory(
        self, sigma: np.ndarray, on_axes: tuple[int, ...], layout: Layout | None = None
    ) -> int | str:
        """The closed-form identifiable count, or why there is none.

        Args:
            sigma: The joints' types (0 revolute, 1 prismatic) in chain order ``(n,)``.
            on_axes: Joint rows (1..n) whose axis passes through the measured point.
            layout: The chain's layout (:class:`~.planar.Layout`): the revolute joints whose
                axis lies along the tool's z axis, the planar layout, the runs of parallel axes.
        """


@dataclass(frozen=True, eq=False)
class Observed:
    """What an instrument reported at each configuration, in its own frame.

    Attributes:
        points: Measured points ``(m, K, 3)`` [m].
        rotations: Measured orientations of the measured frame ``(m, 3, 3)``, or None.
    """

    points: np.ndarray
    rotations: np.ndarray | None = None

    @staticmethod
    def of_poses(poses: np.ndarray, markers: np.ndarray) -> Observed:
        """What measured tool poses ``(m, 4, 4)`` show of markers ``(K, 3)`` [m]."""
        M = np.asarray(poses, dtype=float)
        pts = M[:, None, :3, 3] + np.einsum("mij,kj->mki", M[:, :3, :3], markers)
        return Observed(pts, M[:, :3, :3])


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
            twice = [s for s in ROW_NAMES if names.count(s) > 1]
            if twice:
                raise InvalidArgumentError(f"measure '{measure}' names the row {twice[0]} twice")
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
        """A kind a measured campaign (CSV, simulation, calibration) can hold, pose or position."""
        return self.is_pose or self.is_position

    @property
    def is_contact(self) -> bool:
        """False, an instrument measures the tool."""
        return False

    def unknown_constants(self, n_markers: int = 1) -> int:
        """Constant unknowns a calibration fits besides the robot.

        The measurement frame (6), each marker in the tool frame (3) and, for a measured
        pose, the measured frame's rotation in the tool frame (3).
        """
        return 6 + 3 * int(n_markers) + (3 if self.is_pose else 0)

    @cached_property
    def position_rows(self) -> tuple[int, ...]:
        """The measured position rows (0 x, 1 y, 2 z), per marker."""
        return tuple(r for r in self.rows if r < 3)

    @cached_property
    def rotation_rows(self) -> tuple[int, ...]:
        """The measured orientation rows (0 rx, 1 ry, 2 rz)."""
        return tuple(r - 3 for r in self.rows if r >= 3)

    @cached_property
    def _all_rows(self) -> bool:
        """The rows are those of the pose error, or of a point, all of them."""
        return self.position_rows == _XYZ and self.rotation_rows in ((), _XYZ)

    def rows_of(self, n_markers: int = 1) -> int:
        """Rows per configuration when ``n_markers`` points are measured at once."""
        return n_markers * len(self.position_rows) + len(self.rotation_rows)

    def full_rows(self, n_markers: int = 1) -> int:
        """Rows of the pose error the kind's rows are taken from: 3 per marker, 3 turning."""
        return 3 * n_markers + (3 if self.rotation_rows else 0)

    def row_index(self, n_markers: int = 1) -> list[int] | None:
        """The measured rows among :meth:`full_rows` (None: all of them)."""
        if self._all_rows:
            return None
        lin = [3 * k + r for k in range(n_markers) for r in self.position_rows]
        return lin + [3 * n_markers + r for r in self.rotation_rows]

    def predict(
        self,
        R: np.ndarray,
        p: np.ndarray,
        markers: np.ndarray | None = None,
        frame: np.ndarray | None = None,
        tool_rotation: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """What the instrument should see: the markers and the measured frame's orientation.

        Args:
            R: Tool rotations in the base frame ``(m, 3, 3)``.
            p: Tool origins in the base frame ``(m, 3)`` [m].
            markers: Points in the tool frame, ``(K, 3)`` shared or ``(m, K, 3)`` per
                configuration [m] (default: this kind's marker).
            frame: Pose of the base frame in the instrument's frame ``(4, 4)`` (default: the
                base frame).
            tool_rotation: Orientation of the measured frame in the tool frame ``(3, 3)``
                (default: the tool frame).

        Returns:
            The points ``(m, K, 3)`` [m] and, if orientation rows are measured, the measured
            frame's orientation ``(m, 3, 3)`` (else None), in the instrument's frame.
        """
        mk = self.marker_array[None] if markers is None else markers
        path = "mij,kj->mki" if mk.ndim == 2 else "mij,mkj->mki"
        pts = p[:, None, :] + np.einsum(path, R, mk)
        rot = None
        if frame is not None:
            pts = pts @ frame[:3, :3].T + frame[:3, 3]
        if self.rotation_rows:
            rot = R if frame is None else frame[:3, :3] @ R
            rot = rot if tool_rotation is None else rot @ tool_rotation
        return pts, rot

    def residual(
        self,
        R: np.ndarray,
        p: np.ndarray,
        measured: np.ndarray | Observed | None = None,
        markers: np.ndarray | None = None,
        frame: np.ndarray | None = None,
        tool_rotation: np.ndarray | None = None,
    ) -> np.ndarray:
        """Measured minus predicted, on the measured rows.

        Args:
            R: Predicted tool rotations in the base frame ``(m, 3, 3)``.
            p: Predicted tool origins in the base frame ``(m, 3)`` [m].
            measured: What was measured
                (:class:`~calib.identification.measures.Observed`), or the measured pose
                of the tool per configuration ``(m, 4, 4)`` in the instrument's frame.
            markers: The points of :meth:`predict` (default: this kind's marker).
            frame: The instrument's frame of :meth:`predict`.
            tool_rotation: The measured frame of :meth:`predict`.

        Returns:
            ``(m, rows_of(K))``: each marker's displacement [m] on the position rows, then
            the rotation vector of ``R_measured R_predicted^T`` [rad] (in the instrument's
            frame) on the orientation rows.
        """
        if measured is None:
            raise InvalidArgumentError("a measured kind's residual needs the measured poses")
        mk = self.marker_array[None] if markers is None else np.asarray(markers, dtype=float)
        if not isinstance(measured, Observed):
            measured = Observed.of_poses(measured, mk)
        pts, rot = self.predict(R, p, mk, frame, tool_rotation)
        e = measured.points - pts
        parts = [e.reshape(len(p), -1)]
        if rot is not None:
            parts.append(self.rotation_error(measured, rot))
        full = np.hstack(parts)
        index = self.row_index(pts.shape[1])
        return full if index is None else full[:, index]

    def rotation_error(self, measured: Observed, rot: np.ndarray) -> np.ndarray:
        """All three rows of the orientation error ``Log(R_measured rot^T)`` ``(m, 3)`` [rad].

        Raises:
            InvalidArgumentError: Nothing measured the orientation.
        """
        if measured.rotations is None:
            raise InvalidArgumentError(f"a {self.label} measurement needs measured orientations")
        return rotation_vector(measured.rotations @ np.swapaxes(rot, 1, 2))

    def jacobian_rows(
        self,
        W6: np.ndarray,
        R: np.ndarray | None = None,
        rotation_error: np.ndarray | None = None,
        n_markers: int = 1,
        overwrite: bool = False,
    ) -> np.ndarray:
        """The measured rows of the pose-error Jacobian at the markers.

        Args:
            W6: ``(m, full_rows(K), k)``: the displacement of each marker [m], then the
                rotation [rad] (rows of :meth:`full_rows`; at one marker the pose-error
                Jacobian ``(m, 6, k)``), all in the instrument's frame.
            R: Not used (the tool rotations; the protocol's).
            rotation_error: :meth:`rotation_error` at the prediction ``(m, 3)``, or None: the
                linearisation at zero error. Given, the rotation rows become those of
                ``-Log(R_measured R_model^T)``: ``Jr^-1(error)`` times the rotation rows.
            n_markers: K.
            overwrite: ``W6`` may be written to (its rotation rows become the rows of the
                rotation error: no copy of it).

        Returns:
            ``(m, rows_of(K), k)``, the rows of :meth:`residual`.
        """
        W = W6
        if rotation_error is not None:
            W = W6 if overwrite else W6.copy()
            inverse = inverse_right_jacobian(rotation_error)
            for s in range(0, len(W), ROWS_BLOCK):  # in blocks: no temporary of every row
                part = slice(s, s + ROWS_BLOCK)
                W[part, 3 * n_markers :] = inverse[part] @ W6[part, 3 * n_markers :]
        index = self.row_index(n_markers)
        return W if index is None else W[:, index]

    def theoretical_count(
        self, sigma: np.ndarray, on_axes: tuple[int, ...], layout: Layout | None = None
    ) -> int | None:
        """:meth:`theory`'s count, None where the formula says nothing."""
        found = self.theory(sigma, on_axes, layout)
        return found if isinstance(found, int) else None

    def theory(
        self, sigma: np.ndarray, on_axes: tuple[int, ...], layout: Layout | None = None
    ) -> int | str:
        """4R + 2P + 6 for the pose, 4R + 2P + 3 for a point (2 fewer on the last axis).

        Why not where the formula says nothing: other row subsets, or a point on a joint
        axis other than the last (a wrist centre).

        Args:
            sigma: The joints' types (0 revolute, 1 prismatic) in chain order ``(n,)``.
            on_axes: Joint rows (1..n) whose axis passes through the measured point.
            layout: What the axes' geometry says (:class:`~.planar.Layout`; unused here: the
                formulas hold for planar arms too).
        """
        revolute, prismatic, n = count_joints(sigma)
        if self.is_pose:
            return 4 * revolute + 2 * prismatic + 6
        if self.is_position:
            if any(k != n for k in on_axes):
                return "the point on a joint axis other than the last"
            return 4 * revolute + 2 * prismatic + 3 - (2 if on_axes else 0)
        return f"the formula is for the pose or a point, not the rows {self.label}"

    def marker_count(self, sigma: np.ndarray, n_markers: int) -> int | None:
        """4R + 2P + 3K (+ 3 for a pose) for K markers at generic places, frame and markers free.

        Each marker adds its 3 offsets to the robot's 4R + 2P, a pose the measured frame's
        rotation (:meth:`unknown_constants` less the measurement frame's 6, which the base's
        parameters are). For a tool that turns about every direction; None for other row
        subsets.
        """
        if not self.is_campaign:
            return None
        revolute, prismatic, _ = count_joints(sigma)
        return 4 * revolute + 2 * prismatic + self.unknown_constants(n_markers) - 6


def count_joints(sigma: np.ndarray) -> tuple[int, int, int]:
    """Revolute joints R, prismatic joints P and joints n of a sigma vector."""
    sigma = np.asarray(sigma)
    revolute, prismatic = int(np.sum(sigma == 0)), int(np.sum(sigma == 1))
    return revolute, prismatic, revolute + prismatic


POSE = Measurement(POSE_ROWS)
"""The full pose at the tool origin."""

POSITION = Measurement(POSITION_ROWS, label="position")
"""The position of the tool origin."""


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
            f"got {shown(marker)}"
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
    "POSITION",
    "POSITION_ROWS",
    "ROTATION_ROWS",
    "ROW_NAMES",
    "MeasureKind",
    "Measurement",
    "Observed",
    "checked_marker",
    "count_joints",
]
