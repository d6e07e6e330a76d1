"""Load a robot from a URDF (a file or a catalog name) and extract a serial chain with Pinocchio."""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Literal

import numpy as np
import pinocchio as pin
from numpy.typing import ArrayLike

from ..core.checks import check_count, check_work, joint_positions
from ..exceptions import ChainError, InvalidArgumentError, UnsupportedJointError
from .catalog import CatalogEntry, catalog, catalog_entry, shipped_urdf
from .frames import (
    DEFAULT_PRISMATIC_RANGE,
    PLACEMENT_TOL,
    default_tool,
    describe_joint,
    frame_placement,
    joint_kind,
    joint_placements,
    motion_axis,
    path_joints,
    resolve_frame,
    sampling_bounds,
)
from .mimic import Coupling, chain_coupling
from .urdf_model import build_model, read_urdf_file
from .urdf_xml import URDFInfo, kinematic_xml

__all__ = [
    "DEFAULT_PRISMATIC_RANGE",
    "PLACEMENT_TOL",
    "Chain",
    "CoupledJoints",
    "JointCounts",
    "Robot",
    "RobotModels",
    "chain_between",
    "check_chain",
    "check_count",
    "check_frame_name",
    "check_robot",
    "frame_placement",
    "joint_placements",
    "load_chain",
    "pin_configurations",
    "resolve_frame",
    "robot_source",
]


class JointCounts:
    """Revolute and prismatic joint counts of anything with a ``sigma`` array (0 or 1)."""

    sigma: np.ndarray

    @property
    def n_revolute(self) -> int:
        """Number of revolute (and continuous) joints."""
        return int(np.sum(self.sigma == 0))

    @property
    def n_prismatic(self) -> int:
        """Number of prismatic joints."""
        return int(np.sum(self.sigma == 1))


class CoupledJoints(JointCounts):
    """Joints some of which may follow others (mimic): what a chain and a tree share.

    A subclass has ``joint_names``, ``lower``, ``upper``, ``coupling`` (None without mimic
    joints) and ``n``.
    """

    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    coupling: Coupling | None

    @property
    def n(self) -> int:  # pragma: no cover
        """Number of joints (a subclass's)."""
        raise NotImplementedError

    def check_configurations(self, q: ArrayLike) -> np.ndarray:
        """Validate and reshape joint positions to ``(m, n)``.

        Raises:
            InvalidArgumentError: Wrong shape, or values that are not finite or beyond
                :data:`~calib.core.checks.MAX_JOINT_POSITION`.
        """
        return joint_positions(q, self.n)

    @property
    def variable_names(self) -> tuple[str, ...]:
        """The independent joints: a configuration is given for these (see :mod:`.mimic`).

        The joints, less the mimic joints, plus the masters of those outside the chain or tree.
        """
        return self.joint_names if self.coupling is None else self.coupling.names

    def joint_values(self, variables: np.ndarray) -> np.ndarray:
        """Positions of the joints ``(m, n)`` from the independent joints' ``(m, v)``."""
        if self.coupling is None:
            return self.check_configurations(variables)
        return self.coupling.joint_values(variables)

    def _uniform(self, m: int, seed: int) -> np.ndarray:
        """``m`` configurations drawn uniformly inside the limits (mimic joints follow)."""
        rng = np.random.default_rng(int(seed))
        if self.coupling is None:
            return self.lower + (self.upper - self.lower) * rng.random((int(m), self.n))
        lo, hi = self.coupling.lower, self.coupling.upper
        return self.coupling.joint_values(lo + (hi - lo) * rng.random((int(m), len(lo))))


class Robot(CoupledJoints):
    """The contract a chain and a tree keep: what calib asks of a robot.

    :class:`Chain` and :class:`~calib.kinematics.tree.Tree` derive from it. A chain is a
    tree with one tool: ``tool_frames``, ``tool_ids``, ``n_tools`` and ``chains`` mean the
    same for both. ``is_tree`` tells the places where each keeps its own implementation (a
    chain's MDH model and a tree's model, and what is built on them: calibration,
    campaigns, export, the command line's output); calib asks it rather than the robot's
    class. A subclass has ``name``, ``urdf_path``, ``urdf_resolved``, ``model``,
    ``base_frame``, ``base_id``, the members of :class:`CoupledJoints` and the properties below.
    """

    is_tree: ClassVar[bool] = False
    """True for a tree (of any number of tools), False for a chain."""

    name: str
    urdf_path: Path

    if TYPE_CHECKING:  # each a field of one class, a property of the other: no class attribute

        @property
        def urdf_resolved(self) -> Path:
            """The URDF file resolved when it was read."""
            ...

        @property
        def chains(self) -> tuple[Chain, ...]:
            """The chain to each tool, in tool order."""
            ...

    @property
    def tool_frames(self) -> tuple[str, ...]:  # pragma: no cover
        """Names of the tool frames, in tool order (a subclass's)."""
        raise NotImplementedError

    @property
    def tool_ids(self) -> tuple[int, ...]:  # pragma: no cover
        """Indices of the tool frames in ``model.frames``, in tool order (a subclass's)."""
        raise NotImplementedError

    @property
    def n_tools(self) -> int:
        """Number of tools."""
        return len(self.tool_ids)

    def __repr__(self) -> str:
        """One line: ``<Chain ur5: base_link -> tool0, 6 joints>``."""
        ends = f"{self.chains[0].base_frame} -> {', '.join(self.tool_frames)}"
        return f"<{type(self).__name__} {self.name}: {ends}, {len(self.joint_names)} joints>"


def pin_configurations(
    model: pin.Model, q_ref: np.ndarray, joint_ids: tuple[int, ...], q: np.ndarray
) -> np.ndarray:
    """Pinocchio configurations ``(m, nq)``: ``q_ref`` with the joints ``joint_ids`` set.

    Args:
        model: The Pinocchio model.
        q_ref: Configuration of the other joints ``(nq,)``, or one per row ``(m, nq)``.
        joint_ids: Pinocchio joint indices.
        q: Their URDF positions ``(m, n)`` [rad or m] (a continuous joint's two numbers in
            Pinocchio are ``cos`` and ``sin``).
    """
    out = np.array(np.broadcast_to(q_ref, (len(q), model.nq)), dtype=float)
    for k, jid in enumerate(joint_ids):
        joint = model.joints[jid]
        if joint.nq == 2:  # continuous joint: (cos, sin)
            out[:, joint.idx_q] = np.cos(q[:, k])
            out[:, joint.idx_q + 1] = np.sin(q[:, k])
        else:
            out[:, joint.idx_q] = q[:, k]
    return out


@dataclass(frozen=True, eq=False, repr=False)
class Chain(Robot):
    """A serial chain between a base frame and a tool frame of a Pinocchio model.

    Joint positions are *URDF* positions, one number per chain joint (radians for revolute
    and continuous joints, metres for prismatic ones). Joints outside the chain stay at the
    reference configuration ``q_ref``; they cannot move the tool relative to the base.

    The chain runs from the base frame up the URDF tree to the deepest common ancestor of
    the two frames, then down to the tool frame. The joints of the first part (none when the
    base is an ancestor of the tool) are traversed backwards, from child to parent: their
    ``sign`` is -1, and a positive URDF position moves the tool side by the opposite motion
    (see :mod:`calib.kinematics.mdh`).

    Attributes:
        name: Robot name (catalog name or URDF file stem).
        urdf_path: The URDF file, as given (messages and reports name it).
        urdf_resolved: The same file resolved when it was read (absolute, links followed):
            what calib reads again (export, compliance) and never overwrites, whatever the
            working directory is later. Default: ``urdf_path`` resolved now.
        model: Pinocchio model (never mutated by calib).
        base_frame: Name of the base frame (frame -1).
        tool_frame: Name of the tool frame (frame n+1).
        base_id: Index of the base frame in ``model.frames``.
        tool_id: Index of the tool frame in ``model.frames``.
        joint_ids: Pinocchio joint indices of the chain, from base to tool.
        joint_names: URDF names of those joints.
        sign: +1 for a joint traversed from parent to child, -1 for one traversed backwards
            (between the base frame and the common ancestor), per chain joint.
        sigma: 0 for revolute, 1 for prismatic, per chain joint.
        continuous: True for joints without limits (continuous joints).
        lower: Lower sampling bound per joint [rad or m].
        upper: Upper sampling bound per joint [rad or m].
        q_ref: Pinocchio configuration of the joints outside the chain.
        ideal_model: The same model built from the URDF with round-off removed (see
            :meth:`idealized`), or None.
        coupling: How mimic joints follow the independent ones (:mod:`calib.kinematics.mimic`),
            or None (no chain joint has a ``<mimic>`` tag).
    """

    name: str
    urdf_path: Path
    model: pin.Model
    base_frame: str
    tool_frame: str
    base_id: int
    tool_id: int
    joint_ids: tuple[int, ...]
    joint_names: tuple[str, ...]
    sigma: np.ndarray
    continuous: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    q_ref: np.ndarray
    ideal_model: pin.Model | None = field(default=None, repr=False)
    coupling: Coupling | None = field(default=None, repr=False)
    is_tree: ClassVar[Literal[False]] = False
    sign: np.ndarray = field(default=None, repr=False)  # type: ignore[assignment,arg-type]  # None: all +1 (post_init)
    urdf_resolved: Path = field(default=None, repr=False)  # type: ignore[assignment]  # None: urdf_path resolved (post_init)

    def __post_init__(self) -> None:
        if self.urdf_resolved is None:
            object.__setattr__(self, "urdf_resolved", Path(self.urdf_path).resolve())
        sign = np.ones(len(self.joint_ids), dtype=int) if self.sign is None else self.sign
        sign = np.array(sign, dtype=int)
        if sign.shape != (len(self.joint_ids),) or not np.all(np.abs(sign) == 1):
            raise InvalidArgumentError(f"a chain's signs are +1 or -1 per joint, got {sign}")
        object.__setattr__(self, "sign", _frozen(sign))

    @property
    def reversed_joints(self) -> int:
        """Number of joints traversed backwards (from the base up to the common ancestor)."""
        return int(np.sum(self.sign < 0))

    def idealized(self) -> Chain:
        """The chain on its URDF with round-off removed, for structural analysis.

        The model is built from :func:`~.urdf_xml.kinematic_xml` with ``snap``; a chain
        without such a model returns itself.
        """
        if self.ideal_model is None:
            return self
        return dataclasses.replace(self, model=self.ideal_model, ideal_model=None)

    @property
    def n(self) -> int:
        """Number of joints in the chain."""
        return len(self.joint_ids)

    @property
    def tool_ids(self) -> tuple[int, ...]:
        """The tool frame's index in ``model.frames``, as a one-tool tree has it."""
        return (self.tool_id,)

    @property
    def tool_frames(self) -> tuple[str, ...]:
        """The tool frame's name, as a one-tool tree has it."""
        return (self.tool_frame,)

    @property
    def chains(self) -> tuple[Chain, ...]:
        """The chain itself, as a one-tool tree has it."""
        return (self,)

    def pin_configurations(self, q: np.ndarray) -> np.ndarray:
        """Map URDF joint positions ``(m, n)`` to Pinocchio configurations ``(m, nq)``."""
        return pin_configurations(
            self.model, self.q_ref, self.joint_ids, self.check_configurations(q)
        )

    def random_configurations(self, m: int, seed: int) -> np.ndarray:
        """Draw ``m`` configurations uniformly inside the joint limits (continuous: full turn).

        With mimic joints, the independent joints are drawn and the mimic joints follow.

        Args:
            m: Number of configurations.
            seed: Seed of the random generator.

        Returns:
            Joint positions, shape ``(m, n)`` [rad or m].

        Raises:
            InvalidArgumentError: Bad count or seed, or an analysis of that many
                configurations would not fit in :data:`~calib.core.checks.MAX_WORK_BYTES`.
        """
        check_count(m, "the number of configurations")
        check_count(seed, "the seed", minimum=0)
        check_work(int(m), self.n)
        return self._uniform(m, seed)

    def gravity_torques(self, q: np.ndarray) -> np.ndarray:
        """Gravity torque each chain joint carries ``(m, n)`` [N m or N] (URDF masses).

        The generalized gravity of Pinocchio's model (joints outside the chain at
        ``q_ref``, gravity along -z of the URDF root); zero for a URDF without masses.
        """
        data = self.model.createData()
        idx = [self.model.joints[j].idx_v for j in self.joint_ids]
        return np.array(
            [
                pin.computeGeneralizedGravity(self.model, data, qp)[idx]
                for qp in self.pin_configurations(q)
            ]
        ).reshape(-1, self.n)

    def tool_placements(self, q: np.ndarray) -> np.ndarray:
        """Tool frame in the base frame, from Pinocchio's joint models, shape ``(m, 4, 4)``.

        A reference implementation for tests and checks (one tree walk per row).
        """
        out = []
        path = self._path_joints()
        for qp in self.pin_configurations(q):
            oMi = joint_placements(self.model, qp, last=path)
            oMb = frame_placement(self.model, oMi, self.base_id)
            out.append(oMb.actInv(frame_placement(self.model, oMi, self.tool_id)).homogeneous)
        return np.array(out).reshape(-1, 4, 4)

    def _path_joints(self) -> tuple[int, int]:
        """The joints of the base and tool frames: their ancestors hold the chain."""
        frames = self.model.frames
        return (frames[self.base_id].parentJoint, frames[self.tool_id].parentJoint)

    def joint_lines(
        self, zero: tuple[np.ndarray, np.ndarray] | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint axes at the zero configuration, in the base frame.

        Args:
            zero: The chain's :meth:`zero_frames`, when already computed.

        Returns:
            points ``(n, 3)`` [m] on each axis (the joint frame origin), unit directions
            ``(n, 3)`` of the URDF axes, such that a positive joint position turns (or slides)
            the joint's child link along ``+u`` relative to its parent link (the tool side
            along ``sign * u``), and the tool placement ``(4, 4)`` in the base frame.
        """
        frames, tool = self.zero_frames() if zero is None else zero
        points, dirs = [], []
        for jid, s, F in zip(self.joint_ids, self.sigma, frames, strict=True):
            S = motion_axis(self.model.joints[jid])  # in the joint frame
            u = F[:3, :3] @ (S[:3] if s == 1 else S[3:])
            points.append(F[:3, 3].copy())
            dirs.append(u / np.linalg.norm(u))
        return np.array(points).reshape(-1, 3), np.array(dirs).reshape(-1, 3), tool

    def zero_frames(self, oMi: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Each chain joint's frame (before its motion) and the tool frame at q = 0.

        Args:
            oMi: The model's :func:`~.frames.joint_placements` at this chain's zero
                configuration, holding the base and tool frames' joints and their ancestors
                (default: computed).

        Returns:
            The joint frames ``(n, 4, 4)`` and the tool frame ``(4, 4)`` in the base frame.
        """
        model = self.model
        if oMi is None:
            q0 = self.pin_configurations(np.zeros(self.n))[0]
            oMi = joint_placements(model, q0, last=self._path_joints())
        oMb = frame_placement(model, oMi, self.base_id)
        frames = [oMb.actInv(oMi[jid]).homogeneous for jid in self.joint_ids]
        tool = oMb.actInv(frame_placement(model, oMi, self.tool_id)).homogeneous
        return np.array(frames).reshape(-1, 4, 4), tool


def check_chain(value, what: str = "the robot") -> Chain:
    """``value`` if it is a :class:`Chain`.

    Raises:
        InvalidArgumentError: Anything else (a catalog name, a path, a tree), named.
    """
    if not isinstance(value, Chain):
        raise InvalidArgumentError(f"{what} must be a Chain (see load_chain), got {value!r:.60}")
    return value


def check_robot(value, what: str = "the robot") -> Robot:
    """``value`` if it is a chain or a tree (a :class:`Robot`).

    Raises:
        InvalidArgumentError: Anything else (a catalog name, a path), named.
    """
    if not isinstance(value, Robot):
        raise InvalidArgumentError(
            f"{what} must be a Chain or a Tree (see load_robot), got {value!r:.60}"
        )
    return value


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def check_frame_name(option: str, frame) -> None:
    """Refuse a frame option that is not a non-empty string (None means the default)."""
    if frame is not None and not isinstance(frame, str):
        raise InvalidArgumentError(
            f"the {option} frame is a name (a string), got {type(frame).__name__} {frame!r}"
        )
    if frame is not None and not frame.strip():
        raise InvalidArgumentError(f"the {option} frame name is empty")


@dataclass(frozen=True, eq=False)
class RobotModels:
    """A URDF read once: its Pinocchio model and the model with round-off removed.

    Attributes:
        name: Robot name (catalog name or URDF file stem).
        path: The URDF file, as given.
        resolved: The same file resolved when it was read (:attr:`Chain.urdf_resolved`).
        info: What calib read from the URDF itself (root link, mimic joints, ...).
        model: Pinocchio model of the kinematic URDF.
        ideal_model: The same with round-off removed (see :meth:`Chain.idealized`).
    """

    name: str
    path: Path
    resolved: Path
    info: URDFInfo
    model: pin.Model
    ideal_model: pin.Model

    @staticmethod
    def build(name: str, path: Path, info: URDFInfo) -> RobotModels:
        """Build both Pinocchio models of a URDF just read (``info``) from ``path``."""
        return RobotModels(
            name,
            path,
            path.resolve(),
            info,
            build_model(kinematic_xml(info), str(path)),
            build_model(kinematic_xml(info, snap=True), str(path)),
        )


def _chain_from_model(
    name: str, path: Path, info: URDFInfo, base: str | None, tool: str | None
) -> Chain:
    for option, frame in (("base", base), ("tool", tool)):
        check_frame_name(option, frame)
    return chain_between(RobotModels.build(name, path, info), base, tool)


def chain_between(robot: RobotModels, base: str | None, tool: str | None) -> Chain:
    """The serial chain between two frames of a robot read once (None: the default frame).

    The frames may lie on different branches (a foot and a hand): the chain then runs up from
    the base to their common ancestor, its joints traversed backwards (``sign`` -1), and
    down to the tool.

    Raises:
        CalibError: Unknown or ambiguous frame, no joint between the frames, unsupported
            joint.
    """
    name, path, info, model = robot.name, robot.path, robot.info, robot.model
    base_id = resolve_frame(model, base) if base else resolve_frame(model, info.root_link)
    tool_id = resolve_frame(model, tool) if tool else default_tool(model, info.mimics)
    base_name, tool_name = model.frames[base_id].name, model.frames[tool_id].name
    frames = model.frames
    joint_ids, signs = path_joints(model, frames[base_id].parentJoint, frames[tool_id].parentJoint)
    if not joint_ids:
        raise ChainError(f"no joint between base frame '{base_name}' and tool frame '{tool_name}'")
    sigma, cont, lower, upper = [], [], [], []
    for jid in joint_ids:
        joint, jname = model.joints[jid], model.names[jid]
        short = joint.shortname()
        kind = joint_kind(short)
        if kind is None or joint.nv != 1:
            raise UnsupportedJointError(jname, describe_joint(short))
        sigma.append(1 if kind == "prismatic" else 0)
        cont.append(joint.nq == 2)
        lo, hi = sampling_bounds(model, jid)
        lower.append(lo)
        upper.append(hi)
    joint_names = tuple(model.names[j] for j in joint_ids)
    coupling = None
    if info.mimic_joints & set(joint_names):
        bounds = {
            model.names[j]: sampling_bounds(model, j)
            for j in range(1, model.njoints)
            if joint_kind(model.joints[j].shortname()) and model.joints[j].nv == 1
        }
        coupling = chain_coupling(info, joint_names, bounds)
    return Chain(
        name=name,
        urdf_path=path,
        urdf_resolved=robot.resolved,
        model=model,
        base_frame=base_name,
        tool_frame=tool_name,
        base_id=base_id,
        tool_id=tool_id,
        joint_ids=joint_ids,
        joint_names=joint_names,
        sigma=_frozen(np.array(sigma, dtype=int)),
        continuous=_frozen(np.array(cont, dtype=bool)),
        lower=_frozen(np.array(lower)),
        upper=_frozen(np.array(upper)),
        q_ref=_frozen(pin.neutral(model)),
        ideal_model=robot.ideal_model,
        coupling=coupling,
        sign=_frozen(np.array(signs, dtype=int)),
    )


def robot_source(robot: str | Path) -> tuple[str, Path, CatalogEntry | None]:
    """Name, URDF path and catalog entry (None for a file) of a robot argument.

    Raises:
        CalibError: Not a name or path, or an unknown catalog name.
    """
    if not isinstance(robot, str | os.PathLike):
        raise InvalidArgumentError(
            f"the robot is a catalog name or a URDF path, got {type(robot).__name__} {robot!r}"
        )
    text = os.fspath(robot)
    path = Path(text)
    # A file wins over a catalog name; a folder never shadows the catalog (a folder that is
    # no catalog name is a path, which loading refuses: "is a directory").
    is_path = isinstance(robot, os.PathLike) or path.is_file()
    if path.is_dir() and not is_path:
        is_path = all(entry.name != text for entry in catalog())
    if not is_path and text.endswith(".urdf") and os.sep not in text and "/" not in text:
        found = shipped_urdf(text)  # a bare file name that is no local file
        if found is not None:
            return path.stem, found, None
    if is_path or text.endswith((".urdf", ".xml")) or "/" in text:
        return path.stem, path, None
    entry = catalog_entry(text)
    return entry.name, entry.path, entry


def load_chain(robot: str | Path, base: str | None = None, tool: str | None = None) -> Chain:
    """Load a serial chain from a catalog name or a URDF path.

    Args:
        robot: Catalog name (``ur5``) or path to a URDF file.
        base: Base frame; default: the catalog's, or the URDF root link.
        tool: Tool frame; default: the catalog's, or the tip of the deepest branch.

    Returns:
        The chain.

    Raises:
        CalibError: Unknown robot, bad URDF, unknown or ambiguous frame, no serial chain,
            unsupported joint in the chain, a catalog tree without a tool.
    """
    name, path, entry = robot_source(robot)
    if entry is not None:
        if entry.is_tree and tool is None:
            raise ChainError(
                f"'{entry.name}' is a tree of {len(entry.tools)} tools "
                f"({', '.join(entry.tools)}): name one of them as the tool, or analyse the "
                f"tree (load_tree, `calib analyze {entry.name}`)"
            )
        base = entry.base if base is None else base
        tool = entry.tools[0] if tool is None else tool
    return _chain_from_model(name, path, read_urdf_file(path), base, tool)
