"""Observability indices of a set of configurations, on the parameters a calibration fits.

The columns: what ``calib calibrate --params LEVEL`` fits (measurement frame, markers, the
measured frame's rotation for pose data, and the level's MDH base parameters), reduced to the
b independent ones (the same pivoted QR as :func:`calib.analyze`). The rows: 3 per marker and
3 more for an orientation, weighted as the calibration weighs them (``orientation_weight``
[m/rad]). The observation matrix of K configurations is ``W_b`` (``K rows x b``), its
information matrix ``M = W_b^T W_b``; with a noise of standard deviation sigma per row, the
fitted parameters have the covariance ``sigma^2 M^-1``.

**Scaling.** Angles and lengths enter one matrix: every angle [rad] is expressed as the arc
[m] it sweeps at the chain's characteristic length L (the sum of the MDH lengths
``sqrt(d_k^2 + r_k^2)`` and of the marker's distance to the tool frame), i.e. angle columns
are divided by L. The D criterion and the predicted position error (I, G) do not depend on
this choice; the condition number, O1, O3, O4 and A do.

**Indices** (singular values ``s_1 >= ... >= s_b`` of the scaled ``W_b``):

* ``cond = s_1 / s_b`` (Driels and Pathre 1990); lower is better.
* ``O1 = (s_1 ... s_b)^(1/b) / sqrt(K)`` (Borm and Menq 1991); higher is better.
* ``O3 = s_b``, the smallest singular value (Nahvi, Hollerbach and Hayward 1994); higher.
* ``O4 = s_b^2 / s_1``, the noise amplification index (Nahvi and Hollerbach 1996); higher.
* ``D = log det M`` (D-optimality; Khalil, Gautier and Enguehard 1991 maximise the
  determinant); higher.
* ``A = trace M^-1``: the summed variance of the (scaled) parameters per unit noise; lower.
* ``I`` and ``G``: the predicted position error of the calibrated model on a reference set of
  configurations, per unit of measurement noise: ``sqrt(mean)`` and ``sqrt(max)`` over the
  reference configurations and markers of ``trace(J_p M^-1 J_p^T)``, ``J_p`` the 3 position
  rows of a point (I- and G-optimality). I times the noise [mm] is the expected RMS error
  [mm] of the calibrated point, the quantity a user cares about; lower is better.

The model behind the columns is generic: :class:`ObservationModel` wraps any function that
returns the Jacobian of the calibration's parameters at configurations: a chain's
(:class:`~calib.calibration.model.ErrorModel`) or a tree's, every tool measured at each
configuration (:class:`~calib.design.tree_error_model.TreeErrorModel`, 3 rows per tool).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..calibration.chain_registration import held_markers
from ..calibration.determined import determined_columns, generic_jacobian
from ..calibration.model import (
    FRAME_NAMES,
    TOOL_NAMES,
    ErrorModel,
    MeasuredKind,
    moved,
    nominal_state,
)
from ..calibration.options import check_tree_level
from ..core.checks import MAX_WEIGHT, MAX_WORK_BYTES, check_count, check_number, real_array, shown
from ..core.choices import DEFAULT_CONFIGS, DESIGN_LEVELS
from ..exceptions import InvalidArgumentError
from ..identification.contact_postures import joint_offsets
from ..identification.kinds import campaign_kind
from ..identification.measures import Measurement
from ..identification.parameters import ParameterSet, parameter_set
from ..identification.tree_jacobian import tree_parameters
from ..kinematics.mdh import MDHModel, from_chain
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree
from ..kinematics.tree_model import from_tree
from .tree_error_model import TreeErrorModel, TreeState

REFERENCE_CONFIGS = 200
"""Reference configurations of the predicted position error (I, G) by default."""

STRUCTURE_CONFIGS = 200
"""Configurations on which the independent columns are chosen."""

CRITERIA = {
    "cond": False,
    "O1": True,
    "O3": True,
    "O4": True,
    "D": True,
    "A": False,
    "I": False,
    "G": False,
}
"""Every index and whether higher is better."""


@dataclass(frozen=True, eq=False)
class ObservationModel:
    """The scaled Jacobian of a calibration's independent parameters, at any configurations.

    Attributes:
        names: The b parameters (columns of ``W_b``).
        angular: True for the angle parameters [rad] ``(b,)``.
        length: Characteristic length L [m]: angle columns are divided by it.
        rows: Rows per configuration (3 per marker, then 3 orientation rows for poses; a
            contact's gap rows).
        n_markers: Number of measured points K per configuration (0 for a contact: I and G
            then predict the error of the gap, all its rows).
        joint_names: The joints of a configuration, in order.
        jacobian_of: Returns the weighted, unscaled Jacobian ``(m, rows, c)`` of all the
            calibration's parameters at joint positions ``(m, n)``.
        columns: The independent columns of ``jacobian_of``'s output ``(b,)``.
    """

    names: tuple[str, ...]
    angular: np.ndarray
    length: float
    rows: int
    n_markers: int
    joint_names: tuple[str, ...]
    jacobian_of: Callable[[np.ndarray], np.ndarray]
    columns: np.ndarray

    @property
    def b(self) -> int:
        """Number of parameters (columns)."""
        return len(self.names)

    @property
    def scale(self) -> np.ndarray:
        """Divisor of each column ``(b,)``: L for angles, 1 for lengths."""
        return np.where(self.angular, self.length, 1.0)

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """Scaled ``W_b`` rows of each configuration ``(m, rows, b)``."""
        q = real_array(q, "joint positions", (None, len(self.joint_names)))
        return np.ascontiguousarray(self.jacobian_of(q)[:, :, self.columns] / self.scale)

    def point_jacobian(self, J: np.ndarray) -> np.ndarray:
        """The position rows of each point ``(m K, 3, b)`` from :meth:`jacobian`'s output.

        A contact (no marker): the gap rows of each configuration ``(m, rows, b)``.
        """
        if self.n_markers == 0:
            return J
        m = J.shape[0]
        return J[:, : 3 * self.n_markers].reshape(m * self.n_markers, 3, -1)


def characteristic_length(chain_lengths: np.ndarray, markers: np.ndarray) -> float:
    """L [m]: the summed MDH lengths plus the farthest marker's distance to the tool frame.

    Args:
        chain_lengths: ``sqrt(d_k^2 + r_k^2)`` of every MDH row [m].
        markers: Markers in the tool frame ``(K, 3)`` [m].

    Returns:
        L, at least 1 mm (a chain of zero length would make angles weightless).
    """
    marker = float(np.max(np.linalg.norm(markers, axis=1))) if len(markers) else 0.0
    return max(float(np.sum(chain_lengths)) + marker, 1e-3)


def marker_array(markers) -> np.ndarray:
    """Markers ``(K, 3)`` [m] from None (the tool origin), 3 numbers or ``(K, 3)``.

    Raises:
        InvalidArgumentError: Not 3 or 3 K finite numbers within 1 km.
    """
    if markers is None:
        return np.zeros((1, 3))
    mk = real_array(markers, "markers", (None,) if np.ndim(markers) == 1 else (None, 3), 1e3)
    if mk.ndim == 1:
        if mk.size != 3:
            raise InvalidArgumentError(f"a marker is 3 numbers [m], got {mk.size}")
        mk = mk[None, :]
    if len(mk) == 0:
        raise InvalidArgumentError("give at least one marker")
    return mk


def check_model_arguments(
    measure: str, params: str, orientation_weight: float = 1.0, tree: bool = False
) -> None:
    """Refuse a bad measure, parameter level or orientation weight (before any work).

    Args:
        measure: ``position`` or ``pose`` (a tree: ``position``).
        params: One of ``DESIGN_LEVELS`` (a tree: ``TREE_LEVELS``).
        orientation_weight: Weight of the orientation rows [m/rad], > 0.
        tree: The model is a tree's.

    Raises:
        InvalidArgumentError: One of them is not accepted.
    """
    kind = campaign_kind(measure)
    if tree and not kind.is_position:
        raise InvalidArgumentError("a tree is calibrated from positions: use measure position")
    if tree:
        check_tree_level(params)
    if not isinstance(params, str) or params not in DESIGN_LEVELS:
        raise InvalidArgumentError(
            f"unknown parameter level {shown(params)} for a design: choose "
            f"{', '.join(DESIGN_LEVELS)}"
        )
    check_number(orientation_weight, "the orientation weight", 0.0, MAX_WEIGHT, above=True)
    if orientation_weight != 1.0 and not kind.is_pose:
        raise InvalidArgumentError(
            f"orientation_weight weighs the orientation rows of pose data: measure "
            f"{kind.label} has none"
        )


def observation_model(
    chain: Chain | Tree,
    measure: str = "position",
    markers=None,
    params: str = "complete",
    orientation_weight: float = 1.0,
    structure_q: np.ndarray | None = None,
    seed: int = 0,
    held: tuple[int, ...] = (),
) -> ObservationModel:
    """The observation model of a calibration of a chain or a tree.

    A tree (several tools, :func:`calib.calibrate`) is measured at one point per tool
    and configuration, in position: its rows are 3 per tool, its columns the frame, one
    marker per tool and the tree's base parameters (``complete``) or none (``frames``).

    Args:
        chain: The chain or tree.
        measure: ``position`` or ``pose`` (a tree: ``position``).
        markers: Measured points in the tool frame, ``(3,)`` or ``(K, 3)`` [m] (default:
            the tool origin); for a tree, one point for every tool ``(3,)`` or one per tool
            ``(T, 3)``.
        params: Parameter level, one of ``DESIGN_LEVELS`` (a tree: ``TREE_LEVELS``).
        orientation_weight: Weight of the orientation rows [m/rad] (as in ``calibrate``).
        structure_q: Configurations on which the independent columns are chosen (default:
            ``STRUCTURE_CONFIGS`` random ones drawn with ``seed``); give the candidates when
            they span less than the joint limits.
        seed: Seed of the default ``structure_q``.
        held: Marker coordinates (0-based among the ``3 K``) held at their given value, no
            unknown (a gantry's first marker, as :func:`calib.calibrate` holds it).

    Returns:
        The model.

    Raises:
        InvalidArgumentError: A bad argument.
    """
    if chain.is_tree:
        return _tree_observation_model(chain, measure, markers, params, structure_q, seed)
    check_model_arguments(measure, params, orientation_weight)
    mk = marker_array(markers)
    twice = next(
        ((i, j) for j in range(len(mk)) for i in range(j) if np.allclose(mk[i], mk[j])), None
    )
    if twice is not None:  # one point measured twice: the score of fewer columns than the fit's
        raise InvalidArgumentError(
            f"markers {twice[0] + 1} and {twice[1] + 1} are at one place, {mk[twice[1]].tolist()}"
            " m: give each marker where it is on the tool (its approximate place)"
        )
    kind = campaign_kind(measure)
    nominal = from_chain(chain).idealized()
    pset, names = _level_names(nominal, params)
    own = MeasuredKind(len(mk), bool(kind.rotation_rows), held=held)
    model = ErrorModel(pset, moved(pset, nominal, names), own)
    state = nominal_state(nominal, mk, kind)
    jacobian_of = generic_jacobian(model, state, chain.joint_names, float(orientation_weight))
    if structure_q is None:
        structure_q = chain.random_configurations(STRUCTURE_CONFIGS, check_count(seed, "seed", 0))
    kept = determined_columns(
        jacobian_of(real_array(structure_q, "joint positions", (None, chain.n)))
    )
    all_names = model.names()
    angular = set(FRAME_NAMES[:3]) | set(TOOL_NAMES)
    angular |= {p.name for p in pset.parameters if p.kind.is_rotation}
    lengths = np.hypot(nominal.d, nominal.r)
    return ObservationModel(
        names=tuple(all_names[i] for i in kept),
        angular=np.array([all_names[i] in angular for i in kept], dtype=bool),
        length=characteristic_length(lengths, mk),
        rows=own.rows,
        n_markers=len(mk),
        joint_names=chain.joint_names,
        jacobian_of=jacobian_of,
        columns=np.array(kept, dtype=int),
    )


def _level_names(nominal: MDHModel, level: str) -> tuple[ParameterSet, list[str]]:
    """The standard set of a design level (``DESIGN_LEVELS``) and the names it offers."""
    pset = parameter_set(nominal, "paper" if level == "paper" else "complete")
    if level == "frames":
        return pset, []
    if level == "offsets":
        return pset, list(joint_offsets(nominal).names)
    return pset, list(pset.names)


def robot_markers(robot: Chain | Tree, markers) -> np.ndarray:
    """The measured points of a configuration in their tool's frame ``(K, 3)`` [m].

    A chain: the markers on its tool (:func:`marker_array`). A tree: one marker per tool
    ``(T, 3)``, the origins (None), one for every tool or one per tool.

    Raises:
        InvalidArgumentError: Bad numbers, or a tree given another number of markers.
    """
    mk = marker_array(markers)
    if not robot.is_tree:
        return mk
    tree = robot
    if len(mk) == 1:
        return np.repeat(mk, tree.n_tools, axis=0)
    if len(mk) != tree.n_tools:
        raise InvalidArgumentError(
            f"a tree of {tree.n_tools} tools takes one marker for all or one per tool, "
            f"got {len(mk)}"
        )
    return mk


def _tree_observation_model(
    tree: Tree, measure: str, markers, params: str, structure_q, seed: int
) -> ObservationModel:
    """:func:`observation_model` of a tree (one point per tool, position rows)."""
    check_model_arguments(measure, params, tree=True)
    mk = robot_markers(tree, markers)
    nominal = from_tree(tree).idealized()
    n_tools = nominal.n_tools
    pset = tree_parameters(nominal, "complete") if params == "complete" else None
    if pset is None:
        model = TreeErrorModel(ParameterSet("none", ()), (), n_tools)
    else:
        model = TreeErrorModel(pset, pset.names, n_tools)
    state = TreeState(nominal, np.eye(4), mk)
    x0 = np.zeros(model.size())

    def jacobian_of(q: np.ndarray) -> np.ndarray:
        tool = np.tile(np.arange(n_tools), len(q))
        J = model.jacobian_at(state, x0, np.repeat(q, n_tools, axis=0), tool)
        return J.reshape(len(q), 3 * n_tools, -1)

    if structure_q is None:
        structure_q = tree.random_configurations(STRUCTURE_CONFIGS, check_count(seed, "seed", 0))
    kept = determined_columns(
        jacobian_of(real_array(structure_q, "joint positions", (None, tree.n)))
    )
    all_names = model.names(nominal.tool_frames)
    angular = set(FRAME_NAMES[:3])
    if pset is not None:
        angular |= {p.name for p in pset.parameters if p.kind.is_rotation}
    lengths = np.sqrt(nominal.d**2 + nominal.r**2 + nominal.b**2)
    path = max(float(np.sum(lengths[nominal.path_rows(t)])) for t in range(n_tools))
    return ObservationModel(
        names=tuple(all_names[i] for i in kept),
        angular=np.array([all_names[i] in angular for i in kept], dtype=bool),
        length=characteristic_length(np.array([path]), mk),
        rows=3 * n_tools,
        n_markers=n_tools,
        joint_names=tree.joint_names,
        jacobian_of=jacobian_of,
        columns=np.array(kept, dtype=int),
    )


@dataclass(frozen=True, eq=False)
class Reference:
    """The reference configurations of the predicted position error (I, G).

    Attributes:
        q: Joint positions ``(m, n)``.
        points: Position rows of every point at them ``(m K, 3, b)`` (scaled).
        mean: ``mean_p J_p^T J_p`` ``(b, b)``: trace(mean M^-1) is I^2.
    """

    q: np.ndarray
    points: np.ndarray
    mean: np.ndarray


def reference(model: ObservationModel, q: np.ndarray) -> Reference:
    """The reference set of a model at configurations ``q`` ``(m, n)``."""
    P = model.point_jacobian(model.jacobian(q))
    return Reference(np.asarray(q), P, np.einsum("pri,prj->ij", P, P) / len(P))


@dataclass(frozen=True)
class Indices:
    """Observability indices of K configurations (sources, scaling: ``calib.design.observability``).

    Attributes:
        configs: Number of configurations K.
        parameters: Number of parameters b.
        rank: Numerical rank of ``W_b`` (b when the set identifies every parameter).
        cond: Condition number ``s_1 / s_b`` of the singular values ``s_1 >= ... >= s_b`` of
            the scaled ``W_b`` (inf when rank-deficient); lower is better.
        o1: Borm and Menq's index ``(s_1 ... s_b)^(1/b) / sqrt(K)``; higher is better.
        o3: Smallest singular value ``s_b``; higher is better.
        o4: Noise amplification index ``s_b^2 / s_1``; higher is better.
        d: ``log det M``, ``M = W_b^T W_b`` (-inf when rank-deficient); higher is better.
        a: ``trace M^-1``, the summed variance of the scaled parameters per unit noise (inf
            when rank-deficient); lower is better.
        i: The predicted RMS position error of the calibrated points on the reference set
            per unit noise (times the noise [mm]: the expected RMS error [mm]; inf when
            rank-deficient, None without a reference set); lower is better.
        g: Its maximum over the reference configurations and points.
    """

    configs: int
    parameters: int
    rank: int
    cond: float
    o1: float
    o3: float
    o4: float
    d: float
    a: float
    i: float | None = None
    g: float | None = None

    def value(self, criterion: str) -> float:
        """The index named ``criterion`` (one of ``CRITERIA``)."""
        if not isinstance(criterion, str) or criterion not in CRITERIA:
            raise InvalidArgumentError(
                f"unknown criterion {shown(criterion)}: choose {', '.join(CRITERIA)}"
            )
        v = getattr(self, criterion.lower())
        if v is None:
            raise InvalidArgumentError(f"index {criterion} needs a reference set")
        return float(v)

    def better(self, other: Indices, criterion: str) -> bool:
        """This set is strictly better than ``other`` on ``criterion``."""
        a, b = self.value(criterion), other.value(criterion)
        return a > b if CRITERIA[criterion] else a < b

    def to_dict(self) -> dict:
        """JSON-ready form: infinities (rank-deficient sets) are null."""

        def num(v):
            return None if v is None or not math.isfinite(v) else float(v)

        out = {"configs": self.configs, "parameters": self.parameters, "rank": self.rank}
        return out | {c: num(getattr(self, c.lower())) for c in CRITERIA}


def indices_of(J: np.ndarray, ref: Reference | None = None) -> Indices:
    """Indices of the configurations whose scaled rows are ``J`` ``(K, rows, b)``.

    Args:
        J: Rows of ``W_b`` per configuration (:meth:`ObservationModel.jacobian`).
        ref: Reference set of the predicted position error (None: I and G are None).
    """
    K, _, b = J.shape
    W = J.reshape(-1, b)
    _, s, Vt = np.linalg.svd(W, full_matrices=False)
    s = np.r_[s, np.zeros(b - len(s))]
    rank = int(np.sum(s > max(W.shape) * np.finfo(float).eps * s[0])) if s[0] > 0 else 0
    if rank < b:
        inf = math.inf
        i_g: tuple[float | None, float | None] = (inf, inf) if ref is not None else (None, None)
        o1 = 0.0
        return Indices(K, b, rank, inf, o1, float(s[-1]), 0.0, -inf, inf, *i_g)
    i_g = (None, None)
    if ref is not None:
        V = Vt.T / s  # M^-1 = V V^T
        per_point = np.sum((ref.points @ V) ** 2, axis=(1, 2))
        i_g = (math.sqrt(float(np.mean(per_point))), math.sqrt(float(np.max(per_point))))
    logs = np.log(s)
    return Indices(
        configs=K,
        parameters=b,
        rank=rank,
        cond=float(s[0] / s[-1]),
        o1=float(np.exp(np.mean(logs)) / math.sqrt(K)),
        o3=float(s[-1]),
        o4=float(s[-1] ** 2 / s[0]),
        d=float(2.0 * np.sum(logs)),
        a=float(np.sum(1.0 / s**2)),
        i=i_g[0],
        g=i_g[1],
    )


def indices(
    model: ObservationModel, q: np.ndarray, ref: Reference | None = None, seen=None
) -> Indices:
    """Observability indices of configurations ``q`` ``(K, n)`` under a model.

    ``seen`` ``(K, markers)``: which markers each configuration measures (None: all); a
    marker not seen gives no rows (its rows are 0: the information of those measured).

    Raises:
        InvalidArgumentError: ``model`` is no :class:`ObservationModel`, ``ref`` no
            :class:`Reference`, or ``q`` not configurations of the model's robot.
    """
    if not isinstance(model, ObservationModel):
        raise InvalidArgumentError(
            f"model must be an ObservationModel (observation_model), got {model!r:.60}"
        )
    if ref is not None and not isinstance(ref, Reference):
        raise InvalidArgumentError(f"ref must be a Reference (reference) or None, got {ref!r:.60}")
    J = model.jacobian(q)
    if seen is not None:
        seen = np.asarray(seen, dtype=bool)
        if seen.shape != (len(J), model.n_markers):
            raise InvalidArgumentError(
                f"seen must be ({len(J)}, {model.n_markers}) booleans, got {seen.shape}"
            )
        J[:, : 3 * model.n_markers][~np.repeat(seen, 3, axis=1)] = 0.0
    return indices_of(J, ref)


def identifiable_parameters(
    chain: Chain,
    n_markers: int = 1,
    measure: str = "position",
    configs: int = DEFAULT_CONFIGS,
    seed: int = 0,
    held: tuple[int, ...] | None = None,
) -> tuple[str, ...]:
    """Names of the parameters a calibration with K markers identifies (generic configurations).

    The columns :func:`observation_model` keeps at ``complete`` (``calib analyze --markers``).

    Args:
        chain: The chain.
        n_markers: Points measured per configuration K (markers at generic, distinct places).
        measure: ``position`` or ``pose`` (the orientation of the tool is measured too).
        configs: Random configurations m.
        seed: Seed of the configurations and of the marker places.
        held: Marker coordinates (0-based among the ``3 K``) held at their given value, not
            counted (None: :func:`~calib.calibration.chain_registration.held_markers`).

    Returns:
        Frame, marker (and tool) parameters, then the MDH base parameters.
    """
    k = check_count(n_markers, "the number of markers")
    check_count(configs, "the number of configurations")
    nominal = from_chain(chain).idealized()
    kind = campaign_kind(measure)
    _check_marker_work(configs, k, len(parameter_set(nominal, "complete")), kind)
    q = chain.random_configurations(configs, seed)
    markers = 0.1 * np.random.default_rng([seed, 4]).uniform(-1.0, 1.0, (k, 3))
    held = held_markers(chain, nominal) if held is None else held
    return observation_model(chain, measure, markers, "complete", structure_q=q, held=held).names


MARKER_WORK_COPIES = 4
"""Copies of the identification Jacobian the count holds at once (J, its weighted copy, the
QR's factors), in the estimate of :func:`_check_marker_work`."""


def marker_work_bytes(m: int, k: int, n_params: int, kind: Measurement) -> int:
    """Memory [B] of counting K markers at m configurations: the Jacobian's copies.

    Rows: the kind's rows at K markers per configuration (``3 K``, + 3 for pose); columns:
    the kind's unknown constants (the frame 6, the markers ``3 K``, + 3 for pose) and the
    ``n_params`` geometric parameters.
    """
    rows = m * kind.rows_of(k)
    cols = kind.unknown_constants(k) + n_params
    return MARKER_WORK_COPIES * 8 * rows * cols


def _check_marker_work(m: int, k: int, n_params: int, kind: Measurement) -> None:
    """Refuse, before any work, K markers needing more than MAX_WORK_BYTES (the most that fit)."""
    need = marker_work_bytes(m, k, n_params, kind)
    if need <= MAX_WORK_BYTES:
        return
    lo, hi = 0, k  # the most markers that fit: lo fits (or is 0), hi does not
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (
            (mid, hi) if marker_work_bytes(m, mid, n_params, kind) <= MAX_WORK_BYTES else (lo, mid)
        )
    per_config = marker_work_bytes(1, k, n_params, kind)
    fit = [f"at most {lo} markers"] if lo else []
    if MAX_WORK_BYTES // per_config:
        fit.append(f"at most {MAX_WORK_BYTES // per_config} configurations (configs)")
    raise InvalidArgumentError(
        f"{k} markers at {m} configurations need about {need / 2**30:.3g} GB; calib allows "
        f"{MAX_WORK_BYTES / 2**30:g} GB: use {' or '.join(fit)}"
    )


__all__ = [
    "CRITERIA",
    "DESIGN_LEVELS",
    "MARKER_WORK_COPIES",
    "REFERENCE_CONFIGS",
    "Indices",
    "ObservationModel",
    "Reference",
    "characteristic_length",
    "check_model_arguments",
    "identifiable_parameters",
    "indices",
    "indices_of",
    "marker_array",
    "marker_work_bytes",
    "observation_model",
    "reference",
    "robot_markers",
]
