"""Calibration from flush contacts with one plane: registration, selection, fit, refusal.

The same steps as measured data (:mod:`calib.calibration.pipeline`), for touches recorded by
the joint encoders alone (:class:`~calib.measurements.contact_campaign.ContactData`):

1. rows set aside (``holdout``, within each plane, at least ``MIN_TOUCHES`` kept) or a
   validation campaign;
2. the registration: the plane and the contact frame's tilts fitted in closed form on the
   nominal robot (:func:`~calib.calibration.contact_registration.register_planes`);
3. the free robot parameters: those of joint rows 1..n of the parameter set that the touches
   determine beside the plane and the contact (pivoted QR with those 5 columns first), then
   for ``auto`` the cross-validated forward selection with a prior
   (:func:`~calib.calibration.selection.select`, the plane and contact as the fixed block);
4. least squares (:func:`~calib.calibration.solve.fit`);
5. refusal of a model whose held-out weighted RMS gap ``sqrt(z^2 + w^2 (roll^2 + pitch^2))``
   is worse than the registration's (the nominal robot with its own plane and contact).

With ``elastic=True`` the joint compliances are candidates too (``q' = q + c tau``), ``tau``
the gravity torques of the robot standing on the chain's base frame
(:mod:`calib.kinematics.standing`, the load split with a second foot as ``support`` says).
The URDF cannot hold them: the checks apply to the whole model (URDF and compliances), the
URDF alone is scored too (``train_urdf``, ``held_out_urdf``), and a note says so where it is
worse than the registration (use it only with its compliance file).

The base frame's and the tool frame's own rows are not fitted: the plane (any placement in
the base frame) and the contact frame (any tilt in the tool frame) take their visible part.
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..identification.contacts import CONTACT_TOL, PlaneContact, joint_offsets, project
from ..identification.identifiability import independent_columns, preference_order
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.mdh import MDHModel, frames_at_zero, from_chain, from_lines
from ..kinematics.robot import Chain
from ..kinematics.standing import StandingLoad, Support, standing_load
from ..measurements.contact_campaign import ContactData
from .contact_model import PLANE_COLUMNS, ContactModel, ContactState
from .contact_registration import MIN_TOUCHES, register_planes
from .contact_result import ContactCalibration, GapStats, gap_stats
from .options import Options
from .selection import Selection, select
from .solve import fit
from .weighting import BOUNDS, DEFAULT_WEIGHT

__all__ = [
    "WEIGHT_ROUNDS",
    "WORSE",
    "calibrate_contact_data",
    "calibrate_contacts",
    "contact_frame",
    "flush_postures",
    "split_contacts",
    "tilt_weight",
]


def contact_frame(contact) -> np.ndarray:
    """The contact frame ``(4, 4)`` in the tool frame from a 4x4, 3 or 6 numbers (m, rad).

    Six numbers are ``X Y Z RX RY RZ`` (a rotation vector); None is the tool frame.
    """
    from ..kinematics.so3 import rotation_matrix

    if contact is None:
        return np.eye(4)
    C = np.asarray(contact, dtype=float)
    if C.shape == (4, 4):
        if not np.allclose(C[:3, :3] @ C[:3, :3].T, np.eye(3), atol=1e-9):
            raise InvalidArgumentError("the contact frame must be a rigid transform (4, 4)")
        return C.copy()
    if C.shape not in ((3,), (6,)) or not np.all(np.isfinite(C)):
        raise InvalidArgumentError("the contact frame takes X Y Z [RX RY RZ] (m, rad)")
    T = np.eye(4)
    T[:3, 3] = C[:3]
    if C.shape == (6,):
        T[:3, :3] = rotation_matrix(C[3:])
    return T


def split_contacts(
    data: ContactData, holdout: float, seed: int
) -> tuple[ContactData, ContactData | None]:
    """Training and held-out touches: ``holdout`` of each plane's, seeded, >= MIN_TOUCHES kept."""
    if holdout <= 0:
        return data, None
    rng = np.random.default_rng([seed, 21])
    ids = np.array(data.ids)
    held = np.zeros(data.m, dtype=bool)
    for name in data.contacts:
        rows = np.flatnonzero(ids == name)
        out = min(round(holdout * len(rows)), len(rows) - MIN_TOUCHES)
        if out > 0:
            held[rng.permutation(rows)[:out]] = True
    if not held.any():
        raise DataError(data.source, f"too few touches to hold {holdout:g} of them out")
    return _subset(data, ~held), _subset(data, held)


def _subset(data: ContactData, rows: np.ndarray) -> ContactData:
    keep = np.flatnonzero(rows)
    return ContactData(
        data.joint_names,
        data.q[keep],
        tuple(data.ids[i] for i in keep),
        data.kind,
        data.source,
        None if data.rows is None else tuple(data.rows[i] for i in keep),
    )


def _check(chain, data, validate, opts: Options) -> None:
    if not isinstance(chain, Chain):
        raise InvalidArgumentError(f"contacts are calibrated on one Chain, got {chain!r:.60}")
    for d in (data, validate):
        if d is None:
            continue
        if not isinstance(d, ContactData):
            raise InvalidArgumentError(f"contact data must be ContactData, got {type(d).__name__}")
        if d.joint_names != chain.joint_names:
            raise DataError(d.source, "the touches' joints are not the chain's")
        if not isinstance(d.kind, PlaneContact):
            raise InvalidArgumentError(
                f"calibration from '{d.kind.label}' contacts is not available yet: plane only"
            )
        if len(d.contacts) != 1:
            raise InvalidArgumentError(
                f"{d.source}: one plane per calibration for now, got {len(d.contacts)}"
            )
    if validate is not None and opts.holdout > 0:
        raise InvalidArgumentError("give a validation file or a holdout fraction, not both")
    if opts.fix or opts.free or opts.loss != "linear":
        raise InvalidArgumentError("fix, free and robust losses are not available for contacts")


WEIGHT_ROUNDS = 5
"""Registrations of the tilt weight's estimate."""


def tilt_weight(R: np.ndarray, p: np.ndarray, ids, guess: np.ndarray) -> float:
    """Weight of the tilt rows [m/rad]: RMS height / RMS tilt of the registration, settled.

    Each round registers with the weight of the previous one (from ``DEFAULT_WEIGHT``); the
    result is clipped to ``BOUNDS``.
    """
    w = DEFAULT_WEIGHT
    for _ in range(WEIGHT_ROUNDS):
        r = register_planes(R, p, ids, guess, w).residuals
        tilt = float(np.sqrt(np.mean(r[:, 1:] ** 2)))
        if tilt <= 0:
            break
        w = float(np.clip(np.sqrt(np.mean(r[:, 0] ** 2)) / tilt, *BOUNDS))
    return w


def _register(
    nominal: MDHModel, data: ContactData, guess: np.ndarray, w: float | None
) -> ContactState:
    """The nominal robot with the plane and contact fitted in closed form."""
    kin = nominal.kinematics(data.q)
    if w is None:
        w = tilt_weight(kin.R[:, -1], kin.p[:, -1], data.ids, guess)
    reg = register_planes(kin.R[:, -1], kin.p[:, -1], data.ids, guess, w)
    P = reg.planes[0]
    return ContactState(nominal, reg.contact, P[:3, 2].copy(), float(P[:3, 2] @ P[:3, 3]), w)


def _candidates(nominal: MDHModel, level: str) -> ParameterSet:
    """The robot parameters a level offers: joint rows 1..n only, in preference order."""
    if level == "frames":
        return ParameterSet("none", ())
    if level == "offsets":
        return joint_offsets(nominal)
    pset = parameter_set(nominal, "paper" if level == "paper" else "complete")
    order = preference_order(nominal, pset)
    chosen = [pset.parameters[i] for i in order if 1 <= pset.parameters[i].row <= nominal.n]
    return ParameterSet(pset.label, tuple(chosen))


def _tangent(n: np.ndarray) -> np.ndarray:
    return np.linalg.svd(n[None, :])[2][1:].T


def flush_postures(start: ContactState, q: np.ndarray) -> np.ndarray:
    """Postures near ``q`` where the contact of ``start`` is exactly flush with its plane.

    The model re-expressed in the plane's frame with the contact as its tool, each posture
    Newton-projected onto the plane (:func:`~calib.identification.contacts.project`); those
    that do not reach it are dropped.
    """
    mdh, n = start.mdh, start.mdh.n
    T = frames_at_zero(mdh)
    Pinv = np.linalg.inv(start.plane())
    joints = Pinv @ T[1 : n + 1]
    model = from_lines(
        joints[:, :3, 3],
        joints[:, :3, 2],
        mdh.sigma[1 : n + 1],
        Pinv @ T[-1] @ start.contact,
        tuple(str(x) for x in mdh.joint_names[1 : n + 1]),
        sign=mdh.sign[1 : n + 1],
    )
    qf, gaps = project(model, PlaneContact(), q)
    return qf[gaps < CONTACT_TOL]


def _structural(
    wide: ContactModel, start: ContactState, train: ContactData, load: StandingLoad | None
) -> list[int]:
    """The columns the touches determine, from the Jacobian at flush postures near them.

    At the registration the contact is not quite flush, and the directions no flush contact
    can see (the scale without a prismatic joint, ...) have small columns a rank test would
    keep; at flush postures they vanish.
    """
    qf = flush_postures(start, train.q)
    if len(qf) < len(train.q):  # what could not be projected is judged at the data
        qf = np.concatenate([qf, train.q[len(qf) :]])
    flush = ContactData(train.joint_names, qf, train.ids, train.kind, train.source)
    torque = None if load is None or not wide.compliance else load.torques(qf)
    A = wide.jacobian(start, np.zeros(wide.size()), flush, torque).reshape(-1, wide.size())
    return independent_columns(A, list(range(A.shape[1])))[2]


def _choose(start, train, opts: Options, notes: list[str], load, torque):
    """The model (free parameters and compliances), the selection (auto), the prior weights."""
    offered = _candidates(start.mdh, opts.level)
    comp = tuple(range(start.mdh.n)) if load is not None else ()
    wide = ContactModel(offered, _tangent(start.normal), comp)
    J = wide.jacobian(start, np.zeros(wide.size()), train, torque)
    kept = _structural(wide, start, train, load)
    if kept[:PLANE_COLUMNS] != list(range(PLANE_COLUMNS)):
        raise DataError(train.source, "the touches do not determine the plane and the contact")
    columns = sorted(kept[PLANE_COLUMNS:])
    names = wide.names()
    if len(columns) < len(offered) + len(comp):
        notes.append(
            f"the touches determine {len(columns)} of the {len(offered) + len(comp)} "
            "parameters offered"
        )
    weights: dict[str, float] = {}
    selection: Selection | None = None
    if opts.level == "auto" and columns:
        cols = list(range(PLANE_COLUMNS)) + columns
        cand = tuple(names[c] for c in columns)
        selection, w = select(J[:, :, cols], start.residuals(train, torque), PLANE_COLUMNS, cand)
        weights = dict(zip(selection.kept, w, strict=True))
        columns = [c for c in columns if names[c] in weights]
    split = PLANE_COLUMNS + len(offered)
    params = tuple(offered.parameters[c - PLANE_COLUMNS] for c in columns if c < split)
    joints = tuple(comp[c - split] for c in columns if c >= split)
    model = ContactModel(ParameterSet("free", params), wide.tangent, joints)
    prior = None
    if any(weights.values()):
        prior = np.r_[np.zeros(PLANE_COLUMNS), [weights[k] for k in model.names()[PLANE_COLUMNS:]]]
    return model, selection, prior


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
) -> ContactCalibration:
    """Calibrate a chain from flush touches of one plane (see the module's text).

    Args:
        chain: The nominal chain (base: where the plane is expressed; tool: the contact's).
        data: The touches (:func:`~calib.measurements.contact_campaign.read_contacts`).
        contact: Guess of the contact frame in the tool frame: ``(4, 4)`` or ``X Y Z [RX RY
            RZ]`` [m, rad] (default: the tool frame).
        params: ``auto`` (default), ``frames`` (the registration only), ``offsets``,
            ``paper`` or ``complete``.
        validate: Touches of other postures to score the result on (never fitted).
        orientation_weight: Weight of the tilt rows [m/rad] (default: :func:`tilt_weight`).
        elastic: Fit joint compliances too, under the gravity torques of the robot standing on
            the chain's base frame (opt-in; the URDF cannot hold them).
        support: With ``elastic``: the load split with a second foot
            (:class:`~calib.kinematics.standing.Support`; default: the base foot carries all).
        max_iterations: Most residual evaluations of the solver.
        holdout: Fraction of each plane's touches set aside (seeded).
        seed: Seed of the holdout draw.

    Returns:
        The result: check ``accepted``.

    Raises:
        InvalidArgumentError: A bad argument, or what is not available yet.
        DataError: Touches that do not belong to the chain or determine too little.
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
    if support is not None and not isinstance(support, Support):
        raise InvalidArgumentError(f"support must be a Support, got {type(support).__name__}")
    if support is not None and not opts.elastic:
        raise InvalidArgumentError("support (the load split between feet) needs elastic=True")
    clock = [time.perf_counter()]
    guess = contact_frame(contact)
    w = None if orientation_weight is None else float(orientation_weight)
    train, held = split_contacts(data, opts.holdout, opts.seed)
    held = validate if validate is not None else held
    load = standing_load(chain, support) if opts.elastic else None
    torque = (
        None if load is None else load.torques(train.q),
        None if load is None or held is None else load.torques(held.q),
    )
    nominal = from_chain(chain)
    start = _register(nominal, train, guess, w)
    clock.append(time.perf_counter())
    notes: list[str] = []
    model, selection, prior = _choose(start, train, opts, notes, load, torque[0])
    clock.append(time.perf_counter())
    fitted = fit(
        model, start, train, torque[0], 1.0, prior=prior, max_iterations=opts.max_iterations
    )
    clock.append(time.perf_counter())
    return _assemble(chain, (train, held), torque, start, fitted, selection, notes, clock, load)


def calibrate_contact_data(
    robot,
    data: ContactData,
    *,
    marker=None,
    fix=(),
    free=(),
    loss="linear",
    noise_mm=None,
    **kwargs,
) -> ContactCalibration:
    """:func:`calibrate_contacts` for :func:`~calib.calibration.pipeline.calibrate`.

    ``marker`` is the contact frame's guess; ``fix``, ``free``, ``loss`` and ``noise_mm``
    are not available for contacts (an error unless left at their defaults).
    """
    if fix or free or loss != "linear" or noise_mm is not None:
        raise InvalidArgumentError(
            "fix, free, robust losses and noise_mm are not available for contacts"
        )
    return calibrate_contacts(robot, data, contact=marker, **kwargs)


def _assemble(chain, sets, torque, start, fitted, selection, notes, clock, load):
    train, held = sets
    state = fitted.state
    stats = {
        "train": gap_stats(state, train.q, torque[0]),
        "train_registration": gap_stats(start, train.q),
    }
    refusal = None if fitted.converged else f"the solver did not converge ({fitted.message})"
    if held is not None:
        stats["held_out"] = gap_stats(state, held.q, torque[1])
        stats["held_out_registration"] = gap_stats(start, held.q)
        if refusal is None and _worse(stats["held_out"], stats["held_out_registration"]):
            refusal = (
                "the calibrated model's held-out gaps are worse than the registration's "
                f"({stats['held_out'].weighted_mm:.3f} > "
                f"{stats['held_out_registration'].weighted_mm:.3f} mm weighted RMS)"
            )
    elastic = state.compliance is not None and bool(np.any(state.compliance))
    if elastic:
        _urdf_alone(state, start, (train, held), stats, notes)
    elif load is not None:
        notes.append("elastic: no joint compliance was kept; the URDF is the whole model")
    kin = state.mdh.kinematics(state.joints(train.q, torque[0]))
    centre = np.mean(kin.p[:, -1] + kin.R[:, -1] @ state.contact[:3, 3], axis=0)
    clock.append(time.perf_counter())
    stages = ("registration", "selection", "fit", "validation")
    timings = {s: 1e3 * (b - a) for s, a, b in zip(stages, clock[:-1], clock[1:], strict=True)}
    return ContactCalibration(
        chain=chain,
        nominal=start.mdh,
        calibrated=state.mdh,
        contact=state.contact,
        plane=state.plane(centre),
        plane_id=train.contacts[0],
        free=fitted.model.names()[PLANE_COLUMNS:],
        selection=selection,
        stats=stats,
        refusal=refusal,
        notes=tuple(notes),
        weight=state.weight,
        timings_ms=timings,
        compliance=state.compliance if elastic else None,
        load=load if elastic else None,
    )


def _urdf_alone(state, start, sets, stats, notes) -> None:
    """Score the URDF alone (compliance left out) and note where it is worse than registration."""
    rigid = dataclasses.replace(state, compliance=None)
    notes.append(
        "joint compliance was fitted: the calibrated URDF cannot hold it; it is written to the "
        "compliance file (apply it with calib predict or calib.load_calibrated)"
    )
    for label, key, d in (("the fitted", "train", sets[0]), ("held-out", "held_out", sets[1])):
        if d is None:
            continue
        stats[f"{key}_urdf"] = gap_stats(rigid, d.q)
        if _worse(stats[f"{key}_urdf"], stats[f"{key}_registration"]):
            notes.append(
                f"on {label} touches the calibrated URDF alone (without the fitted joint "
                f"compliance) is worse than the registration alone "
                f"({stats[f'{key}_urdf'].weighted_mm:.3f} > "
                f"{stats[f'{key}_registration'].weighted_mm:.3f} mm weighted RMS): use it only "
                "with its compliance file"
            )


WORSE = 1e-6
"""Relative excess of the held-out weighted RMS over the registration's that refuses a model
(the same model refitted differs by round-off)."""


def _worse(fitted: GapStats, registration: GapStats) -> bool:
    return fitted.weighted_mm > registration.weighted_mm * (1.0 + WORSE)
