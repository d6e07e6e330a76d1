"""The model of a contact calibration, chosen before its fit.

The parameters a level offers, those the touches determine, the selection's columns (by
block with many objects), the robust proposals of outliers, and the memory a calibration
would need (refused up front beyond 2 GB).

Used by :mod:`calib.calibration.contact_pipeline`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.checks import MAX_WORK_BYTES
from ..exceptions import DataError, InvalidArgumentError
from ..identification.contact_postures import joint_offsets, project
from ..identification.contacts import CONTACT_TOL
from ..identification.identifiability import independent_columns, preference_order
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.mdh import MDHModel, frames_at_zero, from_lines
from ..kinematics.standing import StandingLoad
from ..measurements.contact_campaign import ContactData
from ..measurements.postures import posture_groups
from . import contact_checks, determined, outliers
from .contact_fit import block_structural, block_weighted_fit, by_block
from .contact_model import ContactModel, ContactState
from .object_columns import ObjectColumns
from .options import Options
from .selection import Selection, select

__all__ = [
    "SELECTION_BYTES",
    "check_selection_memory",
    "choose",
    "flush_postures",
    "level_candidates",
    "proposals",
    "selection_columns",
    "structural",
    "touching_postures",
]


SELECTION_BYTES = (12_000, 330, 130)
"""Peak memory [B] of a contact calibration per touch, per touch and column of the dense
selection (``params auto``: the contact's and the candidates'), and per touch and object
column (their rows in the fit's Jacobian, which the report keeps dense), with a margin of
a few %: fitted to the whole-process peaks of ``calib calibrate`` on TALOS sole to gripper
(``benchmarks/bench_scale.py``), 20,000 touches of one plane (62 columns to select: 650 MB)
and 2,000 touches of 500 planes (the same 62, and 1,500 of the planes: 438 MB)."""


def check_selection_memory(data: ContactData, nominal: MDHModel, level: str, comp: int) -> None:
    """Refuse, before any work, a calibration that would need more than 2 GB.

    Args:
        data: The touches.
        nominal: The chain's MDH model.
        level: The parameter level (``auto`` selects among dense columns).
        comp: Number of joint compliance columns.

    Raises:
        InvalidArgumentError: The estimate (:data:`SELECTION_BYTES`) exceeds
            ``MAX_WORK_BYTES``; says what to do.
    """
    kind = data.kind
    objects = len(data.contacts) * len(kind.object_dofs)
    dense = len(kind.contact_dofs) + len(level_candidates(nominal, "auto")) + comp
    per_touch, per_column, per_object = SELECTION_BYTES
    auto = level == "auto"
    need = data.m * (per_touch + auto * dense * per_column + objects * per_object)
    if need > MAX_WORK_BYTES:
        way = "fewer touches or " + f"{kind.object_name}s"
        if auto and data.m * (per_touch + objects * per_object) <= MAX_WORK_BYTES:
            way = f"give a level (params complete, paper, offsets or frames), or {way}"
        selected = f", {dense} other columns to select" if auto else ""
        raise InvalidArgumentError(
            f"{data.m} touches of {len(data.contacts)} {kind.object_name}(s) ({objects} of "
            f"their unknowns{selected}) would need about {need / 2**30:.3g} GB, calib allows "
            f"{MAX_WORK_BYTES / 2**30:g} GB: {way}"
        )


def level_candidates(nominal: MDHModel, level: str) -> ParameterSet:
    """The robot parameters a level offers: joint rows 1..n only, in preference order."""
    if level == "frames":
        return ParameterSet("none", ())
    if level == "offsets":
        return joint_offsets(nominal)
    pset = parameter_set(nominal, "paper" if level == "paper" else "complete")
    order = preference_order(nominal, pset)
    chosen = [pset.parameters[i] for i in order if 1 <= pset.parameters[i].row <= nominal.n]
    return ParameterSet(pset.label, tuple(chosen))


def _in_object(mdh: MDHModel, F: np.ndarray, C: np.ndarray) -> MDHModel:
    """The model in an object's frame ``F``, its tool the contact frame ``C``."""
    n = mdh.n
    T = frames_at_zero(mdh)
    Finv = np.linalg.inv(F)
    joints = Finv @ T[1 : n + 1]
    return from_lines(
        joints[:, :3, 3],
        joints[:, :3, 2],
        mdh.sigma[1 : n + 1],
        Finv @ T[-1] @ C,
        tuple(str(x) for x in mdh.joint_names[1 : n + 1]),
        sign=mdh.sign[1 : n + 1],
    )


def touching_postures(start: ContactState, q: np.ndarray, ids) -> tuple[np.ndarray, np.ndarray]:
    """Postures near ``q`` where the contact of ``start`` holds on each touch's object.

    Each object's touches are Newton-projected onto it, the model re-expressed in its frame
    with the contact as its tool (:func:`~calib.identification.contact_postures.project`).

    Returns:
        The postures ``(m, n)`` (the given one where the projection failed) and which
        reached the contact ``(m,)``.
    """
    q = np.asarray(q, dtype=float)
    index = start.frames.index(ids)
    out, reached = q.copy(), np.zeros(len(q), dtype=bool)
    for k, F in enumerate(start.frames.objects):
        rows = np.flatnonzero(index == k)
        if not rows.size:
            continue
        qf, gaps = project(_in_object(start.mdh, F, start.contact), start.kind, q[rows])
        good = gaps < CONTACT_TOL
        out[rows[good]], reached[rows[good]] = qf[good], True
    return out, reached


def flush_postures(start: ContactState, q: np.ndarray, ids=None) -> np.ndarray:
    """Postures near ``q`` where the contact of ``start`` holds (those that reach it)."""
    ids = [start.frames.ids[0]] * len(q) if ids is None else ids
    out, reached = touching_postures(start, q, ids)
    return out[reached]


def structural(
    wide: ContactModel, start: ContactState, train: ContactData, load: StandingLoad | None
) -> list[int]:
    """The columns the touches determine, from the Jacobian at touching postures near them.

    At the registration the contact does not quite hold, and the directions no contact can
    see (the scale without a prismatic joint, ...) have small columns a rank test would
    keep; where the contact holds they vanish.
    """
    qf, _ = touching_postures(start, train.q, train.ids)
    held = dataclasses.replace(train, q=qf)
    torque = None if load is None or not wide.compliance else load.torques(qf, train.readings)
    if by_block(wide):
        return block_structural(wide, start, held, torque)
    A = wide.jacobian(start, np.zeros(wide.size()), held, torque).reshape(-1, wide.size())
    return independent_columns(A, list(range(A.shape[1])))[2]


def choose(start: ContactState, train: ContactData, opts: Options, notes: list[str], load, torque):
    """The model (free parameters and compliances), the selection (auto), the prior weights."""
    offered = level_candidates(start.mdh, opts.level)
    comp = tuple(range(start.mdh.n)) if load is not None else ()
    wide = ContactModel(offered, start.frames, comp)
    fixed = wide.fixed
    kept = structural(wide, start, train, load)
    if kept[:fixed] != list(range(fixed)):
        what = start.kind.object_name
        raise DataError(train.source, f"the touches do not determine the {what}(s) and the contact")
    columns = sorted(kept[fixed:])
    if len(columns) < len(offered) + len(comp):
        notes.append(
            f"the touches determine {len(columns)} of the {len(offered) + len(comp)} "
            "parameters offered"
        )
    groups = posture_groups(train.q, train.ids)
    touches = int(groups.max(initial=-1)) + 1  # distinct: a repeated touch counts once
    equations = touches * start.kind.n_rows
    if opts.level != "auto":
        what = f"parameters of params '{opts.level}' (with the contact's unknowns)"
        determined.check_equations(touches, start.kind.n_rows, fixed + len(columns), what,
                                   train.source, unit="touches")  # fmt: skip
    elif fixed + len(columns) > equations:  # the selection's cross-validation needs spare rows
        columns = _fewer(columns, fixed + len(offered), max(0, equations - fixed - 1))
        notes.append(f"{touches} touches: params 'auto' chooses among {len(columns)} parameters")
    names = wide.names()
    weights: dict[str, float] = {}
    selection: Selection | None = None
    if opts.level == "auto" and columns:
        cand = tuple(names[c] for c in columns)
        J, objects = selection_columns(wide, start, train, torque, columns)
        residuals = start.residuals(train, torque)
        free = J.shape[2] - len(columns)
        selection, w = select(J, residuals, free, cand, groups=groups, objects=objects)
        weights = dict(zip(selection.kept, w, strict=True))
        columns = [c for c in columns if names[c] in weights]
    split = fixed + len(offered)
    params = tuple(offered.parameters[c - fixed] for c in columns if c < split)
    joints = tuple(comp[c - split] for c in columns if c >= split)
    model = ContactModel(ParameterSet("free", params), start.frames, joints)
    prior = None
    if any(weights.values()):
        prior = np.r_[np.zeros(fixed), [weights[k] for k in model.names()[fixed:]]]
    return model, selection, prior


def selection_columns(wide: ContactModel, start: ContactState, train, torque, columns):
    """The selection's columns: the objects' and the contact's, then the candidates.

    With many objects (:func:`~.contact_fit.by_block`) the objects' columns come apart, by
    block (:class:`~.object_columns.ObjectColumns`), the rest dense; else all dense.
    """
    x = np.zeros(wide.size())
    if not by_block(wide):
        J = wide.jacobian(start, x, train, torque)
        return J[:, :, list(range(wide.fixed)) + columns], None
    own, shared, index = wide.blocks(start, x, train, torque)
    split = wide.size() - shared.shape[2]
    cols = list(range(wide.fixed - split)) + [c - split for c in columns]
    return shared[:, :, cols], ObjectColumns(own, index, len(wide.frames.ids))


def _fewer(columns: list[int], split: int, keep: int) -> list[int]:
    """``keep`` of the candidate columns: the least preferred robot parameters dropped first.

    Robot parameters (columns below ``split``) come in preference order; the compliances
    (from ``split``) are dropped only when no robot parameter is left.
    """
    params = [c for c in columns if c < split]
    comp = [c for c in columns if c >= split]
    cut = max(0, len(columns) - keep)
    params = params[: max(0, len(params) - cut)]
    return (params + comp)[:keep]


def proposals(start: ContactState, train: ContactData, opts: Options) -> np.ndarray:
    """Touches a robust fit of every offered parameter, linearised, finds outlying.

    With many objects (:func:`~.contact_fit.by_block`) the fit goes by block.
    """
    offered = level_candidates(start.mdh, "complete")
    wide = ContactModel(offered, start.frames, ())
    rows = train.rows or tuple(range(1, train.m + 1))
    residual = start.residuals(train)
    how: dict = {}
    if by_block(wide):
        how["fit"] = block_weighted_fit(wide, start, train, residual)
        J = None
    else:
        J = wide.jacobian(start, np.zeros(wide.size()), train)
        kept = independent_columns(J.reshape(-1, J.shape[2]), list(range(J.shape[2])))[2]
        J = J[:, :, sorted(kept)]
    return outliers.robust_proposals(
        J, residual, lambda g: contact_checks.gap_errors(g, start.kind), None, rows, **how
    )
