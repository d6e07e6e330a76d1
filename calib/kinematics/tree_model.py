"""Khalil-Kleinfinger modified DH model of a tree (several tools sharing joints).

Row 0 is frame 0 (fixed to the base frame -1), rows 1..n the tree joints (in the order of
:class:`~calib.kinematics.tree.Tree`) and rows n+1..n+T the tools. Row k places frame k in the frame
of its antecedent a(k):

    T(a(k), k) = Rot(z, gamma_k) Trans(z, b_k) Trans(y, y_k) Rot(y, beta_k) Rot(x, alpha_k)
                 Trans(x, d_k) Rot(z, theta_k + (1 - sigma_k) q_k) Trans(z, r_k + sigma_k q_k)

x_{a(k)} lies along the common normal to its first child (the child of smallest row), for
which gamma and b are zero; another child k is placed with gamma_k and b_k (rotation and
translation about z_{a(k)}). A one-tool tree is the chain's model, row for row. Along the path
to one tool, gamma_k and b_k merge into theta_{a(k)} and r_{a(k)}: the path is a serial
:class:`~calib.kinematics.mdh.MDHModel`, and calib computes the tree with its chain machinery.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.checks import joint_positions
from ..exceptions import InvalidArgumentError
from .mdh import (
    PARALLEL_TOL,
    SNAP_ANGLE,
    SNAP_LENGTH,
    MDHModel,
    converted_chain,
    snap_angle,
    snap_length,
)
from .tree import Tree

__all__ = ["ROW_ARRAYS", "TreeMDH", "from_tree"]

ROW_ARRAYS = ("gamma", "b", "beta", "alpha", "d", "theta", "r", "y")
"""The geometric arrays of a row: angles [rad] and lengths [m]."""

_FIELDS = (
    "antecedent",
    "sigma",
    *ROW_ARRAYS,
    "joint_names",
    "parallel",
    "coincident",
    "base_frame",
    "tool_frames",
)


@dataclass(frozen=True, eq=False)
class TreeMDH:
    """Modified-DH rows of a tree (frames 0..n+T), a value object.

    Attributes:
        antecedent: a(k), the row frame k is placed from; -1 for row 0.
        sigma: 0 revolute, 1 prismatic, -1 fixed row (row 0 and the tool rows).
        gamma: Angle about z_{a(k)} [rad] (zero for a first child).
        b: Distance along z_{a(k)} [m] (zero for a first child).
        beta: Hayati angle about y_{a(k)} (after gamma) [rad].
        alpha: Angle about x_{a(k)} (after gamma and beta) [rad].
        d: Distance along that x [m].
        theta: Angle about z_k [rad] (joint offset for a revolute row).
        r: Distance along z_k [m] (joint offset for a prismatic row).
        y: Translation along y_{a(k)} [m] (zero for a converted model).
        joint_names: URDF joint of each row, None for row 0 and the tool rows.
        parallel: Row k whose axis is parallel to its antecedent's.
        coincident: Row k whose axis lies on its antecedent's.
        base_frame: Name of frame -1.
        tool_frames: Names of the tool frames, one per tool row.
        source: The tree a model was converted from and the parallel tolerance (set by
            :func:`~calib.from_tree`), or None.
    """

    antecedent: np.ndarray
    sigma: np.ndarray
    gamma: np.ndarray
    b: np.ndarray
    beta: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    theta: np.ndarray
    r: np.ndarray
    y: np.ndarray
    joint_names: tuple[str | None, ...]
    parallel: np.ndarray
    coincident: np.ndarray
    base_frame: str = ""
    tool_frames: tuple[str, ...] = ()
    source: tuple[Tree, float] | None = field(default=None, repr=False)
    _paths: tuple[tuple[np.ndarray, MDHModel], ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("antecedent", "sigma", *ROW_ARRAYS, "parallel", "coincident"):
            a = np.array(getattr(self, name))
            a.flags.writeable = False
            object.__setattr__(self, name, a)
        object.__setattr__(self, "tool_frames", tuple(self.tool_frames))
        _check_structure(self)
        paths = tuple((rows, self._path_model(rows, t)) for t, rows in enumerate(_paths(self)))
        object.__setattr__(self, "_paths", paths)

    @functools.cached_property
    def n(self) -> int:
        """Number of joints."""
        return int(np.sum(self.sigma >= 0))

    def __repr__(self) -> str:
        """One line: ``<TreeMDH base -> FL_FOOT, FR_FOOT, 6 joints>`` (rows are attributes)."""
        tools = ", ".join(self.tool_frames)
        return f"<TreeMDH {self.base_frame} -> {tools}, {self.n} joints>"

    @property
    def n_tools(self) -> int:
        """Number of tools T."""
        return len(self.sigma) - 1 - self.n

    @functools.cached_property
    def tool_rows(self) -> tuple[int, ...]:
        """Rows of the tools: n+1..n+T."""
        return tuple(range(self.n + 1, len(self.sigma)))

    @property
    def tool_frame(self) -> str:
        """The tool names joined with ', ' (for one-line reports)."""
        return ", ".join(self.tool_frames)

    def tool_frame_of(self, k: int) -> str | None:
        """The tool frame row ``k`` stands for (a tool row), or None (another row, or no names).

        ``tool_frames`` is empty or names every tool row (checked on construction).
        """
        if k not in self.tool_rows or not self.tool_frames:
            return None
        return self.tool_frames[self.tool_rows.index(k)]

    def first_child(self, k: int) -> bool:
        """Whether row k is the first child (smallest row) of its antecedent."""
        return int(np.flatnonzero(self.antecedent == self.antecedent[k])[0]) == k

    def path_rows(self, t: int) -> np.ndarray:
        """Rows from row 0 to tool t's row, in order."""
        return self._paths[t][0]

    def path_joints(self, t: int) -> np.ndarray:
        """Columns of q (0-based joint indices) on the path to tool t."""
        return self._paths[t][0][1:-1] - 1

    def path_model(self, t: int) -> MDHModel:
        """The serial model from the base to tool t (gamma, b merged into the antecedent)."""
        return self._paths[t][1]

    def _path_model(self, rows: np.ndarray, t: int) -> MDHModel:
        theta, r = self.theta[rows].copy(), self.r[rows].copy()
        theta[:-1] += self.gamma[rows[1:]]
        r[:-1] += self.b[rows[1:]]
        return MDHModel(
            np.concatenate([[-1], self.sigma[rows[1:-1]], [-1]]),
            self.beta[rows],
            self.alpha[rows],
            self.d[rows],
            theta,
            r,
            self.y[rows],
            (None, *(self.joint_names[k] for k in rows[1:-1]), None),
            self.parallel[rows],
            self.coincident[rows],
            self.base_frame,
            self.tool_frames[t] if t < len(self.tool_frames) else "",
        )

    def replace(self, **changes) -> TreeMDH:
        """A copy with some fields replaced (the model itself is never mutated).

        ``source`` is kept when only the frame names change (``base_frame``,
        ``tool_frames``), as :meth:`MDHModel.replace` keeps it; any other change sets it to
        None unless ``changes`` gives it.
        """
        if "source" not in changes and changes.keys() <= {"base_frame", "tool_frames"}:
            changes = {**changes, "source": self.source}
        fields = {name: getattr(self, name) for name in _FIELDS}
        fields.update(changes)
        return TreeMDH(**fields)

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Every tool frame in the base frame, shape ``(m, T, 4, 4)``.

        Args:
            q: Joint positions ``(m, n)`` or ``(n,)`` [rad or m].
        """
        q = joint_positions(q, self.n)
        out = [self.path_model(t).forward(q[:, self.path_joints(t)]) for t in range(self.n_tools)]
        return np.stack(out, axis=1)

    def idealized(self, angle_tol: float = SNAP_ANGLE, length_tol: float = SNAP_LENGTH) -> TreeMDH:
        """A copy with URDF round-off removed, for structural analysis.

        As :meth:`MDHModel.idealized`: a converted model starts from the conversion of its
        URDF with round-off removed; then angles (gamma too) within ``angle_tol`` of a multiple
        of 90 degrees and lengths (b too) under ``length_tol`` are snapped.
        """
        source = self
        if self.source is not None and (angle_tol, length_tol) == (SNAP_ANGLE, SNAP_LENGTH):
            tree, parallel_tol = self.source
            source = _converted_tree(tree.idealized(), parallel_tol)
        angles = {k: snap_angle(getattr(source, k), angle_tol) for k in ("gamma", "beta", "alpha")}
        lengths = {k: snap_length(getattr(source, k), length_tol) for k in ("b", "d", "r", "y")}
        theta = snap_angle(source.theta, angle_tol)
        return source.replace(**angles, **lengths, theta=theta)

    def rows(self) -> list[dict]:
        """The rows as JSON-ready dictionaries (radians, metres).

        A chain's keys plus the antecedent, gamma and b, and the tool of a tool row.
        """
        out = []
        for k in range(len(self.sigma)):
            s = int(self.sigma[k])
            row = {
                "name": str(k),
                "antecedent": int(self.antecedent[k]),
                "joint": self.joint_names[k],
                "tool": self.tool_frame_of(k),
                "sigma": None if s < 0 else s,
            }
            row.update({a: float(getattr(self, a)[k]) for a in ROW_ARRAYS})
            out.append(row)
        return out


def _check_structure(model: TreeMDH) -> None:
    """Refuse arrays that do not describe a tree (one line)."""
    rows = len(model.sigma)
    a, s = model.antecedent, model.sigma
    same = all(len(getattr(model, k)) == rows for k in (*ROW_ARRAYS, "antecedent", "parallel"))
    if not same or len(model.joint_names) != rows or len(model.coincident) != rows:
        raise InvalidArgumentError("the rows of a tree model must all have the same length")
    n = int(np.sum(s >= 0))
    ok = rows >= 3 and a[0] == -1 and s[0] == -1 and np.all((s >= -1) & (s <= 1))
    ok = ok and np.all(s[1 : n + 1] >= 0) and np.all(s[n + 1 :] == -1) and n + 1 < rows
    ok = ok and all(0 <= a[k] < k for k in range(1, rows))
    ok = ok and not np.isin(np.arange(n + 1, rows), a).any()
    if not ok:
        raise InvalidArgumentError(
            "a tree model has row 0 fixed (antecedent -1), joint rows 1..n, then tool rows "
            "(leaves), each row after its antecedent"
        )
    if model.tool_frames and len(model.tool_frames) != rows - 1 - n:
        raise InvalidArgumentError(f"a tree model with {rows - 1 - n} tools names each tool")


def _paths(model: TreeMDH) -> list[np.ndarray]:
    out = []
    n = int(np.sum(model.sigma >= 0))
    for tool in range(n + 1, len(model.sigma)):
        rows = [tool]
        while rows[-1] != 0:
            rows.append(int(model.antecedent[rows[-1]]))
        path = np.array(rows[::-1], dtype=int)
        path.flags.writeable = False
        out.append(path)
    return out


def from_tree(tree: Tree, parallel_tol: float = PARALLEL_TOL) -> TreeMDH:
    """Convert a tree to its Khalil-Kleinfinger MDH model (base frame = frame -1).

    Each path is converted as a chain (:func:`~calib.from_chain`); where a frame has
    several children, the path through its first child fixes its x axis, and every other
    child gets gamma and b, the difference of the angle and distance that close the
    antecedent's row along its own path.

    Args:
        tree: The tree.
        parallel_tol: Parallel-axis tolerance [rad].

    Returns:
        The model; the forward kinematics of every tool equals Pinocchio's.
    """
    if not isinstance(tree, Tree):
        raise InvalidArgumentError(
            f"from_tree converts a Tree (see load_tree), got {type(tree).__name__}"
        )
    return _converted_tree(tree, parallel_tol).replace(source=(tree, parallel_tol))


def _converted_tree(tree: Tree, parallel_tol: float) -> TreeMDH:
    n, T = tree.n, tree.n_tools
    models = [converted_chain(c, parallel_tol) for c in tree.chains]
    paths = [np.concatenate([[0], 1 + p, [n + 1 + t]]) for t, p in enumerate(tree.paths)]
    antecedent = np.concatenate([[-1], 1 + tree.parent, [p[-2] for p in paths]])
    rows = 1 + n + T
    values: dict[str, Any] = {k: np.zeros(rows) for k in ROW_ARRAYS}
    flags: dict[str, Any] = {k: np.zeros(rows, dtype=bool) for k in ("parallel", "coincident")}
    # where[k]: (path, position) of the first path through row k
    where: dict[int, tuple[int, int]] = {}
    for t, p in enumerate(paths):
        for i, k in enumerate(p):
            where.setdefault(int(k), (t, i))
    for k in range(1, rows):
        t, i = where[k]
        for name in ("beta", "alpha", "d"):
            values[name][k] = getattr(models[t], name)[i]
        for name in flags:
            flags[name][k] = getattr(models[t], name)[i]
    first: dict[int, int] = {}
    for k in range(1, rows):
        first.setdefault(int(antecedent[k]), k)
    for k in range(rows):  # theta, r of a row close on its first child's path (tools: own)
        t, i = where[first.get(k, k)]
        i = i - 1 if k in first else i
        values["theta"][k], values["r"][k] = models[t].theta[i], models[t].r[i]
    for k in range(1, rows):
        a = int(antecedent[k])
        if first[a] != k:
            t, i = where[k]
            turn = models[t].theta[i - 1] - values["theta"][a]
            values["gamma"][k] = math.remainder(turn, 2 * math.pi)
            values["b"][k] = models[t].r[i - 1] - values["r"][a]
    sigma = np.concatenate([[-1], tree.sigma, -np.ones(T, dtype=int)])
    names = (None, *tree.joint_names, *(None,) * T)
    return TreeMDH(
        antecedent,
        sigma,
        **values,
        joint_names=names,
        **flags,
        base_frame=tree.base_frame,
        tool_frames=tree.tool_frames,
    )
