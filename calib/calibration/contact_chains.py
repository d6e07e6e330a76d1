"""Several chains of one robot calibrated together from flush contacts: shared joints once.

A humanoid's two arms, each calibrated from its foot (``left_sole_link`` to the left
gripper, ``right_sole_link`` to the right one), share the torso joints. Fitted one at a
time, each chain gets its own torso, and no single URDF holds both. Fitted together
(:func:`calibrate_contact_chains`), every URDF joint has one placement error
(:mod:`.placements`) that every chain through it sees, and the result is one URDF of the
whole robot. The steps of every calibration:

1. touches set aside per chain (``holdout``, seeded) or a validation set per chain;
2. the registration: each chain's objects and contact in closed form on the nominal robot
   (a plane shared by chains of one base frame: then refined together by least squares);
3. the free placement components and (``elastic``) joint compliances the touches determine
   (pivoted QR at flush postures), and for ``auto`` the cross-validated forward selection
   with a prior on all chains' touches together (:mod:`.contact_choice`);
4. least squares (one chain touching many objects: by block, :func:`~.contact_fit.block_fit`);
5. refusal of a model whose held-out weighted RMS gap is worse than the registration's.

Each chain has its own contact frame and, unless ``shared_planes``, its own plane: touches
recorded on different days see the table from wherever the robot stood.

A chain's kind is its touches', any contact kind (``plane``, ``plane-point``,
``fixed-point``, ``fixed-pose``), with any number of objects (ids); one chain touching alone
is a problem of one term (:func:`calib.calibrate` routes it here), joint compliance under
gravity included (``elastic``: :mod:`.contact_elastic`). A ``fixed-pose`` chain of a joint fit is a
closed loop through the robot: TALOS's ``left_sole_link`` -> ``right_sole_link``, both soles
flat on the ground at every touch, is one unknown fixed pose of the right sole in the left
one's frame (:func:`~calib.measurements.contact_loops.read_loop` makes its touches from the
recorded postures of the plane touches). Its registration is ``register_contacts`` of that kind, its
contact frame the tool frame (only the relative placement of pose and contact is seen), and
it constrains the joints it shares with the plane chains (the legs) together with them.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence

import numpy as np

from ..core.checks import MAX_WEIGHT, check_number
from ..core.progress import Progress, phase
from ..exceptions import DataError, InvalidArgumentError
from ..identification.contacts import FixedPoseContact
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain
from ..kinematics.standing import Support
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from . import contact_checks, contact_elastic, determined, outliers, validation
from .chain_counts import Generic, assess
from .contact_chains_model import ChainsData, ChainsModel, ChainsState, on_models
from .contact_chains_result import (
    ChainContacts,
    ContactChainsCalibration,
    MeasuredChain,
    Solution,
    measured_part,
)
from .contact_checks import held_out_refusal, subset
from .contact_choice import blocky, chains_model, choose, flush_data, structural
from .contact_fit import block_fit
from .contact_model import ContactState
from .contact_result import gap_stats, part_stats
from .contact_term import (
    check_held_out_gaps,
    check_touches,
    contact_frame,
    contact_guess,
    contact_objects,
    split_contacts,
)
from .instrument import instrument_groups, shared_frame
from .measured_options import compliance_torques, level_offer
from .measured_term import (
    MeasuredState,
    check_measured,
    checked_measured,
    measured_kind,
    one_term_per_frame,
)
from .options import Options, check_run_options, checked_arguments
from .outliers import Outlier
from .pixel_chain import (
    PixelData,
    PixelPart,
    PixelTermState,
    check_pixels,
    checked_pixels,
    pixel_parts,
)
from .pixel_chain_result import PixelChain, pixel_result
from .placements import Placements
from .solve import covariance, fit, fitted_values, gauss_newton_finish

__all__ = [
    "CHAIN_LEVELS",
    "POLISH_GAIN",
    "ROUND_OFF",
    "calibrate_contact_chains",
    "determined_unknowns",
]

CHAIN_LEVELS = ("auto", "frames", "offsets", "paper", "complete")
"""Parameter levels of a joint fit (``paper`` and ``complete``: each chain's MDH sets)."""


def _check(chains, data, validate, params, holdout, instrument=False) -> None:
    if not isinstance(chains, Sequence) or not chains:
        raise InvalidArgumentError("give the chains as a non-empty list of Chain")
    for c in chains:
        if not isinstance(c, Chain):
            raise InvalidArgumentError(f"contacts are calibrated on Chains, got {c!r:.60}")
    first = chains[0]
    for c in chains[1:]:
        if c.urdf_path != first.urdf_path or tuple(c.model.names) != tuple(first.model.names):
            raise InvalidArgumentError("the chains must be chains of one robot (one URDF)")
    pairs = [(c.base_frame, c.tool_frame) for c in chains]
    if len(set(pairs)) != len(pairs):
        raise InvalidArgumentError("a chain is given twice (same base and tool frames)")
    if not isinstance(data, Sequence) or len(data) != len(chains):
        raise InvalidArgumentError("give one set of touches per chain")
    if not instrument:
        one_term_per_frame(chains, data)
    if validate is not None and (
        not isinstance(validate, Sequence) or len(validate) != len(chains)
    ):
        raise InvalidArgumentError("give one validation set (or None) per chain")
    for c, d, v in zip(chains, data, validate or [None] * len(chains), strict=True):
        if isinstance(d, Measurements):
            check_measured(c, d, v, instrument, holdout)
            continue
        if isinstance(d, PixelData):
            check_pixels(c, d, v)
            continue
        for part in (d, v) if v is not None else (d,):
            if not isinstance(part, ContactData):
                what = "validation rows" if part is v else "data"
                raise InvalidArgumentError(
                    f"{c.base_frame} -> {c.tool_frame}: a chain's {what} must be touches "
                    f"(ContactData) or measurements (Measurements) like its data, got "
                    f"{type(part).__name__}"
                )
            check_touches(part)
            if part.joint_names != c.joint_names:
                raise DataError(
                    part.source, f"the touches' joints are not those of {c.tool_frame}'s chain"
                )
            if type(part.kind) is not type(d.kind):
                raise InvalidArgumentError(
                    f"{part.source}: validation touches of kind '{part.kind.label}' for "
                    f"'{d.kind.label}' data"
                )
    if params not in CHAIN_LEVELS:
        raise InvalidArgumentError(
            f"params must be one of {', '.join(CHAIN_LEVELS)}, got {params!r:.40}"
        )
    if validate is not None and any(v is not None for v in validate) and holdout > 0:
        raise InvalidArgumentError("give validation touches or a holdout fraction, not both")
    for d, v in zip(data, validate or [None] * len(chains), strict=True):
        if v is not None and not isinstance(d, PixelData):
            validation.check_held_out(d, v)


def _checked(chains, train, validate, guess, weight, held, notes, iterations, shared, noise=None):
    """Each chain's touches checked as one chain's are (diagnosis, outliers, equations).

    The usual mistakes are diagnosed (the validation touches' too), outliers set aside, and
    the touches kept must determine the chain's objects and contact frame.

    ``guess``: the contact frame's guess and the measured terms' marker guess (or None);
    ``noise``: the measured terms' instrument noise [mm] (or None).
    The held-out touches' outliers are set aside too (``held[c]`` replaced), and a chain
    the contact leaves finitely many postures is noted. A measured term's rows are checked
    as a single chain's (:func:`checked_measured`), its
    registration kept, and its held-out rows' outliers set aside (``held[c]`` replaced).

    Returns:
        Each chain's touches (rows) kept, each chain's outliers, and each term's
        registration on the nominal robot (a contact chain's: of the touches kept).
    """
    kept: list[ContactData | Measurements | PixelPart] = []
    dropped: list[tuple[Outlier, ...]] = []
    registered: list[MeasuredState | PixelTermState | ContactState] = []
    for c, (chain, d) in enumerate(zip(chains, train, strict=True)):
        v = None if validate is None else validate[c]
        if isinstance(d, PixelPart):
            state, bad, found, more, held[c] = checked_pixels(chain, d, held[c])
        elif isinstance(d, Measurements):
            out_m = 0 if held[c] is None else held[c].m
            rows, size = d.kind.rows_of(d.n_markers), len(measured_kind(d).names())
            what = f"unknowns of {chain.base_frame}'s placement and the markers"
            determined.check_equations(d.m, rows, size, what, d.source, held=out_m)
            state, bad, found, more, held[c] = checked_measured(
                chain, d, v, held[c], weight, iterations, guess[1], noise
            )
            state = dataclasses.replace(state, instrument=shared)
        if isinstance(d, Measurements | PixelPart):
            if found:
                more.append(outliers.set_aside_note(found))
            notes += [f"{chain.base_frame} -> {chain.tool_frame}: {n}" for n in more]
            kept.append(d.subset(~bad) if bad.any() else d)
            dropped.append(tuple(found))
            registered.append(state)
            continue
        g = contact_guess(d.kind, guess[0], len(chains))
        start, bad, more = contact_checks.checked_registration(
            chain, from_chain(chain), d, v, g, weight
        )
        out = contact_checks.set_aside(start, d, bad)
        if out:
            more.append(outliers.set_aside_note(out, "touch(es)", "gap"))
            d = subset(d, ~bad)
        held[c] = contact_checks.held_out_set_aside(start, d, held[c], more)
        more += filter(None, [contact_checks.isolated_postures(chain, d, held[c])])
        what = f"unknowns of {chain.tool_frame}'s {d.kind.object_name}(s) and contact frame"
        out_m = 0 if held[c] is None else held[c].m
        rows, size = len(d.kind.row_names), start.frames.size
        determined.check_equations(d.m, rows, size, what, d.source, held=out_m, unit="touches")
        notes += [f"{chain.base_frame} -> {chain.tool_frame}: {n}" for n in more]
        kept.append(d)
        dropped.append(tuple(out))
        registered.append(start)
    return kept, dropped, registered


def _register(
    chains, train, measured, plane_of, notes, max_iterations, pose_weight=1.0
) -> ChainsState:
    """Each chain's registration on the nominal robot (a plane shared by chains: refined).

    ``measured``: each term's registration (``_checked``: a contact chain's objects and
    contact in closed form, a measured term's frames, a pixel term's camera).
    """
    placements = Placements.of(tuple(chains))
    states = list(on_models(tuple(measured), placements.start_models(tuple(chains), measured)))
    for c, p in enumerate(plane_of):  # a shared plane (camera) starts from its first chain's
        mine, owner = states[c], states[plane_of.index(p)]
        if mine is not owner and isinstance(mine, ContactState) and isinstance(owner, ContactState):
            shared = dataclasses.replace(mine.frames, objects=owner.frames.objects)
            states[c] = dataclasses.replace(mine, frames=shared)
        if isinstance(mine, PixelTermState) and isinstance(owner, PixelTermState):
            states[c] = dataclasses.replace(mine, camera=owner.camera)
    scales = tuple(pose_weight if isinstance(d.kind, FixedPoseContact) else 1.0 for d in train)
    states = shared_frame(states, train)
    start = ChainsState(tuple(chains), placements, tuple(states), scales)
    if len(set(plane_of)) == len(plane_of):
        return start
    only_frames = chains_model(start, plane_of, (), placements.names())
    refined = fit(
        only_frames, start, ChainsData(tuple(train)), None, 1.0, max_iterations=max_iterations
    )
    if not refined.converged:
        raise DataError(
            train[0].source,
            f"the registration of the shared plane did not converge ({refined.message})",
        )
    planes = [p for p, s in zip(plane_of, states, strict=True) if isinstance(s, ContactState)]
    if len(set(planes)) < len(planes):
        notes.append("a plane touched by several chains is fitted once (shared planes)")
    return refined.state


def determined_unknowns(
    chains: Sequence[Chain],
    data: Sequence[ContactData | Measurements | PixelData],
    *,
    contact=None,
    shared_planes: bool = False,
    pose_weight: float = 1.0,
    max_iterations: int = 100,
    instrument: bool = False,
) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """What a joint fit of these terms would determine: the steps before its choice.

    The data are checked, outliers set aside and registered as :func:`calibrate_contact_chains`
    does (every row fitted: no holdout); the rank of the Jacobian of every row by every unknown
    (objects, contact frames, measuring frames, markers, and every joint placement component)
    at flush postures is what the data determine. Arguments as
    :func:`calibrate_contact_chains`'s.

    Returns:
        The names of the unknowns determined (a basis, in the columns' order) and of all.
    """
    check_run_options(max_iterations, 0.0, 0)
    _check(chains, data, None, "frames", 0.0, instrument)
    parts = pixel_parts(chains, data)
    contact_checks.check_memory(chains, parts, "complete")
    plane_of = instrument_groups(
        contact_checks.plane_groups(chains, parts, shared_planes), parts, instrument
    )
    check_number(pose_weight, "pose_weight", 0.0, MAX_WEIGHT, above=True)
    held: list = [None] * len(parts)
    guess = (contact_frame(contact), None)
    train, _, measured = _checked(
        chains, list(parts), None, guess, None, held, [], max_iterations, instrument
    )
    start = _register(chains, train, measured, plane_of, [], max_iterations, pose_weight)
    names = start.placements.names()
    wide = chains_model(start, plane_of, range(len(names)), names)
    every = wide.names()
    kept = structural(wide, start, flush_data(start, train, None))
    return tuple(every[k] for k in sorted(kept)), every


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
    max_iterations: int = 100,
    holdout: float = 0.0,
    seed: int = 0,
    progress: Progress | None = None,
    instrument: bool = False,
    held_label: str | None = None,
    elastic: bool | None = None,
    support: Support | None = None,
    marker=None,
    options: Options | None = None,
) -> ContactChainsCalibration:
    """Calibrate several chains of one robot from flush touches, together (module text).

    Args:
        chains: The nominal chains (one URDF; each base: where its plane is expressed;
            each tool: its contact's).
        data: Each chain's touches of one plane (``plane`` kind,
            :func:`~calib.measurements.contact_campaign.read_contacts`) or of one fixed pose
            (``fixed-pose`` kind, a closed loop:
            :func:`~calib.measurements.contact_loops.read_loop`); a chain's kind is its
            touches'; or a camera's pixels (:class:`~.pixel_chain.PixelData`: a pixel term).
        contact: Guess of every plane chain's contact frame in its tool frame: ``(4, 4)``
            or ``X Y Z [RX RY RZ]`` [m, rad] (default: the tool frame; a fixed-pose chain's
            is its tool frame).
        params: ``auto`` (default), ``frames`` (the registration only), ``offsets`` or
            ``complete``.
        validate: Per chain, touches of other postures to score the result on, or None.
        orientation_weight: Weight of the tilt rows [m/rad] (default: each chain's
            :func:`~.contact_term.tilt_weight`).
        shared_planes: Chains of one base frame whose touches name the same plane touch one
            plane (default: each chain its own plane).
        pose_weight: Factor of the ``fixed-pose`` chains' rows against the plane chains'
            (default 1: metres against metres; a loop that closes far better than the table
            is touched may weigh more, a near-hard constraint).
        max_iterations: Most residual evaluations of the solver.
        holdout: Fraction of each chain's touches set aside (seeded).
        seed: Seed of the holdout draw.
        progress: Progress bars of the registration, the selection and the fit
            (:mod:`calib.core.progress`; e.g. ``tqdm.tqdm``), or None.
        instrument: The measured terms are a tree's tools measured by one instrument outside
            the robot (:mod:`.instrument`): its frame one unknown; ``complete`` offers every
            joint placement component.
        held_label: The label of the rows given as ``validate`` in the result (``holdout``:
            rows the caller held out of the data, a tree's, diagnosed with the data by the
            caller, not again); None: each one's source.
        elastic: One chain touching planes: its joint compliances are candidates too, under
            the gravity torques of the robot standing on the chain's base frame
            (:mod:`.contact_elastic`; the URDF cannot hold them: a compliance file).
        support: With ``elastic``: the load split with a second foot
            (:class:`~calib.kinematics.standing.Support`; default: the base foot carries all).
        marker: Guess of each measured term's markers in its tool frame [m]: one point
            for all or one per marker (default: zeros), the registration's start.
        options: One measured chain's :class:`~.options.Options` (``noise_mm``, ``loss``,
            ``fix``/``free``, ``elastic``: :mod:`.measured_options`); None: the defaults.

    Returns:
        The result: check ``accepted``; ``write_urdf`` writes one URDF of the robot.

    Raises:
        InvalidArgumentError: A bad argument.
        DataError: Touches that do not belong to their chain or determine too little.
    """
    level = "auto" if params is None else params
    opts = Options() if options is None else options
    check_run_options(max_iterations, holdout, seed)
    _check(chains, data, validate, level, holdout, instrument)
    load = contact_elastic.term_load(chains, data, elastic, support)
    data, validate = pixel_parts(chains, data), validate and pixel_parts(chains, validate)
    contact_checks.check_memory(chains, data, level, 0 if load is None else chains[0].n)
    clock = [time.perf_counter()]
    if marker is not None and not any(isinstance(d, Measurements) for d in data):
        raise InvalidArgumentError("marker is for measured terms: no term here is measured")
    guess = contact_frame(contact)
    w = None if orientation_weight is None else float(orientation_weight)
    if w is not None and not (np.isfinite(w) and w > 0):
        raise InvalidArgumentError(f"orientation_weight must be a positive number, got {w!r}")
    splits = [validation.split(d, holdout, seed) if isinstance(d, Measurements | PixelPart)
              else split_contacts(d, holdout, seed) for d in data]  # fmt: skip
    train = [s[0] for s in splits]
    held = [
        v if v is not None else s[1]
        for s, v in zip(splits, validate or [None] * len(data), strict=True)
    ]
    plane_of = contact_checks.plane_groups(chains, data, shared_planes)
    plane_of = instrument_groups(plane_of, data, instrument)
    check_number(pose_weight, "pose_weight", 0.0, MAX_WEIGHT, above=True)
    notes: list[str] = []
    diagnosed = None if held_label == "holdout" else validate  # a holdout: with its data's
    train, dropped, measured = _checked(
        chains, train, diagnosed, (guess, marker), w, held, notes, max_iterations, instrument,
        opts.noise_mm,
    )  # fmt: skip
    notes += filter(None, [contact_elastic.readings_note(load, train[0], held[0])])
    torques, comp = compliance_torques(chains, train, held, options, load)
    touches = sum(d.m for d in train)
    with phase(progress, f"calibrate: registration ({len(chains)} chains, {touches} touches)"):
        start = _register(chains, train, measured, plane_of, notes, max_iterations, pose_weight)
    clock.append(time.perf_counter())
    with phase(progress, "calibrate: selection"):
        asked, offer = level_offer(chains[0], start, level, instrument, options)
        flush = flush_data(start, train, load)
        rows = ChainsData(tuple(train), None if torques[0] is None else torques[:1])
        flush = flush if load is not None or not comp else ChainsData(flush.parts, torques[:1])
        generic = Generic(start, tuple(train), seed) if instrument else None
        kept: list[int] = []
        model, _, selection, prior = choose(start, rows, flush, plane_of, offer, notes, comp,
                                            asked, generic, kept)  # fmt: skip
        names = start.placements.names()
        wide = chains_model(start, plane_of, range(len(names)), names, None, comp)
        one = instrument and len(chains) == 1  # its MDH directions span what it sees
        identifiable = len(kept) if one else model.size() if offer == "components" else len(
            structural(wide, start, flush))  # fmt: skip
    clock.append(time.perf_counter())
    with phase(progress, "calibrate: fit"):
        fitted, polished = _fit(model, wide, start, rows, prior, offer, max_iterations, opts)
    if polished:
        notes.append(
            f"polished with all {len(wide.free)} joint placement components (composed with "
            f"the fit of the {len(model.free)} parameters determined at the nominal robot)"
        )
    clock.append(time.perf_counter())
    kept_prior = None if polished else prior
    result = _assemble(
        start,
        fitted,
        model,
        kept_prior,
        train,
        held,
        plane_of,
        selection,
        notes,
        clock,
        (load, torques),
    )
    given = validate or [None] * len(held)
    labels = [None if h is None else "holdout" if v is None else held_label or v.source
              for h, v in zip(held, given, strict=True)]  # fmt: skip
    pairs = zip(result.chains, labels, dropped, strict=True)
    parts = tuple(dataclasses.replace(c, held_source=lab, outliers=o) for c, lab, o in pairs)
    values = fitted_values(fitted, kept_prior)
    rank = None if polished else contact_checks.rank_refusal(fitted.J, fitted.model.fixed)
    refusal = result.refusal or rank or assess(generic, fitted, kept_prior, polished)
    return dataclasses.replace(
        result, chains=parts, params=level, identifiable=identifiable, refusal=refusal,
        solution=Solution(fitted, kept_prior), **values,
    )  # fmt: skip


PIN = 1e-6
"""Weight [m per m or rad] of the polish's pull toward the first fit: the undetermined components
stay put (one solution, whatever the round-off), the determined ones are not held back."""

POLISH_GAIN = 1e-2
"""A polish is kept when it leaves less than this fraction of the fit's cost (see ``_fit``)."""

ROUND_OFF = 1e-12
"""RMS row [m] of a fit already exact: not polished (nothing is left to remove)."""


def _fit(model: ChainsModel, wide: ChainsModel, start: ChainsState, train: ChainsData, prior,
         level, iters, opts: Options):  # fmt: skip
    """Least squares; at ``complete``, polished from its result.

    The rank test at the nominal robot keeps the parameters that span what the touches
    see *there*; a robot off the nominal shows a little more (TALOS's arms, mirror images
    of each other, see one combination of the torso's placements less together than apart
    at the nominal geometry). A fit from the registration then leaves gaps of the order of
    the squared errors (1 um for 1 mm and 1 mrad). From the fitted robot, every joint
    placement component (``wide``, dependent ones included: Levenberg-Marquardt's damping
    keeps their steps small) is fitted again, the errors composed with the first fit's. The polish
    is kept only if it removes that residue (the cost falls below ``POLISH_GAIN`` of the
    fit's): on noisy touches, where it would only fit noise, it is dropped. One chain
    touching or measured by an instrument is not polished (its MDH directions span what it
    sees, as the single chain's fit has always assumed; a polish of 20,000 touches took
    minutes; many objects are fitted by block, :func:`~.contact_fit.block_fit`). ``auto`` (a
    selection, a prior), ``offsets`` and ``components`` (every component offered) are not
    polished, nor a fit already exact (RMS row under ``ROUND_OFF``: the undetermined
    components would only wander), and a polish that wanders to no robot (its chain models
    refused) is dropped; a robust loss (``opts.loss``, scale ``opts.noise_mm``) is not
    polished. A kept polish is finished on the data rows alone
    (:func:`~.solve.gauss_newton_finish`): its pull ``PIN`` leaves a residue (TALOS's head
    camera with both arms' touches: 1.8e-9 px, 4e-12 px finished).

    Returns:
        The fit, and whether it was polished.
    """
    data = train
    if blocky(model, start):
        fitted = block_fit(model, start, data, None, prior=prior, max_iterations=iters)
    else:
        fitted = fit(model, start, data, None, 1.0, prior=prior, max_iterations=iters,
                     loss=opts.loss, scale=opts.noise or 1e-3)  # fmt: skip
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
            wide, again, data, None, 1.0, prior=PIN * np.ones(wide.size()), max_iterations=iters
        )
    except InvalidArgumentError:  # it wandered along undetermined components to no robot
        return fitted, False
    if better.converged and float(better.f @ better.f) < POLISH_GAIN * cost:
        return gauss_newton_finish(better, data), True
    return fitted, False


def _assemble(
    start, fitted, model, prior, train, held, plane_of, selection, notes, clock, elastic
) -> ContactChainsCalibration:
    state: ChainsState = fitted.state.settled()
    refusal = None  # a held-out error worse than the registration's first, then the solver
    parts: list[ChainContacts | MeasuredChain | PixelChain] = []
    cov = None
    for c, chain in enumerate(state.chains):
        s, s0, d, h = state.states[c], start.states[c], train[c], held[c]
        if isinstance(s, MeasuredState | PixelTermState):
            if cov is None:
                cov = covariance(fitted.J, float(fitted.f @ fitted.f), prior)[0]
            own = fitted.model.own_columns(c)
            std = np.sqrt(np.diag(cov))[own]
            part = (
                pixel_result(chain, d, h, s0, s, fitted.x[own], std, c + 1)
                if isinstance(s, PixelTermState)
                else measured_part(chain, d, h, s0, s, std, c + 1, elastic[1], notes)
            )
            if h is not None:
                refusal = refusal or held_out_refusal(part.stats, chain, "errors")
            notes.extend(part.warnings() if isinstance(part, PixelChain) else ())
            parts.append(part)
            continue
        load, torque = elastic if c == 0 else (None, (None, None))
        torques = {id(d): torque[0], id(h): torque[1]}  # the fitted state's deflect

        def stat(st, rows, fitted=s, torques=torques):
            return gap_stats(st, rows.q, rows.ids, torques[id(rows)] if st is fitted else None)

        stats = part_stats(stat, s0, s, d, h)
        if h is not None:
            check_held_out_gaps(stats, h.source)
            refusal = refusal or held_out_refusal(stats, chain, "gaps")
        compliance = contact_elastic.fitted_compliance(s, s0, (d, h), stats, notes, load)
        objects = contact_objects(s, d, torque[0])
        parts.append(
            ChainContacts(
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
                s.frames,
                placed=objects,
                compliance=compliance,
                load=None if compliance is None else load,
                readings=() if compliance is None or d.readings is None else d.readings.names,
            )
        )
    joints = [name for c in state.chains for name in c.joint_names]
    shared = tuple(n for n in dict.fromkeys(joints) if joints.count(n) > 1)
    clock.append(time.perf_counter())
    stages = ("registration", "selection", "fit", "validation")
    return ContactChainsCalibration(
        chains=tuple(parts),
        placements=state.placements,
        shared=shared,
        planes=len(
            {p for p, s in zip(plane_of, state.states, strict=True) if isinstance(s, ContactState)}
        ),
        free=tuple(model.names()[model.fixed :]),
        unknowns=model.size(),
        selection=selection,
        refusal=refusal
        or (None if fitted.converged else f"the solver did not converge ({fitted.message})"),
        notes=tuple(notes),
        timings_ms={
            k: 1e3 * (b - a) for k, a, b in zip(stages, clock[:-1], clock[1:], strict=True)
        },
    )
