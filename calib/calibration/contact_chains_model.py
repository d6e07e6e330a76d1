"""The error model of flush contacts on several chains of one robot, fitted together.

A state is the robot's joint placement errors (:class:`~.placements.Placements`, one error
per URDF joint, whatever chains it is on) and, per chain, its
:class:`~.contact_model.ContactState` (its MDH model on the perturbed robot, its contact
frame and plane, :class:`~.contact_frames.ContactFrames`, and its tilt weight). The
parameters x: for each plane the ``plane`` kind's object unknowns (its height and two tilts),
for each chain its contact's (two tilts), then components of joint placement errors
(``<joint>:x`` ... ``:rz``). A plane touched by several chains is one plane (their chains
share the base frame); each chain has its own contact frame.

The rows: each chain's touches, in chain order, each the kind's 3 rows (height [m] and
weighted roll and pitch), as a single chain's (:class:`~.contact_model.ContactModel`): the
plane and contact columns are that model's, the robot's the kind's rows
(``kind.jacobian_rows``) of the contact frame's displacement in its plane's frame.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..identification.contacts import PlaneContact
from ..identification.parameters import ParameterSet
from ..kinematics.robot import Chain
from ..kinematics.so3 import skew
from ..measurements.contact_campaign import ContactData
from .contact_frames import DOF_NAMES
from .contact_model import ContactModel, ContactState
from .placements import COMPONENTS, Placements, joint_twists

__all__ = ["PLANE_ROWS", "TILT_COLUMNS", "ChainsData", "ChainsModel", "ChainsState"]

PLANE_ROWS = len(PlaneContact.object_dofs)
"""Columns of one plane: its height and two tilts (the ``plane`` kind's object unknowns)."""

TILT_COLUMNS = len(PlaneContact.contact_dofs)
"""Columns of one contact frame: its tilts about its x and y axes."""


@dataclass(frozen=True, eq=False)
class ChainsData:
    """Touches of each chain (one :class:`ContactData` per chain, in chain order)."""

    parts: tuple[ContactData, ...]

    @property
    def m(self) -> int:
        """Touches of all chains."""
        return sum(d.m for d in self.parts)


@dataclass(frozen=True, eq=False)
class ChainsState:
    """The robot's joint placement errors and each chain's contact state.

    Attributes:
        chains: The nominal chains (one robot).
        placements: The joint placement errors.
        states: Each chain's state (its MDH model on the perturbed robot).
        frames: Each chain's joint frames at q = 0 on the perturbed robot ``(n, 4, 4)``.
    """

    chains: tuple[Chain, ...]
    placements: Placements
    states: tuple[ContactState, ...]
    frames: tuple[np.ndarray, ...]

    def residuals(self, data: ChainsData, torque=None) -> np.ndarray:
        """Weighted ``0 - gap`` of every touch ``(m, 3)``, chain after chain."""
        return np.concatenate(
            [s.residuals(d) for s, d in zip(self.states, data.parts, strict=True)]
        )


@dataclass(frozen=True, eq=False)
class ChainsModel:
    """What is free: the planes, the contacts' tilts and joint placement components.

    Attributes:
        plane_of: Index of each chain's plane.
        planes: Number of planes.
        free: The free directions, as indices into ``names_all``.
        names_all: Names of the directions offered.
        directions: The directions offered ``(D, 6 J)``, each a combination of the joint
            placement components (``Placements.names()`` order); None: each component alone
            (``names_all`` is then ``Placements.names()``).
    """

    plane_of: tuple[int, ...]
    planes: int
    free: tuple[int, ...]
    names_all: tuple[str, ...]
    directions: np.ndarray | None = None
    _last: dict = field(default_factory=dict, compare=False, repr=False)

    n_markers = 1
    pose = False

    @property
    def fixed(self) -> int:
        """Columns of the planes and contacts (always free)."""
        return PLANE_ROWS * self.planes + TILT_COLUMNS * len(self.plane_of)

    def size(self) -> int:
        """Number of free parameters."""
        return self.fixed + len(self.free)

    def names(self) -> tuple[str, ...]:
        """Column names."""
        out = []
        for p in range(self.planes):
            out += [f"plane{p + 1}_{DOF_NAMES[d]}" for d in PlaneContact.object_dofs]
        for c in range(len(self.plane_of)):
            out += [f"contact{c + 1}_{DOF_NAMES[d]}" for d in PlaneContact.contact_dofs]
        return (*out, *(self.names_all[k] for k in self.free))

    def with_free(self, free: tuple[int, ...]) -> ChainsModel:
        """The same planes and contacts, other free components."""
        return dataclasses.replace(self, free=tuple(free), _last={})

    def _lift(self) -> np.ndarray:
        """The free directions ``(free, 6 J)``."""
        if self.directions is None:
            return np.eye(len(self.names_all))[list(self.free)]
        return self.directions[list(self.free)]

    def _chain_x(self, x: np.ndarray, c: int) -> np.ndarray:
        p = self.plane_of[c]
        t = PLANE_ROWS * self.planes + TILT_COLUMNS * c
        return np.r_[x[PLANE_ROWS * p : PLANE_ROWS * p + PLANE_ROWS], x[t : t + TILT_COLUMNS]]

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
        dy = self._lift().T @ x[self.fixed :]
        if len(self.free):
            placements = start.placements.shifted(dy)
            models, frames = placements.chain_geometry(start.chains)
        else:
            placements, frames = start.placements, start.frames
            models = tuple(s.mdh for s in start.states)
        states = tuple(
            dataclasses.replace(self._contact_model(s).apply(s, self._chain_x(x, c)), mdh=mdh)
            for c, (s, mdh) in enumerate(zip(start.states, models, strict=True))
        )
        return ChainsState(start.chains, placements, states, frames)

    def jacobian(self, start: ChainsState, x: np.ndarray, data: ChainsData, torque=None):
        """Weighted d(gap)/dx ``(m, 3, size)``, chain after chain."""
        state = self.apply(start, x)
        blocks = []
        for c, (s, d) in enumerate(zip(state.states, data.parts, strict=True)):
            J = np.zeros((d.m, 3, self.size()))
            base = dataclasses.replace(start.states[c], mdh=s.mdh)
            J5 = self._contact_model(base).jacobian(base, self._chain_x(x, c), d)
            p = self.plane_of[c]
            J[:, :, PLANE_ROWS * p : PLANE_ROWS * p + PLANE_ROWS] = J5[:, :, :PLANE_ROWS]
            t = PLANE_ROWS * self.planes + TILT_COLUMNS * c
            J[:, :, t : t + TILT_COLUMNS] = J5[:, :, PLANE_ROWS:]
            if self.free:
                J[:, :, self.fixed :] = self._robot_columns(state, c, d)
            blocks.append(J)
        return np.concatenate(blocks)

    def _robot_columns(self, state: ChainsState, c: int, d: ContactData) -> np.ndarray:
        """Weighted gap rows of the free placement components for chain c ``(m, 3, free)``."""
        chain, s = state.chains[c], state.states[c]
        joints = state.placements.joints
        columns = np.array([joints.index(name) for name in chain.joint_names])
        kin = s.mdh.kinematics(np.asarray(d.q, dtype=float))
        ang, lin = joint_twists(state.placements, chain, s.mdh, state.frames[c], kin, columns)
        R, p = kin.R[:, -1], kin.p[:, -1]
        point = p + R @ s.contact[:3, 3]
        # every component of every joint on the chain, ordered as Placements.names()
        moving = lin - skew(point)[:, None] @ ang  # velocity of the contact point
        full = np.zeros((d.m, 6, len(joints), len(COMPONENTS)))
        full[:, :3, columns] = np.moveaxis(moving, 1, 2)
        full[:, 3:, columns] = np.moveaxis(ang, 1, 2)
        W6 = full.reshape(d.m, 6, -1) @ self._lift().T
        index = s.frames.index(d.ids, d.source)
        Rc, _ = s.frames.relative(R, p, index)
        out = s.kind.jacobian_rows(s.frames.rotate(W6, index), Rc)
        return out * s.row_weights()[None, :, None]
