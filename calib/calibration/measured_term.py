"""A measured term: a frame (on the robot, or an instrument outside it) measures a chain's tool.

A head camera measuring the hand, or a laser tracker: the chain runs from the measuring frame
(its base) to the tool. Its own unknowns are registered on the nominal robot
(:mod:`.chain_registration`), then refined with the joint placements the terms share.
"""

from __future__ import annotations

import dataclasses

import pinocchio as pin

from ..core.words import counted
from ..exceptions import CalibError, DataError, InvalidArgumentError
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain
from ..kinematics.urdf_export import base_joint, read_urdf_source
from ..measurements.data import Measurements
from ..measurements.postures import count
from . import chain_registration, determined, outliers, term_checks, validation, weighting
from .chain_registration import MeasuredState, Seen, held_markers, held_note
from .measured_options import marker_guess
from .model import measured_kind
from .options import Options
from .residuals import ResidualStats
from .solve import unconverged
from .weighting import DEFAULT_WEIGHT

__all__ = ["check_measured", "checked_measured", "measuring_joint", "one_term_per_frame", "unseen"]


def measuring_joint(chain: Chain) -> str:
    """The fixed joint that places the chain's base frame (the measuring frame) on the robot.

    Raises:
        InvalidArgumentError: No fixed joint fixes the base frame to a link.
    """
    _, root = read_urdf_source(chain)
    try:
        return base_joint(root, chain).get("name", "")
    except CalibError:
        frame = chain.model.frames[chain.base_id]
        placed = chain.model.frames[frame.parentFrame]
        if frame.type == pin.FrameType.JOINT:
            where = f"the frame of the moving joint {frame.name}"
        elif placed.type == pin.FrameType.JOINT:
            where = f"the link of the moving joint {placed.name}"
        else:
            where = "the robot's root link"
        raise InvalidArgumentError(
            f"a measured term's base frame '{chain.base_frame}' is {where}, not fixed to a link "
            f"by a fixed joint: measure from a frame fixed on the robot (a head camera's), "
            f"or calibrate an instrument outside it with calib.calibrate(chain, measurements)"
        ) from None


def check_measured(
    chain: Chain, data: Measurements, held, instrument: bool = False, holdout: float = 0.0
) -> None:
    """A measured term's data: its chain's joints, one tool, held-out rows of its kind.

    The postures left once ``holdout`` of them are set aside must determine the frame and
    markers; ``instrument``: its base frame need not be on the robot.

    Raises:
        InvalidArgumentError: The base frame not on the robot, held rows of another kind or tool.
        DataError: Joints not the chain's, or too few postures.
    """
    if not instrument:
        measuring_joint(chain)
    for part in (data, held) if held is not None else (data,):
        if not isinstance(part, Measurements):
            raise InvalidArgumentError(
                f"{chain.base_frame} -> {chain.tool_frame}: validation rows must be "
                f"Measurements like its data, got {type(part).__name__}"
            )
        if part.joint_names != chain.joint_names:
            raise DataError(
                part.source, f"the measurements' joints are not those of {chain.tool_frame}'s chain"
            )
        if part.tool is not None and set(part.tool) != {chain.tool_frame}:
            raise InvalidArgumentError(
                f"{part.source}: a measured term measures its chain's tool "
                f"'{chain.tool_frame}' only, got rows of {', '.join(sorted(set(part.tool)))}"
            )
        if measured_kind(part) != measured_kind(data):
            raise InvalidArgumentError(
                f"{part.source}: validation rows of another kind than the term's "
                f"({measured_kind(part).label}, {counted(part.n_markers, 'markers')} against "
                f"{measured_kind(data).label}, {data.n_markers})"
            )
    postures = count(data.q, data.tool)
    out = round(holdout * postures)
    kind = measured_kind(data)
    seen = determined.seen_equations(data, kind.rows, True)  # the points seen: their share
    kept = None if seen is None else seen * (postures - out) // postures
    determined.check_frames(kind, postures - out, data.source, held=out, equations=kept)


def checked_measured(
    chain: Chain, data: Measurements, validate, held, weight, opts: Options, marker, zero, hold
):
    """A measured term's rows checked as every kind's are (:func:`~.term_checks.checked`).

    ``weight`` [m/rad] None: estimated first; ``opts``: the run's (its iterations and noise);
    ``marker``: the markers' guess; ``zero``: the chain's zero frames, if made (or None);
    ``hold``: hold the coordinates of :func:`~.chain_registration.held_markers` (not a tree's
    tools: another tool may determine their shared frame).

    Returns:
        Its registered state, rows kept, outliers, notes and held-out rows without their
        outliers (or None), as every kind's checks return them.
    """
    what = f"unknowns of {chain.base_frame}'s placement and the markers"
    out = 0 if held is None else held.m
    kind = measured_kind(data)
    equations = determined.seen_equations(data, kind.rows)
    determined.check_frames(kind, data.m, data.source, what, held=out, equations=equations)
    guess = marker_guess(marker, data.n_markers)
    nominal = from_chain(chain, zero=zero)
    pinned = held_markers(chain, nominal) if hold else ()
    at = chain_registration.registrations(nominal, data, guess, opts, pinned)
    if weight is None:  # estimated from the registration (poses)
        weight = DEFAULT_WEIGHT
        if data.quaternion is not None:
            weight = weighting.estimate_weight(
                lambda w: at(w).state.inner.residuals(data, None, at(w).kin),
                weighting.pose_angles(data.n_markers),
            )
    opts = dataclasses.replace(opts, orientation_weight=weight)
    steps = chain_registration.Rows(chain, nominal, data, guess, opts, at, hold=pinned)
    validated = chain_registration.validation_steps(steps, validate)
    registered, notes = term_checks.checked(steps, validated)
    if stopped := unconverged(registered.state, "the registration"):
        raise DataError(data.source, stopped)
    reg, kept, kin = registered.state.state.inner, registered.kept, steps.register().kin
    notes = [held_note(pinned, guess), *notes] if pinned else notes
    rows = [*([kept] if kept is data else []), *([] if held is None else [held])]
    kins = [*([kin] if kept is data else []), *([] if held is None else [reg.kinematics(held.q)])]
    seen = Seen(reg.mdh, tuple(d.q for d in rows), tuple(kins))  # the nominal robot's frames
    state = MeasuredState(reg, float(weight), seen=seen, held=pinned)
    aside = held if held is None else _held_out(state, kept, held, notes, opts.noise)
    found = registered.found
    return state, kept, found, notes + ([outliers.set_aside_note(found)] if found else []), aside


def _held_out(state: MeasuredState, kept, held: Measurements, notes: list[str], noise):
    """The held-out rows without their outliers, checked (``notes`` appended; ``noise`` [m])."""
    reg, k, at = state.inner, held.n_markers, state.frames_at
    fitted, errors = (reg.residuals(d, None, at(d)) for d in (kept, held))
    aside = term_checks.held_out(
        outliers.point_errors(fitted, k),
        outliers.point_errors(errors, k),
        held,
        term_checks.file_lines(held),
        notes,
        noise,
    )
    other = errors if aside is held else reg.residuals(aside, None, at(aside))
    stats = (ResidualStats.of(fitted, k), ResidualStats.of(other, k))
    validation.check_held_out_errors(stats[0].position_rms, stats[1].position_rms, aside.source)
    return aside


def unseen(states: tuple) -> tuple:
    """The states without the registration's frames (they would double a result's memory)."""
    return tuple(
        dataclasses.replace(s, seen=None) if isinstance(s, MeasuredState) and s.seen else s
        for s in states
    )


def one_term_per_frame(chains, data) -> None:
    """Refuse two measured terms of one measuring frame (the URDF holds one placement of it)."""
    measuring = [
        c.base_frame for c, d in zip(chains, data, strict=True) if isinstance(d, Measurements)
    ]
    if shared := sorted({f for f in measuring if measuring.count(f) > 1}):
        raise InvalidArgumentError(
            f"two measured terms measure from '{shared[0]}': one fit takes one measured term per "
            "measuring frame (fit the other tool's rows apart)"
        )
