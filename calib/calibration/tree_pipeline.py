"""Tree calibration as a short pipeline, its result, report and text.

Steps (:func:`calibrate_tree`): check the data and set rows aside, register the measurement
frame and the markers (:func:`calib.calibration.tree.register_tree`, refined by
Levenberg-Marquardt), choose the free parameters (the tree's base parameters at the
measured configurations), fit, and validate with the checks of a chain.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..exceptions import CalibrationRefusedError, DataError, InvalidArgumentError
from ..identifiability import independent_columns, preference_order
from ..measurements import Measurements, check_against_chain
from ..parameters import ParameterSet
from ..tree import Tree
from ..tree_export import tree_measurement_to_base
from ..tree_jacobian import tree_parameters
from ..tree_model import TreeMDH, from_tree
from ..urdf_links import marker_link_names
from . import validation
from .result import REPORT_FORMAT, ResidualStats, finite
from .solve import Fit, covariance, fit
from .tree import TreeErrorModel, TreeState, register_tree

TREE_LEVELS = ("frames", "complete")
"""Parameter levels of a tree calibration."""


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
        rows: Number of fitted rows.
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
    rows: int = 0

    @property
    def accepted(self) -> bool:
        """True when every check passed: the calibrated model may be written."""
        return self.refusal is None

    def check(self) -> TreeCalibrationResult:
        """Return self if accepted, else raise :class:`CalibrationRefusedError`."""
        if self.refusal is not None:
            raise CalibrationRefusedError(self.refusal)
        return self

    def to_dict(self) -> dict:
        """JSON-ready report (metres, radians)."""
        tools = self.state.mdh.tool_frames

        def per_tool(errors):
            return [
                {
                    "tool": e.tool,
                    "registration": e.registration.to_dict(),
                    "calibrated": e.calibrated.to_dict(),
                }
                for e in errors
            ]

        return {
            "format_version": REPORT_FORMAT,
            "deprecated": {},
            "robot": self.tree.name,
            "urdf": str(self.tree.urdf_path),
            "base_frame": self.tree.base_frame,
            "tools": list(tools),
            "params": self.level,
            "rows": self.rows,
            "accepted": self.accepted,
            "refusal": self.refusal,
            "converged": self.converged,
            "residuals": {
                "registration": self.before.to_dict(),
                "calibrated": self.after.to_dict(),
            },
            "per_tool": per_tool(self.per_tool),
            "validation": None
            if self.validation is None
            else {
                "registration": self.validation[0].to_dict(),
                "calibrated": self.validation[1].to_dict(),
                "per_tool": per_tool(self.held_per_tool),
            },
            "parameters": [
                {"name": n, "value": float(v), "std": finite(s)}
                for n, v, s in zip(self.names, self.estimate, self.std, strict=True)
            ],
            "markers": {t: self.state.markers[k].tolist() for k, t in enumerate(tools)},
            "marker_links": {t: marker_link_names(t, 1)[0] for t in tools},
            "measurement_to_base": (
                self.state.frame @ tree_measurement_to_base(self.nominal, self.state.mdh)
            ).tolist(),
        }

    def text(self) -> str:
        """A terminal summary: errors per tool, then the parameters."""
        mm = 1e3
        lines = [
            f"{self.tree.name}: {self.tree.base_frame} -> {', '.join(self.state.mdh.tool_frames)}"
            f" ({self.tree.n} joints), {self.rows} rows, --params {self.level}: "
            f"{len(self.names)} parameters",
            f"fitted rows, position RMS / max [mm]: registration "
            f"{mm * self.before.position_rms:.4g} / {mm * self.before.position_max:.4g}, "
            f"calibrated {mm * self.after.position_rms:.4g} / {mm * self.after.position_max:.4g}",
        ]
        if self.validation is not None:
            reg, cal = self.validation
            lines.append(
                f"held-out rows [mm]: registration {mm * reg.position_rms:.4g} / "
                f"{mm * reg.position_max:.4g}, calibrated {mm * cal.position_rms:.4g} / "
                f"{mm * cal.position_max:.4g}"
            )
        for label, errors in (("fitted", self.per_tool), ("held out", self.held_per_tool)):
            for e in errors:
                lines.append(
                    f"  {label:8s} {e.tool}: {mm * e.registration.position_rms:.4g} -> "
                    f"{mm * e.calibrated.position_rms:.4g} mm RMS"
                )
        lines.append("parameters (change from the registration +- std):")
        for n, v, s in zip(self.names, self.estimate, self.std, strict=True):
            lines.append(f"  {n:>28s} = {v:12.6g} +- {s:.4g}")
        lines.append("accepted" if self.accepted else f"REFUSED: {self.refusal}")
        return "\n".join(lines)


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
    """Frame, markers and the base parameters of the complete set at the measured q.

    The columns are taken in :func:`~calib.identifiability.preference_order`, as a chain's
    are. Coupled (mimic) joints can make the nominal geometry special (a PR2 fingertip stays
    parallel to the palm), and the set order then kept parameters that miss the errors a
    real robot has (PR2's two fingertips: 0.28 mm left after a noise-free fit of 1 mm /
    1 mrad errors; exact in this order).
    """
    pset = tree_parameters(nominal, "complete")
    ordered = tuple(pset.names[i] for i in preference_order(nominal, pset))
    wide = TreeErrorModel(pset, ordered, nominal.n_tools)
    ideal = dataclasses.replace(reg, mdh=nominal.idealized())
    J = wide.jacobian(ideal, np.zeros(wide.size()), data).reshape(-1, wide.size())
    fixed = wide.size() - len(pset)
    _, _, kept, _ = independent_columns(J, list(range(J.shape[1])))
    if len([k for k in kept if k < fixed]) < fixed:
        raise DataError(data.source, "the rows do not determine the frame and every marker")
    base = tuple(ordered[k - fixed] for k in sorted(kept) if k >= fixed)
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
        rows=train.m,
    )
