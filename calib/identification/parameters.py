"""Standard geometric parameter sets: the paper's set and a complete one."""

from __future__ import annotations

import enum
import functools
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from ..core.checks import real_array, shown
from ..exceptions import InvalidArgumentError
from ..kinematics.mdh import MDHModel
from ..kinematics.tree_model import TreeMDH

__all__ = [
    "ROW_NAME",
    "ColumnLayout",
    "Kind",
    "Parameter",
    "ParameterSet",
    "complete_parameters",
    "joint_of",
    "paper_parameters",
    "parameter_set",
]

ROW_NAME = re.compile(r"(alpha|beta|gamma|theta|offset|[dryb]|c)(\d+)")
"""A parameter of an MDH row by its name: its kind (a mimic joint's ``offset``, a compliance
``c`` included) and its row k."""
_PLACEMENT_NAME = re.compile(r"(.+):(r?[xyz]|(?:alpha|beta|gamma|theta|offset|[dryb])\d+)")
"""A joint placement component (``arm_5_joint:rz``) or direction (``arm_5_joint:alpha7``)."""


def joint_of(name: str, joint_names: Sequence[str | None]) -> str | None:
    """The URDF joint a parameter belongs to (of its MDH row, or named), or None for a frame.

    Args:
        name: A parameter's name: of an MDH row (``theta6``: ``joint_names[6]``), or a joint
            placement's (``arm_5_joint:rz``, ``arm_5_joint:alpha7``: the joint it names); a
            direction two chains name alike may end in ``@<tool>``.
        joint_names: The URDF joint of each MDH row (``MDHModel.joint_names``,
            ``TreeMDH.joint_names``: None for the base and tool rows).
    """
    name = name.partition("@")[0]
    row = ROW_NAME.fullmatch(name)
    if row is not None:
        k = int(row.group(2))
        return joint_names[k] if 0 <= k < len(joint_names) else None
    placement = _PLACEMENT_NAME.fullmatch(name)
    return None if placement is None else placement.group(1)


#: A chain's or a tree's MDH model: :meth:`ParameterSet.apply` returns the kind it is given.
_Model = TypeVar("_Model", MDHModel, TreeMDH)


class Kind(enum.Enum):
    """The elementary error a parameter stands for, in row k (frame k-1 to frame k)."""

    GAMMA = "gamma"  # rotation about z_{a(k)} of a tree's branch [rad] (trees only)
    B = "b"  # translation along z_{a(k)} of a tree's branch [m] (trees only)
    Y = "y"  # translation along y_{k-1} [m] (complete set only)
    BETA = "beta"  # rotation about y_{k-1} [rad]
    ALPHA = "alpha"  # rotation about x_{k-1} (after beta) [rad]
    D = "d"  # translation along x_{k-1} (after beta) [m]
    THETA = "theta"  # rotation about z_k [rad]
    R = "r"  # translation along z_k [m]

    @property
    def is_rotation(self) -> bool:
        """True for angles [rad], False for lengths [m]."""
        return self in _ROTATIONS


_ROTATIONS = frozenset((Kind.GAMMA, Kind.BETA, Kind.ALPHA, Kind.THETA))

_COLUMN_OF = {
    "y": (0, 0, 0),
    "beta": (0, 0, 1),
    "alpha": (1, 0, 1),
    "d": (1, 0, 0),
    "theta": (2, 1, 1),
    "r": (2, 1, 0),
}
"""Per kind of a chain's row (by value: an enum's own hash is slow): the vector its column's
axis is (0 y_{k-1}, 1 x after beta and alpha, 2 z_k), the point a rotation turns about (0
where beta and alpha act, 1 the origin of frame k; see :class:`ColumnLayout`), and 1 for a
rotation."""


@dataclass(frozen=True)
class Parameter:
    """One standard geometric parameter.

    Attributes:
        row: Row (frame) index k, 0..n+1.
        kind: Which elementary error.
    """

    row: int
    kind: Kind

    @property
    def name(self) -> str:
        """Name after the frame, e.g. ``theta3``."""
        return f"{self.kind.value}{self.row}"


@dataclass(frozen=True)
class ColumnLayout:
    """Gather plan of a parameter set's Jacobian columns.

    Attributes:
        axis_source: Per column, the vector its axis is: 0 (y_{k-1}), 1 (x after beta and
            alpha) or 2 (z_k).
        axis_row: Per column, the row k where that vector is taken.
        point_source: Per rotation column, the point it turns about: 0 (where beta and alpha
            act) or 1 (the origin of frame k).
        point_row: Per rotation column, the row k of that point.
        rotations: Indices of the rotation columns.
    """

    axis_source: np.ndarray
    axis_row: np.ndarray
    point_source: np.ndarray
    point_row: np.ndarray
    rotations: np.ndarray


@dataclass(frozen=True)
class ParameterSet:
    """An ordered set of standard parameters.

    Attributes:
        label: ``paper`` or ``complete``.
        parameters: The parameters, in row order.
    """

    label: str
    parameters: tuple[Parameter, ...]

    def __len__(self) -> int:
        return len(self.parameters)

    def __repr__(self) -> str:
        """One line of names (the dataclass's listed every Parameter: 6,480 characters)."""
        names = self.names if len(self) <= 8 else (*self.names[:6], "...", self.names[-1])
        return f"<ParameterSet {self.label}: {len(self)} parameters ({', '.join(names)})>"

    @functools.cached_property
    def names(self) -> tuple[str, ...]:
        """Parameter names, e.g. ``('theta0', 'r0', 'alpha1', ...)`` (computed once per set)."""
        return tuple(p.name for p in self.parameters)

    @functools.cached_property
    def layout(self) -> ColumnLayout:
        """How the Jacobian gathers each column's axis and point (computed once per set)."""
        plan = [(p.row, *_COLUMN_OF[p.kind._value_]) for p in self.parameters]
        rows, axis, at_origin, rotation = np.array(plan, dtype=int).reshape(-1, 4).T.copy()
        rot = np.flatnonzero(rotation)
        return ColumnLayout(axis, rows, at_origin[rot], rows[rot], rot)

    def index(self, name: str) -> int:
        """Position of a parameter by name."""
        return self.names.index(name)

    def values(self, mdh: MDHModel) -> np.ndarray:
        """Nominal values of the parameters in a model (chain or tree) [rad or m]."""
        _check_model(mdh, tree=True)
        return np.array([getattr(mdh, p.kind.value)[p.row] for p in self.parameters])

    def apply(self, mdh: _Model, delta: np.ndarray) -> _Model:
        """A new model (chain or tree) whose parameters are shifted by ``delta`` (set order)."""
        _check_model(mdh, tree=True)
        delta = real_array(delta, "delta", (len(self),))
        arrays = {}
        for field, rows, where in self._shifts:
            a = getattr(mdh, field).copy()
            np.add.at(a, rows, delta[where])  # in set order, repeated parameters too
            arrays[field] = a
        return mdh.replace(**arrays)

    @functools.cached_property
    def _shifts(self) -> tuple[tuple[str, np.ndarray, np.ndarray], ...]:
        """Per field of the model the set shifts: its rows and their places in the set."""
        fields: dict[str, list[int]] = {}
        for i, p in enumerate(self.parameters):
            fields.setdefault(p.kind._value_, []).append(i)
        rows = np.array([p.row for p in self.parameters], dtype=int)
        return tuple((f, rows[i], np.array(i)) for f, i in fields.items())


def _check_model(mdh, tree: bool = False) -> None:
    if isinstance(mdh, MDHModel) or (tree and isinstance(mdh, TreeMDH)):
        return
    raise InvalidArgumentError(f"mdh must be an MDHModel (see from_chain), got {mdh!r:.60}")


def paper_parameters(mdh: MDHModel) -> ParameterSet:
    """The paper's set: 4(n+2) - 2 parameters, beta_k where axis k-1 and k are parallel.

    Row 0 carries theta0 and r0 (the base merged into frames 0 and 1); rows 1..n+1 carry
    alpha, d, theta, r, except where rows k >= 2 are parallel: beta_k replaces r_k.
    """
    _check_model(mdh)
    params = [Parameter(0, Kind.THETA), Parameter(0, Kind.R)]
    for k in range(1, mdh.n + 2):
        if mdh.parallel[k] and k >= 2:
            kinds = (Kind.BETA, Kind.ALPHA, Kind.D, Kind.THETA)
        else:
            kinds = (Kind.ALPHA, Kind.D, Kind.THETA, Kind.R)
        params += [Parameter(k, kind) for kind in kinds]
    return ParameterSet("paper", tuple(params))


def complete_parameters(mdh: MDHModel) -> ParameterSet:
    """A set complete at the nominal geometry: the paper's set plus its missing errors.

    Extras: ``beta1`` where the base z axis is parallel to joint 1 (the paper has no beta
    there), and ``y_k`` (a translation along y_{k-1}) wherever lines k-1 and k coincide, where
    no MDH parameter can move line k sideways.
    """
    _check_model(mdh)
    params = list(paper_parameters(mdh).parameters)
    if mdh.parallel[1]:
        params.append(Parameter(1, Kind.BETA))
    params += [Parameter(k, Kind.Y) for k in range(1, mdh.n + 2) if mdh.coincident[k]]
    order = [Kind.Y, Kind.BETA, Kind.ALPHA, Kind.D, Kind.THETA, Kind.R]
    params.sort(key=lambda p: (p.row, order.index(p.kind)))
    return ParameterSet("complete", tuple(params))


def parameter_set(mdh: MDHModel, label: str) -> ParameterSet:
    """The ``paper`` or ``complete`` set of a model.

    Raises:
        InvalidArgumentError: Unknown label.
    """
    if isinstance(label, str) and label == "paper":
        return paper_parameters(mdh)
    if isinstance(label, str) and label == "complete":
        return complete_parameters(mdh)
    raise InvalidArgumentError(f"unknown parameter set {shown(label)}: choose paper or complete")
