"""A contact term's registration, checks, holdout and guess: mistakes, outliers, refusal.

Rationale: docs/developers/engine.md#contact_checks, docs/developers/engine.md#register_contacts
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.words import counted, noun
from ..exceptions import ContactGeometryError, DataError, InvalidArgumentError
from ..identification.contacts import (
    Contact,
    FixedPointContact,
    FixedPoseContact,
    PlaneContact,
    PlanePointContact,
    known_plane,
)
from ..kinematics.mdh import MDHModel, from_chain
from ..kinematics.robot import Chain
from ..kinematics.so3 import rotation_matrix
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from ..measurements.pixels import MAX_TARGET_DISTANCE
from ..measurements.postures import count as count_postures
from ..measurements.postures import posture_groups
from . import determined, diagnosis, outliers, term_checks, validation
from .contact_blocks import BlockSystem, block_lstsq, dense
from .contact_model import ContactFrames, ContactState, plane_frames, row_weights
from .pixel_chain import PixelPart
from .registration import nearest_rotation
from .solve import condition
from .term_checks import Aside
from .weighting import DEFAULT_WEIGHT, estimate_weight

__all__ = [
    "FEW_POSTURES",
    "MIN_TOUCHES",
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
    "register_contacts",
    "registration",
    "split_contacts",
]

MIN_TOUCHES = 3  # fewest touches of one plane, point or pose
ITERATIONS = 50  # most Gauss-Newton steps
STEP_TOLERANCE = 1e-13  # largest parameter step [m or rad] at which Gauss-Newton stops
CONDITION_LIMIT = 1e-9  # smallest singular value accepted, relative to the largest
MIN_SPREAD = 1e-6  # smallest RMS spread [rad] of the tool's orientations about any axis (a tip)
WEIGHT_ROUNDS = 5  # the angle weight's registrations: docs/developers/engine.md#weight_rounds
POSTURE_TOL = 1e-2  # [rad or m]: postures whose joints agree within it (modulo a turn) are one
FEW_POSTURES = 8  # fewest postures of a held-out verdict: docs/developers/engine.md#few_postures
KNOWN_PLANE_OFF = (0.05, 0.1)  # farthest [m], most tilted [rad] a plane given from its touches


def _groups(ids: Sequence[str]) -> tuple[tuple[str, ...], np.ndarray]:
    """The distinct ids in order of appearance and each touch's index among them."""
    names = tuple(dict.fromkeys(str(i) for i in ids))
    index = np.array([names.index(str(i)) for i in ids], dtype=int)
    counts = np.bincount(index, minlength=len(names))
    for name, count in zip(names, counts, strict=True):
        if count < MIN_TOUCHES:
            raise ContactGeometryError(
                f"'{name}' has {counted(count, 'touches')}: at least {MIN_TOUCHES} are needed "
                "to fit it"
            )
    return names, index


def _tilt_to(b: np.ndarray) -> np.ndarray:
    """Rotation vector about an axis orthogonal to z that takes e_z to the unit vector b."""
    axis = np.array([-b[1], b[0], 0.0])
    s = np.linalg.norm(axis)
    return np.zeros(2) if s < 1e-300 else (axis * np.arctan2(s, b[2]) / s)[:2]


def _point_normals(x: np.ndarray, index: np.ndarray, up: np.ndarray) -> np.ndarray:
    """Each plane's normal through its contact points ``x``, on the side of ``up`` ``(K, 3)``."""
    normals = []
    for k, u in enumerate(up):
        centred = x[index == k] - x[index == k].mean(axis=0)
        n = np.linalg.svd(centred, full_matrices=False)[2][-1]
        normals.append(n if n @ u >= 0 else -n)
    return np.array(normals)


def refine(
    frames: ContactFrames,
    rotations: np.ndarray,
    positions: np.ndarray,
    index: np.ndarray,
    weight: float = DEFAULT_WEIGHT,
) -> ContactFrames:
    """The frames at the least-squares minimum of the kind's weighted gap (Gauss-Newton).

    The tool's ``rotations`` ``(m, 3, 3)`` and ``positions`` ``(m, 3)`` [m] in the base frame
    held; ``index``: each touch's object ``(m,)``; ``weight``: the angle rows' [m/rad].
    ContactGeometryError where the touches do not fix the unknowns.
    """
    w = row_weights(frames.kind, weight)
    x = np.zeros(frames.size)
    K = len(frames.ids)
    for _ in range(ITERATIONS):
        cur = frames.moved(x)
        R, p = cur.relative(rotations, positions, index)
        r = frames.kind.residual(R, p) * w
        Jo, Jc = cur.parts(R, p, index, x, w)
        sol = block_lstsq(BlockSystem(Jo, Jc, r, index, K))
        if not sol.smallest > CONDITION_LIMIT * sol.largest:
            names = frames.names()  # the unknowns of the undetermined directions
            found = determined.ill_posed(dense(Jo, Jc, index, K).reshape(-1, frames.size), names)
            found = [d for d in found if d.condition >= 1 / CONDITION_LIMIT]
            named = [n for n in names if any(n in d.names for d in found)]
            which = f" (they cannot separate {', '.join(named)})" if named else ""
            objects = noun(len(frames.ids), f"{frames.kind.object_name}s")
            raise ContactGeometryError(
                f"the touches do not fix the {objects} and the contact frame"
                f"{which}: touch at several orientations, or at spots that span each "
                f"{frames.kind.object_name}"
            )
        step = np.r_[sol.objects.ravel(), sol.shared]
        x = x + step
        if np.max(np.abs(step)) < STEP_TOLERANCE:
            break
    return frames.moved(x)


def _planes(kind, R, p, guess, index, names, weight) -> ContactFrames:
    """Flush touches: the chordal fit of the normals, or the contact points' planes."""
    K = len(names)
    M = np.stack([np.sum(np.swapaxes(R[index == k], 1, 2), axis=0) for k in range(K)])
    U = np.linalg.svd(np.concatenate(list(M), axis=1), full_matrices=False)[0]
    z0 = guess[:3, 2]
    a = U[:, 0] if U[:, 0] @ z0 >= 0 else -U[:, 0]
    x = p + R @ guess[:3, 3]
    up = np.array([(R[index == k] @ z0).sum(axis=0) for k in range(K)])
    candidates = []
    for normals in (np.einsum("kji,j->ki", M, a), _point_normals(x, index, up)):
        normals = normals / np.linalg.norm(normals, axis=1, keepdims=True)
        ak = np.einsum("kij,kj->i", M, normals)
        ak = ak / np.linalg.norm(ak)
        heights = np.array([np.mean(x[index == k] @ normals[k]) for k in range(K)])
        C = guess.copy()
        C[:3, :3] = guess[:3, :3] @ rotation_matrix(np.array([*_tilt_to(guess[:3, :3].T @ ak), 0]))
        planes = plane_frames(normals, heights, p + R @ C[:3, 3], index)
        frames = ContactFrames(kind, C, planes, names)
        cost = np.sum((frames.gaps(R, p, index) * row_weights(kind, weight)) ** 2)
        candidates.append((float(cost), frames))
    return min(candidates, key=lambda c: c[0])[1]


def _plane_points(kind, R, p, guess, index, names, weight) -> ContactFrames:
    """A tip's touches: each plane through the tip's points at the guessed tip."""
    x = p + R @ guess[:3, 3]
    normals = _point_normals(x, index, np.tile([0.0, 0.0, 1.0], (len(names), 1)))
    heights = [float(np.mean(x[index == k] @ n)) for k, n in enumerate(normals)]
    return ContactFrames(kind, guess, plane_frames(normals, np.array(heights), x, index), names)


def _points(kind, R, p, guess, index, names, weight) -> ContactFrames:
    """A tip at fixed points: the tip and the points by linear least squares."""
    K = len(names)
    count = np.bincount(index, minlength=K)[:, None]
    Rbar = np.zeros((K, 3, 3))
    np.add.at(Rbar, index, R)
    pbar = np.zeros((K, 3))
    np.add.at(pbar, index, p)
    Rbar, pbar = Rbar / count[:, :, None], pbar / count
    A = (R - Rbar[index]).reshape(-1, 3)
    tip, _, _, s = np.linalg.lstsq(A, -(p - pbar[index]).ravel(), rcond=None)
    if s[-1] < MIN_SPREAD * np.sqrt(len(p)):
        raise ContactGeometryError(
            "the touches do not fix the tip: touch each point at orientations about several axes"
        )
    C = guess.copy()
    C[:3, 3] = tip
    points = np.tile(np.eye(4), (K, 1, 1))
    points[:, :3, 3] = pbar + Rbar @ tip
    return ContactFrames(kind, C, points, names)


def _poses(kind, R, p, C, index, names, weight) -> ContactFrames:
    """Fixed poses: the mean position, the chordal mean rotation (the contact kept)."""
    Q = R @ C[:3, :3]
    x = p + R @ C[:3, 3]
    poses = np.tile(np.eye(4), (len(names), 1, 1))
    for k in range(len(names)):
        poses[k, :3, :3] = nearest_rotation(Q[index == k].sum(axis=0))
        poses[k, :3, 3] = x[index == k].mean(axis=0)
    return ContactFrames(kind, C, poses, names)


_Start = Callable[..., ContactFrames]

_STARTS: dict[type, tuple[_Start, bool]] = {
    PlaneContact: (_planes, True),
    PlanePointContact: (_plane_points, False),
    FixedPointContact: (_points, False),
    FixedPoseContact: (_poses, False),
}
"""Each kind's closed form, and whether its refinement weighs the angle rows by the weight
given (a plane-point has none; a pose's rotation is its rows' mean whatever their weight)."""


def register_contacts(
    kind: Contact,
    rotations: np.ndarray,
    positions: np.ndarray,
    ids: Sequence[str],
    contact: np.ndarray,
    weight: float = DEFAULT_WEIGHT,
    source: str | None = None,
) -> ContactFrames:
    """The objects and the contact frame registered from the tool's placements (nominal model).

    ``rotations`` ``(m, 3, 3)``, ``positions`` ``(m, 3)`` [m]: the tool's in the base frame;
    ``ids``: each touch's object; ``contact``: the contact frame's guess in the tool frame
    ``(4, 4)`` (a fixed pose's and a tip's rotation kept); ``weight`` [m/rad] (1 mrad counts
    as ``weight`` mm); ``source``: the touches' file, which the errors name first (or None).

    Raises:
        ContactGeometryError: Fewer than ``MIN_TOUCHES`` touches of an object, or a geometry
            that fixes nothing (one orientation and spots on a line for a plane; one
            orientation, or rotations about one axis only, for a tip).
        InvalidArgumentError: A weight that is not positive.
    """
    start, weighted = _STARTS[type(kind)]
    R, p, guess = (np.asarray(a, dtype=float) for a in (rotations, positions, contact))
    try:
        names, index = _groups(ids)
        frames = start(kind, R, p, guess, index, names, weight)
        if isinstance(kind, FixedPointContact):
            return frames  # the closed form is the least squares
        frames = refine(frames, R, p, index, weight if weighted else DEFAULT_WEIGHT)
    except ContactGeometryError as exc:
        if source is None:
            raise
        raise ContactGeometryError(f"{source}: {exc}") from None
    return frames.centred(R, p, index)


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
    """The nominal robot, objects and contact frame registered (``weight`` None: estimated)."""
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
    "touches",
    "touch",
    "gap",
    check="the touches, the chain and the contact frame's guess",
    ends=("base frame", "contact frame"),
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
            return registration(nominal, data.subset(keep), guess, DEFAULT_WEIGHT)

        rows = term_checks.file_lines(data)
        state, bad, found = outliers.until_stable(
            refit, lambda s: length_errors(s, data), None, rows, allowed=enough_touches(data)
        )
        return Aside(state, bad, data.subset(~bad) if bad.any() else data, tuple(found))

    def diagnose(self, rows: ContactData, state: ContactState) -> list[str]:
        """The usual mistakes of the touches kept (``state``: their registration)."""

        def gap(d, nominal=self.nominal) -> float:  # d: the touches, or a corrected copy
            s = registration(nominal, d, self.guess, DEFAULT_WEIGHT)
            return float(np.sqrt(np.mean(length_errors(s, d)[0] ** 2)))

        def on(longer: Chain):  # the touches' registration on another chain
            return lambda d: gap(d, from_chain(longer))

        first = float(np.sqrt(np.mean(length_errors(state, rows)[0] ** 2)))
        return diagnosis.explain(rows, self.chain, gap, first, None, _WORDS, other=on)


def _registrable(data: ContactData) -> bool:
    """Enough touches of every object, and equations, to register them on their own."""
    kind = data.kind
    unknowns = len(data.contacts) * len(kind.object_dofs) + len(kind.contact_dofs)
    return enough_touches(data)(np.zeros(data.m, dtype=bool)) and data.m * kind.n_rows > unknowns


def _held_planes(state: ContactState, data: ContactData, known: dict) -> ContactState:
    """The registration on planes given (``known``, by id): the contact frame refined alone."""
    kin = state.kinematics(data.q)
    R, p = kin.R[:, -1], kin.p[:, -1]
    planes = np.array([known[i] for i in state.frames.ids])
    for name, given, fitted in zip(state.frames.ids, planes, state.frames.objects, strict=True):
        tilt = np.arccos(np.clip(given[:3, 2] @ fitted[:3, 2], -1.0, 1.0))
        off = abs(given[:3, 2] @ (fitted[:3, 3] - given[:3, 3]))
        if off > KNOWN_PLANE_OFF[0] or tilt > KNOWN_PLANE_OFF[1]:
            raise DataError(
                data.source,
                f"the touches put plane '{name}' {off:.3g} m and {np.degrees(tilt):.3g} deg "
                f"from where it is given: is it given in the chain's base frame, in metres?",
            )
    frames = ContactFrames(known_plane(state.kind), state.contact, planes, state.frames.ids)
    index = frames.index(data.ids, data.source)
    try:
        frames = refine(frames, R, p, index, state.weight)
    except ContactGeometryError as exc:
        raise ContactGeometryError(f"{data.source}: {exc}") from None
    return ContactState(state.mdh, frames.centred(R, p, index), state.weight, state.compliance)


def checked_registration(
    chain,
    nominal: MDHModel,
    train: ContactData,
    validate,
    guess,
    weight: float | None,
    held=None,
    known: dict | None = None,
):
    """Outliers set aside, diagnosis, registration: :func:`~.measured_term.checked_measured`'s.

    ``known``: the planes given, by id (every object of the touches): held, not fitted.

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
    if known:
        start = _held_planes(start, kept, known)
        given = f"{noun(len(known), 'planes')} {', '.join(repr(k) for k in known)}"
        notes.append(f"{given} given: held, the contact frame's height fitted instead")
    notes += [outliers.set_aside_note(found, *words)] if found else []
    if held is not None:
        start.frames.index(held.ids, held.source)  # every held-out object was fitted
        fitted, errors = (length_errors(start, d) for d in (kept, held))
        rows = term_checks.file_lines(held)
        held = term_checks.held_out(fitted, errors, held, rows, notes, None, words)
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

    None when they are of full rank: the condition of their unit-norm columns
    (:func:`~.solve.condition`) under 1 / ``validation.RANK_TOL``.

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
    return data.subset(~held), data.subset(held)


def contact_objects(state: ContactState, train: ContactData, torque=None) -> dict[str, np.ndarray]:
    """The objects by id; a plane's origin at its touches' contact points, projected."""
    kin = state.kinematics(train.q, torque)
    frames = state.frames.centred(kin.R[:, -1], kin.p[:, -1], state.frames.index(train.ids))
    return {k: frames.objects[i].copy() for i, k in enumerate(frames.ids)}
