"""The calibration model of a measured chain: what predicts a measurement, and its unknowns.

A point k at q is ``R_f (p_tool(q') + R_tool(q') m_k) + t_f``, ``q' = q + c * tau(q)``; x
(:class:`MeasuredKind`): frame (rotation vector [rad] on the left, translation [m]), markers
[m], the measured frame's rotation [rad] on the right (pose). docs/developers/engine.md#model
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection
from dataclasses import dataclass

import numpy as np

from ..identification.base_columns import preference_order
from ..identification.jacobian import identification_jacobian
from ..identification.measures import POSE, POSITION, Measurement
from ..identification.parameters import ParameterSet
from ..kinematics.mdh import Kinematics, MDHModel
from ..kinematics.so3 import left_jacobian, matrix_to_quaternion, rotation_matrix, skew
from ..measurements.data import Measurements
from .placements import JointFrames

__all__ = [
    "FRAME_NAMES",
    "TOOL_NAMES",
    "ErrorModel",
    "MeasuredKind",
    "State",
    "compliance_name",
    "generic_measurements",
    "measured_kind",
    "moved",
    "moved_frame",
    "nominal_state",
    "point_rows",
    "registration_state",
    "selection_lift",
]

FRAME_NAMES = ("frame.rx", "frame.ry", "frame.rz", "frame.x", "frame.y", "frame.z")
"""Names of the measurement-frame parameters: rotation [rad] then translation [m]."""

TOOL_NAMES = ("tool.rx", "tool.ry", "tool.rz")
"""Names of the measured frame's rotation in the tool frame [rad] (pose data)."""


def compliance_name(joint: int) -> str:
    """Name of the compliance of joint ``joint`` (0-based): ``c<row>``, e.g. ``c3``."""
    return f"c{joint + 1}"


CONFIGURATION_BLOCK = 4096
"""Configurations :meth:`ErrorModel.jacobian` makes MDH columns of at once (bounds temporaries).
Measurements: docs/developers/performance.md#configuration_block-model"""


@dataclass(frozen=True, eq=False)
class State:
    """A complete model of the measurements: geometry, measurement frame, markers, compliance.

    ``mdh``: in the URDF base frame (frame -1); ``frame``: its pose in the measurement frame
    ``(4, 4)``; ``markers`` ``(K, 3)`` [m] and ``tool_rotation`` ``(3, 3)`` (None: position
    data) in the tool frame; ``compliance`` ``(n,)`` [rad/(N m) or m/N].
    """

    mdh: MDHModel
    frame: np.ndarray
    markers: np.ndarray
    tool_rotation: np.ndarray | None
    compliance: np.ndarray

    @property
    def n_markers(self) -> int:
        """Number of markers K."""
        return len(self.markers)

    def joints(self, q: np.ndarray, torque: np.ndarray | None) -> np.ndarray:
        """Joint positions the geometry sees: ``q + c * tau`` [rad or m]."""
        if torque is None or not np.any(self.compliance):
            return q
        return q + torque * self.compliance

    @property
    def kind(self) -> Measurement:
        """What the state predicts: a measured frame's pose (with a tool rotation) or points."""
        return POSITION if self.tool_rotation is None else POSE

    def predict(self, q: np.ndarray, torque: np.ndarray | None = None):
        """Predicted points ``(m, K, 3)`` [m] and orientations ``(m, 3, 3)`` (or None)."""
        kin = self.kinematics(q, torque)
        return self.kind.predict(
            kin.R[:, -1], kin.p[:, -1], self.markers, self.frame, self.tool_rotation
        )

    def kinematics(self, q: np.ndarray, torque: np.ndarray | None = None) -> Kinematics:
        """The geometry's frames at the joints it sees (:meth:`joints`)."""
        return self.mdh.kinematics(self.joints(q, torque))

    def step_kinematics(self, data, torque: np.ndarray | None) -> Kinematics:
        """:meth:`kinematics` at the data's joints (a fit's, once per x)."""
        return self.kinematics(data.q, torque)

    def same_geometry(self, other) -> bool:
        """Whether ``other``'s kinematics at the same data are this state's."""
        return (
            isinstance(other, State)
            and other.mdh is self.mdh
            and np.array_equal(other.compliance, self.compliance)
        )

    def residuals(
        self, data, torque: np.ndarray | None = None, kin: Kinematics | JointFrames | None = None
    ) -> np.ndarray:
        """Measured - model per configuration ``(m, 3 K [+ 3])`` [m, rad].

        ``kin``: frames at the data's joints whose last is the tool's, if already made.
        """
        kind = data.kind if self.tool_rotation is not None else POSITION
        if kin is None:
            kin = self.kinematics(data.q, torque)
        return kind.residual(
            kin.R[:, -1], kin.p[:, -1], data.observed, self.markers, self.frame, self.tool_rotation
        )


@dataclass(frozen=True)
class MeasuredKind:
    """A measured chain's own unknowns and rows: the registration's model, a term's layout.

    ``instrument``: an instrument outside the robot whose frame every such term shares (the
    frame's 6 unknowns are the term's object); ``held``: marker coordinates (0-based among
    the ``3 K``) held at their given value (:func:`~.chain_registration.held_markers`).
    """

    n_markers: int
    pose: bool
    instrument: bool = False
    held: tuple[int, ...] = ()

    object_name = "frame"

    @property
    def measurement(self) -> Measurement:
        """What is measured (pose or position)."""
        return POSE if self.pose else POSITION

    @property
    def label(self) -> str:
        """``pose`` or ``position`` (the report's term kind)."""
        return "pose" if self.pose else "position"

    @property
    def rows(self) -> int:
        """Residual rows per configuration."""
        return self.measurement.rows_of(self.n_markers)

    def names(self) -> tuple[str, ...]:
        """The unknowns: the frame's 6, each marker's 3 (but those held), the tool's 3 (pose)."""
        out = list(FRAME_NAMES) + [f"marker{c // 3 + 1}.{'xyz'[c % 3]}" for c in self._moved]
        return tuple(out + list(TOOL_NAMES if self.pose else ()))

    @property
    def kept(self) -> list[int]:
        """Each unknown's place among the frame's, every marker coordinate's and the tool's."""
        return self._kept(6 + 3 * self.n_markers + 3 * self.pose)

    def _kept(self, width: int) -> list[int]:
        """The columns of ``width`` but the held markers'."""
        return [c for c in range(width) if c - 6 not in self.held]

    @property
    def _moved(self) -> list[int]:
        return [c for c in range(3 * self.n_markers) if c not in self.held]

    def size(self) -> int:
        """Number of unknowns."""
        return 6 + 3 * self.n_markers - len(self.held) + 3 * self.pose

    def determined_by(self, m: int) -> bool:
        """Whether ``m`` configurations give more equations than the unknowns."""
        return m * self.rows > self.size()

    @property
    def object_dofs(self) -> tuple[int, ...]:
        """The term's object's unknowns: all of them, or the frame's (instrument)."""
        return tuple(range(len(FRAME_NAMES) if self.instrument else len(self.names())))

    @property
    def contact_dofs(self) -> tuple[int, ...]:
        """The term's own unknowns beside a shared instrument frame (else none)."""
        return tuple(range(len(self.object_dofs), len(self.names())))

    @property
    def row_names(self) -> tuple[str, ...]:
        """``x y z`` per marker (numbered with several), then ``rx ry rz`` (pose)."""
        tag = [""] if self.n_markers == 1 else [str(k + 1) for k in range(self.n_markers)]
        rows = [f"{a}{t}" for t in tag for a in "xyz"]
        return (*rows, *(("rx", "ry", "rz") if self.pose else ()))

    @property
    def angular(self) -> tuple[bool, ...]:
        """Whether each row is an angle."""
        return (False,) * (3 * self.n_markers) + (True,) * (3 * self.pose)

    def row_weights(self, weight: float) -> np.ndarray:
        """1 on the point rows, ``weight`` [m/rad] on the rotation rows."""
        return np.where(np.array(self.angular), weight, 1.0)

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """X cut into its groups: frame, markers, tool (views)."""
        x, tool = np.asarray(x, dtype=float), len(x) - 3 * self.pose
        return x[:6], x[6:tool], x[tool:]

    def apply(self, start: State, x: np.ndarray) -> State:
        """The state at unknowns x (x = 0 is ``start``; its geometry and compliance kept)."""
        xf, xm, xt = self.split(x)
        dm = np.zeros(3 * self.n_markers)
        dm[self._moved] = xm
        markers = start.markers + dm.reshape(-1, 3)
        tool = start.tool_rotation
        if xt.size:
            tool = tool @ rotation_matrix(xt)
        frame = moved_frame(start.frame, xf)
        return State(start.mdh, frame, markers, tool, start.compliance.copy())

    def jacobian(
        self,
        start: State,
        x: np.ndarray,
        data,
        torque: np.ndarray | None,
        state: State | None = None,
        kin: Kinematics | JointFrames | None = None,
    ) -> np.ndarray:
        """d(model)/dx ``(m, rows, size)``; rotation rows: of ``-Log(R_meas R_model^T)``.

        ``state`` (``apply(start, x)``) and ``kin`` (its frames at the data's joints, whose
        last is the tool's): if already made.
        """
        if state is None:
            state = self.apply(start, x)
        xf, _, xt = self.split(x)
        if kin is None:
            kin = state.kinematics(data.q, torque)
        J, rot = self._columns(state, xf, xt, data.m, kin, 0)
        return self.measured_rows(J, rot, data)

    def _columns(self, state: State, xf, xt, m: int, kin, extra: int):
        """Every own column's full rows (held markers' too, ``extra`` zero ones), rotation.

        The columns ``(m, full rows, 6 + 3 K [+ 3] + extra)``: the frame's, the markers', the
        measured frame's rotation (pose), then ``extra``.
        """
        K, kind = state.n_markers, self.measurement
        R = state.frame[:3, :3]
        pts, rot = kind.predict(
            kin.R[:, -1], kin.p[:, -1], state.markers, state.frame, state.tool_rotation
        )
        P = 3 * K
        J = np.zeros((m, kind.full_rows(K), 6 + P + 3 * self.pose + extra))
        # d(R p)/dphi = -[R p]x Jl(phi) with R = Exp(phi) R0, then translation
        Jl = left_jacobian(xf[:3])
        J[:, :P, :3] = (-skew(pts - state.frame[:3, 3]) @ Jl).reshape(m, P, 3)
        J[:, :P, 3:6] = np.tile(np.eye(3), (K, 1))
        if self.pose:
            J[:, P:, :3] = Jl
        Rt = R @ kin.R[:, -1]
        for k in range(K):
            J[:, 3 * k : 3 * k + 3, 6 + 3 * k : 9 + 3 * k] = Rt
        if self.pose:  # right perturbation: R Jr(psi)
            J[:, P:, 6 + P : 9 + P] = rot @ left_jacobian(xt).T
        return J, rot

    def measured_rows(self, J: np.ndarray, rot, data, held: bool = True) -> np.ndarray:
        """The kind's rows of full rows ``J`` ``(m, 3 K [+ 3], k)``, in place (``held``: out)."""
        kind = self.measurement
        error = kind.rotation_error(data.observed, rot) if rot is not None else None
        J = kind.jacobian_rows(J, rotation_error=error, n_markers=self.n_markers, overwrite=True)
        seen = data.seen_rows(J.shape[1])  # a marker not seen: no rows (solve drops them)
        if seen is not None:
            J[~seen] = 0.0
        return J[..., self._kept(J.shape[2])] if held and self.held else J


def point_rows(Rf: np.ndarray, lin, ang, points: np.ndarray, pose: bool) -> np.ndarray:
    """Full rows ``(m, 3 K [+ 3], k)`` of k motions: a point by ``lin - [point]x ang``."""
    m, K = points.shape[:2]
    rows = (Rf @ (lin[:, None] - skew(points) @ ang[:, None])).reshape(m, 3 * K, -1)
    return np.concatenate([rows, Rf @ ang], axis=1) if pose else rows


def measured_kind(data: Measurements, held: tuple[int, ...] = ()) -> MeasuredKind:
    """The unknowns and rows of a chain measured by these measurements (``held``: no unknown)."""
    return MeasuredKind(data.n_markers, data.quaternion is not None, held=held)


@dataclass(frozen=True, eq=False)
class ErrorModel:
    """A measured chain's own unknowns (``own``) and MDH base values, linearised at a state.

    What rows determine and the outlier proposals; the fits move the geometry through
    :mod:`.placements`, never these columns. ``base``: names of ``params`` (:func:`moved`).
    """

    params: ParameterSet
    base: tuple[str, ...]
    own: MeasuredKind

    def names(self) -> tuple[str, ...]:
        """Names of the columns: the own unknowns', then the base values'."""
        return self.own.names() + tuple(self.base)

    def size(self) -> int:
        """Number of columns."""
        return self.own.size() + len(self.base)

    def jacobian(self, state: State, data, kin: Kinematics | None = None) -> np.ndarray:
        """d(model)/d(columns) at ``state`` ``(m, rows, size)`` (``kin``: if already made)."""
        own, q = self.own, data.q
        if kin is None:
            kin = state.mdh.kinematics(q)
        zero = np.zeros(6 + 3 * own.pose)  # the frame's and the tool's rotations at x = 0
        J, rot = own._columns(state, zero[:6], zero[6:], data.m, kin, len(self.base))
        if self.base:  # in blocks: small temporaries
            c = J.shape[2] - len(self.base)
            for s in range(0, data.m, CONFIGURATION_BLOCK):
                part = slice(s, s + CONFIGURATION_BLOCK)
                sub = Kinematics(*(a[part] for a in kin))
                J[part, :, c:] = self._mdh_columns(state, q[part], sub)
        return own.measured_rows(J, rot, data)

    def _mdh_columns(self, state: State, q: np.ndarray, kin) -> np.ndarray:
        """Columns of the base values ``(m, full rows, len(base))``."""
        R = state.frame[:3, :3]
        m, K = q.shape[0], state.n_markers
        index = [self.params.index(name) for name in self.base]
        if K == 1 and not self.own.pose:
            meas = dataclasses.replace(POSITION, marker=tuple(state.markers[0]))
            W = identification_jacobian(state.mdh, self.params, q, meas, kin=kin)
            return (R @ W.reshape(m, 3, -1))[..., index]
        # each marker from the tool's pose rows: d(p + R_t m_k) = dp - [R_t m_k]x dphi
        W6 = identification_jacobian(state.mdh, self.params, q, POSE, kin=kin).reshape(m, 6, -1)
        lever = np.einsum("mij,kj->mki", kin.R[:, -1], state.markers)
        return point_rows(R, W6[:, :3], W6[:, 3:], lever, self.own.pose)[..., index]


def moved_frame(frame: np.ndarray, xf: np.ndarray) -> np.ndarray:
    """A copy of a frame ``(4, 4)`` moved by x's frame part (rotation [rad], translation [m])."""
    out = frame.copy()
    out[:3, :3] = rotation_matrix(xf[:3]) @ frame[:3, :3]
    out[:3, 3] = frame[:3, 3] + xf[3:]
    return out


def selection_lift(params: ParameterSet, base: tuple[str, ...]) -> np.ndarray:
    """The lift ``(len(params), len(base))`` that moves each base value's own parameter only."""
    lift = np.zeros((len(params), len(base)))
    for j, name in enumerate(base):
        lift[params.index(name), j] = 1.0
    return lift


def moved(
    params: ParameterSet, mdh: MDHModel, offered: Collection[str] | None = None
) -> tuple[str, ...]:
    """An :class:`ErrorModel`'s ``base``: ``offered`` (default: all), in order of preference."""
    return tuple(
        params.names[i]
        for i in preference_order(mdh, params)
        if offered is None or params.names[i] in offered
    )


def registration_state(
    mdh: MDHModel, frame: np.ndarray, markers: np.ndarray, tool_rotation: np.ndarray | None
) -> State:
    """A state with the nominal geometry, no compliance, and the given frame and markers."""
    frame, markers = np.array(frame, dtype=float), np.array(markers, dtype=float)
    return State(mdh, frame, markers, tool_rotation, np.zeros(mdh.n))


def nominal_state(mdh: MDHModel, markers: np.ndarray, kind: Measurement) -> State:
    """A registration state in the instrument's own frame, for a kind's generic counts."""
    tool = np.eye(3) if kind.rotation_rows else None
    return registration_state(mdh, np.eye(4), markers, tool)


def generic_measurements(state: State, joint_names: tuple[str, ...], q: np.ndarray):
    """What a state measures at q, exactly (zero residual; docs/developers/engine.md#model)."""
    pts, rot = state.predict(q)
    quat = None if rot is None else matrix_to_quaternion(rot)
    return Measurements(joint_names, q, pts.reshape(len(q), -1), quat)
