"""Prototype of a contact calibration on a chain between any two frames (for the TALOS study).

Not calib's model: a chain read from Pinocchio (no MDH rows), traversed from the base frame to
the tool, with the joints on the base side traversed backwards. Each joint ``j`` on the path
contributes ``M_j Exp(xi_j) X_j(q_j + d_j)`` (forward) or its inverse (backward), with
``M_j`` Pinocchio's joint placement, ``xi_j`` a 6-vector error of that placement (translation
[m], rotation vector [rad], in the joint's frame), ``d_j`` a joint offset [rad]. Joint
compliance adds ``c_j tau_j(q)`` to ``q_j``, ``tau_j`` the gravity torque the joint carries
when the robot stands on the base foot. Residuals and their Jacobian (analytic: the
adjoint of each error's place, seen at the contact frame) are those of
:func:`calib.calibration.contact_checks.register_contacts`: height, roll, pitch of the contact
in the plane's frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from calib.kinematics.so3 import rotation_matrix, skew, tilt_derivatives, tilts

TORQUE_SCALE = 100.0
"""Compliance parameters are ``c * TORQUE_SCALE`` [rad], so that all parameters are ~rad."""


def frame_id(model: pin.Model, name: str) -> int:
    """Frame id by name (the link's BODY frame first)."""
    ids = [i for i, f in enumerate(model.frames) if f.name == name]
    bodies = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
    return (bodies or ids)[0]


def joint_axis(joint) -> np.ndarray:
    """Unit axis ``(3,)`` of a revolute Pinocchio joint model, in its own frame."""
    short = joint.shortname()
    if short in ("JointModelRX", "JointModelRY", "JointModelRZ"):
        return np.eye(3)["XYZ".index(short[-1])]
    if short == "JointModelRevoluteUnaligned":
        return np.asarray(joint.axis, dtype=float)
    raise ValueError(f"joint model {short} is not a revolute joint")


@dataclass(frozen=True, eq=False)
class Chain:
    """A path base -> tool in a Pinocchio model.

    Attributes:
        model: The Pinocchio model (never modified).
        base, tool: Frame ids.
        joints: Names of the path's joints, base to tool.
        reversed: True for a joint traversed backwards (on the base's side).
        placements: ``M_j`` ``(n, 4, 4)``; axes ``(n, 3)``; ``pre`` = base frame's placement
            inverse, ``post`` = tool frame's placement (in their parent joints' frames).
    """

    model: pin.Model
    base: int
    tool: int
    joints: tuple[str, ...]
    reversed: tuple[bool, ...]
    placements: np.ndarray
    axes: np.ndarray
    pre: np.ndarray
    post: np.ndarray

    @property
    def n(self) -> int:
        return len(self.joints)


def load(model: pin.Model, base: str, tool: str) -> Chain:
    """The path between two frames, through their common ancestor."""
    b, t = frame_id(model, base), frame_id(model, tool)
    up = list(model.supports[model.frames[b].parentJoint])
    down = list(model.supports[model.frames[t].parentJoint])
    common = [j for j in up if j in down][-1]
    back = [j for j in reversed(up) if j not in down or j == common][:-1]
    fwd = [j for j in down if j not in up]
    ids = back + fwd
    return Chain(
        model,
        b,
        t,
        tuple(model.names[j] for j in ids),
        tuple([True] * len(back) + [False] * len(fwd)),
        np.array([model.jointPlacements[j].homogeneous for j in ids]),
        np.array([joint_axis(model.joints[j]) for j in ids]),
        np.linalg.inv(model.frames[b].placement.homogeneous),
        model.frames[t].placement.homogeneous,
    )


def _rot(axes: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Homogeneous rotations ``(m, 4, 4)`` about one axis by angles ``(m,)``."""
    T = np.tile(np.eye(4), (len(angles), 1, 1))
    T[:, :3, :3] = rotation_matrix(np.outer(angles, axes))
    return T


def _exp6(xi: np.ndarray) -> np.ndarray:
    return pin.exp6(pin.Motion(xi[:3], xi[3:])).homogeneous


@dataclass(frozen=True, eq=False)
class Kinematics:
    """Tool placements and where each joint's errors enter (for the Jacobian).

    Attributes:
        T: Tool placements in the base frame ``(m, 4, 4)``.
        at_placement: Prefix products where ``xi_j`` enters ``(n, m, 4, 4)``; sign ``(n,)``.
        at_offset: Prefix products where ``d_j`` enters ``(n, m, 4, 4)``.
        signs: +1 forward, -1 backward ``(n,)``.
        jexp: Right Jacobians of ``Exp`` at each ``xi_j`` ``(n, 6, 6)``.
    """

    T: np.ndarray
    at_placement: np.ndarray
    at_offset: np.ndarray
    signs: np.ndarray
    jexp: np.ndarray


def kinematics(chain: Chain, q: np.ndarray, xi: np.ndarray | None = None) -> Kinematics:
    """Forward kinematics of the chain at joint values ``q`` ``(m, n)`` with placement errors."""
    m = len(q)
    xi = np.zeros((chain.n, 6)) if xi is None else xi
    T = np.broadcast_to(chain.pre, (m, 4, 4)).copy()
    at_p, at_o = [], []
    for j in range(chain.n):
        M = chain.placements[j] @ _exp6(xi[j])
        if chain.reversed[j]:
            T = T @ _rot(chain.axes[j], -q[:, j])
            at_p.append(T)
            at_o.append(T)
            T = T @ np.linalg.inv(M)
        else:
            T = T @ M
            at_p.append(T)
            T = T @ _rot(chain.axes[j], q[:, j])
            at_o.append(T)
    signs = np.where(chain.reversed, -1.0, 1.0)
    jexp = np.array([pin.Jexp6(pin.Motion(x[:3], x[3:])) for x in xi])
    return Kinematics(T @ chain.post, np.array(at_p), np.array(at_o), signs, jexp)


def _adjoint(G: np.ndarray) -> np.ndarray:
    """Adjoint matrices ``(..., 6, 6)`` (twists as (v, w)) of placements ``(..., 4, 4)``."""
    R, p = G[..., :3, :3], G[..., :3, 3]
    A = np.zeros((*G.shape[:-2], 6, 6))
    A[..., :3, :3] = R
    A[..., :3, 3:] = skew(p) @ R
    A[..., 3:, 3:] = R
    return A


def contact_twists(chain: Chain, kin: Kinematics, contact: np.ndarray):
    """Body twists of the contact frame per unit error ``(m, 6, n, 7)``: xi_j (6), then d_j."""
    end = kin.T @ contact
    inv_end = np.linalg.inv(end)
    Ap = _adjoint(inv_end[None] @ kin.at_placement) * kin.signs[:, None, None, None]
    Ap = Ap @ kin.jexp[:, None]
    Ao = _adjoint(inv_end[None] @ kin.at_offset)
    off = np.einsum("jmab,jb->jma", Ao[..., 3:], chain.axes) * kin.signs[:, None, None]
    out = np.concatenate([Ap, off[..., None]], axis=-1)  # (n, m, 6, 7)
    return np.transpose(out, (1, 2, 0, 3)), end


def torques(chain: Chain, Q: np.ndarray, other_leg: str | None) -> np.ndarray:
    """Gravity torque ``(m, n)`` [N m] each chain joint carries, standing on the base foot.

    The load of a forward joint is its subtree; of a backward joint (the standing leg), the
    rest of the robot (without ``other_leg``'s subtree, which stands on its own foot).
    Gravity is -z of the base (sole) frame. ``Q``: Pinocchio configurations ``(m, nq)``.
    """
    model = chain.model
    data = model.createData()
    skip = model.getJointId(other_leg) if other_leg else None
    out = np.zeros((len(Q), chain.n))
    for i, q in enumerate(Q):
        pin.framesForwardKinematics(model, data, q)
        pin.centerOfMass(model, data, q, True)
        g = -9.81 * data.oMf[chain.base].rotation[:, 2]

        def com(j: int) -> np.ndarray:  # Pinocchio 3: a subtree's centre in its joint's frame
            return data.com[0] if j == 0 else data.oMi[j].act(data.com[j])

        total_m, total_mc = data.mass[0], data.mass[0] * com(0)
        if skip is not None:
            total_m = total_m - data.mass[skip]
            total_mc = total_mc - data.mass[skip] * com(skip)
        for k, name in enumerate(chain.joints):
            j = model.getJointId(name)
            o, a = data.oMi[j].translation, data.oMi[j].rotation @ chain.axes[k]
            if chain.reversed[k]:
                mass, mc = total_m - data.mass[j], total_mc - data.mass[j] * com(j)
                out[i, k] = -a @ np.cross(mc / mass - o, mass * g)
            else:
                out[i, k] = a @ np.cross(com(j) - o, data.mass[j] * g)
    return out


@dataclass(frozen=True, eq=False)
class Plane:
    """A plane: unit normal and height (``n . x = h``) in the base frame."""

    normal: np.ndarray
    height: float

    def matrix(self) -> np.ndarray:
        """4x4 with z = normal (x, y: any; origin: the foot of the base origin)."""
        n = self.normal
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        ex = helper - (helper @ n) * n
        ex /= np.linalg.norm(ex)
        P = np.eye(4)
        P[:3, :3] = np.column_stack([ex, np.cross(n, ex), n])
        P[:3, 3] = self.height * n
        return P


def tangent(n: np.ndarray) -> np.ndarray:
    """Orthonormal basis ``(3, 2)`` of the plane orthogonal to a unit vector."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(n, e1)])


def plane_rows(end: np.ndarray, twists: np.ndarray, plane: Plane, weight: float):
    """Weighted residuals ``(m, 3)``, their Jacobian in the robot's errors ``(m, 3, n, 7)``,
    in the plane ``(m, 3, 3)`` (two tilts of the normal, height) and in the contact's tilt
    about its own x and y ``(m, 3, 2)``."""
    R, x = end[:, :3, :3], end[:, :3, 3]
    n = plane.normal
    seen = np.einsum("mji,j->mi", R, n)
    r = np.column_stack([x @ n - plane.height, weight * tilts(seen)])
    L = np.zeros((len(end), 3, 6))
    L[:, 0, :3] = seen
    D = weight * tilt_derivatives(seen)
    L[:, 1:, 3:] = D @ skew(seen)
    J_robot = np.einsum("mab,mbjk->majk", L, twists)
    B = tangent(n)
    J_plane = np.zeros((len(end), 3, 3))
    J_plane[:, 0, :2] = x @ B
    J_plane[:, 1:, :2] = D @ np.swapaxes(R, 1, 2) @ B
    J_plane[:, 0, 2] = -1.0
    return r, J_robot, J_plane, L[:, :, 3:5]
