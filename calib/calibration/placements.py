"""Errors ``E_j`` of URDF joint placements (origin ``O_j E_j``) shared by chains of one robot.

Rationale and measurements: docs/developers/engine.md#placements
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple, cast

import numpy as np
import pinocchio as pin

from ..exceptions import InvalidArgumentError
from ..identification.base_columns import preference_order
from ..identification.jacobian import identification_jacobian
from ..identification.measures import Measurement
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.frames import joint_placements, motion_axis
from ..kinematics.mdh import PARALLEL_TOL, MDHModel, from_chain
from ..kinematics.robot import Chain, pin_configurations
from ..kinematics.so3 import left_jacobian, rotation_matrix, skew

__all__ = [
    "COMPONENTS",
    "ChainPath",
    "JointFrames",
    "Placements",
    "chain_frames",
    "component_of",
    "joint_twists",
    "mdh_directions",
    "offset_component",
    "twist_columns",
    "zero_frames",
]

COMPONENTS = ("x", "y", "z", "rx", "ry", "rz")  # of a joint's placement error, in its axis frame
DIRECTION_CONFIGS = 12  # random configurations matching an MDH parameter to a joint's errors


def _axis_bases(model: pin.Model, ids) -> np.ndarray:
    """Each joint's axis frame in its joint frame ``(J, 3, 3)``: z its axis, x near its x."""
    S = np.array([motion_axis(model.joints[j]) for j in ids]).reshape(-1, 6)
    slides = _norms(S[:, :3]) > 0.5
    u = np.where(slides[:, None], S[:, :3], S[:, 3:])
    u = u / _norms(u).reshape(-1, 1)
    k = (np.abs(u[:, 0]) >= 0.9).astype(int)  # the helper: the frame's x, or y near x
    ex = np.eye(3)[k] - u[np.arange(len(u)), k, None] * u  # helper - (helper . u) u
    ex /= _norms(ex).reshape(-1, 1)
    return np.stack([ex, _cross(u, ex), u], axis=2)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise ``a x b`` ``(k, 3)``: ``np.cross``'s arithmetic without its overhead."""
    i, j = [1, 2, 0], [2, 0, 1]  # component k: a_i b_j - a_j b_i
    return a[:, i] * b[:, j] - a[:, j] * b[:, i]


def _norms(rows: np.ndarray) -> np.ndarray:
    """Each row's norm ``(k,)``, as ``np.linalg.norm`` takes one vector's (its dot product)."""
    return np.sqrt(np.matmul(rows[:, None, :], rows[:, :, None])[:, 0, 0])


def offset_component(model: pin.Model, jid: int) -> str:
    """``rz`` for a revolute joint, ``z`` for a prismatic one (its offset)."""
    S = motion_axis(model.joints[jid])
    return "z" if np.linalg.norm(S[:3]) > 0.5 else "rz"


def component_of(direction: np.ndarray) -> int | None:
    """The one component (its index) a direction ``(6 J,)`` of placement errors moves, or None."""
    c = int(np.argmax(np.abs(direction)))
    return c if direction[c] >= (1.0 - 1e-9) * np.linalg.norm(direction) > 0 else None


class JointFrames(NamedTuple):
    """A chain's frames ``R`` ``(m, n + 1, 3, 3)``, ``p`` ``(m, n + 1, 3)`` [m], the tool's last."""

    R: np.ndarray
    p: np.ndarray


@dataclass(frozen=True, eq=False)
class ChainPath:
    """A chain as arrays: ``fixed`` ``(n + 1, 4, 4)`` transforms between its joints' axis frames."""

    fixed: np.ndarray
    prismatic: np.ndarray
    sign: np.ndarray
    columns: np.ndarray

    @staticmethod
    def of(chain: Chain, zero: tuple, bases: np.ndarray, columns: np.ndarray) -> ChainPath:
        """The path of ``chain`` from its ``zero_frames`` and its joints' axis ``bases``."""
        frames, tool = zero
        A = np.array(frames, dtype=float)  # each joint's axis frame in the base frame
        A[:, :3, :3] = A[:, :3, :3] @ bases
        ends = np.concatenate([np.eye(4)[None], A])
        fixed = np.linalg.inv(ends) @ np.concatenate([A, np.asarray(tool)[None]])
        sigma, sign = np.asarray(chain.sigma), np.asarray(chain.sign, dtype=float)
        return ChainPath(fixed, sigma == 1, sign, np.asarray(columns))

    def composed(self, y: np.ndarray, turns: np.ndarray | None = None) -> np.ndarray:
        """:attr:`fixed` with the errors ``y`` ``(J, 6)`` composed (``turns``: their ``R(w)``)."""
        rows = y[self.columns]
        if not rows.any():
            return self.fixed
        turns = rotation_matrix(rows[:, 3:]) if turns is None else turns
        E = np.zeros((len(rows), 4, 4))
        E[:, :3, :3], E[:, :3, 3], E[:, 3, 3] = turns, rows[:, :3], 1.0
        out = self.fixed.copy()
        back = (self.sign < 0).nonzero()[0]
        if not back.size:  # every joint forwards: the same products, on slices
            out[:-1] = out[:-1] @ E
            return out
        ahead = (self.sign > 0).nonzero()[0]
        out[ahead] = out[ahead] @ E[ahead]
        inverse = np.zeros((len(back), 4, 4))  # E^-1 = [R^T | -R^T v]
        inverse[:, :3, :3] = np.swapaxes(E[back, :3, :3], 1, 2)
        inverse[:, :3, 3] = -(inverse[:, :3, :3] @ rows[back, :3, None])[..., 0]
        inverse[:, 3, 3] = 1.0
        out[back + 1] = inverse @ out[back + 1]
        return out


def chain_frames(
    path: ChainPath, y: np.ndarray, q: np.ndarray, turns: np.ndarray | None = None
) -> JointFrames:
    """Every frame of the chain at configurations ``q`` ``(m, n)`` with the errors ``y``."""
    fixed = path.composed(y, turns)
    q = np.asarray(q, dtype=float).reshape(-1, len(path.sign))
    m, n = q.shape
    move = (q * path.sign).T  # (n, m)
    slide = np.where(path.prismatic[:, None], move, 0.0)
    turn = move - slide
    c, s = np.cos(turn)[:, None], np.sin(turn)[:, None]  # (n, 1, m)
    F, f = fixed[1:, :3, :3, None], fixed[1:, :3, 3, None]  # (n, 3, 3, 1), (n, 3, 1)
    # Component-major (joint, ..., configuration): every operation runs along the m
    # configurations, the innermost axis. Rot(z, turn) followed by the next fixed transform:
    local = np.empty((n, 3, 3, m))
    local[:, 0] = c * F[:, 0] - s * F[:, 1]
    local[:, 1] = s * F[:, 0] + c * F[:, 1]
    local[:, 2] = F[:, 2]
    step = np.empty((n, 3, m))  # and the origin's step, the slide along z included
    step[:, 0] = c[:, 0] * f[:, 0] - s[:, 0] * f[:, 1]
    step[:, 1] = s[:, 0] * f[:, 0] + c[:, 0] * f[:, 1]
    step[:, 2] = f[:, 2] + slide
    Rt = np.empty((n + 1, 3, 3, m))  # each joint's axis frame before its motion, the tool's
    pt = np.empty((n + 1, 3, m))
    Rt[0], pt[0] = fixed[0, :3, :3, None], fixed[0, :3, 3, None]
    for k in range(n):
        np.einsum("ilm,ljm->ijm", Rt[k], local[k], out=Rt[k + 1])
        np.einsum("ilm,lm->im", Rt[k], step[k], out=pt[k + 1])
        pt[k + 1] += pt[k]
    back = (path.sign < 0).nonzero()[0]  # their errors act after their motion
    if back.size:
        Rb, cb, sb = Rt[back], c[back], s[back]  # (b, 3, 3, m) copy, (b, 1, m)
        pt[back] += Rb[:, :, 2] * slide[back, None]
        turned = Rb.copy()
        turned[:, :, 0] = cb * Rb[:, :, 0] + sb * Rb[:, :, 1]
        turned[:, :, 1] = cb * Rb[:, :, 1] - sb * Rb[:, :, 0]
        Rt[back] = turned
    R, p = Rt.transpose(3, 0, 1, 2), pt.transpose(2, 0, 1)  # (m, n + 1, ...) views
    return JointFrames(R, p)


@dataclass(frozen=True, eq=False)
class Placements:
    """The placement errors ``y`` ``(J, 6)`` (x y z [m], rx ry rz [rad]) acting on ``model``."""

    nominal: pin.Model
    model: pin.Model
    joints: tuple[str, ...]
    ids: tuple[int, ...]
    bases: np.ndarray
    y: np.ndarray
    chains: tuple[Chain, ...] = ()
    paths: tuple[ChainPath, ...] = ()

    @staticmethod
    def of(chains: tuple[Chain, ...], zeros: tuple | None = None) -> Placements:
        """Zero errors on every joint of the chains (``zeros``: their :func:`zero_frames`)."""
        model = chains[0].model
        ids = tuple(dict.fromkeys(j for c in chains for j in c.joint_ids))
        bases = _axis_bases(model, ids)
        names = tuple(model.names[j] for j in ids)
        paths = []
        for c, zero in zip(chains, zero_frames(chains) if zeros is None else zeros, strict=True):
            columns = np.array([names.index(n) for n in c.joint_names], dtype=int)
            paths.append(ChainPath.of(c, zero, bases[columns], columns))
        y = np.zeros((len(ids), 6))
        return Placements(model, model, names, ids, bases, y, tuple(chains), tuple(paths))

    def names(self) -> tuple[str, ...]:
        """Column names, joint-major: ``<joint>:x`` ... ``<joint>:rz``."""
        return tuple(f"{j}:{c}" for j in self.joints for c in COMPONENTS)

    def shifted(self, dy: np.ndarray) -> Placements:
        """The errors plus ``dy`` ``(J * 6,)`` (``self`` for a zero ``dy``: same geometry)."""
        if not np.asarray(dy).any():
            return self
        return dataclasses.replace(self, y=self.y + np.reshape(dy, self.y.shape))

    def rebased(self) -> Placements:
        """The same robot with zero errors on a model that holds them (and paths that do)."""
        fixed = (p.composed(self.y, t) for p, t in zip(self.paths, self._turns, strict=True))
        paths = tuple(
            dataclasses.replace(p, fixed=f) for p, f in zip(self.paths, fixed, strict=True)
        )
        y = np.zeros_like(self.y)
        return dataclasses.replace(self, model=self.perturbed_model(), y=y, paths=paths)

    def frames(self, chain: Chain, q: np.ndarray) -> JointFrames:
        """The chain's frames at ``q`` ``(m, n)`` with the errors (:func:`chain_frames`)."""
        k = self._index(chain)
        return chain_frames(self.paths[k], self.y, q, self._turns[k])

    def path(self, chain: Chain) -> ChainPath:
        """The chain's path on :attr:`model` (InvalidArgumentError: not one of :attr:`chains`)."""
        return self.paths[self._index(chain)]

    def turns(self, chain: Chain) -> np.ndarray | None:
        """The rotations ``R(w)`` ``(n, 3, 3)`` of the chain's joints' errors (None: no error)."""
        return self._turns[self._index(chain)]

    @cached_property
    def _turns(self) -> tuple[np.ndarray | None, ...]:
        rows = (self.y[p.columns] for p in self.paths)
        return tuple(rotation_matrix(r[:, 3:]) if r.any() else None for r in rows)

    def _index(self, chain: Chain) -> int:
        for k, c in enumerate(self.chains):
            if c is chain or (c.base_id, c.tool_id) == (chain.base_id, chain.tool_id):
                return k
        raise InvalidArgumentError(
            f"{chain.base_frame} -> {chain.tool_frame} is not a chain of these placements"
        )

    def errors(self) -> dict[str, np.ndarray]:
        """``E_j`` ``(4, 4)`` (origin ``O_j E_j``) by joint name, of the joints moved."""
        model = self._robot()
        out = {}
        for name, jid in zip(self.joints, self.ids, strict=True):
            before, after = self.nominal.jointPlacements[jid], model.jointPlacements[jid]
            if not np.array_equal(before.homogeneous, after.homogeneous):
                out[name] = (before.inverse() * after).homogeneous
        return out

    def _robot(self) -> pin.Model:
        """The robot with the errors, to read: :attr:`model` itself when they are all zero."""
        return self.perturbed_model() if self.y.any() else self.model

    def perturbed_model(self) -> pin.Model:
        """A copy of the model with the joint placements ``O_j E_j``."""
        model = pin.Model(self.model)
        moved = np.flatnonzero(np.any(self.y != 0, axis=1))
        if not moved.size:  # a robot already settled: its copy
            return model
        B, y = self.bases[moved], self.y[moved]
        R = rotation_matrix((B @ y[:, 3:, None])[..., 0])  # every moved joint's at once
        v = (B @ y[:, :3, None])[..., 0]
        placements = model.jointPlacements  # the copy's own (a reference)
        for k, R_k, v_k in zip(moved.tolist(), R, v, strict=True):
            jid = self.ids[k]
            placements[jid] = placements[jid] * pin.SE3(R_k, v_k)
        return model

    def start_models(self, chains: tuple[Chain, ...], states) -> tuple[MDHModel, ...]:
        """:meth:`chain_models` at zero errors, or the states' own models when they are those."""
        mine = tuple(getattr(s, "mdh", None) for s in states)
        if not self.y.any() and all(
            m is not None
            and m.source is not None
            and m.source[0] is c
            and m.source[1] == PARALLEL_TOL
            for m, c in zip(mine, chains, strict=True)
        ):
            return cast(tuple[MDHModel, ...], mine)
        return self.chain_models(chains)

    def chain_models(self, chains: tuple[Chain, ...]) -> tuple[MDHModel, ...]:
        """The MDH model of each chain on the perturbed robot (one walk for equal zeros)."""
        model = self._robot()
        moved = tuple(dataclasses.replace(c, model=model, ideal_model=None) for c in chains)
        return tuple(from_chain(c, zero=z) for c, z in zip(moved, zero_frames(moved), strict=True))


def zero_frames(chains: tuple[Chain, ...]) -> tuple:
    """Each chain's ``zero_frames`` on the first's model (one walk for one zero configuration)."""
    model = chains[0].model
    moved = [
        c if c.model is model else dataclasses.replace(c, model=model, ideal_model=None)
        for c in chains
    ]
    q0 = [pin_configurations(model, c.q_ref, c.joint_ids, np.zeros((1, c.n)))[0] for c in moved]
    ends = [model.frames[f].parentJoint for c in moved for f in (c.base_id, c.tool_id)]
    if all(np.array_equal(q, q0[0]) for q in q0):  # the joint placements at each zero
        oMi = [joint_placements(model, q0[0], last=tuple(ends))] * len(moved)
    else:
        oMi = [
            joint_placements(model, q, last=tuple(ends[2 * i : 2 * i + 2]))
            for i, q in enumerate(q0)
        ]
    return tuple(c.zero_frames(o) for c, o in zip(moved, oMi, strict=True))


def joint_twists(
    placements: Placements, chain: Chain, kin: JointFrames
) -> tuple[np.ndarray, np.ndarray]:
    """Angular, linear velocity ``(m, n, 3, 6)`` of the tool side per unit error of a component."""
    by_v, wv, by_w = _twist_blocks(placements, chain, kin)
    m, n = wv.shape[:2]
    ang, lin = np.zeros((m, n, 3, 6)), np.zeros((m, n, 3, 6))
    ang[..., 3:], lin[..., :3], lin[..., 3:] = wv, by_v, by_w
    return ang, lin


def twist_columns(
    placements: Placements, chain: Chain, kin: JointFrames, lift: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`joint_twists` (linear, angular ``(m, 3, free)``) along directions ``lift``.

    Rationale and measurements: docs/developers/engine.md#twist_columns
    """
    by_v, wv, by_w = _twist_blocks(placements, chain, kin)
    m, n = wv.shape[:2]
    ang, lin = np.zeros((m, 3, n, 6)), np.zeros((m, 3, n, 6))
    ang[..., 3:], lin[..., :3], lin[..., 3:] = (np.swapaxes(b, 1, 2) for b in (wv, by_v, by_w))
    per_joint = lift.reshape(len(lift), len(placements.joints), len(COMPONENTS))
    chain_lift = per_joint[:, placements.path(chain).columns].reshape(len(lift), -1).T
    return lin.reshape(m, 3, -1) @ chain_lift, ang.reshape(m, 3, -1) @ chain_lift


def _twist_blocks(placements: Placements, chain: Chain, kin: JointFrames):
    """:func:`joint_twists`' non-zero blocks ``(m, n, 3, 3)``: linear per dv, angular per dw."""
    n = chain.n
    sign = np.asarray(chain.sign, dtype=float)
    w = placements.y[placements.path(chain).columns, 3:]  # (n, 3)
    RF = sign[:, None, None] * kin.R[:, :n]  # (m, n, 3, 3)
    turns = placements.turns(chain)  # None: no error at all
    if turns is not None and w.any():
        wv = RF @ left_jacobian(-w)  # angular velocity per d(rx ry rz): right Jacobian of R(w)
        # d(origin) per dv: R(w)^T contiguous, as one product per frame reads it fastest
        by_v = RF @ np.ascontiguousarray(np.swapaxes(turns, 1, 2))
    else:  # no rotation error (a start, a rebase): both products by the identity, which
        wv = RF + 0.0  # make a zero +0.0 (the sign Householder reflections read later)
        by_v = wv
    return by_v, wv, skew(kin.p[:, :n]) @ wv  # and the linear per dw


def mdh_directions(
    placements: Placements, chain: Chain, mdh: MDHModel, label: str | ParameterSet
) -> tuple[np.ndarray, tuple[str, ...]]:
    """The chain's MDH parameters of rows 1..n as directions ``(D, 6 J)`` of placement errors.

    Names ``<joint>:<parameter>``; ``placements``: zero errors; ``label``: a level or a set.
    Rationale: docs/developers/engine.md#mdh_directions
    """
    pset = parameter_set(mdh, label) if isinstance(label, str) else label
    chosen, n = [pset.parameters[i] for i in preference_order(mdh, pset)], chain.n
    params = ParameterSet(pset.label, tuple(p for p in chosen if 1 <= p.row <= n))
    q = chain.random_configurations(DIRECTION_CONFIGS, 0)
    pose = Measurement.of("pose", (0.0, 0.0, 0.0))
    W = identification_jacobian(mdh, params, q, pose).reshape(len(q), 6, -1)
    columns = placements.path(chain).columns
    kin = placements.frames(chain, q)
    ang, lin = joint_twists(placements, chain, kin)
    vel = lin - skew(kin.p[:, -1])[:, None] @ ang  # the tool origin's velocity
    A = np.concatenate([vel, ang], axis=2)  # (m, n, 6, 6)
    Wf = W.reshape(-1, W.shape[2])  # every parameter's motion, one column each
    scale = np.linalg.norm(Wf, axis=0)
    # per joint: each parameter's components (6, P) (every parameter at once), whether
    # they match it (n, P)
    C = np.stack([np.linalg.lstsq(A[:, i].reshape(-1, 6), Wf, rcond=None)[0] for i in range(n)])
    miss = np.linalg.norm(A.transpose(1, 0, 2, 3).reshape(n, -1, 6) @ C - Wf, axis=1)
    fits = (miss <= 1e-8 * scale) & (scale > 0)
    out = np.zeros((len(params.parameters), 6 * len(placements.joints)))
    names: list[str] = []
    for k, p in enumerate(params.parameters):
        i = next((i for i in (p.row - 1, p.row - 2, p.row) if 0 <= i < n and fits[i, k]), None)
        if i is not None:
            out[len(names), 6 * columns[i] : 6 * columns[i] + 6] = C[i, :, k]
            names.append(f"{chain.joint_names[i]}:{p.name}")
    return out[: len(names)], tuple(names)
