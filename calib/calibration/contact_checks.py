"""A contact term's registration, checks, holdout and guess: mistakes, outliers, refusal.

Rationale: docs/developers/engine.md#contact_checks
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial

import numpy as np

from ..core.words import counted, noun
from ..exceptions import DataError, InvalidArgumentError
from ..identification.contacts import PlaneContact
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..kinematics.so3 import rotation_matrix
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from ..measurements.pixels import MAX_TARGET_DISTANCE
from ..measurements.postures import count as count_postures
from ..measurements.postures import posture_groups
from . import determined, diagnosis, outliers, term_checks, validation
from .contact_model import ContactFrames, ContactState
from .contact_registration import MIN_TOUCHES, register_contacts
from .pixel_chain import PixelPart
from .solve import condition
from .term_checks import Aside
from .weighting import DEFAULT_WEIGHT, estimate_weight

__all__ = [
    "FEW_POSTURES",
    "check_level_equations",
    "checked_registration",
    "contact_frame",
    "contact_objects",
    "enough_touches",
    "few_postures",
    "held_out_refusal",
    "length_errors",
    "plane_groups",
    "rank_refusal",
    "registration",
    "split_contacts",
    "subset",
]


WEIGHT_ROUNDS = 5
"""Registrations of the angle weight's estimate (all of them: no tolerance).
Rationale and measurements: docs/developers/engine.md#weight_rounds"""


def subset(data: ContactData, keep: np.ndarray) -> ContactData:
    """The touches of a boolean mask (or of indices)."""
    rows = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep)
    return dataclasses.replace(
        data,
        q=data.q[rows],
        ids=tuple(data.ids[i] for i in rows),
        rows=None if data.rows is None else tuple(data.rows[i] for i in rows),
        readings=None if data.readings is None else data.readings.take(rows),
    )


POSTURE_TOL = 1e-2
"""Postures whose joints agree within this [rad or m] (angles modulo a turn) are one posture."""


def _isolated_postures(chain: Chain, train: ContactData, held: ContactData | None) -> str | None:
    """A note when the contact leaves the chain finitely many postures (None otherwise)."""
    kind = train.kind
    if chain.n > kind.n_rows:
        return None
    q = train.q if held is None else np.vstack([train.q, held.q])
    turning = chain.sigma == 0
    parts = np.hstack([np.cos(q[:, turning]), np.sin(q[:, turning]), q[:, ~turning]])
    groups = posture_groups(parts, tol=POSTURE_TOL)
    again = int(np.isin(groups[train.m :], groups[: train.m]).sum())
    text = (
        f"a {chain.n}-joint chain holding a {kind.label} contact ({kind.n_rows} conditions) has "
        f"finitely many postures: the touches sit at {groups.max() + 1} distinct postures"
    )
    if held is not None:
        text += f", and {again} of the {held.m} held-out touches repeat a fitted one"
    return text + ": the model is checked at those postures only"


def registration(
    nominal: MDHModel, data: ContactData, guess: np.ndarray, weight: float | None, first=None
) -> ContactState:
    """The nominal robot with the objects and the contact frame registered at ``weight``.

    ``weight`` [m/rad] None: estimated; ``first``: the registration at ``DEFAULT_WEIGHT``.
    """
    kin = nominal.kinematics(data.q)
    R, p = kin.R[:, -1], kin.p[:, -1]

    def at(w: float) -> ContactFrames:
        if first is not None and w == DEFAULT_WEIGHT:
            return first
        return register_contacts(data.kind, R, p, data.ids, guess, w, data.source)

    def gaps(w: float) -> np.ndarray:
        frames = at(w)
        return frames.gaps(R, p, frames.index(data.ids))

    angle = np.array(data.kind.angular)
    w = weight if weight is not None else estimate_weight(gaps, angle, WEIGHT_ROUNDS, 0.0)
    return ContactState(nominal, at(w), w)


def length_errors(state: ContactState, data: ContactData, torque=None) -> outliers.Errors:
    """Each touch's length gap [m] and angle gap [rad] (None without angle rows): norms."""
    g = state.gaps(data.q, data.ids, torque)
    angle = np.array(state.kind.angular)
    rot = np.linalg.norm(g[:, angle], axis=1) if angle.any() else None
    dims = (int(np.sum(~angle)), int(np.sum(angle)))
    return outliers.Errors(np.linalg.norm(g[:, ~angle], axis=1), rot, dims)


_WORDS = diagnosis.Words(
    "touches", "touch", "gap", check="the touches, the chain and the contact frame's guess"
)


def enough_touches(data: ContactData):
    """Whether an outlier mask leaves every object ``MIN_TOUCHES`` touches."""
    ids = np.array(data.ids)

    def allowed(bad: np.ndarray) -> bool:
        return all(np.sum(ids[~bad] == k) >= MIN_TOUCHES for k in data.contacts)

    return allowed


@dataclass(frozen=True, eq=False)
class _Touches:
    """A contact chain's steps on one set of touches (:class:`~.term_checks.Steps`)."""

    chain: Chain
    nominal: MDHModel
    rows: ContactData
    guess: np.ndarray

    diagnose_first = False

    def register(self) -> ContactState:
        """The registration of every touch at the default weight."""
        return registration(self.nominal, self.rows, self.guess, DEFAULT_WEIGHT)

    def set_aside(self, state: ContactState) -> Aside[ContactData, ContactState]:
        """The registration without the outlier touches, until stable (:mod:`.outliers`)."""
        nominal, data, guess = self.nominal, self.rows, self.guess

        def refit(keep: np.ndarray) -> ContactState:
            if keep.all():
                return state
            return registration(nominal, subset(data, keep), guess, DEFAULT_WEIGHT)

        rows = term_checks.file_lines(data)
        state, bad, found = outliers.until_stable(
            refit, lambda s: length_errors(s, data), None, rows, allowed=enough_touches(data)
        )
        return Aside(state, bad, subset(data, ~bad) if bad.any() else data, tuple(found))

    def diagnose(self, rows: ContactData, state: ContactState) -> list[str]:
        """The usual mistakes of the touches kept (``state``: their registration)."""

        def gap(d) -> float:  # d: the touches, or a corrected copy
            s = registration(self.nominal, d, self.guess, DEFAULT_WEIGHT)
            return float(np.sqrt(np.mean(length_errors(s, d)[0] ** 2)))

        first = float(np.sqrt(np.mean(length_errors(state, rows)[0] ** 2)))
        return diagnosis.explain(rows, self.chain, gap, first, None, _WORDS)


def _registrable(data: ContactData) -> bool:
    """Enough touches of every object, and equations, to register them on their own."""
    kind = data.kind
    unknowns = len(data.contacts) * len(kind.object_dofs) + len(kind.contact_dofs)
    return enough_touches(data)(np.zeros(data.m, dtype=bool)) and data.m * kind.n_rows > unknowns


def checked_registration(
    chain, nominal: MDHModel, train: ContactData, validate, guess, weight: float | None, held=None
):
    """Outliers set aside, diagnosis, registration: :func:`~.measured_term.checked_measured`'s.

    Raises:
        DataError: A held-out touch of an object the training touches do not touch, or too
            few touches.
    """
    checks = []
    if validate is not None and _registrable(validate):
        checks.append((_Touches(chain, nominal, validate, guess), validate.source))
    aside, notes = term_checks.checked(_Touches(chain, nominal, train, guess), checks)
    kept, found, words = aside.kept, list(aside.found), ("touches", "gap")
    start = registration(nominal, kept, guess, weight, aside.state.frames)
    notes += [outliers.set_aside_note(found, *words)] if found else []
    if held is not None:
        start.frames.index(held.ids, held.source)  # every held-out object was fitted
        fitted, errors = (length_errors(start, d) for d in (kept, held))
        rows, cut = term_checks.file_lines(held), partial(subset, held)
        held = term_checks.held_out(fitted, errors, held, rows, cut, notes, None, words)
    notes += filter(None, [_isolated_postures(chain, kept, held)])
    objects = noun(len(kept.contacts), f"{kept.kind.object_name}s")
    what = f"unknowns of {chain.tool_frame}'s {objects} and contact frame"
    rows_each, out = len(kept.kind.row_names), 0 if held is None else held.m
    determined.check_equations(
        kept.m, rows_each, start.frames.size, what, kept.source, held=out, unit="touches"
    )
    return start, kept, found, notes, held


def held_out_refusal(stats, chain: Chain, what: str) -> str | None:
    """Why a term's held-out errors refuse the model (worse than the registration's), or None."""
    got, base = stats["held_out"].weighted_mm, stats["held_out_registration"].weighted_mm
    if validation.worse(got, base, 1e-3):
        return (
            f"the calibrated model's held-out {what} on {chain.base_frame} -> "
            f"{chain.tool_frame} are worse than the registration's ({got:.3f} > "
            f"{base:.3f} mm weighted RMS)"
        )
    return None


FEW_POSTURES = 8
"""Fewest postures a held-out verdict rests on without a note.
Rationale: docs/developers/engine.md#few_postures"""


def few_postures(data, what: str) -> str | None:
    """A note where ``data`` hold under FEW_POSTURES postures; ``what``: the text's start."""
    n = count_postures(data.q, data.ids if isinstance(data, ContactData) else None)
    if n >= FEW_POSTURES:
        return None
    return (
        f"{data.source}: {what} {counted(n, 'postures')}, under {FEW_POSTURES}: an RMS over n "
        f"postures is known to about 1/sqrt(2n) of itself (+-{100 / np.sqrt(2 * n):.0f}% here)"
    )


def rank_refusal(J: np.ndarray, fixed: int) -> str | None:
    """Why a fit whose data rows ``J`` (past ``fixed`` columns) are rank-deficient is refused.

    Rationale and measurements: docs/developers/engine.md#rank_refusal
    """
    if condition(J[:, fixed:]) < 1 / validation.RANK_TOL:
        return None
    return (
        f"the data do not determine the {J.shape[1] - fixed} fitted parameters (rank-deficient "
        "Jacobian at the solution): measure in more varied postures or fit fewer parameters"
    )


def plane_groups(chains, data, shared: bool, instrument: bool = False) -> tuple[int, ...]:
    """Index of each chain's object: one per chain, or shared by base frame and plane id."""
    several = [d for d in data if isinstance(d, ContactData) and len(d.contacts) != 1]
    if shared and several:
        raise InvalidArgumentError(
            f"shared planes: each chain touches one object, {several[0].source} has "
            f"{len(several[0].contacts)}"
        )
    keys: list[tuple] = []
    for k, (c, d) in enumerate(zip(chains, data, strict=True)):
        if isinstance(d, PixelPart):
            keys.append(("camera", d.data.camera.name))
        elif instrument and isinstance(d, Measurements):
            keys.append(("instrument",))
        elif shared and isinstance(d.kind, PlaneContact):
            keys.append((c.base_frame, d.contacts[0]))
        else:
            keys.append((k,))
    planes = [k for k in keys if len(k) == 2 and k[0] != "camera"]
    if shared and len(set(planes)) == len(planes):
        raise InvalidArgumentError(
            "shared planes: no two chains touch one plane (same plane id) from one base frame"
        )
    index = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    return tuple(index[k] for k in keys)


def check_level_equations(train, unknowns: int, level: str) -> None:
    """DataError unless one chain's distinct touches give more equations than a level's unknowns."""
    if level == "auto" or len(train) != 1 or not isinstance(train[0], ContactData):
        return
    d = train[0]
    what = f"parameters of params '{level}' (with the contact's unknowns)"
    touches = count_postures(d.q, d.ids)
    determined.check_equations(touches, d.kind.n_rows, unknowns, what, d.source, unit="touches")


def contact_frame(contact) -> np.ndarray:
    """The contact frame ``(4, 4)`` in the tool frame from a 4x4, ``X Y Z [RX RY RZ]`` or None.

    InvalidArgumentError: beyond ``MAX_TARGET_DISTANCE`` (mm?) or a turn (degrees?).
    """
    if contact is None:
        return np.eye(4)
    try:
        C = np.asarray(contact, dtype=float)
    except (TypeError, ValueError):
        raise InvalidArgumentError("the contact frame takes X Y Z [RX RY RZ] (m, rad)") from None
    if C.shape == (4, 4):
        if not np.allclose(C[:3, :3] @ C[:3, :3].T, np.eye(3), atol=1e-9):
            raise InvalidArgumentError("the contact frame must be a rigid transform (4, 4)")
        T = C.copy()
    elif C.shape not in ((3,), (6,)) or not np.all(np.isfinite(C)):
        raise InvalidArgumentError("the contact frame takes X Y Z [RX RY RZ] (m, rad)")
    else:
        T = np.eye(4)
        T[:3, 3] = C[:3]
        if C.shape == (6,):
            if np.max(np.abs(C[3:])) > 2 * np.pi:
                raise InvalidArgumentError(
                    f"the contact frame's RX RY RZ are radians: {np.max(np.abs(C[3:])):g} is "
                    "more than a turn (degrees?)"
                )
            T[:3, :3] = rotation_matrix(C[3:])
    far = float(np.max(np.abs(T[:3, 3])))
    if far > MAX_TARGET_DISTANCE:
        raise InvalidArgumentError(
            f"the contact frame's X Y Z are metres: {far:g} m from the tool frame is more than "
            f"{MAX_TARGET_DISTANCE:g} m (millimetres? {far:g} mm is {far / 1000:g} m)"
        )
    return T


def split_contacts(
    data: ContactData, holdout: float, seed: int
) -> tuple[ContactData, ContactData | None]:
    """Training and held-out touches: ``holdout`` of each object's, seeded, >= MIN_TOUCHES kept."""
    rng = np.random.default_rng([seed, 21])
    ids = np.array(data.ids)
    groups = posture_groups(data.q, data.ids)  # a touch repeated is held out whole
    held = np.zeros(data.m, dtype=bool)
    for name in data.contacts:
        touches = np.unique(groups[ids == name])  # in order of first appearance
        out = min(round(holdout * len(touches)), len(touches) - MIN_TOUCHES)
        if out > 0:
            held[np.isin(groups, touches[rng.permutation(len(touches))[:out]])] = True
    if not held.any():
        raise DataError(data.source, f"too few touches to hold {holdout:g} of them out")
    return subset(data, ~held), subset(data, held)


def contact_objects(state: ContactState, train: ContactData, torque=None) -> dict[str, np.ndarray]:
    """The objects by id; a plane's origin at its touches' contact points, projected."""
    kin = state.kinematics(train.q, torque)
    frames = state.frames.centred(kin.R[:, -1], kin.p[:, -1], state.frames.index(train.ids))
    return {k: frames.objects[i].copy() for i, k in enumerate(frames.ids)}
