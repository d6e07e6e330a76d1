"""The error model of flush contacts on several chains of one robot, fitted together.

A state is the robot's joint placement errors (:class:`~.placements.Placements`, one error
per URDF joint, whatever chains it is on) and, per chain, its
:class:`~.contact_model.ContactState` (its MDH model on the perturbed robot, its contact
frame and plane, :class:`~.contact_frames.ContactFrames`, and its tilt weight). The
parameters x: for each object (a plane, or a ``fixed-pose`` chain's pose) its kind's object
unknowns (a plane's height and two tilts, a pose's six), for each chain its contact's (a flush
contact's two tilts, none for a fixed pose), then components of joint placement errors
(``<joint>:x`` ... ``:rz``). A plane touched by several chains is one plane (their chains
share the base frame); each chain has its own contact frame.

Each chain's kind is its touches' (:attr:`ContactData.kind`): ``plane`` (flush touches of a
table) or ``fixed-pose`` (a closed loop, e.g. a humanoid's two soles flat on the ground:
``left_sole_link`` to ``right_sole_link`` is one fixed pose at every touch).

The rows: each chain's touches, in chain order, each its kind's rows (a plane's height [m]
and weighted roll and pitch; a pose's position [m] and weighted rotation vector), as a single
chain's (:class:`~.contact_model.ContactModel`), padded with zero rows to the most rows of a
kind in the fit (zero rows change no least-squares solution): the object and contact columns
are that model's, the robot's the kind's rows (``kind.jacobian_rows``) of the contact frame's
displacement in its object's frame.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..exceptions import InvalidArgumentError
from ..identification.contacts import Contact, PlaneContact
from ..identification.parameters import ParameterSet
from ..kinematics.robot import Chain
from ..kinematics.so3 import skew
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from .contact_frames import DOF_NAMES
from .contact_model import ContactModel, ContactState
from .measured_term import MeasuredKind, MeasuredState, measured_columns
from .model import compliance_name
from .pixel_chain import PixelKind, PixelPart, PixelTermState, pixel_block
from .placements import COMPONENTS, Placements, joint_twists

__all__ = [
    "ChainsData",
    "ChainsModel",
    "ChainsState",
    "padded",
    "row_count",
]


def row_count(kinds) -> int:
    """Rows per touch of a fit of chains of these kinds: the most of any kind."""
    return max(len(k.row_names) for k in kinds)


def padded(a: np.ndarray, rows: int) -> np.ndarray:
    """``a`` ``(m, r, ...)`` with zero rows appended to ``(m, rows, ...)``."""
    if a.shape[1] == rows:
        return a
    pad = np.zeros((a.shape[0], rows - a.shape[1], *a.shape[2:]))
    return np.concatenate([a, pad], axis=1)


@dataclass(frozen=True, eq=False)
class ChainsData:
    """Touches of each chain (one :class:`ContactData` per chain, in chain order).

    ``torques``: each chain's gravity torques at its touches, which deflect its compliant
    joints (``elastic``), or None (rigid joints).
    """

    parts: tuple[ContactData | Measurements | PixelPart, ...]
    torques: tuple[np.ndarray | None, ...] | None = None

    @property
    def m(self) -> int:
        """Touches of all chains."""
        return sum(d.m for d in self.parts)

    def torque(self, c: int) -> np.ndarray | None:
        """Chain c's gravity torques ``(m, n)`` [N m or N] (joint compliance), or None."""
        return None if self.torques is None else self.torques[c]


@dataclass(frozen=True, eq=False)
class ChainsState:
    """The robot's joint placement errors and each chain's contact state.

    Attributes:
        chains: The nominal chains (one robot).
        placements: The joint placement errors.
        states: Each chain's state (its MDH model on the perturbed robot).
        frames: Each chain's joint frames at q = 0 on the perturbed robot ``(n, 4, 4)``.
        scales: Factor of each chain's weighted rows in the fit (None: 1 each): a loop's
            rows may weigh more than a table's (``pose_weight``).
    """

    chains: tuple[Chain, ...]
    placements: Placements
    states: tuple[ContactState | MeasuredState | PixelTermState, ...]
    frames: tuple[np.ndarray, ...]
    scales: tuple[float, ...] | None = None

    def scale(self, c: int) -> float:
        """Factor of chain c's rows."""
        return 1.0 if self.scales is None else float(self.scales[c])

    def residuals(self, data: ChainsData, torque=None) -> np.ndarray:
        """Weighted ``0 - gap`` of every touch ``(m, rows)``, chain after chain (padded).

        The gravity torques are the data's (``torque`` is the solver's argument, unused).
        """
        rows = row_count(s.kind for s in self.states)
        return np.concatenate(
            [
                padded(self.scale(c) * s.residuals(d, data.torque(c)), rows)
                for c, (s, d) in enumerate(zip(self.states, data.parts, strict=True))
            ]
        )


@dataclass(frozen=True, eq=False)
class ChainsModel:
    """What is free: the objects, the contacts' unknowns and joint placement components.

    Attributes:
        plane_of: Index of each chain's object (a plane, or a fixed pose).
        planes: Number of objects.
        free: The free directions, as indices into ``names_all``.
        names_all: Names of the directions offered.
        directions: The directions offered ``(D, 6 J)``, each a combination of the joint
            placement components (``Placements.names()`` order); None: each component alone
            (``names_all`` is then ``Placements.names()``).
        kinds: Each chain's contact kind (None: all ``plane``).
        counts: Each chain's number of objects (None: one each; a ``fixed-pose`` chain may
            hold several poses, e.g. one per session: the feet stood elsewhere).
        compliance: The first chain's joints (0-based) whose compliance is free, columns
            after the placement directions (``c<row>``; ``elastic``: one chain touching).
    """

    plane_of: tuple[int, ...]
    planes: int
    free: tuple[int, ...]
    names_all: tuple[str, ...]
    directions: np.ndarray | None = None
    kinds: tuple[Contact | MeasuredKind | PixelKind, ...] | None = None
    counts: tuple[int, ...] | None = None
    compliance: tuple[int, ...] = ()
    _last: dict = field(default_factory=dict, compare=False, repr=False)

    n_markers = 0  # its rows come weighted (solve.row_weights: 1)
    pose = False

    def chain_kinds(self) -> tuple[Contact | MeasuredKind | PixelKind, ...]:
        """Each chain's contact kind."""
        return self.kinds if self.kinds is not None else (PlaneContact(),) * len(self.plane_of)

    def object_kinds(self) -> tuple[Contact | MeasuredKind | PixelKind, ...]:
        """Each object's kind (that of its first chain)."""
        kinds = self.chain_kinds()
        return tuple(kinds[self.plane_of.index(p)] for p in range(self.planes))

    def _count(self, p: int) -> int:
        """Objects of group p."""
        return 1 if self.counts is None else self.counts[self.plane_of.index(p)]

    def _object_start(self, p: int) -> int:
        kinds = self.object_kinds()
        return sum(self._count(g) * len(kinds[g].object_dofs) for g in range(p))

    def _contact_start(self, c: int) -> int:
        objects = self._object_start(self.planes)
        return objects + sum(len(k.contact_dofs) for k in self.chain_kinds()[:c])

    @property
    def fixed(self) -> int:
        """Columns of the objects and contacts (always free)."""
        return self._contact_start(len(self.plane_of))

    def size(self) -> int:
        """Number of free parameters."""
        return self.fixed + len(self.free) + len(self.compliance)

    def object_blocks(self) -> tuple[int, int]:
        """Objects and unknowns of each (a fit by block: one chain touching, the first)."""
        return self._count(0), len(self.chain_kinds()[0].object_dofs)

    def names(self) -> tuple[str, ...]:
        """Column names."""
        out = []
        for p, kind in enumerate(self.object_kinds()):
            if isinstance(kind, MeasuredKind | PixelKind):  # a measured or pixel term's own
                own = kind.names()[: len(kind.object_dofs)]
                tag = "instrument" if getattr(kind, "instrument", False) else f"term{p + 1}"
                out += [f"{tag}.{n}" for n in own]
                continue
            for k in range(self._count(p)):
                tag = f"{kind.object_name}{p + 1}" + (f".{k + 1}" if self._count(p) > 1 else "")
                out += [f"{tag}_{DOF_NAMES[d]}" for d in kind.object_dofs]
        for c, kind in enumerate(self.chain_kinds()):
            if isinstance(kind, MeasuredKind):  # beside a shared instrument: markers, tool
                out += [f"term{c + 1}.{n}" for n in kind.names()[len(kind.object_dofs) :]]
                continue
            out += [f"contact{c + 1}_{DOF_NAMES[d]}" for d in kind.contact_dofs]
        comp = (compliance_name(j) for j in self.compliance)
        return (*out, *(self.names_all[k] for k in self.free), *comp)

    def with_free(self, free: tuple[int, ...], compliance: tuple[int, ...] = ()) -> ChainsModel:
        """The same planes and contacts, other free components and compliances."""
        return dataclasses.replace(self, free=tuple(free), compliance=tuple(compliance), _last={})

    def _lift(self) -> np.ndarray:
        """The free directions ``(free, 6 J)``."""
        if self.directions is None:
            return np.eye(len(self.names_all))[list(self.free)]
        return self.directions[list(self.free)]

    def _chain_columns(self, c: int) -> tuple[slice, slice]:
        """Chain c's object columns and contact columns in x."""
        kind = self.chain_kinds()[c]
        p = self.plane_of[c]
        o, t = self._object_start(p), self._contact_start(c)
        return (
            slice(o, o + self._count(p) * len(kind.object_dofs)),
            slice(t, t + len(kind.contact_dofs)),
        )

    def own_columns(self, c: int) -> np.ndarray:
        """Chain c's own columns in x (a measured term's frame, markers and tool rotation)."""
        obj, con = self._chain_columns(c)
        return np.r_[np.arange(obj.start, obj.stop), np.arange(con.start, con.stop)]

    def _chain_x(self, x: np.ndarray, c: int) -> np.ndarray:
        obj, con = self._chain_columns(c)
        return np.r_[x[obj], x[con]]

    @staticmethod
    def _contact_model(state: ContactState) -> ContactModel:
        """The single-chain model of a chain's plane and contact (no robot parameter)."""
        return ContactModel(ParameterSet("none", ()), state.frames)

    def apply(self, start: ChainsState, x: np.ndarray) -> ChainsState:
        """The state at parameters x (x = 0 is ``start``).

        The last state made is remembered (the solver asks for the residuals, then the
        Jacobian, at one x): a memo of a pure function, invisible from outside.
        """
        x = np.asarray(x, dtype=float)
        key = (id(start), x.tobytes())
        hit = self._last.get(key)
        if hit is not None and hit[0] is start:
            return hit[1]
        state = self._apply(start, x)
        self._last.clear()
        self._last[key] = (start, state)
        return state

    def _apply(self, start: ChainsState, x: np.ndarray) -> ChainsState:
        end = self.fixed + len(self.free)
        dy = self._lift().T @ x[self.fixed : end]
        if len(self.free):
            placements = start.placements.shifted(dy)
            models, frames = placements.chain_geometry(start.chains)
        else:
            placements, frames = start.placements, start.frames
            models = tuple(s.mdh for s in start.states)
        states = tuple(
            s.moved(mdh, self._chain_x(x, c))
            if isinstance(s, MeasuredState | PixelTermState)
            else dataclasses.replace(self._contact_model(s).apply(s, self._chain_x(x, c)), mdh=mdh)
            for c, (s, mdh) in enumerate(zip(start.states, models, strict=True))
        )
        if self.compliance:  # the first chain's joints deflect: q' = q + c tau
            s = states[0]
            if not isinstance(s, ContactState):
                raise InvalidArgumentError("joint compliance is fitted for a chain touching")
            c = np.zeros(s.mdh.n) if s.compliance is None else np.array(s.compliance)
            c[list(self.compliance)] += x[end:]
            states = (dataclasses.replace(s, compliance=c), *states[1:])
        return ChainsState(start.chains, placements, states, frames, start.scales)

    def jacobian(self, start: ChainsState, x: np.ndarray, data: ChainsData, torque=None):
        """Weighted d(gap)/dx ``(m, rows, size)``, chain after chain (padded rows)."""
        state = self.apply(start, x)
        rows = row_count(self.chain_kinds())
        blocks = [
            padded(start.scale(c) * self._block(start, state, x, c, d, data.torque(c)), rows)
            for c, d in enumerate(data.parts)
        ]
        return np.concatenate(blocks)

    def blocks(self, start: ChainsState, x: np.ndarray, data: ChainsData, torque=None):
        """:meth:`jacobian` of one chain touching by block (:mod:`.contact_fit`).

        Returns:
            The weighted rows on each touch's own object's unknowns ``(m, rows, o)``, on the
            shared unknowns (contact, placement directions, compliances) ``(m, rows,
            size - K o)``, and the object of each touch ``(m,)``.

        Raises:
            InvalidArgumentError: Not one chain touching.
        """
        if len(self.plane_of) != 1 or not isinstance(start.states[0], ContactState):
            raise InvalidArgumentError("a fit by block is of one chain touching")
        state = self.apply(start, x)
        own, shared, index = self._contact_parts(start, state, x, 0, data.parts[0], data.torque(0))
        return start.scale(0) * own, start.scale(0) * shared, index

    def _contact_parts(self, start: ChainsState, state: ChainsState, x, c: int, d, torque):
        """Contact chain c's weighted rows by block: own object's, shared (contact, robot)."""
        s, s0 = state.states[c], start.states[c]
        if not (isinstance(s, ContactState) and isinstance(s0, ContactState)):
            raise InvalidArgumentError(f"chain {c + 1}'s state is not of its term's kind")
        comp = self.compliance if c == 0 else ()
        base = dataclasses.replace(s0, mdh=s.mdh, compliance=s.compliance)
        model = ContactModel(ParameterSet("none", ()), s0.frames, comp)
        xc = np.r_[self._chain_x(x, c), np.zeros(len(comp))]
        own, shared, index = model.blocks(base, xc, d, torque)
        con = len(s.kind.contact_dofs)
        robot = (
            self._robot_columns(state, c, s, d, torque)
            if self.free
            else np.zeros((d.m, own.shape[1], 0))
        )
        return own, np.concatenate([shared[:, :, :con], robot, shared[:, :, con:]], axis=2), index

    def _block(self, start: ChainsState, state: ChainsState, x: np.ndarray, c: int, d, torque):
        """Chain c's weighted rows ``(m, rows, size)`` (not scaled, not padded)."""
        s, s0 = state.states[c], start.states[c]
        J = np.zeros((d.m, len(s.kind.row_names), self.size()))
        obj, con = self._chain_columns(c)
        if isinstance(s, PixelTermState) and isinstance(s0, PixelTermState):
            chain, xc, lift = state.chains[c], self._chain_x(x, c), self._lift()
            J[:, :, obj], robot = pixel_block(state.placements, chain, s, s0, xc, d, lift)
            if self.free:
                J[:, :, self.fixed :] = robot
            return J
        if isinstance(s, MeasuredState) and isinstance(s0, MeasuredState):
            J[:, :, self.own_columns(c)] = s0.own_jacobian(s.mdh, self._chain_x(x, c), d)
            if self.free:
                J[:, :, self.fixed :] = measured_columns(
                    state.placements, state.chains[c], s, state.frames[c], d, self._lift()
                )
            return J
        own, shared, index = self._contact_parts(start, state, x, c, d, torque)
        o, k = own.shape[2], con.stop - con.start
        cols = obj.start + o * index[:, None] + np.arange(o)
        J[np.arange(d.m)[:, None, None], np.arange(own.shape[1])[None, :, None], cols[:, None]] = (
            own
        )
        J[:, :, con] = shared[:, :, :k]
        J[:, :, self.fixed : self.fixed + shared.shape[2] - k] = shared[:, :, k:]
        return J

    def _robot_columns(
        self, state: ChainsState, c: int, s: ContactState, d: ContactData, torque=None
    ) -> np.ndarray:
        """Weighted gap rows of the free placement components for chain c ``(m, r, free)``."""
        chain = state.chains[c]
        joints = state.placements.joints
        columns = np.array([joints.index(name) for name in chain.joint_names])
        kin = s.kinematics(np.asarray(d.q, dtype=float), torque)
        ang, lin = joint_twists(state.placements, chain, s.mdh, state.frames[c], kin, columns)
        R, p = kin.R[:, -1], kin.p[:, -1]
        point = p + R @ s.contact[:3, 3]
        moving = lin - skew(point)[:, None] @ ang  # velocity of the contact point
        # the free directions on the chain's joints' components (Placements.names() order),
        # without the (m, 6, 6 J) array of every component of every joint
        lift = self._lift().reshape(-1, len(joints), len(COMPONENTS))[:, columns]
        lift = lift.reshape(len(lift), -1).T  # (n 6, free)
        W6 = np.concatenate(
            [np.moveaxis(v, 2, 1).reshape(d.m, 3, -1) @ lift for v in (moving, ang)], axis=1
        )
        index = s.frames.index(d.ids, d.source)
        Rc, _ = s.frames.relative(R, p, index)
        out = s.kind.jacobian_rows(s.frames.rotate(W6, index), Rc)
        return out * s.row_weights()[None, :, None]
