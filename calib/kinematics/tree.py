"""A tree of serial chains: one base frame, several tool frames, shared joints once.

The tree is the union of the chains from the base frame to each tool. Its joints are
numbered 1..n in Pinocchio's order (a joint's antecedent comes before it); joint positions
are URDF positions, one column per tree joint, like a chain's.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, Literal

import numpy as np
import pinocchio as pin

from ..core.checks import check_count, check_work
from ..exceptions import ChainError, InvalidArgumentError
from .mimic import Coupling, tree_coupling
from .robot import (
    Chain,
    Robot,
    RobotModels,
    chain_between,
    check_frame_name,
    load_chain,
    pin_configurations,
    robot_source,
)
from .urdf_model import read_urdf_file

__all__ = ["Tree", "load_robot", "load_tree", "robot_argument", "tree_of_chains"]


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False, repr=False)
class Tree(Robot):
    """The union of the chains from one base frame to several tool frames.

    Attributes:
        name: Robot name (catalog name or URDF file stem).
        urdf_path: The URDF file, as given (messages and reports name it).
        chains: The chain to each tool, in tool order (they share one Pinocchio model).
        joint_ids: Pinocchio joint indices of the tree, antecedents first.
        joint_names: URDF names of those joints.
        parent: Tree index (0-based) of each joint's antecedent joint, -1 on the base.
        paths: For each tool, the tree indices of its chain's joints, base to tool.
        sigma: 0 revolute, 1 prismatic, per tree joint.
        lower: Lower sampling bound per joint [rad or m].
        upper: Upper sampling bound per joint [rad or m].
        coupling: How the tree's mimic joints follow the independent joints
            (:func:`!calib.kinematics.mimic.tree_coupling`), or None when no tree joint has a
            ``<mimic>`` tag.
    """

    name: str
    urdf_path: Path
    chains: tuple[Chain, ...]
    joint_ids: tuple[int, ...]
    joint_names: tuple[str, ...]
    parent: np.ndarray
    paths: tuple[np.ndarray, ...]
    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    coupling: Coupling | None = field(default=None, repr=False)
    is_tree: ClassVar[Literal[True]] = True

    @property
    def urdf_resolved(self) -> Path:
        """The URDF file resolved when it was read.

        The chains' :attr:`~calib.Chain.urdf_resolved`, which they share.
        """
        return self.chains[0].urdf_resolved

    @property
    def model(self) -> pin.Model:
        """The Pinocchio model (shared by every chain; never mutated)."""
        return self.chains[0].model

    @property
    def base_id(self) -> int:
        """Index of the base frame in ``model.frames``."""
        return self.chains[0].base_id

    @property
    def tool_ids(self) -> tuple[int, ...]:
        """Indices of the tool frames in ``model.frames``, in tool order."""
        return tuple(c.tool_id for c in self.chains)

    @property
    def base_frame(self) -> str:
        """Name of the base frame (frame -1)."""
        return self.chains[0].base_frame

    @property
    def tool_frames(self) -> tuple[str, ...]:
        """Names of the tool frames, in tool order."""
        return tuple(c.tool_frame for c in self.chains)

    @property
    def continuous(self) -> np.ndarray:
        """True for joints without limits (continuous joints), per tree joint."""
        out = np.zeros(self.n, dtype=bool)
        for chain, path in zip(self.chains, self.paths, strict=True):
            out[path] = chain.continuous
        return out

    @property
    def n(self) -> int:
        """Number of joints of the tree (shared joints once)."""
        return len(self.joint_ids)

    @property
    def n_tools(self) -> int:
        """Number of tools."""
        return len(self.chains)

    def idealized(self) -> Tree:
        """The tree on its URDF with round-off removed (see :meth:`Chain.idealized`)."""
        return dataclasses.replace(self, chains=tuple(c.idealized() for c in self.chains))

    def pin_configurations(self, q: np.ndarray) -> np.ndarray:
        """Map URDF joint positions ``(m, n)`` to Pinocchio configurations ``(m, nq)``."""
        q = self.check_configurations(q)
        return pin_configurations(self.model, self.chains[0].q_ref, self.joint_ids, q)

    def random_configurations(self, m: int, seed: int) -> np.ndarray:
        """Draw ``m`` configurations uniformly inside the joint limits (as a chain does).

        With mimic joints, the independent joints are drawn and the mimic joints follow.

        Returns:
            Joint positions, shape ``(m, n)`` [rad or m].

        Raises:
            InvalidArgumentError: Bad count or seed, or more work than memory allows.
        """
        check_count(m, "the number of configurations")
        check_count(seed, "the seed", minimum=0)
        check_work(int(m), self.n, f"{self.name} ({self.n_tools} tools)", self.n_tools)
        return self._uniform(m, seed)

    def tool_placements(self, q: np.ndarray) -> np.ndarray:
        """Every tool frame in the base frame, from Pinocchio, shape ``(m, T, 4, 4)``.

        A reference for tests and checks (one tree walk per tool and configuration).
        """
        q = self.check_configurations(q)
        out = [c.tool_placements(q[:, p]) for c, p in zip(self.chains, self.paths, strict=True)]
        return np.stack(out, axis=1)


def tree_of_chains(name: str, path: Path, chains: tuple[Chain, ...]) -> Tree:
    """Assemble chains of one model that share their base frame into a tree.

    Mimic joints on the chains follow their masters in the tree as in each chain
    (:func:`~calib.kinematics.mimic.tree_coupling`).

    Raises:
        InvalidArgumentError: A tool given twice, or chains from different base frames.
        ChainError: A tool that is not below the base (a chain with reversed joints).
    """
    tools = [c.tool_id for c in chains]
    for i, c in enumerate(chains):
        if c.tool_id in tools[:i]:
            raise InvalidArgumentError(f"tool frame '{c.tool_frame}' is given twice")
        if c.base_id != chains[0].base_id:
            raise InvalidArgumentError("the chains of a tree start from one base frame")
        if c.reversed_joints:
            raise ChainError(
                f"tool frame '{c.tool_frame}' is not below base frame '{c.base_frame}': the "
                f"tools of a tree hang from its base (one tool gives the chain through their "
                f"common ancestor)"
            )
    joint_ids = tuple(sorted({j for c in chains for j in c.joint_ids}))
    index = {j: i for i, j in enumerate(joint_ids)}
    model = chains[0].model
    parent = np.array([index.get(model.parents[j], -1) for j in joint_ids], dtype=int)
    sigma, lower, upper = (np.zeros(len(joint_ids)) for _ in range(3))
    for c in chains:
        at = [index[j] for j in c.joint_ids]
        sigma[at], lower[at], upper[at] = c.sigma, c.lower, c.upper
    joint_names = tuple(model.names[j] for j in joint_ids)
    coupling = tree_coupling(joint_names, lower, upper, tuple(c.coupling for c in chains))
    return Tree(
        name=name,
        urdf_path=path,
        chains=chains,
        joint_ids=joint_ids,
        joint_names=joint_names,
        parent=_frozen(parent),
        paths=tuple(_frozen(np.array([index[j] for j in c.joint_ids], dtype=int)) for c in chains),
        sigma=_frozen(sigma.astype(int)),
        lower=_frozen(lower),
        upper=_frozen(upper),
        coupling=coupling,
    )


def load_tree(
    robot: str | Path, base: str | None = None, tools: Sequence[str] | str | None = None
) -> Tree:
    """Load the tree from a base frame to several tools (a catalog name or a URDF path).

    Args:
        robot: Catalog name (``talos``) or path to a URDF file.
        base: Base frame; default: the catalog's, or the URDF root link.
        tools: Tool frame names (one or more); default: the catalog entry's tools.

    Returns:
        The tree (a one-tool tree is the chain to that tool).

    Raises:
        CalibError: Unknown robot, bad URDF, unknown or ambiguous frame, a tool that is not
            below the base, unsupported joint on a path, a tool given twice, no tools.
    """
    name, path, entry = robot_source(robot)
    if isinstance(tools, str):
        tools = (tools,)
    if tools is None:
        if entry is None:
            raise InvalidArgumentError("a tree from a URDF file needs its tool frames")
        tools = entry.tools
    if not isinstance(tools, list | tuple) or not tools or any(t is None for t in tools):
        raise InvalidArgumentError(f"the tools of a tree are frame names, got {tools!r:.60}")
    if entry is not None and base is None:
        base = entry.base
    check_frame_name("base", base)
    for tool in tools:
        check_frame_name("tool", tool)
    models = RobotModels.build(name, path, read_urdf_file(path))
    return tree_of_chains(name, path, tuple(chain_between(models, base, t) for t in tools))


def load_robot(
    robot: str | Path | Chain | Tree,
    base: str | None = None,
    tool: str | Sequence[str] | None = None,
) -> Chain | Tree:
    """A chain, or a tree where several tools are named.

    Args:
        robot: Catalog name, URDF path, or an already loaded chain or tree (returned as is:
            a base or tool given must be its own).
        base: Base frame (default: the catalog's or the URDF root).
        tool: One tool frame, several (a list: the tree of their chains), or None: the
            catalog entry's tool or tools, or a URDF's deepest tip.

    Raises:
        CalibError: See :func:`~calib.load_chain` and :func:`!load_tree`;
            a loaded robot with another base or tool (ignored before).
    """
    if isinstance(robot, Robot):
        given = tuple(tool) if isinstance(tool, list | tuple) else (tool,)
        named = all(f is None or isinstance(f, str) for f in (base, *given))
        if (
            not named
            or base not in (None, robot.base_frame)
            or given not in ((None,), robot.tool_frames)
        ):
            raise InvalidArgumentError(
                f"{robot!r} is loaded already: a base or tool chooses the frames of a robot "
                f"to load (its URDF, {robot.urdf_path}, or its catalog name)"
            )
        return robot
    tools = (tool,) if tool is None or isinstance(tool, str) else tool
    if not isinstance(tools, list | tuple) or not tools:
        raise InvalidArgumentError(f"the tool is a frame name or a list of names, got {tool!r:.60}")
    if len(tools) > 1:
        return load_tree(robot, base, tuple(tools))
    if tools[0] is None and (entry := robot_source(robot)[2]) is not None and entry.is_tree:
        return load_tree(robot, base)
    return load_chain(robot, base, tools[0])


def robot_argument(value: str | Path | Chain | Tree, what: str = "the robot") -> Chain | Tree:
    """A chain or tree as given, or the robot a catalog name or URDF path names.

    A name or path loads as :func:`calib.analyze` loads it, by :func:`load_robot` (the
    catalog's base and tool, or the URDF's root and deepest tip): to choose the frames, load
    the robot first.

    Raises:
        CalibError: Anything else, named with ``what``, or what loading raises.
    """
    if isinstance(value, str | Path):
        return load_robot(value)
    if not isinstance(value, Chain | Tree):
        raise InvalidArgumentError(
            f"{what} must be a Chain, a Tree (see load_robot), a catalog name or a URDF path, "
            f"got {value!r:.60}"
        )
    return value
