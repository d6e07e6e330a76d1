"""The joint fit's error model: the robot's joint placement errors and each term's state.

Rationale and measurements: docs/developers/engine.md#engine_model
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property, partial
from typing import cast

import numpy as np

from ..exceptions import InvalidArgumentError
from ..identification.contacts import Contact, PlaneContact
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from .chain_registration import MeasuredState
from .contact_model import DOF_NAMES, ContactState
from .model import MeasuredKind, compliance_name
from .pixel_chain import PixelKind, PixelPart, PixelTermState, pixel_block
from .placements import JointFrames, Placements, twist_columns

__all__ = ["ChainsData", "ChainsModel", "ChainsState", "joint_motions", "on_models", "padded"]


def padded(a: np.ndarray, rows: int) -> np.ndarray:
    """``a`` ``(m, r, ...)`` with zero rows appended to ``(m, rows, ...)``."""
    if a.shape[1] == rows:
        return a
    pad = np.zeros((a.shape[0], rows - a.shape[1], *a.shape[2:]))
    return np.concatenate([a, pad], axis=1)


@dataclass(frozen=True, eq=False)
class ChainsData:
    """Each chain's rows, in chain order, and its gravity torques there (None: rigid)."""

    parts: tuple[ContactData | Measurements | PixelPart, ...]
    torques: tuple[np.ndarray | None, ...] | None = None

    @property
    def m(self) -> int:
        """Touches of all chains."""
        return sum(d.m for d in self.parts)

    def seen_rows(self, width: int) -> np.ndarray | None:
        """Rows of ``width`` per row measured ``(m, width)``, None: all (padded rows kept)."""
        seen = [d.seen_rows(width) if isinstance(d, Measurements) else None for d in self.parts]
        if all(s is None for s in seen):
            return None
        ones = (np.ones((d.m, width), dtype=bool) for d in self.parts)
        return np.concatenate([o if s is None else s for o, s in zip(ones, seen, strict=True)])

    def torque(self, c: int) -> np.ndarray | None:
        """Chain c's gravity torques ``(m, n)`` [N m or N], or None."""
        return None if self.torques is None else self.torques[c]


def on_models(states: tuple, models: tuple[MDHModel, ...]) -> tuple:
    """Each chain's state with its MDH model replaced (a measured term's inner state's)."""
    return tuple(_with(s, mdh=mdh) for s, mdh in zip(states, models, strict=True))


def _robot_part(s):
    """The part of a chain's state that holds its MDH model and compliance."""
    return s.inner if isinstance(s, MeasuredState) else s


def _with(s, **changes):
    """A chain's state with fields of :func:`_robot_part` replaced."""
    if isinstance(s, MeasuredState):
        return dataclasses.replace(s, inner=dataclasses.replace(s.inner, **changes))
    return dataclasses.replace(s, **changes)


def joint_motions(path, kin, joints: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The tool side's linear (at the base origin) and angular velocity ``(m, 3, k)`` per joint.

    Each joint turns about (slides along) its frame's z in ``kin``, signed by ``path``'s
    direction through it.
    """
    z = kin.R[:, joints][..., 2] * np.asarray(path.sign, dtype=float)[joints, None]  # (m, k, 3)
    slide = np.asarray(path.prismatic)[joints][None, :, None]
    ang = np.where(slide, 0.0, z)
    lin = np.where(slide, z, np.cross(kin.p[:, joints], ang))
    return np.swapaxes(lin, 1, 2), np.swapaxes(ang, 1, 2)


def _deflection(s) -> np.ndarray:
    """A chain state's joint compliance (zeros: rigid)."""
    c = getattr(_robot_part(s), "compliance", None)
    return np.zeros(0) if c is None or not np.any(c) else np.asarray(c)


def _compliant(s, joints: list[int], dc: np.ndarray):
    """A chain's state with the compliances of ``joints`` moved by ``dc``."""
    part = _robot_part(s)
    if isinstance(part, PixelTermState):
        raise InvalidArgumentError("joint compliance is fitted for a chain touching or measured")
    c = np.zeros(part.mdh.n) if part.compliance is None else np.array(part.compliance, dtype=float)
    c[joints] += dc
    return _with(s, compliance=c)


@dataclass(frozen=True, eq=False)
class ChainsState:
    """The robot's joint placement errors and each chain's state.

    Each state's MDH model is its chain on ``placements.model`` (the errors are seen through
    :meth:`kinematics`); ``scales``: each chain's row factor (``pose_weight``; None: 1 each).
    """

    chains: tuple[Chain, ...]
    placements: Placements
    states: tuple[ContactState | MeasuredState | PixelTermState, ...]
    scales: tuple[float, ...] | None = None

    def scale(self, c: int) -> float:
        """Factor of chain c's rows."""
        return 1.0 if self.scales is None else float(self.scales[c])

    def kinematics(self, data: ChainsData, torque=None) -> tuple[JointFrames, ...]:
        """Each chain's frames at its data's joints, errors and deflections included."""
        frames = []
        for c, (chain, s, d) in enumerate(zip(self.chains, self.states, data.parts, strict=True)):
            robot, q = _robot_part(s), np.asarray(d.q, dtype=float)  # a pixel part's: its rows'
            seen = q if isinstance(robot, PixelTermState) else robot.joints(q, data.torque(c))
            frames.append(self.placements.frames(chain, seen))
        return tuple(frames)

    step_kinematics = kinematics  # what :class:`~.solve.Problem` makes once per x

    def same_geometry(self, other) -> bool:
        """Whether ``other``'s kinematics at the same data are this state's."""
        return (
            isinstance(other, ChainsState)
            and other.placements is self.placements
            and all(
                np.array_equal(_deflection(a), _deflection(b))
                for a, b in zip(self.states, other.states, strict=True)
            )
        )

    def settled(self) -> ChainsState:
        """The same robot with its errors composed into its model and the MDH models remade."""
        if not self.placements.y.any():
            return self
        placements = self.placements.rebased()
        models = placements.chain_models(self.chains)
        return dataclasses.replace(
            self, placements=placements, states=on_models(self.states, models)
        )

    def residuals(self, data: ChainsData, torque=None, kin=None) -> np.ndarray:
        """Weighted ``0 - gap`` of every row ``(m, rows)``, chain after chain (padded)."""
        if kin is None:
            kin = self.kinematics(data, torque)
        rows = max(len(s.kind.row_names) for s in self.states)
        parts = zip(self.states, data.parts, kin, strict=True)
        out = [s.residuals(d, None, k) for s, d, k in parts]
        scaled = (r if self.scale(c) == 1.0 else self.scale(c) * r for c, r in enumerate(out))
        return np.concatenate([padded(r, rows) for r in scaled])  # times 1: the same numbers


@dataclass(frozen=True, eq=False)
class ChainsModel:
    """What is free: the objects, the contacts' unknowns and joint placement components.

    Attributes:
        plane_of: Index of each chain's object group; ``planes``: their number.
        free: The free directions, as indices into ``names_all`` (the names offered).
        directions: The directions offered ``(D, 6 J)`` in the components
            (``Placements.names()`` order); None: each component alone.
        kinds: Each chain's kind (None: all ``plane``).
        counts: Each chain's number of objects (None: one each).
        compliance: The first chain's joints (0-based) whose compliance is free.
    """

    plane_of: tuple[int, ...]
    planes: int
    free: tuple[int, ...]
    names_all: tuple[str, ...]
    directions: np.ndarray | None = None
    kinds: tuple[Contact | MeasuredKind | PixelKind, ...] | None = None
    counts: tuple[int, ...] | None = None
    compliance: tuple[int, ...] = ()

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

    @cached_property
    def _starts(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """Each object's first column and each chain's contact's, each then the end (once)."""
        kinds, objects = self.object_kinds(), [0]
        for p in range(self.planes):
            objects.append(objects[-1] + self._count(p) * len(kinds[p].object_dofs))
        contacts = [objects[-1]]
        for kind in self.chain_kinds():
            contacts.append(contacts[-1] + len(kind.contact_dofs))
        return tuple(objects), tuple(contacts)

    @property
    def fixed(self) -> int:
        """Columns of the objects and contacts (always free)."""
        return self._starts[1][-1]

    def size(self) -> int:
        """Number of free parameters."""
        return self.fixed + len(self.free) + len(self.compliance)

    def object_blocks(self) -> tuple[int, int]:
        """The first chain's objects and unknowns of each (a fit by block)."""
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
        return dataclasses.replace(self, free=tuple(free), compliance=tuple(compliance))

    @cached_property
    def _lift(self) -> np.ndarray:
        """The free directions ``(free, 6 J)`` (made once: read only)."""
        free = list(self.free)
        lift = (
            np.eye(len(self.names_all))[free] if self.directions is None else self.directions[free]
        )
        lift.flags.writeable = False
        return lift

    @cached_property
    def _columns(self) -> tuple[tuple[slice, slice, np.ndarray], ...]:
        """Each chain's object columns, contact columns and both as indices (made once)."""
        out = []
        for c, kind in enumerate(self.chain_kinds()):
            p = self.plane_of[c]
            o, t = self._starts[0][p], self._starts[1][c]
            obj = slice(o, o + self._count(p) * len(kind.object_dofs))
            con = slice(t, t + len(kind.contact_dofs))
            own = np.r_[np.arange(obj.start, obj.stop), np.arange(con.start, con.stop)]
            own.flags.writeable = False
            out.append((obj, con, own))
        return tuple(out)

    def own_columns(self, c: int) -> np.ndarray:
        """Chain c's own columns in x (a measured term's frame, markers and tool rotation)."""
        return self._columns[c][2]

    def apply(self, start: ChainsState, x: np.ndarray) -> ChainsState:
        """The state at parameters x (x = 0 is ``start``): no MDH model is remade."""
        x = np.asarray(x, dtype=float)
        placements = start.placements
        end = self.fixed + len(self.free)
        if len(self.free):
            placements = placements.shifted(self._lift.T @ x[self.fixed : end])
        states = tuple(s.moved(x[self.own_columns(c)]) for c, s in enumerate(start.states))
        if self.compliance:  # the first chain's joints deflect: q' = q + c tau
            states = (_compliant(states[0], list(self.compliance), x[end:]), *states[1:])
        return dataclasses.replace(start, placements=placements, states=states)

    def jacobian(
        self, start: ChainsState, x: np.ndarray, data: ChainsData, torque=None, state=None, kin=None
    ):
        """Weighted d(gap)/dx ``(m, rows, size)``, chain after chain (padded rows).

        ``state`` (:meth:`apply` at x) and ``kin`` (its kinematics at ``data``): if made.
        """
        if state is None:
            state = self.apply(start, x)
        if kin is None:
            kin = state.kinematics(data, torque)
        rows = max(len(k.row_names) for k in self.chain_kinds())
        blocks = []
        for c, d in enumerate(data.parts):
            block = self._block(start, state, x, c, d, kin[c], data.torque(c))
            if start.scale(c) != 1.0:  # in place: a fresh array (times 1: the same numbers)
                block *= start.scale(c)
            blocks.append(padded(block, rows))
        return blocks[0] if len(blocks) == 1 else np.concatenate(blocks)  # one term: no copy

    def blocks(self, start: ChainsState, x: np.ndarray, data: ChainsData):
        """One chain touching's :meth:`jacobian` by block (robot columns: shared)."""
        if len(self.plane_of) != 1 or not isinstance(start.states[0], ContactState):
            raise InvalidArgumentError("a fit by block is of one chain touching")
        state = self.apply(start, x)
        kin, s, d = state.kinematics(data)[0], cast(ContactState, state.states[0]), data.parts[0]
        own, shared, index = start.states[0].blocks(x[self.own_columns(0)], d, kin, s)
        robot = self._robot_rows(state, 0, kin, data.torque(0), partial(s.motion_rows, kin, d))
        shared = np.concatenate([shared, *robot], axis=2)
        return start.scale(0) * own, start.scale(0) * shared, index

    def _robot_rows(self, state: ChainsState, c: int, kin, torque, rows_of) -> list[np.ndarray]:
        """Chain c's rows ``(m, r, k)`` of the free directions, then compliances, by ``rows_of``."""
        chain, out = state.chains[c], []
        if self.free:
            out.append(rows_of(*twist_columns(state.placements, chain, kin, self._lift)))
        if self.compliance and c == 0:  # q' = q + c tau: d/dc_j = tau_j d/dq_j
            motions = joint_motions(state.placements.path(chain), kin, list(self.compliance))
            gain = np.asarray(torque, dtype=float)[:, None, list(self.compliance)]  # (m, 1, k)
            out.append(rows_of(*motions) * gain)
        return out

    def _block(self, start: ChainsState, state: ChainsState, x: np.ndarray, c: int, d, kin, torque):
        """Chain c's weighted rows ``(m, rows, size)`` (not scaled, not padded)."""
        s, s0, chain, lift = state.states[c], start.states[c], state.chains[c], self._lift
        J = np.zeros((d.m, len(s.kind.row_names), self.size()))
        mine = self._columns[c][2]
        if isinstance(s, PixelTermState) and isinstance(s0, PixelTermState):
            J[:, :, mine], robot = pixel_block(
                state.placements, chain, s, s0, x[mine], d, lift, kin
            )
            robots = [robot]
        elif isinstance(s, ContactState | MeasuredState) and isinstance(s0, type(s)):
            J[:, :, mine] = s0.own_rows(x[mine], d, kin, s)  # type: ignore[arg-type]
            robots = self._robot_rows(state, c, kin, torque, partial(s.motion_rows, kin, d))
        else:
            raise InvalidArgumentError(f"chain {c + 1}'s state is not of its term's kind")
        k = self.fixed
        for rows in robots:
            J[:, :, k : k + rows.shape[2]] = rows
            k += rows.shape[2]
        return J
