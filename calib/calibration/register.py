"""A joint fit's steps before its choice (:func:`register_contact_chains`).

A :class:`Run` checked, its held-out rows drawn, its outliers set aside, each chain
registered on the nominal robot; :func:`~.engine.fit_registered` continues.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..core.checks import MAX_OBJECTS, MAX_TOUCHES, MAX_WEIGHT, check_number, check_size
from ..core.progress import Progress, phase
from ..exceptions import DataError, InvalidArgumentError
from ..identification.contacts import FixedPoseContact
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain, check_chain
from ..kinematics.standing import Support
from ..measurements.contact_campaign import ContactData
from ..measurements.contact_objects import term_planes
from ..measurements.data import Measurements
from . import contact_checks, contact_elastic, validation
from .chain_registration import MeasuredState, held_markers
from .choice import chains_model, check_selection_memory, flush_data, structural
from .contact_model import ContactState
from .engine_model import ChainsData, ChainsState, on_models
from .instrument import shared_frame
from .measured_options import compliance_torques
from .measured_term import check_measured, checked_measured, one_term_per_frame
from .options import Options
from .outliers import Outlier
from .pixel_chain import PixelData, PixelPart, PixelTermState, check_pixels, pixel_parts
from .pixel_fit import checked_pixels
from .placements import Placements, zero_frames
from .solve import fit

__all__ = ["Registered", "Run", "determined_unknowns", "drawn", "register_contact_chains"]


@dataclasses.dataclass(frozen=True, eq=False)
class Run:
    """One run of the joint engine: :func:`~.engine.calibrate_contact_chains`'s args."""

    chains: Sequence[Chain]
    data: Sequence[ContactData | Measurements | PixelData]
    validate: Sequence[ContactData | Measurements | PixelData | None] | None = None
    options: Options = dataclasses.field(default_factory=Options)
    contact: Any = None
    marker: Any = None
    shared_planes: bool = False
    pose_weight: float = 1.0
    instrument: bool = False
    held_label: str | None = None
    support: Support | None = None
    progress: Progress | None = None
    known_planes: Any = None


def _check(run: Run) -> None:
    """The terms given as one robot's chains, each with data (and validation data) of its kind."""
    chains, data, validate, holdout = run.chains, run.data, run.validate, run.options.holdout
    if not isinstance(chains, Sequence) or not chains:
        raise InvalidArgumentError("give the chains as a non-empty list of Chain")
    for c in chains:
        check_chain(c, "each chain")
    if len({(c.urdf_resolved, tuple(c.model.names)) for c in chains}) > 1:
        raise InvalidArgumentError("the chains must be chains of one robot (one URDF)")
    pairs = [(c.base_frame, c.tool_frame) for c in chains]
    if len(set(pairs)) != len(pairs):
        raise InvalidArgumentError("a chain is given twice (same base and tool frames)")
    if not isinstance(data, Sequence) or len(data) != len(chains):
        raise InvalidArgumentError("give one set of touches per chain")
    if not run.instrument:
        one_term_per_frame(chains, data)
    if validate is not None and (
        not isinstance(validate, Sequence) or len(validate) != len(chains)
    ):
        raise InvalidArgumentError("give one validation set (or None) per chain")
    for c, d, v in zip(chains, data, validate or [None] * len(chains), strict=True):
        if isinstance(d, Measurements):
            check_measured(c, d, v, run.instrument, holdout)
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
            if not part.m:
                raise DataError(part.source, "no touches: an empty contact set")
            check_size(part.m, MAX_TOUCHES, "touches", part.source)
            check_size(len(part.contacts), MAX_OBJECTS, f"{part.id_column}s", part.source)
            if part.joint_names != c.joint_names:
                raise DataError(
                    part.source, f"the touches' joints are not those of {c.tool_frame}'s chain"
                )
            if type(part.kind) is not type(d.kind):
                raise InvalidArgumentError(
                    f"{part.source}: validation touches of kind '{part.kind.label}' for "
                    f"'{d.kind.label}' data"
                )
    if validate is not None and any(v is not None for v in validate) and holdout > 0:
        raise InvalidArgumentError("give validation touches or a holdout fraction, not both")
    for d, v in zip(data, validate or [None] * len(chains), strict=True):
        if v is not None and not isinstance(d, PixelData):
            validation.check_held_out(d, v)


def _holds(run: Run, train) -> list[bool]:
    """Which measured terms hold the marker coordinates no posture separates from their frame.

    Rationale: docs/developers/engine.md#_holds
    """
    if not run.instrument or len(run.chains) == 1:
        return [True] * len(run.chains)
    tools = [c for c, d in enumerate(train) if isinstance(d, Measurements)]
    turns = any(np.any(np.asarray(run.chains[c].sigma) == 0) for c in tools)  # a revolute joint
    still = not turns and all(
        len(held_markers(run.chains[c], from_chain(run.chains[c]))) == 3 for c in tools
    )
    return [still and c == tools[0] for c in range(len(run.chains))]


def _checked(run: Run, train, validate, guess, held, notes, zeros):
    """Each term's rows checked by its kind's checks (``held[c]`` replaced by its rows kept).

    Returns each chain's rows kept, its outliers and its registration on the nominal robot.
    """
    known = term_planes(run.chains, run.data, run.known_planes)
    kept: list[ContactData | Measurements | PixelPart] = []
    dropped: list[tuple[Outlier, ...]] = []
    registered: list[MeasuredState | PixelTermState | ContactState] = []
    chains, opts = run.chains, run.options
    weight = None if opts.orientation_weight is None else float(opts.orientation_weight)
    holds = _holds(run, train)
    for c, (chain, d) in enumerate(zip(chains, train, strict=True)):
        v = None if validate is None else validate[c]
        zero = zeros[c] if chain.model is chains[0].model else None
        if isinstance(d, PixelPart):
            state, d, found, more, held[c] = checked_pixels(chain, d, held[c])
        elif isinstance(d, Measurements):
            state, d, found, more, held[c] = checked_measured(
                chain, d, v, held[c], weight, opts, run.marker, zero, holds[c]
            )
            state = dataclasses.replace(state, instrument=run.instrument)
        else:
            loop = len(chains) > 1 and isinstance(d.kind, FixedPoseContact)  # a closed loop
            g = np.eye(4) if loop else guess  # (TALOS's soles): from its tool frame
            state, d, found, more, held[c] = contact_checks.checked_registration(
                chain, from_chain(chain, zero=zero), d, v, g, weight, held[c], known[c]
            )
        notes += [f"{chain.base_frame} -> {chain.tool_frame}: {n}" for n in more]
        kept.append(d)
        dropped.append(tuple(found))
        registered.append(state)
    return kept, dropped, registered


def _register(run: Run, train, measured, plane_of, notes, zeros) -> ChainsState:
    """The terms' registrations ``measured`` on the nominal robot (a plane shared: refined)."""
    chains, pose_weight = run.chains, run.pose_weight
    placements = Placements.of(tuple(chains), zeros)
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
        only_frames,
        start,
        ChainsData(tuple(train)),
        None,
        max_iterations=run.options.max_iterations,
    )
    if not refined.converged:
        raise DataError(
            train[0].source,
            f"the registration of the shared plane did not converge ({refined.message})",
        )
    given = [  # a plane given has no unknown of its own
        (p, not s.frames.kind.object_dofs)
        for p, s in zip(plane_of, states, strict=True)
        if isinstance(s, ContactState)
    ]
    for held, word in ((False, "fitted once"), (True, "given: held, the same for each")):
        planes = [p for p, h in given if h == held]
        if len(set(planes)) < len(planes):
            notes.append(f"a plane touched by several chains is {word} (shared planes)")
    return refined.state


def determined_unknowns(run: Run) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """What a joint fit of these terms would determine, and every unknown's name.

    The rank, at flush postures, of the run's rows (every row: no validation, no holdout,
    rigid) registered, by every unknown and joint placement component; the names determined
    are a basis, in the columns' order.
    """
    complete = dataclasses.replace(run.options, params="complete")  # its memory estimate
    r = register_contact_chains(dataclasses.replace(run, options=complete))
    names = r.start.placements.names()
    wide = chains_model(r.start, r.plane_of, range(len(names)), names)
    every = wide.names()
    kept = structural(wide, r.start, flush_data(r.start, r.train, None))
    return tuple(every[k] for k in sorted(kept)), every


@dataclasses.dataclass(frozen=True)
class Registered:
    """A run up to its registration, to be fitted (:func:`~.engine.fit_registered`)."""

    run: Run
    train: list
    held: list
    dropped: list
    notes: list[str]
    plane_of: Sequence[int]
    load: Any
    torques: Any
    comp: Any
    start: ChainsState
    clock: list[float]


def drawn(data: Sequence, holdout: float, seed: int) -> list[tuple]:
    """Each term's rows split into training and held-out rows (``(rows, None)``: none held).

    By posture (measurements, pixels) or by object (touches); seeded.
    """
    return [
        (d, None)
        if holdout == 0
        else validation.split(d, holdout, seed)
        if isinstance(d, Measurements | PixelPart)
        else contact_checks.split_contacts(d, holdout, seed)
        for d in data
    ]


def register_contact_chains(run: Run) -> Registered:
    """A run checked, held out, its outliers set aside, each chain registered.

    Raises:
        InvalidArgumentError: A bad argument.
        DataError: Touches that do not belong to their chain or determine too little.
    """
    chains, opts, holdout, seed = run.chains, run.options, run.options.holdout, run.options.seed
    _check(run)
    one_measured = len(chains) == 1 and isinstance(run.data[0], Measurements)  # its own elastic
    elastic = None if one_measured else opts.elastic  # (:func:`compliance_torques`)
    load = contact_elastic.term_load(chains, run.data, elastic, run.support)
    data = pixel_parts(chains, run.data)
    validate = run.validate and pixel_parts(chains, run.validate)
    check_selection_memory(chains, data, opts.level, 0 if load is None else chains[0].n)
    clock = [time.perf_counter()]
    if run.marker is not None and not any(isinstance(d, Measurements) for d in data):
        raise InvalidArgumentError("marker is for measured terms: no term here is measured")
    guess = contact_checks.contact_frame(run.contact)
    splits = drawn(data, holdout, seed)
    train = [s[0] for s in splits]
    given = validate or [None] * len(data)
    held = [v if v is not None else s[1] for s, v in zip(splits, given, strict=True)]
    plane_of = contact_checks.plane_groups(chains, data, run.shared_planes, run.instrument)
    check_number(run.pose_weight, "pose_weight", 0.0, MAX_WEIGHT, above=True)
    notes: list[str] = []
    diagnosed = None if run.held_label == "holdout" else validate  # a holdout: with its data's
    zeros = zero_frames(tuple(chains))  # one walk: the registrations' models and the paths
    train, dropped, measured = _checked(run, train, diagnosed, guess, held, notes, zeros)
    notes += filter(None, [contact_elastic.readings_note(load, train[0], held[0])])
    torques, comp = compliance_torques(chains, train, held, opts, load)
    touches = sum(d.m for d in train)
    with phase(run.progress, f"calibrate: registration ({len(chains)} chains, {touches} touches)"):
        start = _register(run, train, measured, plane_of, notes, zeros)
    clock.append(time.perf_counter())
    return Registered(run, train, held, dropped, notes, plane_of, load, torques, comp, start, clock)
