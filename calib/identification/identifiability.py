"""Identifiable (base) parameters by QR decomposition, regrouping and completeness."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.checks import check_count, check_work, joint_positions, shown
from ..core.choices import DEFAULT_CONFIGS, DEFAULT_MEASURE, DEFAULT_SET
from ..exceptions import InvalidArgumentError, warn_user
from ..kinematics.mdh import MDHModel, from_chain
from ..kinematics.mimic import MimicJoint
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree, load_robot
from ..kinematics.tree_model import TreeMDH, from_tree
from .base_columns import (
    checked_selection,
    identify_base,
    independent_columns,
    numerical_rank,
    pivoted_diagonal,
    preference_order,
    select_by_rank,
    select_independent,
)
from .contact_postures import contact_configurations
from .contacts import Contact
from .jacobian import complete_jacobian, identification_jacobian
from .kinds import kind_of
from .measures import MeasureKind, Measurement
from .parameters import Kind, Parameter, ParameterSet, joint_of, parameter_set
from .rank_notes import missing_errors, rank_notes
from .theory import axes_through_point, per_tool_theory, theory_of
from .tree_jacobian import tree_complete_jacobian, tree_jacobian, tree_parameters

REGROUP_TOL = 1e-8
"""Regrouping coefficients smaller than this (in absolute value) are printed as zero."""


class RankWarning(UserWarning):
    """The observation matrix is too small, or its rank gap too weak, to trust the rank."""


@dataclass(frozen=True, eq=False)
class Identifiability:
    """Result of the identifiability analysis of one chain and measurement set-up.

    Attributes:
        robot: Robot name.
        base_frame: Frame -1.
        tool_frame: Frame n+1.
        mdh: The nominal MDH model.
        measurement: What is measured.
        params: The standard parameter set analysed.
        n_configs: Number of random configurations m.
        seed: Seed of the configurations.
        n_rows: Rows r of the observation matrix.
        diag: ``|R_ii|`` of the pivoted QR, non-increasing.
        tolerance: ``tau = r eps |R_11|``.
        base: Base parameters kept, in the order of preference.
        others: Standard parameters not kept (regrouped or zero), in set order.
        zero: Parameters with no effect (zero columns).
        B: Regrouping matrix: base value = kept + B @ others, shape (b, len(others)).
        n_complete: Rank of the complete reference error model.
        n_theory: 4R + 2P + 6 (pose) or + 3 (position), or None.
        theory_note: Why ``n_theory`` is None, in a few words (empty where it is a count).
        on_axes: Revolute joints whose axis passes through the measured point.
        missing: One sentence per error direction the set cannot represent.
        warnings: Reasons not to trust the rank.
        per_tool: For a tree, each tool's chain alone: its name and theoretical count (the
            tree's count is lower where tools share joints: see :func:`!tree_theoretical_count`).
        snapped: URDF round-off removed before the analysis (by :func:`~calib.analyze`), one
            ``name: value -> snapped`` string per changed parameter.
        timings_ms: Time of each stage [ms].
        mimic: The chain's mimic joints (set by :func:`~calib.analyze`): the offset of each one's
            mimic expression, named ``offset<k>`` after its row k, is one parameter with its
            joint offset (theta_k or r_k) and regroups with it.
    """

    robot: str
    base_frame: str
    tool_frame: str
    mdh: MDHModel | TreeMDH
    measurement: MeasureKind
    params: ParameterSet
    n_configs: int
    seed: int
    n_rows: int
    diag: np.ndarray
    tolerance: float
    base: tuple[str, ...]
    others: tuple[str, ...]
    zero: tuple[str, ...]
    B: np.ndarray
    n_complete: int
    n_theory: int | None
    on_axes: tuple[int, ...]
    missing: tuple[str, ...]
    warnings: tuple[str, ...]
    snapped: tuple[str, ...] = ()
    timings_ms: dict[str, float] = field(default_factory=dict)
    per_tool: tuple[tuple[str, int | None], ...] = ()
    mimic: tuple[MimicJoint, ...] = ()
    theory_note: str = ""

    def __repr__(self) -> str:
        """One line (the arrays are in the attributes, the full text in :meth:`summary`)."""
        return (
            f"<Identifiability {self.robot}: {self.base_frame} -> {self.tool_frame}, measure "
            f"{self.measurement.label}, {self.params.label} set, {self.n_base} of "
            f"{self.n_standard} identifiable>"
        )

    @property
    def n_standard(self) -> int:
        """Number of standard parameters."""
        return len(self.params)

    @property
    def n_base(self) -> int:
        """Number of base (identifiable) parameters, the rank."""
        return len(self.base)

    @property
    def tool_frames(self) -> tuple[str, ...]:
        """The tool frames, one for a chain, several for a tree."""
        return getattr(self.mdh, "tool_frames", (self.tool_frame,))

    @property
    def on_last_axis(self) -> bool:
        """The measured point lies on the last joint axis (of some tool, for a tree)."""
        return any(int(self.mdh.antecedent[t]) in self.on_axes for t in self.mdh.tool_rows)

    @property
    def missing_parameters(self) -> tuple[str, ...]:
        """Names of the complete set's extras that the set lacks (see ``missing``)."""
        return tuple(m.split(":", 1)[0] for m in self.missing if ":" in m)

    @property
    def rank(self) -> int:
        """Numerical rank, the number of pivots ``|R_ii| > tau`` of the pivoted QR."""
        return numerical_rank(self.diag, self.n_rows)[0]

    def regrouping_coefficients(
        self, threshold: float = REGROUP_TOL
    ) -> dict[str, dict[str, float]]:
        """Each base parameter's regrouped parameters and their coefficients (B's rows).

        A mimic joint's offset (``offset<k>``, see :attr:`mimic`) enters wherever its joint
        offset does, with the same coefficient: their columns are equal.
        """
        out = {
            name: {
                o: float(c)
                for o, c in zip(self.others, self.B[i], strict=True)
                if abs(c) > threshold
            }
            for i, name in enumerate(self.base)
        }
        for k, joint_offset in self.mimic_offsets().items():
            for name, terms in out.items():
                c = 1.0 if name == joint_offset else terms.get(joint_offset)
                if c is not None:
                    terms[f"offset{k}"] = c
        return out

    def mimic_offsets(self) -> dict[int, str]:
        """The joint offset parameter (theta_k or r_k) of each mimic joint's row k."""
        out = {}
        for mj in self.mimic:
            k = mj.joint + 1
            out[k] = f"{'theta' if self.mdh.sigma[k] == 0 else 'r'}{k}"
        return out

    @property
    def gap(self) -> tuple[float, float | None]:
        """``|R_bb|`` and ``|R_(b+1)(b+1)|``, the smallest kept and largest dropped pivots."""
        b = self.rank
        last = float(self.diag[b - 1]) if b else 0.0
        nxt = float(self.diag[b]) if b < len(self.diag) else None
        return last, nxt

    def regrouping(self, threshold: float = REGROUP_TOL) -> dict[str, str]:
        """Each base parameter as the expression it stands for, e.g. ``theta5 - 4.762 d6``."""
        out = {}
        for name, terms in self.regrouping_coefficients(threshold).items():
            expr = name
            for other, c in terms.items():
                sign = "-" if c < 0 else "+"
                coef = "" if abs(abs(c) - 1.0) < 1e-9 else f"{abs(c):.4g} "
                expr += f" {sign} {coef}{other}"
            out[name] = expr
        return out

    def status(self, name: str) -> str:
        """``identifiable``, ``regrouped`` (eliminated into base parameters) or ``zero``."""
        if name in self.base:
            return "identifiable"
        if name in self.zero:
            return "zero"
        if name in self.params.names:
            return "regrouped"
        raise InvalidArgumentError(f"'{name}' is not a parameter of the {self.params.label} set")

    def joint_of(self, name: str) -> str | None:
        """The URDF joint of a parameter's MDH row, as calibrate's report names it.

        None for the base frame's row 0 and a tool frame's row (``theta7`` of a 6-joint chain).
        """
        return joint_of(name, self.mdh.joint_names)

    def row_frame(self, k: int) -> str | None:
        """The fixed frame of row k: the base frame (row 0), a tool's; None for a joint's."""
        return self.base_frame if k == 0 else self.mdh.tool_frame_of(k)

    def summary(self) -> str:
        """The text ``calib analyze`` prints (:func:`!report.analysis_text`)."""
        from .report import analysis_text  # the report reads this module

        return analysis_text(self)

    def to_dict(self) -> dict:
        """JSON-ready summary (a contact adds its rows and what it can never identify)."""
        out = self._summary()
        if self.measurement.is_contact:
            out["rows"] = list(self.measurement.row_names)
            out["unseen"] = list(self.unseen)
        return out

    @property
    def unseen(self) -> tuple[str, ...]:
        """What the contact can never identify (the scale, only without a prismatic joint)."""
        lines = tuple(getattr(self.measurement, "unseen", ()))
        if lines and np.any(self.mdh.sigma == 1):  # a prismatic reading fixes the scale
            lines = tuple(u for u in lines if not u.startswith("without a prismatic joint"))
        return lines

    def _summary(self) -> dict:
        last, nxt = self.gap
        return {
            "robot": self.robot,
            "base_frame": self.base_frame,
            "tool_frame": self.tool_frame,
            "tool_frames": list(self.tool_frames),
            "measure": self.measurement.label,
            "marker": list(self.measurement.marker),
            "params": self.params.label,
            "joints": {
                "revolute": int(np.sum(self.mdh.sigma == 0)),
                "prismatic": int(np.sum(self.mdh.sigma == 1)),
            },
            "configs": self.n_configs,
            "seed": self.seed,
            "n_standard": self.n_standard,
            "n_base": self.n_base,
            "n_complete": self.n_complete,
            "n_theory": self.n_theory,
            "theory_note": self.theory_note,
            "per_tool_theory": {name: count for name, count in self.per_tool},
            "point_on_last_axis": self.on_last_axis,
            "point_on_axes": list(self.on_axes),
            "standard_parameters": list(self.params.names),
            "parameters": [
                {
                    "name": p.name,
                    "row": p.row,
                    "joint": self.joint_of(p.name),
                    "frame": self.row_frame(p.row),
                    "status": self.status(p.name),
                }
                for p in self.params.parameters
            ],
            "base_parameters": list(self.base),
            "nonidentifiable": list(self.zero),
            "regrouped": [n for n in self.others if n not in self.zero],
            "regrouping": self.regrouping(),
            "missing": list(self.missing),
            "missing_parameters": list(self.missing_parameters),
            "tolerance": self.tolerance,
            "gap": {"last_kept": last, "first_dropped": nxt},
            "warnings": list(self.warnings),
            "snapped": list(self.snapped),
            "timings_ms": dict(self.timings_ms),
            "mimic": [
                {
                    "row": mj.joint + 1,
                    "joint": mj.name,
                    "master": mj.master,
                    "multiplier": mj.multiplier,
                    "offset": mj.offset,
                    "offset_parameter": f"offset{mj.joint + 1}",
                    "regroups_with": self.mimic_offsets()[mj.joint + 1],
                }
                for mj in self.mimic
            ],
        }


def _checked_arguments(mdh, params, measurement, configs):
    """Checked arguments of :func:`analyze_model`: measurement, parameter set, ``(m, n)``."""
    if not isinstance(mdh, MDHModel | TreeMDH):
        raise InvalidArgumentError(
            f"mdh must be an MDHModel or a TreeMDH (see from_chain, from_tree), got {mdh!r:.60}"
        )
    measurement = kind_of("pose") if measurement is None else measurement
    if not isinstance(measurement, MeasureKind) or isinstance(measurement, str):
        raise InvalidArgumentError(
            f"measurement must be a measurement kind (see kind_of, Measurement.of), got "
            f"{measurement!r:.60}"
        )
    if isinstance(mdh, TreeMDH) and not isinstance(measurement, Measurement):
        raise InvalidArgumentError(
            f"a tree is analysed with measured poses or points, not {measurement.label}"
        )
    if isinstance(params, str):
        pset = _set_of(mdh, params)
    elif isinstance(params, ParameterSet) and all(
        isinstance(p, Parameter) and 0 <= p.row < len(mdh.sigma) for p in params.parameters
    ):
        pset = params
    else:
        raise InvalidArgumentError(
            f"params must be 'paper', 'complete' or a ParameterSet of this model's rows, "
            f"got {params!r:.60}"
        )
    if configs is None:
        raise InvalidArgumentError("analyze_model needs the configurations (m, n) to analyse")
    q = joint_positions(configs, mdh.n)
    check_work(len(q), mdh.n, per_config=len(mdh.tool_rows))
    return measurement, pset, q


def _set_of(mdh: MDHModel | TreeMDH, label: str) -> ParameterSet:
    """The ``paper`` or ``complete`` set of a chain or tree model."""
    return tree_parameters(mdh, label) if isinstance(mdh, TreeMDH) else parameter_set(mdh, label)


def _matrices(mdh: MDHModel | TreeMDH, params: ParameterSet, q: np.ndarray, measurement):
    """W of a set (for a tree: its small factor), W's rows, and the complete model's W."""
    if isinstance(mdh, TreeMDH):
        F = tree_jacobian(mdh, params, q, measurement, factor=True)
        rows = len(q) * mdh.n_tools * measurement.n_rows
        return F, rows, lambda: tree_complete_jacobian(mdh, q, measurement, factor=True)
    kin = mdh.kinematics(q)
    W = identification_jacobian(mdh, params, q, measurement, kin=kin)
    return W, W.shape[0], lambda: complete_jacobian(mdh, q, measurement, kin=kin)


def analyze_model(
    mdh: MDHModel | TreeMDH,
    params: str | ParameterSet = "paper",
    measurement: MeasureKind | None = None,
    configs: np.ndarray | None = None,
    robot: str = "",
    seed: int = 0,
) -> Identifiability:
    """Identifiability of an MDH model (chain or tree) at given configurations.

    Args:
        mdh: Nominal model: a chain's, or a tree's (every tool measured at each configuration).
        params: ``paper``, ``complete`` or an explicit set.
        measurement: What is measured (default: the full pose at the tool origin).
        configs: Joint positions ``(m, n)``.
        robot: Name for reports.
        seed: Seed that drew ``configs`` (reported only).

    Returns:
        The analysis.

    Raises:
        InvalidArgumentError: A bad argument: configurations of the wrong shape, with NaN,
            or too many to fit in memory (:data:`~calib.core.checks.MAX_WORK_BYTES`).
    """
    measurement, pset, q = _checked_arguments(mdh, params, measurement, configs)
    check_count(seed, "the seed", minimum=0)
    names = pset.names
    extras = [p for p in _set_of(mdh, "complete").parameters if p.name not in names]
    t0 = time.perf_counter()
    # One Jacobian for the set and the complete set's extras; ranks of column subsets come
    # from the small triangular factor, which keeps W's column geometry.
    all_params = ParameterSet(pset.label, (*pset.parameters, *extras))
    W_all, n_rows, complete = _matrices(mdh, all_params, q, measurement)
    W = W_all[:, : len(pset)]
    t1 = time.perf_counter()
    diag, tau, kept, others, B = identify_base(mdh, pset, W, n_rows)
    col_norm = np.linalg.norm(W, axis=0)
    zero = tuple(names[i] for i in others if col_norm[i] <= tau)
    t2 = time.perf_counter()
    n_complete, _ = numerical_rank(pivoted_diagonal(complete()), n_rows)
    on_axes = axes_through_point(mdh, measurement)
    theory = theory_of(mdh, measurement, on_axes)  # the count, or why there is none
    missing = missing_errors(mdh, W_all, pset, extras, kept, n_complete, n_rows)
    t3 = time.perf_counter()
    notes = rank_notes(diag, n_rows, len(kept), len(pset))
    for note in notes:
        warn_user(note, RankWarning)
    return Identifiability(
        robot=robot,
        base_frame=mdh.base_frame,
        tool_frame=mdh.tool_frame,
        mdh=mdh,
        measurement=measurement,
        params=pset,
        n_configs=len(q),
        seed=seed,
        n_rows=n_rows,
        diag=diag,
        tolerance=tau,
        base=tuple(names[i] for i in kept),
        others=tuple(names[i] for i in others),
        zero=zero,
        B=B,
        n_complete=n_complete,
        n_theory=theory if isinstance(theory, int) else None,
        theory_note=theory if isinstance(theory, str) else "",
        on_axes=on_axes,
        per_tool=per_tool_theory(mdh, measurement) if isinstance(mdh, TreeMDH) else (),
        missing=tuple(missing),
        warnings=tuple(notes),
        timings_ms={
            "jacobian": 1e3 * (t1 - t0),
            "qr": 1e3 * (t2 - t1),
            "complete": 1e3 * (t3 - t2),
        },
    )


SNAPPED_CHANGE = 1e-3
"""Largest change [rad or m] :func:`snapped_values` lists: a larger one is a different frame
choice of the idealized conversion (a 90-degree offset), not round-off."""


def snapped_values(exact: MDHModel | TreeMDH, idealized: MDHModel | TreeMDH) -> tuple[str, ...]:
    """What :meth:`MDHModel.idealized` changed, as ``name: value -> new`` strings.

    Changes under 1e-14 (float noise of the conversion) and over :data:`SNAPPED_CHANGE` are
    not listed; angles are compared modulo 2 pi. A change that 7 digits do not show is
    written as the value and how far off it was: ``r5: -0.33 m (was +8.9e-12 m off)``.
    """
    out = []
    for kind in Kind:
        if not hasattr(exact, kind.value):  # gamma and b: trees only
            continue
        a, b = getattr(exact, kind.value), getattr(idealized, kind.value)
        diff = b - a
        if kind.is_rotation:
            diff = (diff + math.pi) % (2 * math.pi) - math.pi
        unit = "rad" if kind.is_rotation else "m"
        for k in np.flatnonzero((np.abs(diff) > 1e-14) & (np.abs(diff) <= SNAPPED_CHANGE)):
            was, new = f"{a[k]:.7g}", f"{b[k]:.7g}"
            if was == new:  # past 7 digits: the value printed once, with how far off it was
                out.append(f"{kind.value}{k}: {new} {unit} (was {-diff[k]:+.2g} {unit} off)")
            else:
                out.append(f"{kind.value}{k}: {was} {unit} -> {new}")
    return tuple(out)


def analyze(
    robot: str | Path | Chain | Tree,
    base: str | None = None,
    tool: str | Sequence[str] | None = None,
    measure: str = DEFAULT_MEASURE,
    marker=None,
    params: str = DEFAULT_SET,
    configs: int = DEFAULT_CONFIGS,
    seed: int = 0,
) -> Identifiability:
    """Load a robot and analyse the identifiability of its geometric parameters.

    Args:
        robot: Catalog name, URDF path, or an already loaded chain or tree.
        base: Base frame (default: the catalog's or the URDF root).
        tool: Tool frame (default: the catalog's or the deepest tip), or several: the tree of
            their chains, every tool measured at each configuration (see :func:`load_robot`).
        measure: ``position`` (default: a point measured, as the command line's), ``pose``,
            comma-separated rows (``x,y,z,rx``), a contact (``plane``, ``plane-point``,
            ``fixed-point``, ``fixed-pose``) or a kind.
        marker: Measured point in the tool frame, 3 numbers [m].
        params: ``complete`` (default: the set ``calibrate`` chooses from) or ``paper``.
        configs: Number of random configurations m (>= 1).
        seed: Seed of the configurations.

    The analysis runs on the nominal geometry with URDF round-off removed
    (:meth:`MDHModel.idealized`); the result's ``snapped`` lists what that changed. A contact
    is analysed at postures where it holds: the plane, point or pose is the tool frame's
    placement at a first random configuration and becomes frame -1 (the base frame, whose
    complete parameters stand for its unknown placement); the other configurations are
    projected onto the contact
    (:func:`~calib.identification.contact_postures.contact_configurations`).

    Returns:
        The analysis, with load/convert/jacobian/qr timings.
    """
    measurement = kind_of(measure, marker)
    check_count(configs, "the number of configurations")
    check_count(seed, "the seed", minimum=0)
    if not isinstance(params, str) or params not in ("paper", "complete"):
        raise InvalidArgumentError(
            f"unknown parameter set {shown(params)}: choose paper or complete"
        )
    t0 = time.perf_counter()
    chain = load_robot(robot, base, tool)
    t1 = time.perf_counter()
    exact = from_tree(chain) if chain.is_tree else from_chain(chain)
    mdh = exact.idealized()
    t2 = time.perf_counter()
    mdh, q = _configurations(chain, mdh, measurement, int(configs), seed)
    t3 = time.perf_counter()
    result = analyze_model(mdh, params, measurement, q, robot=chain.name, seed=seed)
    timings = {"load": 1e3 * (t1 - t0), "convert": 1e3 * (t2 - t1), **result.timings_ms}
    if measurement.is_contact:
        timings["contact"] = 1e3 * (t3 - t2)  # the postures where the contact holds
    result = dataclasses.replace(result, snapped=snapped_values(exact, mdh), timings_ms=timings)
    return result if chain.coupling is None else _coupled(result, chain)


def _configurations(
    chain: Chain | Tree, mdh: MDHModel | TreeMDH, measurement: MeasureKind, m: int, seed: int
) -> tuple[MDHModel | TreeMDH, np.ndarray]:
    """The model and the m configurations :func:`analyze` analyses (module text of a contact).

    Raises:
        InvalidArgumentError: A contact on a tree or a chain with mimic joints.
    """
    if not measurement.is_contact:
        return mdh, chain.random_configurations(m, seed)
    if (
        not isinstance(mdh, MDHModel)
        or not isinstance(measurement, Contact)
        or chain.coupling is not None
    ):
        raise InvalidArgumentError(
            f"a {measurement.label} contact is analysed on one chain without mimic joints"
        )
    return contact_configurations(
        mdh, measurement, lambda c, r: chain.random_configurations(c, seed + r), m
    )


def _coupled(result: Identifiability, chain: Chain | Tree) -> Identifiability:
    """A coupled robot's analysis: no theoretical count (the formula is for independent joints).

    A tree's count of each tool's chain through mimic joints is silent too; the mimic joints
    are set (:attr:`Identifiability.mimic`).
    """
    per_tool = result.per_tool
    if chain.is_tree:
        pairs = zip(per_tool, chain.chains, strict=True)
        per_tool = tuple((t, None if c.coupling else n) for (t, n), c in pairs)
    mimic = () if chain.coupling is None else chain.coupling.mimic
    note = "coupled (mimic) joints: the formula is for independent joints"
    return dataclasses.replace(
        result, n_theory=None, theory_note=note, mimic=mimic, per_tool=per_tool
    )


__all__ = [
    "DEFAULT_CONFIGS",
    "Identifiability",
    "RankWarning",
    "analyze",
    "analyze_model",
    # Re-exported from .base_columns (their home), where they were imported from before:
    "checked_selection",
    "identify_base",
    "independent_columns",
    "preference_order",
    "select_by_rank",
    "select_independent",
]
