"""The error model of flush contacts: one plane, the contact frame's tilts, robot parameters.

A state is the robot's MDH model (frame -1: the chain's base frame), the contact frame in the
tool frame and the plane (unit normal ``n`` and height ``h``: the points x with ``n . x = h``)
in the base frame. A touch's gap is the contact frame's height [m] and its roll and pitch
[rad] in the plane's frame (:func:`~calib.calibration.contact_registration.plane_residuals`).

The parameters x of :class:`ContactModel`: the plane's normal (two steps in the tangent plane
of its start) and height, the contact's tilts about its own x and y axes (its origin and yaw
are invisible or regroup with the height), then shifts of robot parameters, then the joint
compliances asked for (``elastic``: the geometry sees ``q' = q + c tau``, ``tau`` the gravity
torques given with the data, :mod:`calib.kinematics.standing`). The analytic
Jacobian: a displacement ``dx`` of the contact origin moves the height by ``n . dx``; a
rotation ``dphi`` of the tool (base frame) moves the normal seen from the contact frame,
``s = (R C)^T n``, by ``(R C)^T [n]x dphi``; a compliance column is its joint's offset column
times ``tau_j`` (times the joint's sign on a reversed chain).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..identification.jacobian import identification_jacobian
from ..identification.measures import Measurement
from ..identification.parameters import ParameterSet
from ..kinematics.mdh import MDHModel
from ..kinematics.so3 import left_jacobian, rotation_matrix, skew
from .contact_registration import plane_residuals, tilt_derivatives
from .model import compliance_name, offset_parameter

__all__ = ["PLANE_COLUMNS", "ContactModel", "ContactState", "plane_frame"]

PLANE_COLUMNS = 5
"""Columns of the plane (2 normal steps and the height) and the contact's tilts (2)."""


def plane_frame(normal: np.ndarray, height: float, centre: np.ndarray) -> np.ndarray:
    """The plane ``(4, 4)``: z = normal, origin the projected ``centre`` [m], x the base x."""
    n = np.asarray(normal, dtype=float)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    ex = helper - (helper @ n) * n
    ex /= np.linalg.norm(ex)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([ex, np.cross(n, ex), n])
    T[:3, 3] = centre - (n @ centre - height) * n
    return T


@dataclass(frozen=True, eq=False)
class ContactState:
    """The robot, the contact frame and the plane.

    Attributes:
        mdh: The robot's MDH model (frame -1: the chain's base frame).
        contact: The contact frame in the tool frame ``(4, 4)``.
        normal: The plane's unit normal in the base frame ``(3,)``.
        height: The plane's height along its normal [m].
        weight: Weight of the tilt rows [m/rad].
        compliance: Joint compliance ``(n,)`` [rad/(N m) or m/N], or None (rigid joints).
    """

    mdh: MDHModel
    contact: np.ndarray
    normal: np.ndarray
    height: float
    weight: float
    compliance: np.ndarray | None = None

    def joints(self, q: np.ndarray, torque: np.ndarray | None = None) -> np.ndarray:
        """Joint positions the geometry sees: ``q + c * tau`` [rad or m] (``q`` without torque)."""
        q = np.asarray(q, dtype=float)
        if torque is None or self.compliance is None or not np.any(self.compliance):
            return q
        return q + np.asarray(torque, dtype=float) * self.compliance

    def plane(self, centre: np.ndarray | None = None) -> np.ndarray:
        """The plane ``(4, 4)`` in the base frame (origin: ``centre`` projected, default 0)."""
        return plane_frame(self.normal, self.height, np.zeros(3) if centre is None else centre)

    def gaps(self, q: np.ndarray, torque: np.ndarray | None = None) -> np.ndarray:
        """Height [m], roll and pitch [rad] ``(m, 3)`` of the contact frame in the plane's frame.

        ``torque``: gravity torques ``(m, n)`` [N m or N] that deflect the joints (compliance).
        """
        kin = self.mdh.kinematics(self.joints(q, torque))
        return plane_residuals(kin.R[:, -1], kin.p[:, -1], self.contact, self.plane())

    def residuals(self, data, torque: np.ndarray | None = None) -> np.ndarray:
        """Weighted ``0 - gap`` ``(m, 3)``: height [m], ``weight`` x roll and pitch."""
        return -self.gaps(data.q, torque) * np.array([1.0, self.weight, self.weight])


@dataclass(frozen=True, eq=False)
class ContactModel:
    """What is free: the plane, the contact's tilts, robot parameters, joint compliances.

    Its rows come weighted (``n_markers`` 1, no pose rows: :func:`~.solve.fit` weighs them 1).

    Attributes:
        params: The free robot parameters.
        tangent: The start normal's tangent plane ``(3, 2)``.
        compliance: Joints (0-based) whose compliance is free.
    """

    params: ParameterSet
    tangent: np.ndarray
    compliance: tuple[int, ...] = ()

    n_markers = 1
    pose = False

    def size(self) -> int:
        """Number of free parameters."""
        return PLANE_COLUMNS + len(self.params) + len(self.compliance)

    def names(self) -> tuple[str, ...]:
        """Column names (a compliance: ``c<row>``, e.g. ``c3``)."""
        comp = tuple(compliance_name(j) for j in self.compliance)
        return (
            "plane_nx",
            "plane_ny",
            "plane_h",
            "contact_rx",
            "contact_ry",
            *self.params.names,
            *comp,
        )

    def apply(self, start: ContactState, x: np.ndarray) -> ContactState:
        """The state at parameters x (x = 0 is ``start``)."""
        n = start.normal + self.tangent @ x[:2]
        C = start.contact.copy()
        C[:3, :3] = start.contact[:3, :3] @ rotation_matrix(np.array([x[3], x[4], 0.0]))
        p = PLANE_COLUMNS + len(self.params)
        mdh = self.params.apply(start.mdh, x[PLANE_COLUMNS:p]) if len(self.params) else start.mdh
        c = start.compliance
        if self.compliance:
            c = np.zeros(start.mdh.n) if c is None else np.array(c, dtype=float)
            c[list(self.compliance)] += x[p:]
        return dataclasses.replace(
            start,
            mdh=mdh,
            contact=C,
            normal=n / np.linalg.norm(n),
            height=start.height + float(x[2]),
            compliance=c,
        )

    def jacobian(self, start: ContactState, x: np.ndarray, data, torque=None) -> np.ndarray:
        """Weighted d(gap)/dx ``(m, 3, size)``."""
        s = self.apply(start, x)
        q = s.joints(data.q, torque)
        kin = s.mdh.kinematics(q)
        R, p = kin.R[:, -1], kin.p[:, -1]
        RC = R @ s.contact[:3, :3]
        point = p + R @ s.contact[:3, 3]
        seen = np.einsum("mji,j->mi", RC, s.normal)
        D = tilt_derivatives(seen)  # (m, 2, 3)
        J = np.zeros((len(q), 3, self.size()))
        raw = start.normal + self.tangent @ x[:2]
        dn = (np.eye(3) - np.outer(s.normal, s.normal)) @ self.tangent / np.linalg.norm(raw)
        J[:, 0, :2] = point @ dn
        J[:, 1:, :2] = D @ np.swapaxes(RC, 1, 2) @ dn
        J[:, 0, 2] = -1.0
        Jr = left_jacobian(-np.array([x[3], x[4], 0.0]))[:, :2]
        J[:, 1:, 3:5] = D @ skew(seen) @ Jr
        if len(self.params) or self.compliance:
            offsets = tuple(offset_parameter(s.mdh, j) for j in self.compliance)
            pset = ParameterSet("columns", (*self.params.parameters, *offsets))
            marker = Measurement.of("pose", tuple(s.contact[:3, 3]))
            W6 = identification_jacobian(s.mdh, pset, q, marker, kin).reshape(len(q), 6, -1)
            if self.compliance:  # d/dc_j = tau_j d/dq_j = tau_j sign_j d(offset_j)
                joints = list(self.compliance)
                gain = np.asarray(torque, dtype=float)[:, joints] * s.mdh.sign[1:-1][joints]
                W6[:, :, len(self.params) :] *= gain[:, None, :]
            J[:, 0, PLANE_COLUMNS:] = np.einsum("i,mik->mk", s.normal, W6[:, :3])
            turn = np.swapaxes(RC, 1, 2) @ skew(s.normal)
            J[:, 1:, PLANE_COLUMNS:] = D @ turn @ W6[:, 3:]
        return J * np.array([1.0, s.weight, s.weight])[None, :, None]
