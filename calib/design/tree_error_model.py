"""A tree's measurement model for design: several tools measured in one campaign.

Each row measures one point on one tool (the CSV's ``tool`` column). The model of row i,
measuring tool t, is ``R_f (p_t(q_i) + R_t(q_i) m_t) + t_f``: the tree's geometry
(Khalil-Kleinfinger notation, :class:`~calib.kinematics.tree_model.TreeMDH`), one
measurement frame for every tool, and one marker per tool. The free parameters
(:class:`TreeErrorModel`) are the frame, the markers and base parameters of the tree's
standard set; their Jacobian (the analytic one of
:func:`calib.identification.tree_jacobian.tree_jacobian`) is what the design of a tree's
configurations scores (:mod:`calib.design.observability`). A tree is calibrated by the joint
engine (one measured term per tool: :mod:`calib.calibration.instrument`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..calibration.model import FRAME_NAMES, moved_frame, selection_lift
from ..identification.measures import POSITION
from ..identification.parameters import ParameterSet
from ..identification.tree_jacobian import tree_jacobian
from ..kinematics.so3 import left_jacobian, skew
from ..kinematics.tree_model import TreeMDH

__all__ = [
    "TreeErrorModel",
    "TreeState",
]


def _tool_marker_names(tool: str) -> tuple[str, str, str]:
    """Names of the marker coordinates on a tool [m]: ``<tool>.x``, ``.y``, ``.z``."""
    return (f"{tool}.x", f"{tool}.y", f"{tool}.z")


@dataclass(frozen=True, eq=False)
class TreeState:
    """A model of tree measurements: geometry, measurement frame, one marker per tool.

    Attributes:
        mdh: The tree's MDH model in the URDF base frame.
        frame: Pose of the URDF base frame in the measurement frame ``(4, 4)``.
        markers: Measured point on each tool, in the tool's frame ``(T, 3)`` [m].
    """

    mdh: TreeMDH
    frame: np.ndarray
    markers: np.ndarray

    def tool_placements(self, q: np.ndarray, tool: np.ndarray):
        """Rotation ``(m, 3, 3)`` and origin ``(m, 3)`` of each row's tool in the base frame."""
        R, p = np.empty((len(q), 3, 3)), np.empty((len(q), 3))
        for t in np.unique(tool):
            rows = tool == t
            kin = self.mdh.path_model(t).kinematics(q[rows][:, self.mdh.path_joints(t)])
            R[rows], p[rows] = kin.R[:, -1], kin.p[:, -1]
        return R, p

    def base_points(self, q: np.ndarray, tool: np.ndarray) -> np.ndarray:
        """Each row's marker in the URDF base frame ``(m, 3)`` [m]."""
        R, p = self.tool_placements(q, tool)
        return p + np.einsum("mij,mj->mi", R, self.markers[tool])


@dataclass(frozen=True, eq=False)
class TreeErrorModel:
    """The free parameters of a tree fit: frame, markers, base values of the tree's set.

    Attributes:
        params: The tree's standard parameter set.
        base: Names of the free base values (each a parameter of ``params``).
        n_tools: Number of tools T (one marker each).
    """

    params: ParameterSet
    base: tuple[str, ...]
    n_tools: int

    def names(self, tools: tuple[str, ...]) -> tuple[str, ...]:
        """Names of the free parameters, in the order of x."""
        markers = [n for t in tools for n in _tool_marker_names(t)]
        return (*FRAME_NAMES, *markers, *self.base)

    def _sizes(self) -> tuple[int, int, int]:
        return 6, 3 * self.n_tools, len(self.base)

    def size(self) -> int:
        """Number of free parameters."""
        return sum(self._sizes())

    def split(self, x: np.ndarray) -> list[np.ndarray]:
        """X cut into frame, markers and base values."""
        return np.split(np.asarray(x, dtype=float), np.cumsum(self._sizes())[:-1])

    def lift(self) -> np.ndarray:
        """``dX = lift @ x_b``: each base value moves its own standard parameter."""
        return selection_lift(self.params, self.base)

    def apply(self, start: TreeState, x: np.ndarray) -> TreeState:
        """The state at parameters x (x = 0 is ``start``)."""
        xf, xm, xb = self.split(x)
        frame = moved_frame(start.frame, xf)
        markers = start.markers + xm.reshape(-1, 3)
        mdh = self.params.apply(start.mdh, self.lift() @ xb) if xb.size else start.mdh
        return TreeState(mdh, frame, markers)

    def jacobian_at(
        self, start: TreeState, x: np.ndarray, q: np.ndarray, tool: np.ndarray
    ) -> np.ndarray:
        """d(model)/dx at rows of joint positions ``(m, n)`` and tool indices ``(m,)``.

        Returns:
            ``(m, 3, size)``.
        """
        state = self.apply(start, x)
        R = state.frame[:3, :3]
        Rt, _ = state.tool_placements(q, tool)
        lever = state.base_points(q, tool) @ R.T
        rot = -skew(lever) @ left_jacobian(self.split(x)[0][:3])
        blocks = [np.concatenate([rot, np.broadcast_to(np.eye(3), rot.shape)], axis=2)]
        markers = np.zeros((len(q), 3, 3 * self.n_tools))
        for t in range(self.n_tools):
            markers[tool == t, :, 3 * t : 3 * t + 3] = R @ Rt[tool == t]
        blocks.append(markers)
        if self.base:
            blocks.append(self._geometry_block(state, q, tool) @ self.lift())
        return np.concatenate(blocks, axis=2)

    def _geometry_block(self, state: TreeState, q: np.ndarray, tool: np.ndarray) -> np.ndarray:
        """Columns of the standard parameters, ``(m, 3, len(params))``."""
        out = np.zeros((len(q), 3, len(self.params)))
        for t in np.unique(tool):
            rows = tool == t
            measured = np.zeros((int(rows.sum()), self.n_tools), dtype=bool)
            measured[:, t] = True
            meas = dataclasses.replace(POSITION, marker=tuple(state.markers[t]))
            W = tree_jacobian(state.mdh, self.params, q[rows], meas, measured)
            out[rows] = state.frame[:3, :3] @ W.reshape(-1, 3, len(self.params))
        return out
