"""Coupled joints: the URDF ``<mimic>`` relation of a chain's joints to independent joints.

A mimic joint's position is ``multiplier * q_master + offset``. In a chain, the mimic joint
is a joint like any other (its geometric parameters enter the model, it has an MDH row), but
its position is computed: the chain's configuration is given for its *independent joints*
(the variables), which are the chain joints without a ``<mimic>`` tag and the masters of its
mimic joints, in or outside the chain. A mimic of a mimic follows the end of the relation.

Since the joint angle of a revolute mimic row k is ``theta_k + multiplier q + offset``, the
offset of the mimic expression and the joint offset theta_k (r_k for a prismatic joint) are
one parameter: no measurement separates them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.checks import joint_positions
from ..exceptions import ChainError
from .urdf_xml import URDFInfo

__all__ = [
    "MAX_MIMIC_DEPTH",
    "Coupling",
    "MimicJoint",
    "chain_coupling",
    "tree_coupling",
]

MAX_MIMIC_DEPTH = 64
"""Longest chain of mimic tags followed (a longer one is a cycle)."""


@dataclass(frozen=True)
class MimicJoint:
    """One chain joint that follows another: ``q_joint = multiplier * q_master + offset``.

    Attributes:
        joint: Index of the chain joint (0-based).
        name: Its URDF name.
        master: The independent joint it follows (at the end of the mimic tags).
        multiplier: Factor.
        offset: Offset [rad or m].
    """

    joint: int
    name: str
    master: str
    multiplier: float
    offset: float


@dataclass(frozen=True, eq=False)
class Coupling:
    """Positions of a chain's joints from its independent joints (URDF ``<mimic>`` tags).

    Attributes:
        names: The independent joints (variables): chain joints without a mimic tag in chain
            order, then the masters outside the chain, in the order they are first needed.
        matrix: ``(n, v)``: ``q_joints = q_variables @ matrix.T + offset``.
        offset: ``(n,)`` [rad or m].
        lower: Lower sampling bound per variable [rad or m].
        upper: Upper sampling bound per variable [rad or m].
        mimic: The chain joints that follow another joint.
    """

    names: tuple[str, ...]
    matrix: np.ndarray
    offset: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    mimic: tuple[MimicJoint, ...]

    def __post_init__(self) -> None:
        for name in ("matrix", "offset", "lower", "upper"):
            a = np.array(getattr(self, name), dtype=float)
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    @property
    def n_variables(self) -> int:
        """Number of independent joints."""
        return len(self.names)

    def joint_values(self, variables: np.ndarray) -> np.ndarray:
        """Chain joint positions ``(m, n)`` from independent joint positions ``(m, v)``.

        Raises:
            InvalidArgumentError: Wrong shape, NaN, or values beyond
                :data:`~calib.core.checks.MAX_JOINT_POSITION`.
        """
        qv = joint_positions(variables, self.n_variables)
        return qv @ self.matrix.T + self.offset

    def variables(self, q: np.ndarray) -> np.ndarray:
        """Independent joint positions ``(m, v)`` of chain joint positions ``(m, n)``.

        Each variable is read from the first chain joint it drives; on positions that follow
        the relation, this inverts :meth:`joint_values`.
        """
        q = joint_positions(q, self.matrix.shape[0])
        rows = np.argmax(self.matrix != 0, axis=0)
        cols = np.arange(self.n_variables)
        return (q[:, rows] - self.offset[rows]) / self.matrix[rows, cols]


def _resolve(info: URDFInfo, name: str) -> tuple[str, float, float]:
    """The independent joint a joint follows and the composed factor and offset."""
    joints = {j.name: j for j in info.joints}
    factor, offset, current, seen = 1.0, 0.0, name, [name]
    while (tag := joints[current].mimic) is not None:
        if tag.joint not in joints:
            raise ChainError(
                f"joint '{current}' mimics '{tag.joint}', which is not a joint of the URDF "
                f"(a broken <mimic> tag)"
            )
        if tag.joint in seen or len(seen) > MAX_MIMIC_DEPTH:
            path = " -> ".join([*seen, tag.joint])
            raise ChainError(f"the <mimic> tags of joint '{name}' form a cycle: {path}")
        factor, offset = factor * tag.multiplier, offset + factor * tag.offset
        current = tag.joint
        seen.append(current)
    return current, factor, offset


def chain_coupling(
    info: URDFInfo,
    joint_names: tuple[str, ...],
    limits: dict[str, tuple[float, float]],
) -> Coupling:
    """The coupling of a chain's joints (identity when none has a mimic tag).

    Args:
        info: The checked URDF.
        joint_names: The chain joints, base to tool.
        limits: Sampling bounds [rad or m] of every revolute, continuous or prismatic joint
            of the model by name (a master outside the chain needs its own).

    Raises:
        ChainError: A mimic tag names a missing joint, the tags form a cycle, or a master is
            not a revolute, continuous or prismatic joint.
    """
    tags = {j.name: j.mimic for j in info.joints}
    mimic: list[MimicJoint] = []
    for k, joint in enumerate(joint_names):
        if tags[joint] is None:
            continue
        master, factor, offset = _resolve(info, joint)
        if master not in limits:
            raise ChainError(
                f"joint '{joint}' mimics '{master}', which is not a revolute, continuous or "
                f"prismatic joint: it cannot drive it"
            )
        mimic.append(MimicJoint(k, joint, master, factor, offset))
    return _coupling(joint_names, mimic, limits)


def _coupling(
    joint_names: tuple[str, ...],
    mimic: list[MimicJoint],
    limits: dict[str, tuple[float, float]],
) -> Coupling:
    """The coupling of joints of which ``mimic`` follow others (rows in joint order)."""
    following = {mj.name for mj in mimic}
    names = [n for n in joint_names if n not in following]
    for mj in mimic:  # a 0 multiplier: a joint held at its offset, no variable
        if mj.multiplier != 0.0 and mj.master not in names:
            names.append(mj.master)
    matrix = np.zeros((len(joint_names), len(names)))
    offsets = np.zeros(len(joint_names))
    for k, joint in enumerate(joint_names):
        if joint not in following:
            matrix[k, names.index(joint)] = 1.0
    for mj in mimic:
        offsets[mj.joint] = mj.offset
        if mj.multiplier != 0.0:
            matrix[mj.joint, names.index(mj.master)] = mj.multiplier
    return Coupling(
        names=tuple(names),
        matrix=matrix,
        offset=offsets,
        lower=np.array([limits[n][0] for n in names]),
        upper=np.array([limits[n][1] for n in names]),
        mimic=tuple(mimic),
    )


def tree_coupling(
    joint_names: tuple[str, ...],
    lower: np.ndarray,
    upper: np.ndarray,
    couplings: tuple[Coupling | None, ...],
) -> Coupling | None:
    """The coupling of a tree's joints, from the couplings of its chains (None: no mimic).

    The variables are the tree joints without a mimic tag in tree order, then the masters
    outside the tree in the order first needed, as for a chain.

    Args:
        joint_names: The tree joints, antecedents first.
        lower: Their lower sampling bounds [rad or m].
        upper: Their upper sampling bounds [rad or m].
        couplings: The coupling (or None) of each chain of the tree.
    """
    limits = {n: (float(a), float(b)) for n, a, b in zip(joint_names, lower, upper, strict=True)}
    follows: dict[str, MimicJoint] = {}
    for coupling in couplings:
        if coupling is None:
            continue
        bounds = zip(coupling.names, coupling.lower, coupling.upper, strict=True)
        limits.update({n: (float(lo), float(hi)) for n, lo, hi in bounds if n not in limits})
        follows.update({mj.name: mj for mj in coupling.mimic})
    if not follows:
        return None
    mimic = [
        MimicJoint(k, name, follows[name].master, follows[name].multiplier, follows[name].offset)
        for k, name in enumerate(joint_names)
        if name in follows
    ]
    return _coupling(joint_names, mimic, limits)
