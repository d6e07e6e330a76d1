"""The joint engine's model, chosen before its fit (:func:`choose`).

The directions a level offers, those the data determine at touching postures, ``auto``'s
selection; and the memory a contact term would need (:func:`check_selection_memory`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.checks import MAX_WORK_BYTES
from ..core.words import counted
from ..exceptions import DataError, InvalidArgumentError
from ..identification.contact_postures import in_frame, joint_offsets, project
from ..identification.contacts import CONTACT_TOL
from ..identification.identifiability import independent_columns
from ..identification.parameters import parameter_set
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain
from ..kinematics.standing import StandingLoad
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from ..measurements.postures import posture_groups
from .chain_counts import sampled
from .contact_checks import check_level_equations
from .contact_fit import block_structural, by_block
from .contact_model import ContactState
from .engine_model import ChainsData, ChainsModel, ChainsState, joint_motions
from .object_columns import ObjectColumns
from .pixel_chain import PixelPart, with_tool
from .placements import COMPONENTS, JointFrames, component_of, mdh_directions, offset_component
from .selection import Selection, select

__all__ = [
    "SELECTION_BYTES",
    "chains_model",
    "check_selection_memory",
    "choose",
    "flush_data",
    "structural",
    "touching_postures",
    "weakly_seen",
]


SELECTION_BYTES = (12_000, 330, 130)
"""Peak memory [B] of a contact calibration per touch, per touch and column of the dense
selection (``params auto``), and per touch and object column.
Measurements: docs/developers/performance.md#selection_bytes-choice"""


def check_selection_memory(chains, data, level: str, comp: int = 0) -> None:
    """Refuse, before any work, contact terms that would need over ``MAX_WORK_BYTES``.

    Raises:
        InvalidArgumentError: A touching term's estimate (:data:`SELECTION_BYTES`) over it.
    """
    per_touch, per_column, per_object = SELECTION_BYTES
    auto = level == "auto"
    for chain, d in zip(chains, data, strict=True):
        if not isinstance(d, ContactData):
            continue
        kind = d.kind
        objects = len(d.contacts) * len(kind.object_dofs)
        mdh = from_chain(chain)  # auto's candidates: the complete set's joint rows 1..n
        rows = sum(1 <= p.row <= mdh.n for p in parameter_set(mdh, "complete").parameters)
        dense = len(kind.contact_dofs) + rows + comp
        need = d.m * (per_touch + auto * dense * per_column + objects * per_object)
        if need <= MAX_WORK_BYTES:
            continue
        way = "fewer touches or " + f"{kind.object_name}s"
        if auto and d.m * (per_touch + objects * per_object) <= MAX_WORK_BYTES:
            way = f"give a level (params complete, paper, offsets or frames), or {way}"
        selected = f", {dense} other columns to select" if auto else ""
        raise InvalidArgumentError(
            f"{d.m} touches of {counted(len(d.contacts), kind.object_name + 's')} ({objects} of "
            f"their unknowns{selected}) would need about {need / 2**30:.3g} GB, calib allows "
            f"{MAX_WORK_BYTES / 2**30:g} GB: {way}"
        )


def touching_postures(start: ContactState, q: np.ndarray, ids) -> tuple[np.ndarray, np.ndarray]:
    """Postures near ``q`` where the contact of ``start`` holds on each touch's object.

    Returns the postures ``(m, n)`` (``q``'s where the projection failed) and which reached
    the contact ``(m,)``.
    """
    q = np.asarray(q, dtype=float)
    index = start.frames.index(ids)
    out, reached = q.copy(), np.zeros(len(q), dtype=bool)
    for k, F in enumerate(start.frames.objects):
        rows = np.flatnonzero(index == k)
        if not rows.size:
            continue
        qf, gaps = project(in_frame(start.mdh, F, start.contact), start.kind, q[rows])
        good = gaps < CONTACT_TOL
        out[rows[good]], reached[rows[good]] = qf[good], True
    return out, reached


def chains_model(
    state: ChainsState, plane_of, free, names, directions=None, comp=()
) -> ChainsModel:
    """The engine's model of a state: ``free`` of the directions ``names``, ``comp`` compliant."""
    p, c, kinds = tuple(plane_of), tuple(comp), tuple(s.kind for s in state.states)
    counts = tuple(len(s.frames.ids) if isinstance(s, ContactState) else 1 for s in state.states)
    return ChainsModel(p, len(set(p)), tuple(free), tuple(names), directions, kinds, counts, c)


def _offer_directions(
    start: ChainsState, level: str
) -> tuple[np.ndarray | None, tuple[str, ...], list]:
    """Directions a level offers: (directions or None for components, names, indices).

    Rationale: docs/developers/engine.md#_offer_directions
    """
    pl = start.placements
    if level == "frames":
        return None, pl.names(), []
    if level == "components":  # every component (a tree's complete): the rank keeps a basis
        return None, pl.names(), list(range(len(pl.names())))
    if level == "offsets":
        offsets = [
            6 * j + COMPONENTS.index(offset_component(pl.model, jid))
            for j, jid in enumerate(pl.ids)
        ]
        return None, _offset_names(start, offsets), offsets
    rows: list[np.ndarray] = []
    labels: list[tuple[str, Chain]] = []
    if level == "complete":
        branch = _branch_components(start)
        rows.extend(np.eye(6 * len(pl.joints))[branch])
        labels.extend((pl.names()[c], start.chains[0]) for c in branch)
    for chain, s in zip(start.chains, start.states, strict=True):
        mdh_set = "paper" if level == "paper" else "complete"
        D, more = with_tool(pl, chain, s, *mdh_directions(pl, chain, s.mdh, mdh_set))
        rows.extend(D)
        labels.extend((name, chain) for name in more)
    offered = np.array(rows).reshape(len(rows), -1)
    units = offered / np.linalg.norm(offered, axis=1, keepdims=True)  # every norm at once
    parallel = (~(np.abs(units @ units.T) <= 1.0 - 1e-12)).tolist()  # a zero row (NaN): parallel
    kept: list[int] = []
    for i, row in enumerate(parallel):
        if not any(row[k] for k in kept):  # parallel to none kept
            kept.append(i)
    return offered[kept], _unique([labels[i] for i in kept]), list(range(len(kept)))


def _branch_components(start: ChainsState) -> list[int]:
    """The components of the joints shared by chains and of their neighbours on a path.

    Rationale and measurements: docs/developers/engine.md#_branch_components
    """
    pl = start.placements
    paths = [list(pl.path(chain).columns) for chain in start.chains]
    seen = [j for path in paths for j in path]
    shared = {j for j in seen if seen.count(j) > 1}
    near = {
        j
        for path in paths
        for i, j in enumerate(path)
        if shared & {j, *path[max(i - 1, 0) : i + 2]}
    }
    return [6 * j + k for j in sorted(near) for k in range(6)]


def _offset_names(start: ChainsState, offsets: list[int]) -> tuple[str, ...]:
    """The components' names, each joint offset (``offsets``) as ``complete`` names it."""
    pl, chart = start.placements, dict[int | None, str]()
    for chain, s in zip(start.chains, start.states, strict=True):
        D, labels = mdh_directions(pl, chain, s.mdh, joint_offsets(s.mdh))
        chart = {component_of(d): label for d, label in zip(D, labels, strict=True)} | chart
    names = pl.names()
    return tuple(chart.get(c, names[c]) if c in offsets else names[c] for c in range(len(names)))


def _unique(labels: list[tuple[str, Chain]]) -> tuple[str, ...]:
    """Each direction's name, one that several chains give saying whose it is.

    ``torso_1_joint:d7@gripper_left_base_link`` (``@base->tool`` where chains share a tool).
    """
    out = []
    for name, chain in labels:
        same = [c for n, c in labels if n == name]
        tools = {c.tool_frame for c in same}
        own = (
            chain.tool_frame
            if len(tools) == len(same)
            else f"{chain.base_frame}->{chain.tool_frame}"
        )
        out.append(name if len(same) == 1 else f"{name}@{own}")
    return tuple(out)


def flush_data(start: ChainsState, train, load: StandingLoad | None) -> ChainsData:
    """Each chain's touches at flush postures near them (a measured term's rows as they are).

    Rationale: docs/developers/engine.md#flush_data
    """
    parts: list[ContactData | Measurements | PixelPart] = []
    for chain, s, d in zip(start.chains, start.states, train, strict=True):
        if not isinstance(s, ContactState):
            parts.append(d)
            continue
        q, reached = touching_postures(s, d.q, d.ids)  # the others: as recorded
        path = start.placements.path(chain)
        for _ in range(2):
            kin = start.placements.frames(chain, q)
            g = s.gaps(q, d.ids, None, kin) * s.row_weights()
            J = s.motion_rows(kin, d, *joint_motions(path, kin, list(range(chain.n))))
            q[reached] -= (np.linalg.pinv(J) @ g[..., None])[reached, :, 0]
        parts.append(dataclasses.replace(d, q=q))
    first = parts[0]
    torques = None
    if load is not None and isinstance(first, ContactData):
        torques = (load.torques(first.q, first.readings),)
    return ChainsData(tuple(parts), torques)


class AtStart:
    """A model's Jacobian at the registration (``x = 0``), made once for the same rows.

    The rank test and the selection share the Jacobian, the fit its kinematics too, and
    :func:`weakly_seen` the rank test's (the last two rows' are kept: touches are tested at
    flush postures, selected at their own). The arrays returned are shared: read only.
    """

    def __init__(self, wide: ChainsModel, start: ChainsState) -> None:
        self.wide, self.start = wide, start
        self._kin: tuple[ChainsData, tuple[JointFrames, ...]] | None = None
        self._last: list[tuple[ChainsData, np.ndarray]] = []  # the two last rows' (flush, data)

    def kinematics(self, data: ChainsData) -> tuple[JointFrames, ...]:
        """The registration's kinematics at the rows ``data``."""
        if self._kin is None or not same_rows(self._kin[0], data):
            self._kin = (data, self.start.kinematics(data))
        return self._kin[1]

    def __call__(self, data: ChainsData) -> np.ndarray:
        """The Jacobian ``(m, rows, size)`` at the rows ``data``."""
        for rows, J in self._last:
            if same_rows(rows, data):
                return J
        x = np.zeros(self.wide.size())
        state = self.wide.apply(self.start, x)  # the registration's geometry (x = 0)
        J = self.wide.jacobian(self.start, x, data, None, state, self.kinematics(data))
        self._last = [*self._last[-1:], (data, J)]
        return J


WEAKLY_SEEN = 0.05
"""Share of a fitted direction's rows left once the objects' and frames' columns take theirs,
under which :func:`weakly_seen` names it. Measurements: docs/developers/engine.md#weakly_seen"""


def weakly_seen(model: ChainsModel, at: AtStart, flush: ChainsData) -> dict[str, float]:
    """The fitted directions the always-free columns nearly span, each with the share left.

    The share: the norm of a direction's column at the registration (``flush`` rows) once
    projected off the objects', contact frames' and instrument frames' columns, over its
    norm. The columns are those of :func:`choose`'s Jacobian ``at`` (made once: the rank
    test's, where the rows are the same). None for a fit by block (no dense Jacobian).
    """
    wide, end = at.wide, model.fixed + len(model.free)
    if by_block(model, at.start) or end == model.fixed:
        return {}
    offered = {f: wide.fixed + k for k, f in enumerate(wide.free)}
    columns = [*range(model.fixed), *(offered[f] for f in model.free)]
    A = at(flush).reshape(-1, wide.size())[:, columns]
    U, s, _ = np.linalg.svd(A[:, : model.fixed], full_matrices=False)
    U = U[:, s > s[0] * 1e-10] if s.size else U
    names, out = model.names(), {}
    for c in range(model.fixed, end):
        column = A[:, c]
        share = np.linalg.norm(column - U @ (U.T @ column)) / np.linalg.norm(column)
        if share < WEAKLY_SEEN:
            out[names[c]] = float(share)
    return out


def same_rows(a: ChainsData, b: ChainsData) -> bool:
    """Whether ``a`` and ``b`` hold the very same parts and torques (the same objects)."""
    pairs = [(a.parts, b.parts), (a.torques or (), b.torques or ())]
    return (a.torques is None) == (b.torques is None) and all(
        len(x) == len(y) and all(u is v for u, v in zip(x, y, strict=True)) for x, y in pairs
    )


def structural(
    wide: ChainsModel, start: ChainsState, flush: ChainsData, at: AtStart | None = None
) -> list[int]:
    """The columns the touches determine, from the Jacobian at flush postures (``flush_data``)."""
    if by_block(wide, start):
        return block_structural(wide, start, flush)
    A = (at or AtStart(wide, start))(flush).reshape(-1, wide.size())
    return independent_columns(A, list(range(A.shape[1])))[2]


def choose(
    start: ChainsState,
    data: ChainsData,
    flush,
    plane_of,
    level: str,
    notes,
    comp=(),
    asked=None,
    generic=None,
    kept_out: list[int] | None = None,
):
    """The model, the start's Jacobians (:class:`AtStart`), ``auto``'s selection, the priors.

    The model's kinematics at ``data``: ``at.kinematics(data)`` (a fit by block: none).
    ``comp``: the joints whose compliance is offered; ``asked``: a measured chain's ``fix`` and
    ``free`` (:class:`~.measured_options.Asked`), or None; ``generic``: the generic
    configurations of terms measured by an instrument (:class:`~.chain_counts.Generic`), or
    None; ``kept_out``: filled with the columns the data determine, as ``notes`` with remarks.
    """
    train = list(data.parts)
    directions, names, offered = _offer_directions(start, level)
    forced: tuple[str, ...] = ()
    if asked is not None:
        directions, names, offered, forced = asked.offer(directions, names, offered)
    wide = chains_model(start, plane_of, offered, names, directions, comp)
    fixed, every = wide.fixed, len(offered) + len(comp)
    at = AtStart(wide, start)
    kept = structural(wide, start, flush, at) if every else list(range(fixed))
    if asked is not None:
        asked.check(wide, start, flush, kept)
    if generic is not None:
        allowed = generic.columns(wide)
        generic.check(wide, kept, allowed, flush, level)
        notes += [generic.note(wide, len(kept), allowed)] if len(kept) < len(allowed) else []
    elif sorted(kept[:fixed]) != list(range(fixed)):
        raise DataError(train[0].source, "the touches do not determine the planes and the contacts")
    columns = [c for c in kept if c >= fixed]
    if kept_out is not None:
        kept_out.extend(kept)
    if generic is None and len(columns) < every:
        what = "touches" if all(isinstance(s, ContactState) for s in start.states) else "data"
        notes.append(f"the {what} determine {len(columns)} of the {every} parameters offered")
    check_level_equations(train, fixed + len(columns), level)
    selection: Selection | None = None
    prior = None
    if level == "auto" and columns:
        selection, prior = _auto(wide, start, (data, at), columns, (generic, forced, notes))
        columns = [columns[k] for k in selection.index]  # by position: names may repeat
    split = fixed + len(offered)
    free_dirs = tuple(offered[c - fixed] for c in columns if c < split)
    model = wide.with_free(free_dirs, tuple(comp[c - split] for c in columns if c >= split))
    if prior is not None:  # the model's order: the directions, then the compliances
        order = [c for c in columns if c < split] + [c for c in columns if c >= split]
        prior = np.r_[np.zeros(fixed), prior[fixed:][[columns.index(c) for c in order]]]
    return model, at, selection, prior


def _auto(wide: ChainsModel, start: ChainsState, at_data: tuple, columns: list, asked: tuple):
    """``auto``'s selection among ``columns`` and its prior weights (None: all zero).

    ``at_data``: the data and the start's Jacobians (:class:`AtStart`); ``asked``: the
    generic configurations (or None), the names the user forced free, the notes to add to.
    """
    data, at = at_data
    generic, forced, notes = asked
    fixed = wide.fixed
    all_names = wide.names()
    cand_names = tuple(all_names[c] for c in columns)
    drawn = None if generic is None else generic.sample(fixed, len(columns), notes)
    data = sampled(data, drawn)
    J, objects, free = _selection_columns(wide, start, data, columns, at)
    groups = _postures(data) if generic is None else generic.groups(drawn)
    e = start.residuals(data, None, at.kinematics(data))
    seen = data.seen_rows(e.shape[1])  # a marker not seen: its rows 0 (no equation)
    e, measured = (e, None) if seen is None else (np.where(seen, e, 0.0), seen.sum(axis=1))
    keep = tuple(cand_names.index(n) for n in forced if n in cand_names)
    selection, weights = select(
        J, e, free, cand_names, keep, groups=groups, objects=objects, measured=measured
    )
    return selection, np.r_[np.zeros(fixed), weights] if np.any(weights) else None


def _postures(data: ChainsData) -> np.ndarray | None:
    """One chain touching: each touch's posture (a touch recorded again counts once)."""
    first = data.parts[0]
    if len(data.parts) != 1 or not isinstance(first, ContactData):
        return None
    return posture_groups(first.q, first.ids)


def _selection_columns(
    wide: ChainsModel, start: ChainsState, data: ChainsData, columns, at: AtStart
):
    """The selection's dense columns (the always-free ones, then ``columns``), and the rest.

    Returns them ``(m, rows, free + len(columns))``, the objects by block
    (:class:`~.object_columns.ObjectColumns`) or None, and the number of always-free dense
    columns.
    """
    x = np.zeros(wide.size())
    if not by_block(wide, start):
        return at(data)[:, :, list(range(wide.fixed)) + list(columns)], None, wide.fixed
    own, shared, index = wide.blocks(start, x, data)
    K, o = wide.object_blocks()
    cols = list(range(wide.fixed - K * o)) + [c - K * o for c in columns]
    return shared[:, :, cols], ObjectColumns(own, index, K), wide.fixed - K * o
