"""Calibration of a tree: several tools measured in one campaign, shared joints fitted once.

Each row of the data measures one point on one tool (the CSV's ``tool`` column). The model
of row i, measuring tool t, is ``R_f (p_t(q_i) + R_t(q_i) m_t) + t_f``: the tree's geometry
(Khalil-Kleinfinger notation, :class:`~calib.tree_model.TreeMDH`), one measurement frame for
every tool, and one marker per tool. Steps, as for a chain:

1. registration: the frame by Horn/Umeyama on the nominal points of every tool together,
   each tool's marker by linear least squares, alternated, then Levenberg-Marquardt;
2. the free parameters: the frame, the markers and the base parameters of the tree's
   complete set at the measured configurations (pivoted QR of the stacked Jacobian, frame
   and markers first), or the frame and markers only (``frames``);
3. the fit (:func:`calib.calibration.solve.fit`, the analytic Jacobian of
   :func:`calib.tree_jacobian.tree_jacobian`);
4. validation and the checks of a chain (:func:`calib.calibration.validation.refusal`),
   with the errors per tool.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..identifiability import independent_columns
from ..jacobian import Measurement
from ..measurements import Measurements, check_against_chain
from ..parameters import ParameterSet
from ..so3 import left_jacobian, rotation_matrix, skew
from ..tree import Tree
from ..tree_jacobian import tree_jacobian, tree_parameters
from ..tree_model import TreeMDH, from_tree
from . import validation
from .model import FRAME_NAMES
from .registration import rigid_fit
from .result import ResidualStats
from .solve import Fit, covariance, fit

TREE_LEVELS = ("frames", "complete")
"""Parameter levels of a tree calibration."""

REGISTRATION_ITERATIONS = 50
"""Most alternations of the closed-form registration (frame, then markers)."""


def tool_marker_names(tool: str) -> tuple[str, str, str]:
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

    def residuals(self, data: Measurements, torque=None) -> np.ndarray:
        """Measured - model per row ``(m, 3)`` [m] (``torque`` is not used)."""
        pts = self.base_points(data.q, tool_indices(self.mdh, data))
        return data.position - (pts @ self.frame[:3, :3].T + self.frame[:3, 3])


def tool_indices(mdh: TreeMDH, data: Measurements) -> np.ndarray:
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
    pose: bool = False
    rows: int = 3

    def names(self, tools: tuple[str, ...]) -> tuple[str, ...]:
        """Names of the free parameters, in the order of x."""
        out = list(FRAME_NAMES) if self.frame else []
        if self.markers:
            out += [n for t in tools for n in tool_marker_names(t)]
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
        state = self.apply(start, x)
        tool = tool_indices(state.mdh, data)
        R = state.frame[:3, :3]
        Rt, _ = state.tool_placements(data.q, tool)
        lever = state.base_points(data.q, tool) @ R.T
        blocks = []
        if self.frame:
            rot = -skew(lever) @ left_jacobian(self.split(x)[0][:3])
            blocks.append(np.concatenate([rot, np.broadcast_to(np.eye(3), rot.shape)], axis=2))
        if self.markers:
            blk = np.zeros((data.m, 3, 3 * self.n_tools))
            for t in range(self.n_tools):
                blk[tool == t, :, 3 * t : 3 * t + 3] = R @ Rt[tool == t]
            blocks.append(blk)
        if self.base:
            blocks.append(self._geometry_block(state, data.q, tool) @ self.lift())
        return np.concatenate(blocks, axis=2) if blocks else np.zeros((data.m, 3, 0))

    def _geometry_block(self, state: TreeState, q: np.ndarray, tool: np.ndarray) -> np.ndarray:
        """Columns of the standard parameters, ``(m, 3, len(params))``."""
        out = np.zeros((len(q), 3, len(self.params)))
        for t in np.unique(tool):
            rows = tool == t
            measured = np.zeros((int(rows.sum()), self.n_tools), dtype=bool)
            measured[:, t] = True
            meas = Measurement((0, 1, 2), tuple(state.markers[t]), "position")
            W = tree_jacobian(state.mdh, self.params, q[rows], meas, measured)
            out[rows] = state.frame[:3, :3] @ W.reshape(-1, 3, len(self.params))
        return out


def register_tree(nominal: TreeMDH, data: Measurements) -> TreeState:
    """The measurement frame and the markers in closed form, from the nominal tree."""
    tool = tool_indices(nominal, data)
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


@dataclass(frozen=True, eq=False)
class ToolErrors:
    """Errors of one tool's rows: registration and calibrated model."""

    tool: str
    registration: ResidualStats
    calibrated: ResidualStats


@dataclass(frozen=True, eq=False)
class TreeCalibrationResult:
    """Result of a tree calibration.

    Attributes:
        tree: The nominal tree (its URDF is what :mod:`calib.tree_export` edits).
        level: ``frames`` or ``complete``.
        names: Free parameters, in the order of ``estimate``.
        nominal: The nominal tree model (URDF base frame).
        registration: Nominal geometry with the fitted frame and markers.
        state: The calibrated model.
        estimate: Fitted changes from the registration [rad, m].
        std: Their standard deviations (NaN where undefined).
        before: Registration errors on the fitted rows.
        after: Calibrated errors on the fitted rows.
        per_tool: Errors on the fitted rows, per tool.
        validation: Registration and calibrated errors on held-out rows, or None.
        held_per_tool: Errors on held-out rows, per tool (empty without held-out rows).
        converged: The fit converged.
        refusal: Why the model must not be written (None: accepted).
    """

    tree: Tree
    level: str
    names: tuple[str, ...]
    nominal: TreeMDH
    registration: TreeState
    state: TreeState
    estimate: np.ndarray
    std: np.ndarray
    before: ResidualStats
    after: ResidualStats
    per_tool: tuple[ToolErrors, ...]
    validation: tuple[ResidualStats, ResidualStats] | None
    held_per_tool: tuple[ToolErrors, ...]
    converged: bool
    refusal: str | None

    @property
    def accepted(self) -> bool:
        """True when every check passed: the calibrated model may be written."""
        return self.refusal is None

    def check(self) -> TreeCalibrationResult:
        """Return self if accepted, else raise :class:`CalibrationRefusedError`."""
        from ..exceptions import CalibrationRefusedError

        if self.refusal is not None:
            raise CalibrationRefusedError(self.refusal)
        return self


def calibrate_tree(
    tree: Tree,
    data: Measurements,
    params: str = "complete",
    *,
    validate: Measurements | None = None,
    holdout: float = 0.0,
    seed: int = 0,
    max_iterations: int = 100,
) -> TreeCalibrationResult:
    """Calibrate a tree from measurements of several tools (one point per row and tool).

    Args:
        tree: The nominal tree (:func:`calib.tree.load_tree`).
        data: Measurements whose ``tool`` names the tool of each row.
        params: ``complete`` (frame, markers and the tree's base parameters) or ``frames``.
        validate: Measurements of other configurations to score the result on.
        holdout: Fraction of the rows set aside (seeded) when ``validate`` is not given.
        seed: Seed of the holdout draw.
        max_iterations: Most residual evaluations of each solver run.

    Raises:
        DataError: Data of other joints or tools, pose or several-point rows, too few rows.
        InvalidArgumentError: A bad argument.
    """
    train, held = _tree_datasets(tree, data, params, validate, holdout, seed)
    nominal = from_tree(tree)
    frames = TreeErrorModel(ParameterSet("none", ()), (), nominal.n_tools)
    reg = fit(
        frames, register_tree(nominal, train), train, None, 1.0, max_iterations=max_iterations
    )
    if not reg.converged:
        raise DataError(train.source, f"the registration did not converge ({reg.message})")
    model = _tree_model(nominal, reg.state, train) if params == "complete" else frames
    fitted = fit(model, reg.state, train, None, 1.0, max_iterations=max_iterations)
    return _tree_result(tree, params, train, held, fitted, reg.state)


def _tree_datasets(tree, data, params, validate, holdout, seed):
    if not isinstance(tree, Tree):
        raise InvalidArgumentError(f"tree must be a Tree (see load_tree), got {tree!r:.60}")
    if params not in TREE_LEVELS:
        raise InvalidArgumentError(
            f"unknown parameter level '{params}' for a tree: choose {', '.join(TREE_LEVELS)}"
        )
    for d in (data, validate):
        if d is None:
            continue
        if not isinstance(d, Measurements):
            raise InvalidArgumentError(f"data must be Measurements, got {type(d).__name__}")
        check_against_chain(d, tree)
        if d.quaternion is not None or d.n_markers != 1:
            raise DataError(
                d.source, "a tree is calibrated from one point per row (x, y, z and a tool)"
            )
    if validate is not None:
        return data, validate
    return validation.split(data, holdout, seed)


def _tree_model(nominal: TreeMDH, reg: TreeState, data: Measurements) -> TreeErrorModel:
    """Frame, markers and the base parameters of the complete set at the measured q."""
    pset = tree_parameters(nominal, "complete")
    wide = TreeErrorModel(pset, pset.names, nominal.n_tools)
    ideal = dataclasses.replace(reg, mdh=nominal.idealized())
    J = wide.jacobian(ideal, np.zeros(wide.size()), data).reshape(-1, wide.size())
    fixed = wide.size() - len(pset)
    _, _, kept, _ = independent_columns(J, list(range(J.shape[1])))
    if len([k for k in kept if k < fixed]) < fixed:
        raise DataError(data.source, "the rows do not determine the frame and every marker")
    base = tuple(pset.names[k - fixed] for k in sorted(kept) if k >= fixed)
    return dataclasses.replace(wide, base=base)


def _per_tool(state_a, state_b, data, tools) -> tuple[ToolErrors, ...]:
    out = []
    for name in tools:
        rows = np.array([t == name for t in data.tool]) if data.tool else np.ones(data.m, bool)
        if np.any(rows):
            sub = data.subset(rows)
            out.append(
                ToolErrors(
                    name, validation.stats(state_a, sub, None), validation.stats(state_b, sub, None)
                )
            )
    return tuple(out)


def _tree_result(tree, level, train, held, fitted: Fit, reg: TreeState) -> TreeCalibrationResult:
    cov, _ = covariance(fitted.J, float(fitted.f @ fitted.f))
    before = validation.stats(reg, train, None)
    after = validation.stats(fitted.state, train, None)
    val = None
    if held is not None:
        val = (validation.stats(reg, held, None), validation.stats(fitted.state, held, None))
    tools = fitted.state.mdh.tool_frames
    reason = validation.refusal(
        fitted.converged,
        before,
        after,
        validation.full_rank(fitted.J),
        val,
        fitted.model.names(tools),
    )
    with np.errstate(invalid="ignore"):
        std = np.sqrt(np.diag(cov)) if fitted.x.size else np.zeros(0)
    return TreeCalibrationResult(
        tree=tree,
        level=level,
        names=fitted.model.names(tools),
        nominal=reg.mdh,
        registration=reg,
        state=fitted.state,
        estimate=fitted.x,
        std=std,
        before=before,
        after=after,
        per_tool=_per_tool(reg, fitted.state, train, tools),
        validation=val,
        held_per_tool=() if held is None else _per_tool(reg, fitted.state, held, tools),
        converged=fitted.converged,
        refusal=reason,
    )
