"""Tree calibration as a short pipeline, its result, report and text.

Steps (:func:`calibrate_tree`): check the data and set rows aside, register the measurement
frame and the markers (:func:`calib.calibration.tree.register_tree`, refined by
Levenberg-Marquardt), choose the free parameters (the tree's base parameters at the
measured configurations), fit, and validate with the checks of a chain.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from ..core.choices import DEFAULT_CONFIGS
from ..core.progress import Progress, phase
from ..exceptions import CalibrationRefusedError, DataError, InvalidArgumentError
from ..identification.base_columns import independent_columns, preference_order
from ..identification.parameters import ParameterSet
from ..identification.tree_jacobian import tree_parameters
from ..kinematics.tree import Tree
from ..kinematics.tree_export import calibrated_tree_urdf, tree_measurement_to_base
from ..kinematics.tree_model import TreeMDH, from_tree
from ..kinematics.urdf_links import marker_link_names
from ..measurements.data import Measurements
from ..measurements.limits import check_against_chain
from . import determined, diagnosis, outliers, validation
from .delivery import Delivered, RowErrors, row_rms_mm
from .options import DEFAULT_MAX_ITERATIONS, DEFAULT_TREE_LEVEL, Options, checked_arguments
from .report import (
    FORMAT2_MOVED,
    build_report,
    fit_dict,
    outlier_dict,
    parameter_entries,
    parameter_lines,
    pose_dict,
    term_dict,
    verdict,
)
from .result import ResidualStats
from .solve import Fit, covariance, fit
from .tree import TreeErrorModel, TreeState, register_tree

__all__ = [
    "ToolErrors",
    "TreeCalibrationResult",
    "calibrate_tree",
]


@dataclass(frozen=True, eq=False)
class ToolErrors:
    """Errors of one tool's rows: registration and calibrated model."""

    tool: str
    registration: ResidualStats
    calibrated: ResidualStats


@dataclass(frozen=True, eq=False, repr=False)
class TreeCalibrationResult(Delivered):
    """Result of a tree calibration.

    Attributes:
        tree: The nominal tree (its URDF is what :mod:`calib.kinematics.tree_export` edits).
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
        data: The measurements fitted (outliers and held-out rows removed), or None.
        outliers: Rows set aside.
        iterations: Jacobian evaluations of the final fit.
        message: Solver message of the final fit.
        warnings: Reasons to be careful with the result.
        timings_ms: Time of each stage [ms].
        held_source: The held-out rows' source (``holdout`` or the validation file), or None.
        held: The held-out rows themselves, or None.
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
    data: Measurements | None = None
    outliers: tuple[outliers.Outlier, ...] = ()
    iterations: int = 0
    message: str = ""
    warnings: tuple[str, ...] = ()
    timings_ms: dict[str, float] = field(default_factory=dict)
    held_source: str | None = None
    held: Measurements | None = None

    @property
    def accepted(self) -> bool:
        """True when every check passed: the calibrated model may be written."""
        return self.refusal is None

    @property
    def measurement_to_base(self) -> np.ndarray:
        """Pose of the calibrated URDF's base frame in the measurement frame ``(4, 4)``."""
        return self.state.frame @ tree_measurement_to_base(self.nominal, self.state.mdh)

    def check(self) -> TreeCalibrationResult:
        """Return self if accepted, else raise :class:`CalibrationRefusedError`."""
        if self.refusal is not None:
            raise CalibrationRefusedError(self.refusal)
        return self

    def to_dict(self) -> dict:
        """The JSON report (format 3, :mod:`calib.calibration.report`)."""
        tools, mdh = self.state.mdh.tool_frames, self.nominal
        data = self.data
        train = _errors(self.before, self.after)
        held = None
        if self.validation is not None:
            held = {"source": self.held_source, **_errors(*self.validation)}
        held_by_tool = {e.tool: e for e in self.held_per_tool}
        terms, per_term = [], []
        for e in self.per_tool:
            rows = sum(t == e.tool for t in data.tool) if data is not None and data.tool else 0
            source = None if data is None else data.source
            terms.append(term_dict(self.tree.base_frame, e.tool, "position", source, rows))
            h = held_by_tool.get(e.tool)
            per_term.append(
                {
                    "train": _errors(e.registration, e.calibrated),
                    "held_out": None
                    if h is None
                    else {"source": self.held_source, **_errors(h.registration, h.calibrated)},
                }
            )
        links = {t: marker_link_names(t, 1)[0] for t in tools}
        fields = {
            "robot": self.tree.name,
            "urdf": str(self.tree.urdf_path),
            "shape": "tree",
            "terms": terms,
            **verdict(self.level, self.refusal, (self.converged, self.message, self.iterations)),
            "parameters": parameter_entries(
                self.names, self.estimate, self.std, mdh.joint_names, mdh.sigma
            ),
            "errors": {"train": train, "held_out": held, "terms": per_term},
            "frames": {
                "measurement": pose_dict(self.measurement_to_base),
                "measured": None,
                "markers": {links[t]: self.state.markers[k].tolist() for k, t in enumerate(tools)},
                "contacts": {},
                "world_link": None,
                "tool_link": None,
                "on_robot": False,
            },
            "objects": {},
            "fit": fit_dict(),
            "model_choice": None,
            "outliers": [outlier_dict(o) for o in self.outliers],
            "compliance": {},
            "model": {"mdh_nominal": mdh.rows(), "mdh_calibrated": self.state.mdh.rows()},
            "warnings": list(self.warnings),
            "timings_ms": dict(self.timings_ms),
        }
        return build_report(fields, self._format2(), FORMAT2_MOVED)

    def _format2(self) -> dict:
        """Format 2's keys that format 3 replaced (written until format 4)."""
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
            "data": None if self.data is None else self.data.source,
            "base_frame": self.tree.base_frame,
            "tools": list(tools),
            "measure": "position",
            "rows": self.rows,
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
            "markers": {t: self.state.markers[k].tolist() for k, t in enumerate(tools)},
            "marker_links": {t: marker_link_names(t, 1)[0] for t in tools},
            "measurement_to_base": pose_dict(self.measurement_to_base),
        }

    def row_errors(self) -> RowErrors:
        """Position error of each fitted and held-out row, before and after [mm]."""
        if self.data is None:
            return super().row_errors()
        parts = [(self.data, False)] + ([] if self.held is None else [(self.held, True)])
        before = [row_rms_mm(self.registration.residuals(d), 1) for d, _ in parts]
        after = [row_rms_mm(self.state.residuals(d), 1) for d, _ in parts]
        held = [np.full(len(d.q), h) for d, h in parts]
        return RowErrors(np.concatenate(before), np.concatenate(after), np.concatenate(held))

    def urdf(self) -> bytes:
        """The calibrated URDF of every branch, with each tool's marker link."""
        return calibrated_tree_urdf(self.tree, self.nominal, self.state.mdh, self.state.markers)

    def summary(self) -> str:
        """A terminal summary: errors per tool, then the parameters."""
        mm = 1e3
        lines = [
            f"{self.tree.name}: {self.tree.base_frame} -> {', '.join(self.state.mdh.tool_frames)}"
            f" ({self.tree.n} joints), {self.rows} rows, level {self.level}: "
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
        mdh = self.nominal
        lines += parameter_lines(
            parameter_entries(self.names, self.estimate, self.std, mdh.joint_names, mdh.sigma)
        )
        lines += [f"warning: {w}" for w in self.warnings]
        lines.append("accepted" if self.accepted else f"REFUSED: {self.refusal}")
        return "\n".join(lines)


@checked_arguments
def calibrate_tree(
    tree: Tree,
    data: Measurements,
    *,
    params: str | None = None,
    marker=None,
    validate: Measurements | None = None,
    fix: tuple[str, ...] = (),
    free: tuple[str, ...] = (),
    elastic: bool | None = None,
    loss: str = "linear",
    noise_mm: float | None = None,
    orientation_weight: float | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    holdout: float = 0.0,
    seed: int = 0,
    progress: Progress | None = None,
) -> TreeCalibrationResult:
    """Calibrate a tree from measurements of several tools (one point per row and tool).

    It takes the arguments of :func:`~calib.calibration.entry.calibrate` (which calls it
    for a tree), checked as one :class:`~.options.Options`; those a tree cannot honour
    (``marker`` and :data:`~.options.CHAIN_ONLY`) are refused unless left at their defaults.
    The guards of a chain's calibration apply: a level the rows cannot determine is refused
    (:mod:`.determined`), data (and validation data) that match the tree only under a usual
    mistake are refused naming it (:mod:`.diagnosis`), outlier rows are set aside
    (:mod:`.outliers`), and a model worse than the registration is refused
    (:func:`calib.calibration.validation.refusal`).

    Args:
        tree: The nominal tree (:func:`calib.kinematics.tree.load_tree`).
        data: Measurements whose ``tool`` names the tool of each row.
        params: ``complete`` (frame, markers and the tree's base parameters, the default) or
            ``frames``.
        marker: Not for a tree (its markers are registered in closed form): None.
        validate: Measurements of other configurations to score the result on.
        fix: Not for a tree: ``()``.
        free: Not for a tree: ``()``.
        elastic: Not for a tree: None.
        loss: Not for a tree: ``linear``.
        noise_mm: Not for a tree: None.
        orientation_weight: Not for a tree: None.
        max_iterations: Most residual evaluations of each solver run.
        holdout: Fraction of the rows set aside (seeded); not with ``validate``.
        seed: Seed of the holdout draw and of the generic configurations of the rank check.
        progress: Progress bars of the registration, the model's choice and the fit
            (:mod:`calib.core.progress`; e.g. ``tqdm.tqdm``), or None.

    Raises:
        DataError: Data of other joints or tools, pose or several-point rows, too few or
            too poor rows for the level, a usual mistake (named), validation rows that
            are training rows.
        InvalidArgumentError: A bad argument, or one only a chain's calibration takes.
    """
    opts = Options(
        level=DEFAULT_TREE_LEVEL if params is None else params,
        fix=fix,
        free=free,
        elastic=elastic,
        loss=loss,
        noise_mm=noise_mm,
        orientation_weight=orientation_weight,
        max_iterations=max_iterations,
        holdout=holdout,
        seed=seed,
    )
    if not isinstance(tree, Tree):
        raise InvalidArgumentError(f"tree must be a Tree (see load_tree), got {tree!r:.60}")
    if marker is not None:
        raise InvalidArgumentError(
            "marker is for one chain: a tree's markers are registered in closed form"
        )
    return _calibrate_tree(tree, data, validate, opts.for_tree(), progress)


def _calibrate_tree(
    tree: Tree, data, validate, opts: Options, progress: Progress | None = None
) -> TreeCalibrationResult:
    """:func:`calibrate_tree` with its options checked."""
    clock = [time.perf_counter()]
    max_iterations = opts.max_iterations
    train, held = _tree_datasets(tree, data, validate, opts)
    nominal = from_tree(tree)
    notes: list[str] = []
    with phase(progress, f"calibrate: registration ({train.m} rows)"):
        if validate is not None and _registrable(tree, validate):  # validation data are data
            _, kept, _ = _drop_outliers(tree, nominal, validate, max_iterations)
            _diagnose(tree, nominal, kept, max_iterations, None)
        reg, train, dropped = _drop_outliers(tree, nominal, train, max_iterations)
        _diagnose(tree, nominal, train, max_iterations, notes, reg)
        if dropped:
            notes.append(outliers.set_aside_note(dropped))
        if not reg.converged:
            raise DataError(train.source, f"the registration did not converge ({reg.message})")
        held = _held_out_outliers(reg.state, train, held, notes)
    clock.append(time.perf_counter())
    with phase(progress, "calibrate: selection"):
        model = _tree_model(tree, nominal, reg.state, train, opts.level, opts.seed)
    clock.append(time.perf_counter())
    with phase(progress, f"calibrate: fit ({model.size()} parameters)"):
        fitted = fit(model, reg.state, train, None, 1.0, max_iterations=max_iterations)
    clock.append(time.perf_counter())
    result = _tree_result(tree, opts.level, train, held, fitted, reg.state)
    clock.append(time.perf_counter())
    stages = ("registration", "selection", "fit", "validation")
    return dataclasses.replace(
        result,
        outliers=dropped,
        warnings=tuple(notes),
        timings_ms={s: 1e3 * (b - a) for s, a, b in zip(stages, clock, clock[1:], strict=False)},
    )


def _registrable(tree: Tree, data: Measurements) -> bool:
    """Whether data can be registered on their own: every tool, more equations than unknowns."""
    return set(data.tools) == set(tree.tool_frames) and 3 * data.m > 6 + 3 * tree.n_tools


def _registration(nominal: TreeMDH, data: Measurements, max_iterations: int) -> Fit:
    """Closed-form registration of the frame and markers refined by Levenberg-Marquardt."""
    frames = TreeErrorModel(ParameterSet("none", ()), (), nominal.n_tools)
    start = register_tree(nominal, data)
    return fit(frames, start, data, None, 1.0, max_iterations=max_iterations)


def _diagnose(tree, nominal, data, max_iterations, notes: list[str] | None, reg=None) -> Fit:
    """The registration of ``data`` (unless given); the likely mistake if it cannot be.

    ``notes``: where to note data no usual mistake explains (None: validation data, whose
    registration is only checked).
    """
    reg = _registration(nominal, data, max_iterations) if reg is None else reg
    first = validation.stats(reg.state, data, None).position_rms
    if not diagnosis.suspect(first, None):
        return reg

    def rms(d):  # the closed form only: every swap of two joints is tried
        return validation.stats(register_tree(nominal, d), d, None).position_rms

    cause = diagnosis.likely_cause(data, tree.sigma == 0, rms, first)
    if cause is not None:
        raise DataError(
            data.source,
            f"the data look like {cause[0]}: the registration error drops from "
            f"{1e3 * first:.4g} mm to {1e3 * cause[1]:.4g} mm RMS once corrected",
        )
    if notes is not None:
        notes.append(
            f"the registration leaves {1e3 * first:.4g} mm RMS, far above geometric errors, "
            f"and no usual mistake (swapped joint columns, degrees, millimetres) explains it: "
            f"check the data and the tree"
        )
    return reg


def _held_out_outliers(reg: TreeState, train, held, notes: list[str]):
    """The held-out rows without their outliers (:func:`.outliers.held_out_outliers`)."""
    if held is None:
        return None
    rows = held.rows or tuple(range(1, held.m + 1))
    bad, dropped = outliers.held_out_outliers(
        outliers.point_errors(reg.residuals(train), 1),
        outliers.point_errors(reg.residuals(held), 1),
        None,
        rows,
    )
    if not dropped:
        return held
    notes.append(outliers.held_out_note(dropped))
    return held.subset(~bad)


def _drop_outliers(tree, nominal, data: Measurements, max_iterations: int):
    """The registration without the rows far from the others (:mod:`.outliers`)."""
    unknowns = 6 + 3 * nominal.n_tools

    def refit(keep: np.ndarray) -> Fit:
        return _registration(nominal, data if keep.all() else data.subset(keep), max_iterations)

    def errors(reg: Fit) -> outliers.Errors:
        return outliers.point_errors(reg.state.residuals(data), 1)

    def allowed(bad: np.ndarray) -> bool:  # every tool, more equations than unknowns
        kept = data.subset(~bad)
        return _registrable(tree, kept) and 3 * kept.m > unknowns

    rows = data.rows or tuple(range(1, data.m + 1))
    reg, bad, dropped = outliers.until_stable(refit, errors, None, rows, allowed=allowed)
    return reg, data.subset(~bad) if bad.any() else data, tuple(dropped)


def _tree_datasets(tree, data, validate, opts: Options):
    """Check the data; the training set and the held-out set."""
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
    missing = [t for t in tree.tool_frames if t not in data.tools]
    if missing:
        raise DataError(
            data.source,
            f"no row measures the tool {missing[0]}: calibrate the tools the rows measure "
            f"(a tool for each)",
        )
    out = round(opts.holdout * data.m)
    unknowns = 6 + 3 * tree.n_tools
    what = "measurement frame and marker parameters"
    determined.check_equations(data.m - out, 3, unknowns, what, data.source, held=out, unit="rows")
    if validate is not None:
        if opts.holdout > 0:
            raise InvalidArgumentError("give a validation file or a holdout fraction, not both")
        validation.check_held_out(data, validate)
        return data, validate
    return validation.split(data, opts.holdout, opts.seed)


def _tree_model(
    tree: Tree, nominal: TreeMDH, reg: TreeState, data: Measurements, level: str, seed: int
) -> TreeErrorModel:
    """Frame, markers (and, ``complete``, the base parameters of the complete set).

    The columns are taken in :func:`~.base_columns.preference_order`, as a chain's
    are. Coupled (mimic) joints can make the nominal geometry special (a PR2 fingertip stays
    parallel to the palm), and the set order then kept parameters that miss the errors a
    real robot has (PR2's two fingertips: 0.28 mm left after a noise-free fit of 1 mm /
    1 mrad errors; exact in this order).

    Raises:
        DataError: The rows do not determine what generic configurations would.
    """
    pset = tree_parameters(nominal, "complete") if level == "complete" else ParameterSet("none", ())
    ordered = tuple(pset.names[i] for i in preference_order(nominal, pset)) if len(pset) else ()
    wide = TreeErrorModel(pset, ordered, nominal.n_tools)
    ideal = dataclasses.replace(reg, mdh=nominal.idealized())
    J = wide.jacobian(ideal, np.zeros(wide.size()), data).reshape(-1, wide.size())
    _, _, kept, _ = independent_columns(J, list(range(J.shape[1])))
    determined.check_rank(
        len(kept), _generic_count(tree, wide, ideal, seed), data.m, 3, level, data.source, "rows"
    )
    fixed = wide.size() - len(pset)
    base = tuple(ordered[k - fixed] for k in sorted(kept) if k >= fixed)
    return dataclasses.replace(wide, base=base)


def _generic_count(tree: Tree, wide: TreeErrorModel, state: TreeState, seed: int) -> int:
    """Parameters of ``wide`` determined with every tool at random configurations."""
    q = tree.random_configurations(DEFAULT_CONFIGS, seed)
    t = tree.n_tools
    Q, tool = np.repeat(q, t, axis=0), np.tile(np.arange(t), len(q))
    J = wide.jacobian_at(state, np.zeros(wide.size()), Q, tool).reshape(-1, wide.size())
    return len(independent_columns(J, list(range(J.shape[1])))[2])


def _errors(registration: ResidualStats, calibrated: ResidualStats) -> dict:
    """``registration``, ``calibrated`` and ``urdf`` (the calibrated model: no compliance)."""
    cal = calibrated.in_mm()
    return {"registration": registration.in_mm(), "calibrated": cal, "urdf": cal}


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
        validation.check_held_out_errors(before, val[0], held.source)
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
        held_source=None if held is None else held.source,
        held=held,
        converged=fitted.converged,
        refusal=reason,
        rows=train.m,
        data=train,
        iterations=fitted.iterations,
        message=fitted.message,
    )
