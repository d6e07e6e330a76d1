"""A chain measured by an instrument: registration, model choice, fit, validation."""

from __future__ import annotations

import dataclasses
import gc
import time
import warnings

import numpy as np

from ..core.progress import phase
from ..exceptions import DataError, InvalidArgumentError
from ..identification.identifiability import DEFAULT_CONFIGS, independent_columns, preference_order
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.mdh import MDHModel, from_chain
from ..kinematics.robot import Chain
from ..kinematics.so3 import matrix_to_quaternion
from ..measurements.csvfile import Measurements, check_against_chain
from ..measurements.postures import count as count_postures
from ..measurements.postures import posture_groups, sample_postures
from . import determined, freedoms, outliers, validation
from .chain_registration import (
    checked_registration,
    frames_model,
    held_out_outliers,
    ill_posed,
    proposals,
    registration,
)
from .contact_chains_result import ContactChainsCalibration
from .expansion import explained
from .model import ErrorModel, State, compliance_name, offset_parameter, selection_lift
from .options import Options
from .residuals import ResidualStats, Validation
from .result import CalibrationResult
from .selection import Selection, select
from .solve import Fit, condition, covariance, fit, row_weights

__all__ = [
    "GROUPS",
    "Options",
    "calibrate_chain",
    "level_names",
    "residual_stats",
]

GROUPS = ("frame", "markers", "tool")
"""Names ``--fix`` takes for whole groups (besides single parameters)."""


@dataclasses.dataclass(frozen=True)
class _Round:
    """One fit of the rows an outlier mask keeps: registration, choice, least squares."""

    train: Measurements
    reg: State
    torque: tuple
    model: ErrorModel
    selection: Selection | None
    prior: np.ndarray | None
    fitted: Fit
    notes: tuple[str, ...]
    fit_ms: float


COLLECT_ROWS = 10_000
"""Configurations from which a calibration frees its reference cycles between its stages (a
full ``gc.collect`` costs tens of ms in a large process: worth it for memory only at scale)."""


def _collect(m: int) -> None:
    """Free reference cycles (the stages' Jacobians) when the campaign has ``m`` >= COLLECT_ROWS."""
    if m >= COLLECT_ROWS:
        gc.collect()


def _round(chain, nominal, data, keep, guess, opts, held, reg=None, progress=None) -> _Round:
    """Register (unless ``reg`` is given), choose and fit the rows ``keep`` of ``data``."""
    train = data if keep.all() else data.subset(keep)
    reg = registration(nominal, train, guess, opts) if reg is None else reg
    torque = _torques(chain, opts, train, held)
    kin = reg.kinematics(train.q, torque[0])  # x = 0 is the registration: once per round
    notes: list[str] = []
    with phase(progress, "calibrate: selection"):
        model, selection, prior = _choose(chain, nominal, reg, train, torque[0], opts, notes, kin)
    _collect(train.m)  # the registration's and selection's cycles held 130 MB at 100,000 poses
    tic = time.perf_counter()
    with phase(progress, f"calibrate: fit ({model.size()} parameters)"):
        fitted = fit(
            model,
            reg,
            train,
            torque[0],
            opts.orientation_weight,
            prior=prior,
            loss=opts.loss,
            scale=opts.noise or 1e-3,
            max_iterations=opts.max_iterations,
            kin=kin,
        )
    ms = 1e3 * (time.perf_counter() - tic)
    return _Round(train, reg, torque, model, selection, prior, fitted, tuple(notes), ms)


def calibrate_chain(chain, data, marker, validate, opts, progress=None) -> CalibrationResult:
    """:func:`~.entry.calibrate` of a chain measured, its :class:`Options` checked (``opts``)."""
    clock = [time.perf_counter()]
    train, held = _datasets(chain, data, validate, opts)
    nominal = from_chain(chain)
    guess = freedoms.marker_guess(marker, train.n_markers)
    checked = held if validate is not None else None
    with phase(progress, f"calibrate: registration ({train.m} rows)"):
        opts, reg, bad, notes = checked_registration(chain, nominal, train, checked, guess, opts)
        held = held_out_outliers(reg, train, held, opts, notes)
    clock.append(time.perf_counter())
    first = ~bad
    all_torque = _torques(chain, opts, train, None)[0]

    def refit(keep: np.ndarray) -> _Round:
        same = np.array_equal(keep, first)
        return _round(
            chain, nominal, train, keep, guess, opts, held, reg if same else None, progress
        )

    def errors(rnd: _Round) -> outliers.Errors:
        kin = rnd.fitted.kin if rnd.train is train else None  # the fit's, on all the rows
        residual = rnd.fitted.state.residuals(train, all_torque, kin)
        return outliers.point_errors(residual, train.n_markers)

    rows = train.rows or tuple(range(1, train.m + 1))
    start = bad | proposals(nominal, reg, train, opts)
    rnd, _, dropped = outliers.until_stable(refit, errors, opts.noise, rows, start)
    notes = [*notes, *rnd.notes]
    if dropped:
        notes.append(outliers.set_aside_note(dropped))
    clock.append(time.perf_counter() - 1e-3 * rnd.fit_ms)  # the selections, then the last fit
    clock.append(time.perf_counter())
    _collect(train.m)  # what the rounds left in cycles, before the checks' copies of the Jacobian
    result = _assemble(
        chain,
        nominal,
        rnd.train,
        held,
        rnd.torque,
        rnd.fitted,
        rnd.prior,
        rnd.selection,
        dropped,
        notes,
        opts,
    )
    clock.append(time.perf_counter())
    stages = ("registration", "selection", "fit", "validation")
    timings = {s: 1e3 * (b - a) for s, a, b in zip(stages, clock[:-1], clock[1:], strict=True)}
    return dataclasses.replace(result, timings_ms=timings)


def _datasets(chain, data, validate, opts) -> tuple[Measurements, tuple | None]:
    """Check the data; the training set and the held-out set (with its label)."""
    if not isinstance(chain, Chain):
        raise InvalidArgumentError(
            f"the robot must be a Chain or a Tree (see load_robot), got {chain!r:.60}"
        )
    if not isinstance(data, Measurements):
        raise InvalidArgumentError(
            f"data must be Measurements (read_measurements), got {type(data).__name__}"
        )
    check_against_chain(data, chain)
    postures = count_postures(data.q, data.tool)
    out = round(opts.holdout * postures)
    determined.check_equations(
        postures - out,
        data.kind.rows_of(data.n_markers),
        frames_model(data, opts).size(),
        "measurement frame and marker parameters",
        data.source,
        held=out,
    )
    train, held = validation.split(data, opts.holdout, opts.seed)
    if validate is not None:
        if opts.holdout > 0:
            raise InvalidArgumentError("give a validation file or a holdout fraction, not both")
        check_against_chain(validate, chain)
        if (validate.n_markers, validate.measure) != (data.n_markers, data.measure):
            raise DataError(
                validate.source, "the validation data measure other points than the data"
            )
        validation.check_held_out(data, validate)
        return train, (validate, validate.source)
    return train, None if held is None else (held, "holdout")


def _torques(chain, opts, train, held):
    """Gravity torques of the training and held-out configurations, if compliance may be fitted.

    Compliance is opt-in (``elastic=True``, or a compliance named in ``free``): the URDF
    cannot hold it, so by default every level chooses among what the URDF holds.
    """
    forced = any(n[:1] == "c" and n[1:].isdigit() for n in opts.free)
    if not (opts.elastic or (opts.elastic is None and forced)):
        return None, None
    tau = chain.gravity_torques(train.q)
    return tau, None if held is None else chain.gravity_torques(held[0].q)


def level_names(nominal: MDHModel, opts: Options) -> tuple[ParameterSet, list[str]]:
    """The standard set and the names a level offers (before --fix / --free)."""
    pset = parameter_set(nominal, "paper" if opts.level == "paper" else "complete")
    if opts.level == "frames":
        names: list[str] = []
    elif opts.level == "offsets":
        names = [offset_parameter(nominal, j).name for j in range(nominal.n)]
    else:
        names = list(pset.names)
    valid = set(pset.names) | {compliance_name(j) for j in range(nominal.n)} | set(GROUPS)
    for name in (*opts.fix, *opts.free):
        if name not in valid:
            raise InvalidArgumentError(
                f"unknown parameter '{name}' for fix/free: give frame, markers, tool, a "
                f"parameter of the {pset.label} set (e.g. {', '.join(pset.names[2:5])}) or a "
                f"compliance c1..c{nominal.n}"
            )
    names += [n for n in opts.free if n in pset.names and n not in names]
    return pset, [n for n in names if n not in opts.fix]


def _choose(chain, nominal, reg: State, data, torque, opts, notes: list[str], kin=None):
    """The free parameters: the level's identifiable ones, or the selection's (``auto``).

    ``kin``: the registration's kinematics at the data's joints, if already made.
    """
    pset, names = level_names(nominal, opts)
    joints = [] if torque is None else [j for j in range(nominal.n) if np.any(torque[:, j])]
    freedoms.check_compliance(chain, torque, joints, opts)
    joints = [j for j in joints if compliance_name(j) not in opts.fix]
    base = frames_model(data, opts)
    ordered = tuple(
        pset.names[i] for i in preference_order(nominal, pset) if pset.names[i] in names
    )
    wide = base.with_(
        params=pset, base=ordered, lift=selection_lift(pset, ordered), compliance=tuple(joints)
    )
    ideal = dataclasses.replace(reg, mdh=nominal.idealized())
    w = row_weights(wide, opts.orientation_weight)
    J = wide.jacobian(ideal, np.zeros(wide.size()), data, torque)
    J *= w[None, :, None]  # in place: a fresh array (100,000 poses: 200 MB)
    fixed = base.size()
    _, _, kept, _ = independent_columns(J.reshape(-1, J.shape[2]), list(range(J.shape[2])))
    columns = [i for i in kept if i >= fixed]  # kept is in column order
    cand = [wide.names()[i] for i in columns]
    freedoms.check_free(opts.free, cand, wide.names(), J.reshape(-1, J.shape[2]), fixed)
    if len(kept) < fixed:
        raise DataError(
            data.source,
            "the configurations do not even determine the measurement frame and markers",
        )
    separated = _generic_kept(chain, wide, ideal, data, w, torque is not None, opts.seed)
    generic = len(separated)
    postures = count_postures(data.q, data.tool)
    if opts.level != "auto":
        flat = J.reshape(-1, J.shape[2])[:, separated]
        del J  # memory: a level needs no more of it (100,000 poses: 200 MB)
        unknowns = tuple(wide.names()[i] for i in separated)
        found = determined.ill_posed(flat, unknowns, overwrite=True)
        lost = tuple(dict.fromkeys(n for d in found for n in d.names))
        determined.check_rank(
            len(kept), generic, postures, wide.rows, opts.level, data.source, lost=lost
        )
    elif len(kept) < generic:
        notes.append(
            f"the {data.m} configurations determine {len(kept)} of the {generic} parameters "
            f"generic configurations would: params 'auto' chooses among those only"
        )
    if opts.level == "auto":
        sample = determined.selection_configurations(J.shape[0], J.shape[1], fixed, len(cand))
        del J  # memory: the selection's arrays are the campaign's largest
        if sample < data.m:
            data, torque = _sample(data, torque, sample, opts.seed, notes)
            kin = None  # made at the sample's joints
        forced = [cand.index(n) for n in opts.free if n in cand]
        chosen = _select(wide, reg, data, torque, w, fixed, columns, cand, forced, kin)
        selection, weights = chosen
        cand = list(selection.kept)
    else:
        selection, weights = None, np.zeros(len(cand))
    mdh_names = tuple(c for c in cand if c in pset.names)
    comp = tuple(j for j in joints if compliance_name(j) in cand)
    model = base.with_(
        params=pset, base=mdh_names, lift=selection_lift(pset, mdh_names), compliance=comp
    )
    order_w = {c: wt for c, wt in zip(cand, weights, strict=True)}
    prior = np.r_[np.zeros(fixed), [order_w[n] for n in model.names()[fixed:]]]
    return model, selection, prior if np.any(prior) else None


def _sample(data: Measurements, torque, size: int, seed: int, notes: list[str]):
    """A sample of about ``size`` configurations the selection chooses on (a note says so).

    Whole postures drawn with ``seed``, every tool in proportion
    (:func:`~calib.measurements.postures.sample_postures`); the fit uses every row.
    """
    groups = posture_groups(data.q, data.tool)
    keep = sample_postures(groups, size, seed, data.tool)
    notes.append(
        f"params 'auto' chose the parameters on {int(keep.sum())} of the {data.m} "
        f"configurations (whole postures drawn with seed {seed}, every tool in proportion: "
        f"the selection's work bound); the fit uses all of them"
    )
    return data.subset(keep), None if torque is None else torque[keep]


def _select(wide: ErrorModel, reg: State, data, torque, w, fixed, columns, cand, forced, kin):
    """The selection among the candidates ``cand`` (columns ``columns`` of ``wide``).

    ``kin``: the registration's kinematics at the data's joints, or None (made here).
    """
    if kin is None:
        kin = reg.kinematics(data.q, torque)  # x = 0 is the registration
    cols = list(range(fixed)) + columns
    Jr = wide.jacobian(reg, np.zeros(wide.size()), data, torque, reg, kin)[:, :, cols]
    Jr *= w[None, :, None]
    e = explained(wide, reg, data, torque, Jr, cols, reg.residuals(data, kin=kin) * w, w)
    groups = posture_groups(data.q, data.tool)
    return select(Jr, e, fixed, tuple(cand), forced, groups)


def _generic_kept(chain, wide: ErrorModel, state: State, data, w, elastic: bool, seed) -> list[int]:
    """Columns of ``wide`` determined at random configurations (the same markers)."""
    q = chain.random_configurations(DEFAULT_CONFIGS, seed)
    torque = chain.gravity_torques(q) if elastic else None
    kin = state.kinematics(q, torque)  # x = 0 is the state
    pts, rot = state.predict(q, torque, kin)
    quat = None if data.quaternion is None else matrix_to_quaternion(rot)
    generic = Measurements(data.joint_names, q, pts.reshape(len(q), -1), quat)
    J = wide.jacobian(state, np.zeros(wide.size()), generic, torque, state, kin)
    J = J * w[None, :, None]
    return sorted(independent_columns(J.reshape(-1, J.shape[2]), list(range(J.shape[2])))[2])


def _compliance_notes(fitted: Fit, torque, before, urdf_after, val) -> list[str]:
    """Where compliance was fitted: it is not in the URDF, and when the URDF alone is worse."""
    notes = []
    if torque[0] is not None and np.any(fitted.state.compliance):
        notes.append(
            "joint compliance was fitted: the calibrated URDF cannot hold it; it is written "
            "to the compliance file (apply it with calib predict or calib.load_calibrated)"
        )
    if urdf_after is not None:
        alone = validation.urdf_alone_warning(
            (before, urdf_after), None if val is None else (val.registration, val.geometry)
        )
        notes += [alone] if alone is not None else []
    return notes


def _assemble(
    chain,
    nominal,
    train,
    held,
    torque,
    fitted: Fit,
    prior,
    selection: Selection | None,
    dropped,
    notes,
    opts,
):
    """Statistics, validation and checks of a fit, as a result."""
    p = fitted.x.size
    cov, sigma = covariance(fitted.J, float(fitted.f @ fitted.f), prior)
    reg = fitted.start
    before = validation.stats(reg, train, None)
    after = validation.stats(fitted.state, train, torque[0], fitted.kin)
    m, rows = train.m, fitted.model.rows
    std_train = validation.predicted_std(fitted.J.reshape(m, rows, p), cov, train.n_markers)
    val = None if held is None else _validation(fitted, held, torque[1], cov)
    if val is not None:
        validation.check_held_out_errors(before, val.registration, held[0].source)
    checks = (before, after) if val is None else (val.registration, val.calibrated)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        std = np.sqrt(np.diag(cov)) if p else np.zeros(0)
    reason = validation.refusal(
        fitted.converged,
        before,
        after,
        validation.full_rank(fitted.J),
        None if val is None else checks,
        fitted.model.names(),
        ill_posed(chain, fitted, train, opts, std),
    )
    urdf_after = _geometry_stats(fitted.state, train)
    notes = [*notes, *_compliance_notes(fitted, torque, before, urdf_after, val)]
    return CalibrationResult(
        robot=chain.name,
        chain=chain,
        data=train,
        level=opts.level,
        model=fitted.model,
        names=fitted.model.names(),
        nominal=nominal,
        registration=reg,
        state=fitted.state,
        estimate=fitted.x,
        std=std,
        covariance=cov,
        sigma=sigma,
        condition=condition(fitted.J),
        before=before,
        after=after,
        predicted_std=std_train,
        validation=val,
        selection=selection,
        outliers=tuple(dropped),
        prior=np.zeros(p) if prior is None else prior,
        iterations=fitted.iterations,
        evaluations=fitted.evaluations,
        converged=fitted.converged,
        message=fitted.message,
        orientation_weight=opts.orientation_weight,
        refusal=reason,
        warnings=tuple(notes),
        urdf_after=urdf_after,
    )


def _geometry_stats(state: State, data: Measurements) -> ResidualStats | None:
    """Errors of the state without its compliance (the URDF alone), None without compliance."""
    if not np.any(state.compliance):
        return None
    return validation.stats(
        dataclasses.replace(state, compliance=np.zeros_like(state.compliance)), data, None
    )


def _validation(fitted: Fit, held, torque, cov) -> Validation:
    """Errors of the registration and of the fit on held-out data, and the predicted std."""
    data, label = held
    J = fitted.model.jacobian(fitted.start, fitted.x, data, torque)
    return Validation(
        label,
        validation.stats(fitted.start, data, None),
        validation.stats(fitted.state, data, torque),
        validation.predicted_std(J, cov, data.n_markers),
        _geometry_stats(fitted.state, data),
        data,
    )


def residual_stats(
    result: CalibrationResult | ContactChainsCalibration, data: Measurements
) -> ResidualStats:
    """Errors of a calibrated model on other data (gravity torques recomputed if needed).

    A joint fit of one chain measured by an instrument (shape ``chain``) is scored by its
    chain's state (rigid joints).

    Raises:
        InvalidArgumentError: Not a calibration of one chain and measurements of its chain.
    """
    if isinstance(result, ContactChainsCalibration) and isinstance(data, Measurements):
        part = result.one_chain()
        check_against_chain(data, part.chain)
        return validation.stats(part.state.inner, data, None)
    if not isinstance(result, CalibrationResult) or not isinstance(data, Measurements):
        raise InvalidArgumentError("residual_stats takes a CalibrationResult and Measurements")
    check_against_chain(data, result.chain)
    torque = result.chain.gravity_torques(data.q) if np.any(result.state.compliance) else None
    return validation.stats(result.state, data, torque)
