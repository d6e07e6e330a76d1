"""Calibration of a tree: several tools measured in one campaign, shared joints fitted once.

Each row of the data measures one point on one tool (the CSV's ``tool`` column). The model
of row i, measuring tool t, is ``R_f (p_t(q_i) + R_t(q_i) m_t) + t_f``: the tree's geometry
(Khalil-Kleinfinger notation, :class:`~.tree_model.TreeMDH`), one measurement frame for
every tool, and one marker per tool. Steps, as for a chain:

1. registration: the frame by Horn/Umeyama on the nominal points of every tool together,
   each tool's marker by linear least squares, alternated, then Levenberg-Marquardt;
2. the free parameters: the frame, the markers and the base parameters of the tree's
   complete set at the measured configurations (pivoted QR of the stacked Jacobian, frame
   and markers first), or the frame and markers only (``frames``);
3. the fit (:func:`calib.calibration.solve.fit`, the analytic Jacobian of
   :func:`calib.identification.tree_jacobian.tree_jacobian`);
4. validation and the checks of a chain (:func:`calib.calibration.validation.refusal`),
   with the errors per tool.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..identification.measures import POSITION, Measurement
from ..identification.parameters import ParameterSet
from ..identification.tree_jacobian import tree_jacobian
from ..kinematics.so3 import left_jacobian, rotation_matrix, skew
from ..kinematics.tree_model import TreeMDH
from ..measurements.data import Measurements
from .model import FRAME_NAMES
from .registration import rigid_fit

__all__ = [
    "REGISTRATION_ITERATIONS",
    "TreeErrorModel",
    "TreeState",
    "register_tree",
]

REGISTRATION_ITERATIONS = 50
"""Most alternations of the closed-form registration (frame, then markers)."""


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

    @property
    def kind(self) -> Measurement:
        """What each row measures: the position of its tool's marker."""
        return POSITION

    def residuals(self, data: Measurements, torque=None) -> np.ndarray:
        """Measured - model per row ``(m, 3)`` [m] (``torque`` is not used)."""
        tool = _tool_indices(self.mdh, data)
        R, p = self.tool_placements(data.q, tool)
        markers = self.markers[tool][:, None, :]
        return self.kind.residual(R, p, data.observed, markers, self.frame)


def _tool_indices(mdh: TreeMDH, data: Measurements) -> np.ndarray:
    """Index of each row's tool among the model's tools."""
    if data.tool is None:
        return np.zeros(data.m, dtype=int)
    index = {name: t for t, name in enumerate(mdh.tool_frames)}
    return np.array([index[name] for name in data.tool], dtype=int)


@dataclass(frozen=True, eq=False)
class TreeErrorModel:
    """The free parameters of a tree fit: frame, markers, base values of the tree's set.

    Attributes:
        params: The tree's standard parameter set.
        base: Names of the free base values (each a parameter of ``params``).
        n_tools: Number of tools T (one marker each).
        frame: The measurement frame is free.
        markers: The markers are free.
    """

    params: ParameterSet
    base: tuple[str, ...]
    n_tools: int
    frame: bool = True
    markers: bool = True
    n_markers: int = 1  # points per row (the interface of calib.calibration.solve)

    @property
    def kind(self) -> Measurement:
        """What each row measures: the position of its tool's marker."""
        return POSITION

    @property
    def pose(self) -> bool:
        """Orientation rows are fitted (never: a tree's rows are points)."""
        return bool(self.kind.rotation_rows)

    @property
    def rows(self) -> int:
        """Residual rows per row of the data."""
        return self.kind.rows_of(self.n_markers)

    def names(self, tools: tuple[str, ...]) -> tuple[str, ...]:
        """Names of the free parameters, in the order of x."""
        out = list(FRAME_NAMES) if self.frame else []
        if self.markers:
            out += [n for t in tools for n in _tool_marker_names(t)]
        return (*out, *self.base)

    def _sizes(self) -> tuple[int, int, int]:
        return 6 * self.frame, 3 * self.n_tools * self.markers, len(self.base)

    def size(self) -> int:
        """Number of free parameters."""
        return sum(self._sizes())

    def split(self, x: np.ndarray) -> list[np.ndarray]:
        """X cut into frame, markers and base values."""
        return np.split(np.asarray(x, dtype=float), np.cumsum(self._sizes())[:-1])

    def lift(self) -> np.ndarray:
        """``dX = lift @ x_b``: each base value moves its own standard parameter."""
        lift = np.zeros((len(self.params), len(self.base)))
        for j, name in enumerate(self.base):
            lift[self.params.index(name), j] = 1.0
        return lift

    def apply(self, start: TreeState, x: np.ndarray) -> TreeState:
        """The state at parameters x (x = 0 is ``start``)."""
        xf, xm, xb = self.split(x)
        frame = start.frame.copy()
        if self.frame:
            frame[:3, :3] = rotation_matrix(xf[:3]) @ start.frame[:3, :3]
            frame[:3, 3] = start.frame[:3, 3] + xf[3:]
        markers = start.markers + (xm.reshape(-1, 3) if self.markers else 0.0)
        mdh = self.params.apply(start.mdh, self.lift() @ xb) if xb.size else start.mdh
        return TreeState(mdh, frame, markers)

    def jacobian(self, start: TreeState, x: np.ndarray, data, torque=None) -> np.ndarray:
        """d(model)/dx, ``(m, 3, size)`` (rows in the data's order)."""
        return self.jacobian_at(start, x, data.q, _tool_indices(start.mdh, data))

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
        blocks = []
        if self.frame:
            rot = -skew(lever) @ left_jacobian(self.split(x)[0][:3])
            blocks.append(np.concatenate([rot, np.broadcast_to(np.eye(3), rot.shape)], axis=2))
        if self.markers:
            blk = np.zeros((len(q), 3, 3 * self.n_tools))
            for t in range(self.n_tools):
                blk[tool == t, :, 3 * t : 3 * t + 3] = R @ Rt[tool == t]
            blocks.append(blk)
        if self.base:
            blocks.append(self._geometry_block(state, q, tool) @ self.lift())
        J = np.concatenate(blocks, axis=2) if blocks else np.zeros((len(q), 3, 0))
        return self.kind.jacobian_rows(J, n_markers=self.n_markers)

    def _geometry_block(self, state: TreeState, q: np.ndarray, tool: np.ndarray) -> np.ndarray:
        """Columns of the standard parameters, ``(m, 3, len(params))``."""
        out = np.zeros((len(q), 3, len(self.params)))
        for t in np.unique(tool):
            rows = tool == t
            measured = np.zeros((int(rows.sum()), self.n_tools), dtype=bool)
            measured[:, t] = True
            meas = dataclasses.replace(self.kind, marker=tuple(state.markers[t]))
            W = tree_jacobian(state.mdh, self.params, q[rows], meas, measured)
            out[rows] = state.frame[:3, :3] @ W.reshape(-1, 3, len(self.params))
        return out


def register_tree(nominal: TreeMDH, data: Measurements) -> TreeState:
    """The measurement frame and the markers in closed form, from the nominal tree."""
    tool = _tool_indices(nominal, data)
    R, p = TreeState(nominal, np.eye(4), np.zeros((nominal.n_tools, 3))).tool_placements(
        data.q, tool
    )
    markers = np.zeros((nominal.n_tools, 3))
    frame = np.eye(4)
    for _ in range(REGISTRATION_ITERATIONS):
        pts = p + np.einsum("mij,mj->mi", R, markers[tool])
        frame[:3, :3], frame[:3, 3] = rigid_fit(pts, data.position)
        local = (data.position - frame[:3, 3]) @ frame[:3, :3] - p  # R_t m_t, base frame
        new = markers.copy()
        for t in np.unique(tool):
            rows = tool == t
            A, b = R[rows].reshape(-1, 3), local[rows].reshape(-1)
            new[t] = np.linalg.lstsq(A, b, rcond=None)[0]
        if np.max(np.abs(new - markers)) < 1e-12:
            markers = new
            break
        markers = new
    return TreeState(nominal, frame, markers)
