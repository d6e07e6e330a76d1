"""The calibration model: what predicts a measurement, and which of its parameters are free.

A measured point k at configuration q is predicted as

    p_k(q) = R_f (p_tool(q') + R_tool(q') m_k) + t_f,     q' = q + c * tau(q)

* ``(R_f, t_f)``: the measurement frame, i.e. the pose of the URDF base frame (frame -1 of
  the MDH model) in the instrument's frame;
* ``m_k``: marker k in the tool frame [m];
* ``p_tool, R_tool``: the MDH model's tool frame (geometric errors live in its rows);
* ``c * tau``: joint compliance c_j [rad/(N m) or m/N] times the gravity torque tau_j(q)
  [N m or N] that the joint carries (nominal masses of the URDF); zero unless chosen.

A measured orientation (pose data) is predicted as ``R_f R_tool(q') R_m``, ``R_m`` the
orientation of the measured frame in the tool frame.

The free parameters x, in this order: the frame (rotation vector [rad] applied on the left,
then translation [m]), the markers (3 per marker [m]), the measured frame's rotation (pose
data, rotation vector [rad] on the right) and the MDH base values (``dX = lift @ x_b``).
Marker coordinates may be held (no column); the compliance is the state's, never x's (the
engine fits it). The Jacobian is analytic (frame and tool rotations through the SO(3) left
Jacobian, so it is exact at any x).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Collection
from dataclasses import dataclass
from itertools import accumulate

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
    "State",
    "compliance_name",
    "generic_measurements",
    "moved",
    "moved_frame",
    "nominal_state",
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
"""Configurations whose robot-parameter columns :meth:`ErrorModel.jacobian` computes at once:
the identification Jacobian's temporaries (several arrays of rows x parameters per
configuration) stay a few MB whatever the campaign's size (100,000 configurations: they
peaked at about 400 MB beside the Jacobian itself)."""


@dataclass(frozen=True, eq=False)
class State:
    """A complete model of the measurements: geometry, measurement frame, markers, compliance.

    Attributes:
        mdh: MDH model in the URDF base frame (frame -1).
        frame: Pose of the URDF base frame in the measurement frame ``(4, 4)``.
        markers: Measured points in the tool frame ``(K, 3)`` [m].
        tool_rotation: Orientation of the measured frame in the tool frame ``(3, 3)``, or
            None for position data.
        compliance: Joint compliance ``(n,)`` [rad/(N m) or m/N].
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
        """:meth:`kinematics` at the data's joints (what a fit makes once per x)."""
        return self.kinematics(data.q, torque)

    def same_geometry(self, other) -> bool:
        """Whether ``other``'s kinematics at the same data are this state's.

        True when x moved no geometry (the frame and markers only).
        """
        return (
            isinstance(other, State)
            and other.mdh is self.mdh
            and np.array_equal(other.compliance, self.compliance)
        )

    def residuals(
        self, data, torque: np.ndarray | None = None, kin: Kinematics | JointFrames | None = None
    ) -> np.ndarray:
        """Measured - model per configuration ``(m, 3 K [+ 3])`` [m, rad].

        The rows of the data's kind (the state's points only if it has no tool rotation);
        ``kin``: :meth:`kinematics` at the data's joints (or any frames whose last is the
        tool's), if already computed.
        """
        kind = data.kind if self.tool_rotation is not None else POSITION
        if kin is None:
            kin = self.kinematics(data.q, torque)
        return kind.residual(
            kin.R[:, -1], kin.p[:, -1], data.observed, self.markers, self.frame, self.tool_rotation
        )


@dataclass(frozen=True, eq=False)
class ErrorModel:
    """Which parameters of a :class:`State` a fit moves, and how.

    Attributes:
        params: Standard MDH parameter set the base values come from.
        base: Names of the free MDH base values, each a parameter of ``params``.
        lift: ``dX = lift @ x_b`` ``(len(params), len(base))``: how the base values move
            the standard parameters.
        n_markers: Number of markers K.
        kind: What is measured (its rows, residual and Jacobian rows): the position of the
            markers (default) or the pose (then the measured frame's rotation is free).
        held: Marker coordinates (0-based among the ``3 K``) held at the start, no column of
            x (:func:`~.chain_registration.held_markers`).
    """

    params: ParameterSet
    base: tuple[str, ...]
    lift: np.ndarray
    n_markers: int = 1
    kind: Measurement = POSITION
    held: tuple[int, ...] = ()

    @property
    def pose(self) -> bool:
        """Orientation rows are fitted."""
        return bool(self.kind.rotation_rows)

    def names(self) -> tuple[str, ...]:
        """Names of the free parameters, in the order of x."""
        out = list(FRAME_NAMES) + [f"marker{c // 3 + 1}.{'xyz'[c % 3]}" for c in self._moved]
        return tuple(out + list(TOOL_NAMES if self.pose else ()) + list(self.base))

    @property
    def columns(self) -> list[int]:
        """Each of x's parameters' place among every column (the held markers' included)."""
        return [c for c in range(self.size() + len(self.held)) if c - 6 not in self.held]

    @property
    def _moved(self) -> list[int]:
        return [c for c in range(3 * self.n_markers) if c not in self.held]

    def _sizes(self) -> tuple[int, int, int, int]:
        return 6, 3 * self.n_markers - len(self.held), 3 * self.pose, len(self.base)

    def size(self) -> int:
        """Number of free parameters."""
        return sum(self._sizes())

    def split(self, x: np.ndarray) -> list[np.ndarray]:
        """X cut into its groups: frame, markers, tool, base values (views, as ``np.split``'s)."""
        x, ends = np.asarray(x, dtype=float), list(accumulate(self._sizes()))
        return [x[a:b] for a, b in zip([0, *ends[:-1]], [*ends[:-1], len(x)], strict=True)]

    def apply(self, start: State, x: np.ndarray) -> State:
        """The state at parameters x (x = 0 is ``start``)."""
        xf, xm, xt, xb = self.split(x)
        dm = np.zeros(3 * self.n_markers)
        dm[self._moved] = xm
        markers = start.markers + dm.reshape(-1, 3)
        tool = start.tool_rotation
        if xt.size:
            tool = tool @ rotation_matrix(xt)
        mdh = self.params.apply(start.mdh, self.lift @ xb) if np.any(xb) else start.mdh
        return State(mdh, moved_frame(start.frame, xf), markers, tool, start.compliance.copy())

    def jacobian(
        self,
        start: State,
        x: np.ndarray,
        data,
        torque: np.ndarray | None,
        state: State | None = None,
        kin: Kinematics | JointFrames | None = None,
    ) -> np.ndarray:
        """d(model)/dx, ``(m, rows, size)``: the kind's rows (3 K point rows, 3 rotation rows).

        The rotation rows are the derivative of ``-Log(R_meas R_model^T)`` (so that the
        whole Jacobian is that of model - measured). ``state`` (``apply(start, x)``) and
        ``kin`` (its :meth:`State.kinematics` at the data's joints): if already computed
        (other frames whose last is the tool's, e.g. a joint fit's, for a model of no MDH
        column).
        """
        if state is None:
            state = self.apply(start, x)
        xf, _, xt, _ = self.split(x)
        q = state.joints(data.q, torque)
        if kin is None:
            kin = state.mdh.kinematics(q)
        m, K = data.m, state.n_markers
        R = state.frame[:3, :3]
        pts, rot = self.kind.predict(
            kin.R[:, -1], kin.p[:, -1], state.markers, state.frame, state.tool_rotation
        )
        P, width = 3 * K, self.size() + len(self.held)  # every marker column, then held's out
        J = np.zeros((m, self.kind.full_rows(K), width))  # 3 K point rows, 3 turning
        # d(R p)/dphi = -[R p]x Jl(phi) with R = Exp(phi) R0, then translation
        Jl = left_jacobian(xf[:3])
        J[:, :P, :3] = (-skew(pts - state.frame[:3, 3]) @ Jl).reshape(m, P, 3)
        J[:, :P, 3:6] = np.tile(np.eye(3), (K, 1))
        if self.kind.rotation_rows:
            J[:, P:, :3] = Jl
        Rt = R @ kin.R[:, -1]
        for k in range(K):
            J[:, 3 * k : 3 * k + 3, 6 + 3 * k : 9 + 3 * k] = Rt
        c = 6 + P
        if self.pose:
            J[:, P:, c : c + 3] = rot @ left_jacobian(xt).T  # right perturbation: R Jr(psi)
            c += 3
        if self.base:  # the MDH columns need the MDH model's frames
            mdh_kin = kin if isinstance(kin, Kinematics) else state.mdh.kinematics(q)
            for s in range(0, m, CONFIGURATION_BLOCK):  # in blocks: small temporaries
                part = slice(s, s + CONFIGURATION_BLOCK)
                sub = Kinematics(*(a[part] for a in mdh_kin))
                J[part, :, c:] = self._mdh_columns(state, q[part], sub)
        error = self.kind.rotation_error(data.observed, rot) if rot is not None else None
        J = self.kind.jacobian_rows(J, rotation_error=error, n_markers=K, overwrite=True)
        return J[..., self.columns] if self.held else J

    @property
    def rows(self) -> int:
        """Residual rows per configuration."""
        return self.kind.rows_of(self.n_markers)

    def _mdh_columns(self, state: State, q: np.ndarray, kin) -> np.ndarray:
        """Columns of the base values (through the lift) ``(m, rows, len(base))``."""
        R = state.frame[:3, :3]
        m, K = q.shape[0], state.n_markers
        if K == 1 and not self.pose:
            meas = dataclasses.replace(POSITION, marker=tuple(state.markers[0]))
            W = identification_jacobian(state.mdh, self.params, q, meas, kin=kin)
            return (R @ W.reshape(m, 3, -1)) @ self.lift
        # each marker from the tool's pose rows: d(p + R_t m_k) = dp - [R_t m_k]x dphi
        W6 = identification_jacobian(state.mdh, self.params, q, POSE, kin=kin).reshape(m, 6, -1)
        lever = np.einsum("mij,kj->mki", kin.R[:, -1], state.markers)
        cols = (R @ (W6[:, None, :3] - skew(lever) @ W6[:, None, 3:])).reshape(m, 3 * K, -1)
        if self.pose:  # then the rotation rows
            cols = np.concatenate([cols, R @ W6[:, 3:]], axis=1)
        return cols @ self.lift


def moved_frame(frame: np.ndarray, xf: np.ndarray) -> np.ndarray:
    """A copy of a frame ``(4, 4)`` moved by x's frame part ``xf``.

    ``xf``: a rotation vector [rad] applied on the left, then a translation [m].
    """
    out = frame.copy()
    out[:3, :3] = rotation_matrix(xf[:3]) @ frame[:3, :3]
    out[:3, 3] = frame[:3, 3] + xf[3:]
    return out


def selection_lift(params: ParameterSet, base: tuple[str, ...]) -> np.ndarray:
    """The lift that moves each base value's own standard parameter only."""
    lift = np.zeros((len(params), len(base)))
    for j, name in enumerate(base):
        lift[params.index(name), j] = 1.0
    return lift


def moved(
    params: ParameterSet, mdh: MDHModel, offered: Collection[str] | None = None
) -> tuple[tuple[str, ...], np.ndarray]:
    """An :class:`ErrorModel`'s ``base`` and ``lift`` that move parameters from the nominal.

    The parameters ``offered`` of ``params`` (default: all) in the paper's order of
    preference at ``mdh`` (:func:`preference_order`), each its own (:func:`selection_lift`).
    """
    base = tuple(
        params.names[i]
        for i in preference_order(mdh, params)
        if offered is None or params.names[i] in offered
    )
    return base, selection_lift(params, base)


def registration_state(
    mdh: MDHModel, frame: np.ndarray, markers: np.ndarray, tool_rotation: np.ndarray | None
) -> State:
    """A state with the nominal geometry, no compliance, and the given frame and markers."""
    return State(
        mdh,
        np.array(frame, dtype=float),
        np.array(markers, dtype=float),
        tool_rotation,
        np.zeros(mdh.n),
    )


def nominal_state(mdh: MDHModel, markers: np.ndarray, kind: Measurement) -> State:
    """A registration state in the instrument's own frame, for a kind's generic counts.

    The measured frame is the tool frame when the kind measures orientation rows.
    """
    tool = np.eye(3) if kind.rotation_rows else None
    return registration_state(mdh, np.eye(4), markers, tool)


def generic_measurements(state: State, joint_names: tuple[str, ...], q: np.ndarray):
    """What a state measures at q: its own points and, with a tool rotation, orientations.

    The data the counts of :mod:`~.determined` and the design's Jacobians are evaluated on:
    exact, so the residual is zero and the Jacobian is the plain linearisation (measured
    identity orientations would scale the rotation rows by ``Jr^-1`` of the tool's rotation).
    """
    pts, rot = state.predict(q)
    quat = None if rot is None else matrix_to_quaternion(rot)
    return Measurements(joint_names, q, pts.reshape(len(q), -1), quat)
