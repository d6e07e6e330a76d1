"""Errors of URDF joint placements shared by several chains of one robot.

Each URDF joint j on a chain has a placement ``O_j`` in its parent link (its ``<origin>``).
Its error is a small rigid motion ``E_j = [R(w) | v]`` after it: the calibrated origin is
``O_j E_j``. A joint on several chains (a humanoid's torso, on both arms' chains from the
feet) has one error, seen by every chain through it: this is how chains share.

The six numbers of ``E_j`` are expressed in the joint's *axis frame*: z along the joint
axis, x the joint frame's x (or y) made perpendicular to it. Their names are
``<joint>:x``, ``:y``, ``:z`` (translation [m]) and ``<joint>:rx``, ``:ry``, ``:rz``
(rotation [rad]); ``:rz`` of a revolute joint and ``:z`` of a prismatic one are its offset.

A chain between two frames of the tree may traverse joints backwards (``Chain.sign``); each
chain's kinematics is its MDH model (:func:`calib.kinematics.mdh.from_chain`) of the
perturbed Pinocchio model, so every chain sees the same perturbed robot.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..identification.base_columns import preference_order
from ..identification.jacobian import identification_jacobian
from ..identification.measures import Measurement
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.frames import joint_placements, motion_axis
from ..kinematics.mdh import MDHModel, frames_at_zero, from_chain
from ..kinematics.robot import Chain
from ..kinematics.so3 import left_jacobian, rotation_matrix, skew

__all__ = [
    "COMPONENTS",
    "DIRECTION_CONFIGS",
    "Placements",
    "axis_basis",
    "joint_twists",
    "mdh_directions",
    "offset_component",
    "placement_error",
]

COMPONENTS = ("x", "y", "z", "rx", "ry", "rz")
"""The six components of a joint's placement error, in its axis frame."""


def axis_basis(model: pin.Model, jid: int) -> np.ndarray:
    """The axis frame's axes in the joint frame ``(3, 3)``: columns x, y, z (z = the axis)."""
    S = motion_axis(model.joints[jid])
    u = S[:3] if np.linalg.norm(S[:3]) > 0.5 else S[3:]
    u = u / np.linalg.norm(u)
    helper = np.eye(3)[0] if abs(u[0]) < 0.9 else np.eye(3)[1]
    ex = helper - (helper @ u) * u
    ex /= np.linalg.norm(ex)
    return np.column_stack([ex, np.cross(u, ex), u])


def offset_component(model: pin.Model, jid: int) -> str:
    """``rz`` for a revolute joint, ``z`` for a prismatic one (its offset)."""
    S = motion_axis(model.joints[jid])
    return "z" if np.linalg.norm(S[:3]) > 0.5 else "rz"


def placement_error(basis: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``E = [R(w) | v]`` ``(4, 4)`` of axis-frame components ``y`` (x y z rx ry rz)."""
    E = np.eye(4)
    E[:3, :3] = rotation_matrix(basis @ y[3:])
    E[:3, 3] = basis @ y[:3]
    return E


@dataclass(frozen=True, eq=False)
class Placements:
    """The placement errors of the joints of several chains of one robot.

    The errors ``y`` act on the placements of ``model``, the nominal robot or a robot
    already fitted (:meth:`rebased`): a fit is refined by fitting again from its result,
    each round composing its errors with the previous ones (the components kept by a rank
    test span the identifiable motions to first order only; composing restores exactness).

    Attributes:
        nominal: The nominal Pinocchio model (never mutated).
        model: The model the errors ``y`` act on (``nominal`` or a fitted copy).
        joints: URDF names of the joints on any chain, each once.
        ids: Their Pinocchio joint indices.
        bases: Axis frame of each joint in its joint frame ``(J, 3, 3)``.
        y: Errors in the axis frames ``(J, 6)`` (x y z [m], rx ry rz [rad]).
    """

    nominal: pin.Model
    model: pin.Model
    joints: tuple[str, ...]
    ids: tuple[int, ...]
    bases: np.ndarray
    y: np.ndarray

    @staticmethod
    def of(chains: tuple[Chain, ...]) -> Placements:
        """Zero errors on every joint of the chains (which share one model)."""
        model = chains[0].model
        ids = tuple(dict.fromkeys(j for c in chains for j in c.joint_ids))
        bases = np.array([axis_basis(model, j) for j in ids]).reshape(-1, 3, 3)
        names = tuple(model.names[j] for j in ids)
        return Placements(model, model, names, ids, bases, np.zeros((len(ids), 6)))

    def names(self) -> tuple[str, ...]:
        """Column names, joint-major: ``<joint>:x`` ... ``<joint>:rz``."""
        return tuple(f"{j}:{c}" for j in self.joints for c in COMPONENTS)

    def shifted(self, dy: np.ndarray) -> Placements:
        """The errors plus ``dy`` ``(J * 6,)`` (joint-major)."""
        return dataclasses.replace(self, y=self.y + np.reshape(dy, self.y.shape))

    def rebased(self) -> Placements:
        """The same robot with zero errors on a model that holds them."""
        return dataclasses.replace(self, model=self.perturbed_model(), y=np.zeros_like(self.y))

    def errors(self) -> dict[str, np.ndarray]:
        """``E_j`` ``(4, 4)`` from the nominal placement, by joint name, of the joints moved.

        The calibrated origin of joint j is ``O_j E_j``.
        """
        model = self.perturbed_model()
        out = {}
        for name, jid in zip(self.joints, self.ids, strict=True):
            before, after = self.nominal.jointPlacements[jid], model.jointPlacements[jid]
            if not np.array_equal(before.homogeneous, after.homogeneous):
                out[name] = (before.inverse() * after).homogeneous
        return out

    def perturbed_model(self) -> pin.Model:
        """A copy of the model with the joint placements ``O_j E_j``."""
        model = pin.Model(self.model)
        moved = np.flatnonzero(np.any(self.y != 0, axis=1))
        B, y = self.bases[moved], self.y[moved]
        R = rotation_matrix((B @ y[:, 3:, None])[..., 0])  # every moved joint's at once
        v = (B @ y[:, :3, None])[..., 0]
        for k, R_k, v_k in zip(moved, R, v, strict=True):
            jid = self.ids[k]
            model.jointPlacements[jid] = model.jointPlacements[jid] * pin.SE3(R_k, v_k)
        return model

    def chain_models(self, chains: tuple[Chain, ...]) -> tuple[MDHModel, ...]:
        """The MDH model of each chain on the perturbed robot."""
        return self.chain_geometry(chains)[0]

    def chain_geometry(
        self, chains: tuple[Chain, ...]
    ) -> tuple[tuple[MDHModel, ...], tuple[np.ndarray, ...]]:
        """Each chain's MDH model on the perturbed robot and its joint frames at q = 0.

        The joint frames (before each joint's motion, in the chain's base frame) are
        ``(n, 4, 4)`` per chain (see :func:`joint_twists`).
        """
        model = self.perturbed_model()
        moved = [dataclasses.replace(c, model=model, ideal_model=None) for c in chains]
        mdh, frames = [], []
        for c, oMi in zip(moved, _zero_placements(model, moved), strict=True):
            zero = c.zero_frames(oMi)
            mdh.append(from_chain(c, zero=zero))
            frames.append(zero[0])
        return tuple(mdh), tuple(frames)


def _zero_placements(model: pin.Model, chains: list[Chain]) -> list[dict]:
    """The joint placements at each chain's zero configuration: one walk for equal ones."""
    q0 = [c.pin_configurations(np.zeros(c.n))[0] for c in chains]
    ends = [model.frames[f].parentJoint for c in chains for f in (c.base_id, c.tool_id)]
    if all(np.array_equal(q, q0[0]) for q in q0):
        return [joint_placements(model, q0[0], last=tuple(ends))] * len(chains)
    return [
        joint_placements(model, q, last=tuple(ends[2 * i : 2 * i + 2])) for i, q in enumerate(q0)
    ]


def joint_twists(
    placements: Placements,
    chain: Chain,
    mdh: MDHModel,
    frames: np.ndarray,
    kin,
    columns: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Motion of the tool side of the chain per unit error of each joint's components.

    A joint frame ``F`` (before the joint's motion) moves with the MDH frame of the link
    that carries it: frame k-1 for a joint traversed forwards (row k), frame k backwards.
    An error ``dy`` moves everything on the chain's tool side of the joint by the body
    twist ``(R(w)^T dv, J_r(w) dw)`` of ``F`` (with a minus sign backwards).

    Args:
        placements: The current errors (of the model ``mdh`` was made from).
        chain: The nominal chain.
        mdh: Its MDH model on the perturbed robot.
        frames: Its joint frames at q = 0 on the perturbed robot ``(n, 4, 4)``
            (:meth:`Placements.chain_geometry`).
        kin: ``mdh.kinematics(q)``.
        columns: Index into ``placements.joints`` of each chain joint ``(n,)``.

    Returns:
        Angular ``(m, n, 3, 6)`` and linear ``(m, n, 3, 6)`` velocity of the base-frame
        origin's point moving with the tool side, per component (x y z rx ry rz).
    """
    sign = np.asarray(chain.sign, dtype=float)
    a = np.where(sign > 0, np.arange(chain.n), np.arange(chain.n) + 1)  # the carrying frame
    K = np.linalg.inv(frames_at_zero(mdh)[a]) @ frames  # (n, 4, 4), every joint at once
    B = placements.bases[columns]  # (n, 3, 3), every chain joint's at once
    w = np.einsum("nab,nb->na", B, placements.y[columns, 3:])
    body_v = np.swapaxes(rotation_matrix(w), 1, 2) @ B  # d(origin) per dv, in F
    body_w = left_jacobian(-w) @ B  # right Jacobian of R(w), in F
    Ra = kin.R[:, a]  # (m, n, 3, 3)
    RF = sign[:, None, None] * (Ra @ K[:, :3, :3])
    pF = kin.p[:, a] + (Ra @ K[:, :3, 3:])[..., 0]
    wv = RF @ body_w  # (m, n, 3, 3) angular velocity per d(rx ry rz)
    m = kin.R.shape[0]
    ang = np.zeros((m, chain.n, 3, 6))
    lin = np.zeros((m, chain.n, 3, 6))
    ang[..., 3:] = wv
    lin[..., :3] = RF @ body_v
    lin[..., 3:] = skew(pF) @ wv
    return ang, lin


DIRECTION_CONFIGS = 12
"""Random configurations at which an MDH parameter's motion is matched to a joint's errors."""


def mdh_directions(
    placements: Placements,
    chain: Chain,
    mdh: MDHModel,
    frames: np.ndarray,
    seed: int = 0,
    label: str = "complete",
) -> tuple[np.ndarray, tuple[str, ...]]:
    """The chain's MDH parameters of joint rows 1..n as directions of joint placement errors.

    An MDH parameter of row k moves everything on the tool side of one link rigidly: it is
    an error of the placement of joint k (of joint k-1 for a row traversed backwards, whose
    link lies on the base side). Its direction is the combination of that joint's six
    components that moves the tool as the parameter does, at ``DIRECTION_CONFIGS`` random
    configurations (exactly, or the parameter is not offered: a row-1 tilt backwards moves
    the base frame's own fixed joint, which the plane takes). The parameters come in the
    single-chain pipeline's order of preference.

    Args:
        placements: The (zero) placement errors of the robot.
        chain: The chain.
        mdh: Its MDH model on the robot of ``placements``.
        frames: Its joint frames at q = 0 (:meth:`Placements.chain_geometry`).
        seed: Seed of the configurations.
        label: The MDH parameter set offered: ``complete`` or ``paper``.

    Returns:
        Directions ``(D, 6 J)`` (in the units of the MDH parameters) and their names
        ``<joint>:<parameter>`` (the parameter's name in this chain's rows).
    """
    pset = parameter_set(mdh, label)
    chosen = [pset.parameters[i] for i in preference_order(mdh, pset)]
    params = ParameterSet(label, tuple(p for p in chosen if 1 <= p.row <= mdh.n))
    q = chain.random_configurations(DIRECTION_CONFIGS, seed)
    kin = mdh.kinematics(q)
    pose = Measurement.of("pose", (0.0, 0.0, 0.0))
    W = identification_jacobian(mdh, params, q, pose, kin).reshape(len(q), 6, -1)
    columns = np.array([placements.joints.index(n) for n in chain.joint_names])
    ang, lin = joint_twists(placements, chain, mdh, frames, kin, columns)
    vel = lin - skew(kin.p[:, -1])[:, None] @ ang  # the tool origin's velocity
    A = np.concatenate([vel, ang], axis=2)  # (m, n, 6, 6)
    out, names = [], []
    for k, p in enumerate(params.parameters):
        w = W[:, :, k].reshape(-1)
        for i in (p.row - 1, p.row - 2, p.row):
            if not 0 <= i < chain.n:
                continue
            Ai = A[:, i].reshape(-1, 6)
            c = np.linalg.lstsq(Ai, w, rcond=None)[0]
            scale = float(np.linalg.norm(w))
            if float(np.linalg.norm(Ai @ c - w)) <= 1e-8 * scale and scale > 0:
                d = np.zeros(6 * len(placements.joints))
                d[6 * columns[i] : 6 * columns[i] + 6] = c
                out.append(d)
                names.append(f"{chain.joint_names[i]}:{p.name}")
                break
    return np.array(out).reshape(-1, 6 * len(placements.joints)), tuple(names)
