"""A joint fit's steps before its choice (:func:`register_contact_chains`).

The terms checked, their outliers set aside, each chain registered on the nominal robot.

:func:`~.contact_chains.calibrate_contact_chains` is :func:`register_contact_chains` then
:func:`~.contact_chains.fit_registered`; one chain measured by an instrument is registered
first by its outlier loop (:mod:`.chain_outliers`), whose proposals read the registration
of every row before any fit. :func:`determined_unknowns` is the same steps, then the rank.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import Any

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
from .contact_chains_model import ChainsData, ChainsState, on_models
from .contact_checks import subset
from .contact_choice import chains_model, flush_data, structural
from .contact_model import ContactState
from .contact_term import check_touches, contact_frame, contact_guess, split_contacts
from .instrument import instrument_groups, shared_frame
from .measured_options import compliance_torques
from .measured_term import (
    MeasuredState,
    check_measured,
    checked_measured,
    measured_kind,
    one_term_per_frame,
)
from .options import Options, check_run_options
from .outliers import Outlier
from .pixel_chain import PixelData, PixelPart, PixelTermState, check_pixels, pixel_parts
from .pixel_fit import checked_pixels
from .placements import Placements, zero_frames
from .solve import fit

__all__ = [
    "CHAIN_LEVELS",
    "Registered",
    "determined_unknowns",
    "register_contact_chains",
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


def _checked(
    chains, train, validate, guess, weight, held, notes, iterations, shared, noise=None, zeros=None
):
    """Each chain's touches checked as one chain's are (diagnosis, outliers, equations).

    The usual mistakes are diagnosed (the validation touches' too), outliers set aside (the
    held-out ones' too: ``held[c]`` replaced), the touches kept must determine the chain's
    objects and contact frame, and a chain the contact leaves finitely many postures is
    noted; a measured term's rows are checked as a single chain's (:func:`checked_measured`).
    ``guess``: the contact frame's and the markers' guesses (or None); ``noise``: the measured
    terms' instrument noise [mm] (or None); ``zeros``: :func:`~.placements.zero_frames` or None.

    Returns:
        Each chain's touches (rows) kept, each chain's outliers, and each term's
        registration on the nominal robot (a contact chain's: of the touches kept).
    """
    kept: list[ContactData | Measurements | PixelPart] = []
    dropped: list[tuple[Outlier, ...]] = []
    registered: list[MeasuredState | PixelTermState | ContactState] = []
    for c, (chain, d) in enumerate(zip(chains, train, strict=True)):
        v = None if validate is None else validate[c]
        zero = None if zeros is None or chain.model is not chains[0].model else zeros[c]
        if isinstance(d, PixelPart):
            state, bad, found, more, held[c] = checked_pixels(chain, d, held[c])
        elif isinstance(d, Measurements):
            out_m = 0 if held[c] is None else held[c].m
            rows, size = d.kind.rows_of(d.n_markers), len(measured_kind(d).names())
            what = f"unknowns of {chain.base_frame}'s placement and the markers"
            determined.check_equations(d.m, rows, size, what, d.source, held=out_m)
            state, bad, found, more, held[c] = checked_measured(
                chain, d, v, held[c], weight, iterations, guess[1], noise, zero
            )
            state = dataclasses.replace(state, instrument=shared)
        if isinstance(d, Measurements | PixelPart):
            if found:
                more.append(outliers.set_aside_note(found))
            d = d.subset(~bad) if bad.any() else d
        else:
            g = contact_guess(d.kind, guess[0], len(chains))
            state, bad, found, more = contact_checks.checked_registration(
                chain, from_chain(chain, zero=zero), d, v, g, weight
            )
            if found:
                more.append(outliers.set_aside_note(found, "touch(es)", "gap"))
                d = subset(d, ~bad)
            held[c] = contact_checks.held_out_set_aside(state, d, held[c], more)
            more += filter(None, [contact_checks.isolated_postures(chain, d, held[c])])
            what = f"unknowns of {chain.tool_frame}'s {d.kind.object_name}(s) and contact frame"
            out_m = 0 if held[c] is None else held[c].m
            rows, size = len(d.kind.row_names), state.frames.size
            determined.check_equations(d.m, rows, size, what, d.source, held=out_m, unit="touches")
        notes += [f"{chain.base_frame} -> {chain.tool_frame}: {n}" for n in more]
        kept.append(d)
        dropped.append(tuple(found))
        registered.append(state)
    return kept, dropped, registered


def _register(
    chains, train, measured, plane_of, notes, max_iterations, pose_weight=1.0, zeros=None
) -> ChainsState:
    """Each chain's registration on the nominal robot (a plane shared by chains: refined).

    ``measured``: each term's registration (``_checked``: a contact chain's objects and
    contact in closed form, a measured term's frames, a pixel term's camera); ``zeros``:
    the chains' frames at zero (:func:`~.placements.zero_frames`), or None.
    """
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

    The data are checked, outliers set aside and registered as
    :func:`~.contact_chains.calibrate_contact_chains` does (every row fitted: no holdout);
    the rank of the Jacobian of every row by every unknown (objects, contact frames,
    measuring frames, markers, and every joint placement component) at flush postures is
    what the data determine. Arguments as
    :func:`~.contact_chains.calibrate_contact_chains`'s.

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


@dataclasses.dataclass(frozen=True)
class Registered:
    """A calibration up to its registration (:func:`register_contact_chains`), to be fitted.

    The arguments and state :func:`fit_registered` continues from: the rows kept and held out,
    the outliers set aside, the notes so far, the load and compliance torques, the registered
    state ``start`` and the stage clock; the other fields are the arguments'.
    """

    chains: tuple[Chain, ...]
    level: str
    opts: Options
    train: list
    held: list
    validate: Sequence | None
    held_label: str | None
    dropped: list
    notes: list[str]
    plane_of: Sequence[int]
    load: Any
    torques: Any
    comp: Any
    start: ChainsState
    clock: list[float]
    max_iterations: int
    seed: int
    instrument: bool
    options: Options | None
    progress: Progress | None


def register_contact_chains(
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
) -> Registered:
    """:func:`~.contact_chains.calibrate_contact_chains` up to the registration.

    Its arguments, by name (checked there).

    The rows checked, their outliers set aside, each chain registered on the nominal robot:
    :func:`fit_registered` continues (the outlier loop reads the registration first).

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
    splits = [(d, None) if holdout == 0 else validation.split(d, holdout, seed)
              if isinstance(d, Measurements | PixelPart) else split_contacts(d, holdout, seed)
              for d in data]  # fmt: skip
    train = [s[0] for s in splits]
    given = validate or [None] * len(data)
    held = [v if v is not None else s[1] for s, v in zip(splits, given, strict=True)]
    plane_of = contact_checks.plane_groups(chains, data, shared_planes)
    plane_of = instrument_groups(plane_of, data, instrument)
    check_number(pose_weight, "pose_weight", 0.0, MAX_WEIGHT, above=True)
    notes: list[str] = []
    diagnosed = None if held_label == "holdout" else validate  # a holdout: with its data's
    zeros = zero_frames(tuple(chains))  # one walk: the registrations' models and the paths
    train, dropped, measured = _checked(
        chains, train, diagnosed, (guess, marker), w, held, notes, max_iterations, instrument,
        opts.noise_mm, zeros,
    )  # fmt: skip
    notes += filter(None, [contact_elastic.readings_note(load, train[0], held[0])])
    torques, comp = compliance_torques(chains, train, held, options, load)
    touches = sum(d.m for d in train)
    with phase(progress, f"calibrate: registration ({len(chains)} chains, {touches} touches)"):
        start = _register(
            chains, train, measured, plane_of, notes, max_iterations, pose_weight, zeros
        )
    clock.append(time.perf_counter())
    return Registered(
        tuple(chains), level, opts, train, held, validate, held_label, dropped, notes, plane_of,
        load, torques, comp, start, clock, max_iterations, seed, instrument, options, progress,
    )  # fmt: skip
