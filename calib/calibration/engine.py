"""The joint engine: every term of one robot fitted together, shared joints once.

A run is registered (:mod:`.register`), its model chosen (:mod:`.choice`),
fitted (:func:`fit_registered`) and refused where its held-out errors are worse than the
registration's. Rationale and measurements: docs/developers/engine.md#engine
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import cast

import numpy as np

from ..core.progress import Progress, phase
from ..exceptions import InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.standing import Support
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from ..measurements.limits import check_limits
from . import contact_checks, contact_elastic, term_checks, validation
from .chain_counts import Generic, assess
from .chain_outliers import fit_terms_until_stable
from .chain_registration import MeasuredState
from .choice import chains_model, choose, flush_data, structural, weakly_seen
from .contact_checks import contact_objects, few_postures, held_out_refusal
from .contact_fit import block_fit, by_block
from .contact_model import ContactState
from .contact_result import gap_stats, part_stats
from .delivery import read_files
from .determined import ILL_CONDITION, Direction
from .engine_model import ChainsData, ChainsModel, ChainsState
from .engine_result import ChainContacts, ContactChainsCalibration, nothing_fitted
from .measured_options import level_offer
from .measured_term import unseen
from .measured_view import MeasuredChain, Solution, measured_part
from .options import DEFAULT_MAX_ITERATIONS, Options, checked_arguments
from .pixel_chain import PixelData, PixelPart, PixelTermState
from .pixel_chain_result import PixelChain, check_fitted_pixels, pixel_result
from .problem import check_pose_weighed, check_weighed
from .register import Registered, Run, determined_unknowns, register_contact_chains
from .selection import Selection
from .solve import fit, fitted_values, gauss_newton_finish, unconverged

__all__ = [
    "HOLDS",
    "NOTHING_HELD",
    "OWN_VALIDATE",
    "POLISH_GAIN",
    "ROUND_OFF",
    "Registered",
    "Run",
    "calibrate_contact_chains",
    "check_readings",
    "determined_unknowns",
    "fit_registered",
    "fit_run",
    "nothing_held",
    "register_contact_chains",
]


@checked_arguments
def calibrate_contact_chains(
    chains: Sequence[Chain],
    data: Sequence[ContactData | Measurements | PixelData],
    *,
    contact=None,
    params: str | None = None,
    validate: Sequence[ContactData | Measurements | PixelData | None] | None = None,
    orientation_weight: float | None = None,
    shared_planes: bool = False,
    pose_weight: float = 1.0,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    holdout: float = 0.0,
    seed: int = 0,
    progress: Progress | None = None,
    instrument: bool = False,
    held_label: str | None = None,
    elastic: bool | None = None,
    support: Support | None = None,
    marker=None,
    known_planes=None,
    fix: tuple[str, ...] = (),
    free: tuple[str, ...] = (),
) -> ContactChainsCalibration:
    """Calibrate several chains of one robot together: a problem's terms, as arguments.

    ``chains`` and ``data`` are each term's robot and data, ``validate`` each one's
    validation data (or None), ``contact`` the touching terms' contact frame guess; the
    options are :class:`~.problem.Problem`'s (``pose_weight``: a loop that closes far better
    than the table is touched may weigh more). Besides: ``instrument``: the measured terms
    are a tree's tools measured by one instrument outside the robot (:mod:`.instrument`);
    ``held_label``: the label of the ``validate`` rows in the result (``holdout``: rows the
    caller held out and diagnosed; None: each one's source); ``support``: with ``elastic``,
    the load split with a second foot (:class:`~calib.kinematics.standing.Support`);
    ``marker``: a guess of each measured term's markers in its tool frame [m] (one point or
    one per marker; default: zeros); ``known_planes``: planes held, not fitted
    (:class:`~.problem.Problem`'s); ``fix``, ``free``: one chain's parameters held at the
    nominal or always fitted (:class:`~.options.Options`'); ``progress``: progress bars
    (:mod:`calib.core.progress`).

    Returns:
        The result: check ``accepted``; ``write_urdf`` writes one URDF of the robot.

    Raises:
        InvalidArgumentError: A bad argument.
        DataError: Touches that do not belong to their chain or determine too little.
    """
    check_weighed(orientation_weight, data)
    check_pose_weighed(pose_weight, data)
    if isinstance(chains, Sequence) and isinstance(data, Sequence):  # else refused later
        held = validate if isinstance(validate, Sequence) else [None] * len(data)
        for c, d, v in zip(chains, data, held, strict=False):
            check_readings(c, d, v)
    if (fix or free) and len(chains) != 1:
        raise InvalidArgumentError("fix and free name one chain's parameters: give one chain")
    options = Options(
        params=params,
        fix=fix,
        free=free,
        orientation_weight=orientation_weight,
        elastic=elastic,
        max_iterations=max_iterations,
        holdout=holdout,
        seed=seed,
    )
    run = Run(
        chains,
        data,
        validate,
        options,
        contact,
        marker,
        shared_planes,
        pose_weight,
        instrument,
        held_label,
        support,
        progress,
        known_planes,
    )
    return dataclasses.replace(fit_run(run), inputs=read_files(chains, data, validate))


def check_readings(chain: object, *parts: object) -> None:
    """A chain's joint readings in each part against its limits: past one warned, far refused.

    Measurements and a pixel term's rows are checked here; touches when read, a tree's rows
    with the tree.
    """
    if not isinstance(chain, Chain):
        return
    for part in parts:
        if isinstance(part, PixelData):
            obs = part.obs
            mine = np.asarray(obs.camera) == part.camera.name
            lines = np.array(term_checks.file_lines(obs))
            joints, q, rows = obs.joint_names, obs.q[mine], lines[mine]
        elif isinstance(part, Measurements):
            joints, q, rows = part.joint_names, part.q, part.file_rows()
        else:
            continue
        if tuple(joints) == tuple(chain.joint_names) and len(q):
            check_limits(chain, q, part.source, rows)


def fit_run(run: Run) -> ContactChainsCalibration:
    """A run registered and fitted, each term's outliers set aside after each fit until stable."""
    return fit_terms_until_stable(run, fit_registered)


def fit_registered(r: Registered) -> ContactChainsCalibration:
    """Select, fit and assemble a registered run.

    A fit refused (or stalled) for combinations that each name a parameter ``auto`` chose
    (not ``free``; :func:`~.chain_counts.assess`) is fitted again without the one of largest
    component in the weakest (held at its nominal value, a note), at most ``HOLDS`` times.
    Rationale: docs/developers/engine.md#holds
    """
    run, train, plane_of, start = r.run, r.train, r.plane_of, r.start
    load, torques, comp = r.load, r.torques, r.comp
    chains, opts, instrument, progress = run.chains, run.options, run.instrument, run.progress
    notes, clock = list(r.notes), list(r.clock)  # a registration fitted twice: its own lists
    with phase(progress, "calibrate: selection"):
        asked, offer = level_offer(chains[0], start, instrument, opts)
        flush = flush_data(start, train, load)
        rows = ChainsData(tuple(train), None if torques[0] is None else torques[:1])
        flush = flush if load is not None or not comp else ChainsData(flush.parts, torques[:1])
        generic = Generic(start, tuple(train), opts.seed) if instrument else None
        kept: list[int] = []
        model, at, selection, prior = choose(
            start, rows, flush, plane_of, offer, notes, comp, asked, generic, kept
        )
        kin = None if by_block(model, start) else at.kinematics(rows)
        names = start.placements.names()
        wide = chains_model(start, plane_of, range(len(names)), names, None, comp)
        if instrument and len(chains) == 1:  # its MDH directions span what it sees
            identifiable = len(kept)
        elif offer == "components":
            identifiable = model.size()
        else:
            identifiable = len(structural(wide, start, flush))
    clock.append(time.perf_counter())
    given = () if asked is None else asked.free
    converged = []
    for attempt in range(HOLDS + 1):
        with phase(progress, "calibrate: fit"):
            fitted, polished = _fit(model, wide, start, rows, prior, offer, opts, kin)
        converged.append(fitted.converged)
        fit_of = (fitted, polished, prior, generic)
        result, found = _assessed(r, fit_of, model, selection, list(notes), list(clock))
        held = _held(found, selection, given)
        if held is None or attempt == HOLDS:
            break
        name, weak = held
        model, prior, selection = _without(model, prior, selection, name)
        why = "was refused" if fitted.converged else "did not converge"
        notes.append(
            f"params 'auto' held {name} at the nominal value: the fit with it {why}: the "
            f"data cannot separate {' and '.join(weak.names)} (condition {weak.condition:.3g} "
            f"of the fitted unknowns, over {ILL_CONDITION:g})"
        )
    barely = weakly_seen(model, at, flush) if result.accepted else {}
    return _finished(r, result, converged, identifiable, barely)


def _finished(r: Registered, result, converged: list[bool], identifiable: int, barely: dict):
    """The last fit's ``result`` with the run's level, counts and notes (stalled: checked).

    ``barely``: the fitted directions the data barely see (:func:`~.choice.weakly_seen`).
    """
    opts = r.run.options
    if not converged[-1]:
        for part in result.chains:
            _check_fitted(part, opts.noise)
    stalled = not all(converged)
    result = dataclasses.replace(
        result, params=opts.level, identifiable=identifiable, stalled=stalled
    )
    few = [few_postures(h, "the held-out verdict rests on") for h in r.held if h is not None]
    far = turned_far(result) if result.accepted else None
    missed = _above_noise(result, opts.noise)
    unseen, held = moved_unseen(result, barely), nothing_held(result)
    notes = (nothing_fitted(result, bool(opts.fix)), far, unseen, missed, held, *few)
    added = [n for n in notes if n]
    return dataclasses.replace(result, notes=(*result.notes, *added)) if added else result


def _above_noise(result: ContactChainsCalibration, noise: float | None) -> str | None:
    """The warning of a chain measured whose fitted rows are missed far above ``noise`` [m]."""
    part = result.chains[0]
    if noise is None or len(result.chains) > 1 or not isinstance(part, MeasuredChain):
        return None
    rows = cast(np.ndarray, part.stats["train"].residuals)  # measured_part keeps them
    found = validation.far_above_noise(rows, part.data.n_markers, result.unknowns, noise)
    return found and f"{part.chain.base_frame} -> {part.chain.tool_frame}: {found}"


def _check_fitted(part: ChainContacts | MeasuredChain | PixelChain, noise: float | None) -> None:
    """Stop on a term's data no calibration explains (a DataError); ``noise`` [m]."""
    if isinstance(part, PixelChain):
        check_fitted_pixels(part)
        return
    markers = part.data.n_markers if isinstance(part, MeasuredChain) else None
    noise = noise if isinstance(part, MeasuredChain) else None
    validation.check_fitted_errors(part.stats, markers, noise, part.source, part.chain)


TURNED_STD = 10.0
"""Standard deviations from 0 over which a far-turned angle is said (:func:`turned_far`)."""


def turned_far(result: ContactChainsCalibration) -> str | None:
    """The note of fitted angles over :data:`~.validation.ORIENTATION_REFUSED`, or None.

    Rationale and measurements: docs/developers/engine.md#turned_std
    """
    far = [
        e
        for e in result.entries()
        if e["unit"] == "rad"
        and abs(e["value"]) > validation.ORIENTATION_REFUSED
        and abs(e["value"]) > TURNED_STD * e["std"]  # NaN: undefined, not said
    ]
    if not far:
        return None
    said = ", ".join(f"{e['name']} by {np.degrees(e['value']):.3g} deg" for e in far)
    return (
        f"the fit turns {said}, far beyond any geometric error (over "
        f"{np.degrees(validation.ORIENTATION_REFUSED):.3g} deg): a joint zero that far off in "
        "the URDF, or a frame given on the wrong link (a joint in its chain that does not move "
        "it, or one left out)?"
    )


MOVED_SAID = (0.01, 0.01)
"""A fitted change [m, rad] over which :func:`moved_unseen` says a weakly seen direction."""


def moved_unseen(result: ContactChainsCalibration, weak: dict[str, float]) -> str | None:
    """The note of fitted changes over :data:`MOVED_SAID` along directions the data barely see.

    ``weak``: each such direction's share of its rows the data see (:func:`~.choice.weakly_seen`).
    Rationale and measurements: docs/developers/engine.md#weakly_seen
    """
    said = [
        f"{e['name']} by {e['value'] * 1000:.4g} +- {e['std'] * 1000:.3g} "
        f"{'mm' if e['unit'] == 'm' else 'mrad'} (the fitted objects and frames take up "
        f"{100 * (1 - weak[e['name']]):.3g} % of its effect on the rows)"
        for e in result.entries()
        if e["name"] in weak and abs(e["value"]) > MOVED_SAID[e["unit"] == "rad"]
    ]
    if not said:
        return None
    it, which = ("it", "that joint's origin") if len(said) == 1 else ("them", "those origins")
    return (
        f"the fit moves {'; '.join(said)}: the data barely see {it}, so the written URDF "
        f"moves {which}, and the fitted objects or frames with it, on little evidence; check "
        f"{it} against the robot's drawings, and compare params='offsets' on held-out rows"
    )


NOTHING_HELD = "nothing held out: not checked on unseen postures (hold some out: "
"""The head of :func:`nothing_held`'s note (folds drop it from their full fit's notes)."""

OWN_VALIDATE = "a term's validate, as the other terms)"
"""The way out of :func:`nothing_held`'s note on terms beside terms with validation rows."""


def nothing_held(result: ContactChainsCalibration) -> str | None:
    """The note of an accepted ``result`` with terms that held no row out, or None."""
    none = [c.named(k) for k, c in enumerate(result.chains) if c.held_source is None]
    if not result.accepted or not none:
        return None
    if len(none) < len(result.chains):
        return f"{', '.join(none)}: {NOTHING_HELD}{OWN_VALIDATE}"
    pixels = any(isinstance(c, PixelChain) for c in result.chains)  # not cross-validated
    return NOTHING_HELD + ("holdout or validate)" if pixels else "holdout, validate or folds)")


HOLDS = 3
"""Most parameters ``auto`` holds, one a refit (:func:`fit_registered`)."""


def _assessed(r: Registered, fit_of, model, selection, notes, clock):
    """A fit's result and the combinations :func:`~.chain_counts.assess` refused it for.

    A stalled fit is assessed where it stopped. ``fit_of``: the fit, whether it was
    polished, its prior weights and :class:`~.chain_counts.Generic` configurations (or None).
    """
    fitted, polished, prior, generic = fit_of
    if polished:
        notes.append(
            f"polished with all {len(fitted.model.free)} joint placement components (composed "
            f"with the fit of the {len(model.free)} parameters determined at the nominal robot)"
        )
    clock.append(time.perf_counter())
    bare = dataclasses.replace(fitted.start, states=unseen(fitted.start.states))
    solution = Solution(dataclasses.replace(fitted, start=bare), None if polished else prior)
    result = _assemble(r, solution, model, selection, notes, clock)
    given = r.run.validate or [None] * len(r.held)
    labels = [
        None if h is None else "holdout" if v is None else r.run.held_label or v.source
        for h, v in zip(r.held, given, strict=True)
    ]
    pairs = zip(result.chains, labels, map(_lines, r.held), r.dropped, strict=True)
    parts = tuple(
        dataclasses.replace(c, held_source=lab, held_rows=rows, outliers=o)
        for c, lab, rows, o in pairs
    )
    cov = solution.covariance[0]
    values = fitted_values(fitted, cov)
    stopped = unconverged(fitted)
    ranked = polished or not fitted.converged  # a stalled fit's rank is not judged
    rank = None if ranked else contact_checks.rank_refusal(fitted.J, fitted.model.fixed)
    refusal, found = result.refusal or stopped or rank, list[Direction]()
    if result.refusal is None and rank is None:  # accepted so far, or only stalled
        weak, found = assess(generic, fitted, cov, polished)
        stalled = stopped and weak and f"{weak}; assessed where the fit stopped: {stopped}"
        refusal = stalled or refusal or weak
    out = dataclasses.replace(result, chains=parts, refusal=refusal, solution=solution, **values)
    return out, found


def _lines(held) -> tuple[int, ...] | None:
    """Held-out rows' lines in their file (pixels: each point's), or None: none held out."""
    if held is None:
        return None
    return held.rows.lines if isinstance(held, PixelPart) else term_checks.file_lines(held)


def _held(found, selection: Selection | None, given) -> tuple[str, Direction] | None:
    """The parameter ``auto`` chose (not ``given``) to hold and its combination, or None."""
    chosen = set(() if selection is None else selection.kept) - set(given)
    named = [
        [(abs(w), n) for n, w in zip(d.names, d.weights, strict=True) if n in chosen] for d in found
    ]
    return (max(named[0])[1], found[0]) if found and all(named) else None


def _without(model: ChainsModel, prior, selection: Selection, name: str):
    """The model, its prior weights and the selection without the parameter ``name``."""
    c, j = model.names().index(name), selection.kept.index(name)
    k, n = c - model.fixed, len(model.free)  # the directions, then the compliances
    free = tuple(f for i, f in enumerate(model.free) if i != k)
    comp = tuple(f for i, f in enumerate(model.compliance) if i != k - n)
    kept = tuple(x for i, x in enumerate(selection.kept) if i != j)
    index = tuple(x for i, x in enumerate(selection.index) if i != j)
    winner = selection.winner if kept else "registration"
    selection = dataclasses.replace(selection, kept=kept, index=index, winner=winner)
    prior = None if prior is None else np.delete(prior, c)
    return model.with_free(free, comp), prior, selection


PIN = 1e-6
"""Weight [m per m or rad] of the polish's pull toward the first fit (undetermined: stay put)."""

POLISH_GAIN = 1e-2
"""A polish is kept when it leaves less than this fraction of the fit's cost (see ``_fit``)."""

ROUND_OFF = 1e-12
"""RMS row [m] of a fit already exact: not polished (nothing is left to remove)."""


def _fit(
    model: ChainsModel,
    wide: ChainsModel,
    start: ChainsState,
    train: ChainsData,
    prior,
    level,
    opts: Options,
    kin=None,
):
    """Least squares; at ``complete``, polished by every component (``wide``) where it helps.

    Returns the fit and whether it was polished.
    Rationale and measurements: docs/developers/engine.md#_fit
    """
    data, iters = train, opts.max_iterations
    if by_block(model, start):
        fitted = block_fit(model, start, data, prior=prior, max_iterations=iters)
    else:
        fitted = fit(
            model,
            start,
            data,
            None,
            prior=prior,
            max_iterations=iters,
            loss=opts.loss,
            scale=opts.noise or 1e-3,
            kin=kin,
        )
    rows = sum(d.m * len(s.kind.row_names) for s, d in zip(start.states, data.parts, strict=True))
    alone = start.states[0] if len(start.states) == 1 else None  # one chain: not polished
    one_chain = isinstance(alone, ContactState) or getattr(alone, "instrument", False)
    polish = level == "complete" and model.free and opts.loss == "linear" and not opts.fix
    if not polish or rows < wide.size() or one_chain:
        return fitted, False
    cost = float(fitted.f @ fitted.f)
    if not fitted.converged or cost <= ROUND_OFF**2 * fitted.f.size:
        return fitted, False
    again = fitted.state.settled()
    try:
        better = fit(
            wide, again, data, None, prior=PIN * np.ones(wide.size()), max_iterations=iters
        )
    except InvalidArgumentError:  # it wandered along undetermined components to no robot
        return fitted, False
    if better.converged and float(better.f @ better.f) < POLISH_GAIN * cost:
        return gauss_newton_finish(better, data), True
    return fitted, False


def _assemble(r: Registered, solution, model, selection, notes, clock) -> ContactChainsCalibration:
    """The result of a run's fit, refused for a held-out error only (:func:`_assessed`: more)."""
    fitted = solution.fit
    state: ChainsState = fitted.state.settled()
    refusal = None  # a held-out error worse than the registration's (the solver's: _assessed)
    parts: list[ChainContacts | MeasuredChain | PixelChain] = []
    for c, chain in enumerate(state.chains):
        s, s0, d, h = state.states[c], r.start.states[c], r.train[c], r.held[c]
        if not isinstance(s, MeasuredState | PixelTermState):
            part, why = _touching(r, c, s0, s, fitted.converged, notes)
            refusal = refusal or why
            parts.append(part)
            continue
        own = fitted.model.own_columns(c)
        std = np.sqrt(np.diag(solution.covariance[0]))[own]
        part = (
            pixel_result(chain, d, h, s0, s, fitted.x[own], std, c + 1)
            if isinstance(s, PixelTermState)
            else measured_part(chain, d, h, s0, s, std, c + 1, r.torques, notes)
        )
        if fitted.converged:  # else refused, or fitted again (auto): fit_registered
            _check_fitted(part, r.run.options.noise)
        if h is not None:
            refusal = refusal or held_out_refusal(part.stats, chain, "errors")
        notes.extend(part.warnings() if isinstance(part, PixelChain) else ())
        parts.append(part)
    notes += contact_elastic.none_kept_note(parts[0], r.comp, r.load)
    joints = [name for c in state.chains for name in c.joint_names]
    shared = tuple(n for n in dict.fromkeys(joints) if joints.count(n) > 1)
    clock.append(time.perf_counter())
    stages = ("registration", "selection", "fit", "validation")
    spans = zip(stages, clock[:-1], clock[1:], strict=True)
    planes = {
        p for p, s in zip(r.plane_of, state.states, strict=True) if isinstance(s, ContactState)
    }
    one_touching = len(parts) == 1 and isinstance(parts[0], ChainContacts)
    return ContactChainsCalibration(
        chains=tuple(parts),
        shape="contacts" if one_touching else "chains",
        placements=state.placements,
        shared=shared,
        planes=len(planes),
        free=tuple(model.names()[model.fixed :]),
        unknowns=model.size(),
        selection=selection,
        refusal=refusal,
        notes=tuple(notes),
        timings_ms={k: 1e3 * (b - a) for k, a, b in spans},
    )


def _touching(r: Registered, c: int, s0, s: ContactState, converged: bool, notes):
    """Touching chain c's part of a fit's result, and its held-out refusal (or None)."""
    chain, d, h = r.start.chains[c], r.train[c], r.held[c]
    load, torque = (r.load, r.torques) if c == 0 else (None, (None, None))
    torques = {id(d): torque[0], id(h): torque[1]}  # the fitted state's deflect

    def stat(st, rows):
        return gap_stats(st, rows.q, rows.ids, torques[id(rows)] if st is s else None)

    stats = part_stats(stat, s0, s, d, h)
    if converged:  # a fit that stalled is refused, or fitted again (auto)
        validation.check_fitted_errors(stats, None, None, d.source, chain)
    refusal = None
    if h is not None:
        near, far = (1e-3 * stats[f"{k}_registration"].length_rms_mm for k in ("train", "held_out"))
        validation.check_held_out_errors(near, far, h.source, validation.TOUCHES)
        refusal = held_out_refusal(stats, chain, "gaps")
    compliance = contact_elastic.fitted_compliance(s, (d, h), stats, notes)
    objects = contact_objects(s, d, torque[0])
    part = ChainContacts(
        chain,
        d.source,
        d.contacts[0],
        objects[d.contacts[0]],
        s.contact,
        s0.mdh,
        s.mdh,
        s.weight,
        stats,
        s.kind,
        objects,
        compliance=compliance,
        load=None if compliance is None else load,
        readings=() if compliance is None or d.readings is None else d.readings.names,
    )
    return part, refusal
