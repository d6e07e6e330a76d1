"""Calibration from contacts of any kind: registration, selection, fit, refusal.

The same steps as measured data (:mod:`calib.calibration.pipeline`), for touches recorded by
the joint encoders alone (:class:`~calib.measurements.contact_campaign.ContactData`), of any
contact kind (``plane``, ``plane-point``, ``fixed-point``, ``fixed-pose``) and any number of
objects (planes, points, poses: the ids of the file):

1. touches set aside (``holdout``, within each object, at least ``MIN_TOUCHES`` kept) or a
   validation campaign;
2. the registration: the objects and the contact frame fitted in closed form on the nominal
   robot, the usual mistakes diagnosed and the outlier touches set aside
   (:func:`~calib.calibration.contact_checks.checked_registration`);
3. the free robot parameters: those of joint rows 1..n of the parameter set that the touches
   determine beside the objects and the contact (pivoted QR, those columns first, at the
   touches projected onto the registered contact), then for ``auto`` the cross-validated
   forward selection with a prior (:func:`~calib.calibration.selection.select`, the objects
   and the contact as the fixed block);
4. least squares (:func:`~calib.calibration.solve.fit`) of the kind's own gap;
5. refusal (:func:`~calib.calibration.contact_checks.refusal`), e.g. of a model whose
   held-out weighted RMS gap (lengths, and angles times the orientation weight) is worse
   than the registration's (the nominal robot with its own objects and contact).

With ``elastic=True`` (plane contacts) the joint compliances are candidates too
(:mod:`calib.calibration.contact_elastic`): the checks apply to the whole model (URDF and
compliances), and the URDF alone is scored too (``train_urdf``, ``held_out_urdf``).

The base frame's and the tool frame's own rows are not fitted: the objects (any placement in
the base frame) and the contact frame (in the tool frame) take their visible part.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..core.checks import MAX_OBJECTS, MAX_TOUCHES, check_size
from ..core.progress import Progress, phase
from ..exceptions import DataError, InvalidArgumentError
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain
from ..kinematics.standing import Support
from ..measurements.contact_campaign import ContactData
from ..measurements.postures import count as count_postures
from . import contact_checks, contact_elastic, determined, outliers, validation
from .contact_checks import WEIGHT_ROUNDS, subset
from .contact_choice import (
    check_selection_memory,
    choose,
    flush_postures,
    proposals,
    touching_postures,
)
from .contact_fit import block_fit, by_block
from .contact_model import ContactState
from .contact_result import ContactCalibration, gap_stats
from .contact_term import (
    check_held_out_gaps,
    contact_frame,
    contact_objects,
    split_contacts,
    tilt_weight,
)
from .options import Options
from .selection import Selection
from .solve import Fit, fit, fitted_values

__all__ = [
    "WEIGHT_ROUNDS",
    "calibrate_contacts",
    "check_held_out_gaps",
    "contact_frame",
    "flush_postures",
    "split_contacts",
    "tilt_weight",
    "touching_postures",
]


def _check(chain, data, validate, opts: Options) -> None:
    if not isinstance(chain, Chain) or chain.is_tree:
        raise InvalidArgumentError(f"contacts are calibrated on one Chain, got {chain!r:.60}")
    for d in (data, validate):
        if d is None:
            continue
        if not isinstance(d, ContactData):
            raise InvalidArgumentError(f"contact data must be ContactData, got {type(d).__name__}")
        if d.joint_names != chain.joint_names:
            raise DataError(d.source, "the touches' joints are not the chain's")
        if not d.m:
            raise DataError(d.source, "no touches: an empty contact set")
        check_size(d.m, MAX_TOUCHES, "touches", d.source)
        check_size(len(d.contacts), MAX_OBJECTS, f"{d.id_column}s", d.source)
    if validate is not None:
        if opts.holdout > 0:
            raise InvalidArgumentError("give a validation file or a holdout fraction, not both")
        if validate.kind != data.kind:
            raise DataError(
                validate.source,
                f"validation touches of kind '{validate.kind.label}' for '{data.kind.label}' data",
            )
        validation.check_held_out(data, validate)
    if opts.fix or opts.free or opts.loss != "linear":
        raise InvalidArgumentError("fix, free and robust losses are not available for contacts")


def calibrate_contacts(
    chain: Chain,
    data: ContactData,
    *,
    contact=None,
    params: str | None = None,
    validate: ContactData | None = None,
    orientation_weight: float | None = None,
    elastic: bool | None = None,
    support: Support | None = None,
    max_iterations: int = 100,
    holdout: float = 0.0,
    seed: int = 0,
    progress: Progress | None = None,
) -> ContactCalibration:
    """Calibrate a chain from touches of any contact kind (see the module's text).

    Args:
        chain: The nominal chain (base: where the objects are expressed; tool: the contact's).
        data: The touches (:func:`~calib.measurements.contact_campaign.read_contacts`).
        contact: Guess of the contact frame in the tool frame: ``(4, 4)`` or ``X Y Z [RX RY
            RZ]`` [m, rad] (default: the tool frame).
        params: ``auto`` (default), ``frames`` (the registration only), ``offsets``,
            ``paper`` or ``complete``.
        validate: Touches of other postures to score the result on (never fitted).
        orientation_weight: Weight of the angle rows [m/rad] (default: estimated,
            :func:`~calib.calibration.contact_checks.estimate_weight`).
        elastic: Fit joint compliances too (plane contacts), under the gravity torques of
            the robot standing on the chain's base frame (opt-in; the URDF cannot hold them).
        support: With ``elastic``: the load split with a second foot
            (:class:`~calib.kinematics.standing.Support`; default: the base foot carries all).
        max_iterations: Most residual evaluations of the solver.
        holdout: Fraction of each object's touches set aside (seeded).
        seed: Seed of the holdout draw.
        progress: Progress bars of the registration, the selection and the fit
            (:mod:`calib.core.progress`; e.g. ``tqdm.tqdm``), or None.

    Returns:
        The result: check ``accepted``.

    Raises:
        InvalidArgumentError: A bad argument, or what is not available yet.
        DataError: Touches that do not belong to the chain, determine too little, or look
            like a usual mistake (which is named).
        ContactGeometryError: Touches that cannot fix an object or the contact frame.
    """
    opts = Options(
        level="auto" if params is None else params,
        elastic=elastic,
        orientation_weight=orientation_weight,
        max_iterations=max_iterations,
        holdout=holdout,
        seed=seed,
    )
    _check(chain, data, validate, opts)
    load = contact_elastic.standing(chain, data.kind, opts.elastic, support)
    nominal = from_chain(chain)
    check_selection_memory(data, nominal, opts.level, 0 if load is None else chain.n)
    clock = [time.perf_counter()]
    guess = contact_frame(contact)
    w = opts.orientation_weight
    train, held = split_contacts(data, opts.holdout, opts.seed)
    held = validate if validate is not None else held
    with phase(progress, f"calibrate: registration ({train.m} touches)"):
        first, bad, notes = contact_checks.checked_registration(
            chain, nominal, train, validate, guess, w
        )
        held = _held_out_outliers(first, train, held, notes)
    clock.append(time.perf_counter())
    full = contact_elastic.torques(load, train, None)[0]

    def refit(keep: np.ndarray) -> _Round:
        reg = first if np.array_equal(keep, ~bad) else None
        return _round(chain, nominal, subset(train, keep), held, guess, opts, load, reg, progress)

    def errors(rnd: _Round):
        return contact_checks.length_errors(rnd.fitted.state, train, full)

    rows = train.rows or tuple(range(1, train.m + 1))
    enough = contact_checks.enough_touches(train)
    start = bad | proposals(first, train, opts)
    start = start if enough(start) else bad  # every object keeps enough touches
    rnd, _, dropped = outliers.until_stable(refit, errors, None, rows, start, enough)
    notes = [*notes, *rnd.notes]
    if dropped:
        notes.append(outliers.set_aside_note(dropped, "touch(es)", "gap"))
    clock.append(time.perf_counter() - 1e-3 * rnd.fit_ms)  # the selections, then the last fit
    clock.append(time.perf_counter())
    sets = (rnd.train, held)
    result = _assemble(chain, sets, rnd.torque, rnd.start, rnd.fitted, rnd.selection, notes,
                       clock, load)  # fmt: skip
    return dataclasses.replace(
        result,
        outliers=tuple(dropped),
        params=opts.level,
        sources=(train.source, _held_label(held, validate)),
        **{k: v for k, v in fitted_values(rnd.fitted, rnd.prior).items() if k != "fitted"},
    )


@dataclasses.dataclass(frozen=True)
class _Round:
    """One fit of the touches an outlier mask keeps: registration, choice, least squares."""

    train: ContactData
    start: ContactState
    torque: tuple
    fitted: Fit
    selection: Selection | None
    notes: tuple[str, ...]
    fit_ms: float
    prior: np.ndarray | None = None


def _held_out_outliers(start: ContactState, train, held, notes: list[str]):
    """The held-out touches without their outliers (:func:`.outliers.held_out_outliers`)."""
    if held is None:
        return None
    start.frames.index(held.ids, held.source)  # every held-out object was fitted
    rows = held.rows or tuple(range(1, held.m + 1))
    bad, dropped = outliers.held_out_outliers(
        contact_checks.length_errors(start, train),
        contact_checks.length_errors(start, held),
        None,
        rows,
    )
    if not dropped:
        return held
    notes.append(outliers.held_out_note(dropped, "touch(es)", "gap"))
    return subset(held, ~bad)


def _round(chain, nominal, train, held, guess, opts, load, start=None, progress=None) -> _Round:
    """Register (unless ``start`` is given), check, choose and fit some touches."""
    if start is None:
        start = contact_checks.registration(nominal, train, guess, opts.orientation_weight)
    kind = train.kind
    what = f"unknowns of the {kind.object_name}(s) and the contact frame"
    determined.check_equations(count_postures(train.q, train.ids), kind.n_rows,
                               start.frames.size, what, train.source,
                               held=0 if held is None else held.m, unit="touches")  # fmt: skip
    if held is not None:
        start.frames.index(held.ids, held.source)  # every held-out object was fitted
    notes = list(filter(None, [contact_checks.isolated_postures(chain, train, held)]))
    torque = contact_elastic.torques(load, train, held)
    notes += filter(None, [contact_elastic.readings_note(load, train, held)])
    with phase(progress, "calibrate: selection"):
        model, selection, prior = choose(start, train, opts, notes, load, torque[0])
    tic = time.perf_counter()
    with phase(progress, f"calibrate: fit ({model.size()} parameters)"):
        fitted = _fit(model, start, train, torque[0], prior, opts)
    ms = 1e3 * (time.perf_counter() - tic)
    return _Round(train, start, torque, fitted, selection, tuple(notes), ms, prior)


def _fit(model, start, train, torque, prior, opts: Options):
    """Least squares of the touches; with many objects, their unknowns eliminated per object."""
    if by_block(model):
        return block_fit(
            model, start, train, torque, prior=prior, max_iterations=opts.max_iterations
        )
    return fit(model, start, train, torque, 1.0, prior=prior, max_iterations=opts.max_iterations)


def _held_label(held, validate) -> str | None:
    """``holdout``, the validation file, or None without held-out touches."""
    if held is None:
        return None
    return "holdout" if validate is None else validate.source


def _assemble(chain, sets, torque, start, fitted, selection, notes, clock, load):
    train, held = sets
    state = fitted.state
    stats = {
        "train": gap_stats(state, train.q, train.ids, torque[0]),
        "train_registration": gap_stats(start, train.q, train.ids),
    }
    if held is not None:
        stats["held_out"] = gap_stats(state, held.q, held.ids, torque[1])
        stats["held_out_registration"] = gap_stats(start, held.q, held.ids)
        check_held_out_gaps(stats, held.source)
    refusal = contact_checks.refusal(
        None if fitted.converged else fitted.message,
        stats,
        validation.full_rank(fitted.J[:, fitted.model.fixed :]),
        fitted.model.size() - fitted.model.fixed,
    )
    compliance = contact_elastic.fitted_compliance(state, start, sets, stats, notes, load)
    clock.append(time.perf_counter())
    stages = ("registration", "selection", "fit", "validation")
    timings = {s: 1e3 * (b - a) for s, a, b in zip(stages, clock[:-1], clock[1:], strict=True)}
    return ContactCalibration(
        chain=chain,
        kind=train.kind,
        nominal=start.mdh,
        calibrated=state.mdh,
        contact=state.contact,
        objects=contact_objects(state, train, torque[0]),
        free=fitted.model.names()[fitted.model.fixed :],
        selection=selection,
        stats=stats,
        refusal=refusal,
        notes=tuple(notes),
        weight=state.weight,
        timings_ms=timings,
        compliance=compliance,
        load=None if compliance is None else load,
        readings=() if compliance is None or train.readings is None else train.readings.names,
    )
