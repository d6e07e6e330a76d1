"""Experiment design: which K configurations to measure for a calibration.

:func:`design` draws candidates within the joint limits (or takes the user's), keeps those
a campaign can measure (:mod:`calib.design.constraints`), and picks K of them that optimise a
criterion of the information matrix of the calibration's parameters
(:mod:`calib.design.observability`) by a greedy start and exchanges with low-rank updates
(:mod:`calib.design.exchange`). It compares the result with random sets of K of the same
candidates. :func:`evaluate` gives the indices of a user's set.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.checks import DESIGN_BYTES_PER_CANDIDATE_JOINT as DESIGN_PER_JOINT
from ..core.checks import check_count, check_work, shown
from ..core.choices import CONTACT_MEASURES, DEFAULT_CANDIDATES, DEFAULT_MEASURE, DEFAULT_SET
from ..core.progress import phase, steps
from ..exceptions import InvalidArgumentError
from ..identification.contacts import Contact, contact_kind
from ..kinematics.robot import Chain
from ..kinematics.standing import JointReadings
from ..kinematics.tree import Tree, robot_argument
from ..measurements.limits import check_limits, warn_default_ranges
from .constraints import Constraints, FilterReport, cheap_filters, variable_bounds
from .contact_design import (
    ContactCandidates,
    checked_contact_chain,
    contact_candidates,
    contact_observation_model,
)
from .design_text import design_text, indices_table
from .exchange import EXCHANGE_CRITERIA, CandidatesExhaustedError, least_i, optimal_subset
from .observability import (
    CRITERIA,
    REFERENCE_CONFIGS,
    Indices,
    ObservationModel,
    Reference,
    check_model_arguments,
    indices,
    indices_of,
    observation_model,
    reference,
    robot_markers,
)

RANDOM_SETS = 20
"""Random sets of K candidates the design is compared with."""

RANDOM_POOL = 10
"""With collision checks, the random sets are drawn from a pool of this many times K
candidates drawn and checked first (each set a uniform random K of the collision-free
candidates all the same, at half the checks of 20 sets drawn apart)."""


@dataclass(frozen=True, eq=False)
class Design:
    """A designed set of configurations and how it compares with random ones.

    Attributes:
        robot: Robot name.
        tools: The measured tool frames (one for a chain).
        joint_names: The joints of the chain or tree.
        q: The chosen configurations ``(K, n)`` [rad or m].
        criterion: ``D``, ``A`` or ``I``.
        model: The observation model (the calibration's parameters).
        indices: Indices of the design.
        greedy: Indices of the greedy start.
        random: Indices of random sets of K of the same candidates.
        filters: What the candidate filters did.
        candidates: Candidates the design chose from (after the filters).
        exchanges: Exchanges made after the greedy start.
        sweeps: Sweeps of the exchange.
        seed: Seed of the candidates, the reference set and the random sets.
        timings_ms: Time of each stage [ms].
        contact: For a contact campaign, the plane, point or pose its postures hold, in the
            base frame ``(4, 4)`` (the nominal contact frame at the first candidate); else None.
        readings: The joints off the chain at the chosen configurations, as the candidates
            recorded them (``readings`` of :func:`design`), or None.
    """

    robot: str
    tools: tuple[str, ...]
    joint_names: tuple[str, ...]
    q: np.ndarray
    criterion: str
    model: ObservationModel
    indices: Indices
    greedy: Indices
    random: tuple[Indices, ...]
    filters: FilterReport
    candidates: int
    exchanges: int
    sweeps: int
    seed: int
    timings_ms: dict[str, float] = field(default_factory=dict)
    contact: np.ndarray | None = None
    readings: JointReadings | None = None

    def __repr__(self) -> str:
        """One line (the configurations are ``q``, the full text :meth:`summary`)."""
        return (
            f"<Design {self.robot}: {len(self.q)} configurations of {self.candidates} "
            f"candidates, criterion {self.criterion}, seed {self.seed}>"
        )

    def summary(self, noise_mm: float = 0.05) -> str:
        """The text ``calib design`` prints (:func:`design_text`; ``noise_mm`` [mm])."""
        return design_text(self, noise_mm)

    def random_median(self, name: str) -> float:
        """Median of an index over the random sets."""
        return float(np.median([r.value(name) for r in self.random]))

    def to_dict(self) -> dict:
        """JSON-ready summary (radians, metres)."""
        median = {c: self.random_median(c) for c in CRITERIA}
        return {
            "robot": self.robot,
            "tools": list(self.tools),
            "criterion": self.criterion,
            "configs": len(self.q),
            "candidates": self.candidates,
            "seed": self.seed,
            "parameters": list(self.model.names),
            "characteristic_length": self.model.length,
            "filters": self.filters.to_dict(),
            "design": self.indices.to_dict(),
            "greedy": self.greedy.to_dict(),
            "random_median": {c: (v if np.isfinite(v) else None) for c, v in median.items()},
            "random_sets": len(self.random),
            "exchanges": self.exchanges,
            "sweeps": self.sweeps,
            "joint_names": list(self.joint_names),
            "q": self.q.tolist(),
            "timings_ms": dict(self.timings_ms),
        } | (
            ({} if self.contact is None else {"contact": self.contact.tolist()})
            | ({} if self.readings is None else {"readings": _readings_dict(self.readings)})
        )


def _readings_dict(readings: JointReadings) -> dict[str, list[float]]:
    """The joints off the chain: each joint's positions [rad or m], one per configuration."""
    return {name: readings.values[:, k].tolist() for k, name in enumerate(readings.names)}


def candidate_configurations(
    chain: Chain | Tree, n: int, seed: int, margin: float = 0.0
) -> np.ndarray:
    """``n`` configurations ``(n, j)`` drawn uniformly within the joint limits less the margin.

    The independent joints are drawn (mimic joints follow the joint they mimic).
    """
    check_count(n, "the number of candidates")
    check_work(n, chain.n, chain.name, len(chain.tool_ids), "candidates", DESIGN_PER_JOINT)
    lower, upper = variable_bounds(chain, margin)
    rng = np.random.default_rng([check_count(seed, "the seed", 0), 5])
    return chain.joint_values(lower + (upper - lower) * rng.random((n, len(lower))))


def _subset(n: int, k: int, rng: np.random.Generator) -> np.ndarray:
    return np.sort(rng.choice(n, size=min(n, k), replace=False))


def design(
    chain: Chain | Tree | str | Path,
    configs: int,
    *,
    candidates: int | np.ndarray = DEFAULT_CANDIDATES,
    criterion: str = "D",
    measure: str = DEFAULT_MEASURE,
    marker=None,
    params: str = DEFAULT_SET,
    orientation_weight: float = 1.0,
    constraints: Constraints | None = None,
    seed: int = 0,
    random_sets: int = RANDOM_SETS,
    progress: Callable | None = None,
    readings: JointReadings | None = None,
) -> Design:
    """Choose K configurations to measure.

    Args:
        chain: The chain, or a tree (its tools measured at every configuration), or a
            catalog name or URDF path (loaded as :func:`calib.analyze` loads it: the catalog's
            base and tool).
        configs: Number of configurations K.
        candidates: Number of random candidates, or the candidates ``(N, n)`` themselves
            (configurations known to be reachable).
        criterion: ``D`` (log det of the information), ``A`` (mean parameter variance) or
            ``I`` (mean predicted position error on the reference set).
        measure: ``position`` or ``pose`` (a tree: ``position``), or a contact (``plane``,
            ``plane-point``, ``fixed-point``, ``fixed-pose``; a chain): the candidates are
            then postures on the contact (:mod:`!calib.design.contact_design`).
        marker: Measured points in the tool frame ``(3,)`` or ``(K, 3)`` [m] (a tree: one
            point for every tool, or one per tool; a contact: none).
        params: The calibration's parameter level (``DESIGN_LEVELS``; a tree: ``frames`` or
            ``complete``; a contact: ``complete``).
        orientation_weight: Weight of the orientation rows of pose data [m/rad]: the ratio
            of the position noise to the orientation noise (``calibrate`` estimates it from
            the data; 1 by default).
        constraints: Limits of the campaign (default: self-collision checked, no margin).
        seed: Seed of the candidates, the reference set and the random sets.
        random_sets: Random sets of K candidates to compare with.
        progress: Progress bars of the phases (:mod:`!calib.core.progress`; e.g.
            ``tqdm.tqdm``), or None.
        readings: Positions of joints off the chain, a row per given candidate (a
            recording's other arm and leg), where the collision and line-of-sight checks
            hold them; None: at zero.

    Returns:
        The design.

    Raises:
        InvalidArgumentError: A bad argument, too few candidates left, or candidates that
            cannot identify the parameters.
    """
    clock = [time.perf_counter()]
    chain = robot_argument(chain, "chain")
    k = check_count(configs, "the number of configurations")
    seed = check_count(seed, "the seed", 0)
    constraints = _checked_options(criterion, constraints, progress)
    readings = _checked_readings(chain, candidates, readings)
    asked = (measure, _contact_of(measure), marker, params, orientation_weight)
    chain, cands, q_all, readings = _candidates(
        chain, asked, candidates, seed, constraints.margin, readings, progress
    )
    q, lazy = _filtered(chain, q_all, marker, constraints, k, readings)
    check = lazy.ok if lazy.active else None
    clock.append(time.perf_counter())
    rng = np.random.default_rng([seed, 6])
    model = _observation(chain, cands, asked, seed)
    ref = _reference(model, q, rng, check, (lazy, k))
    with phase(progress, f"design: Jacobians of {len(q)} candidates"):
        J = model.jacobian(q)
    clock.append(time.perf_counter())
    result = _exchanged(J, (k, criterion), ref, progress, check, lazy)
    clock.append(time.perf_counter())
    chosen = np.array(result.design)
    rand = _random_indices(J, ref, (k, random_sets), rng, check, progress)
    clock.append(time.perf_counter())
    report = lazy.report()
    return Design(
        robot=chain.name,
        tools=chain.tool_frames,
        joint_names=chain.joint_names,
        q=q[chosen],
        criterion=criterion,
        model=model,
        indices=_indices_rows(J, chosen, ref),
        greedy=_indices_rows(J, np.array(result.greedy), ref),
        random=rand,
        filters=report,
        candidates=len(q) - _lazily_rejected(report),
        exchanges=result.exchanges,
        sweeps=result.sweeps,
        seed=seed,
        timings_ms=_timings(clock),
        contact=None if cands is None else cands.frame,
        readings=None if lazy.readings is None else lazy.readings.take(chosen),
    )


def _candidates(
    chain: Chain | Tree, asked: tuple, candidates, seed: int, margin: float, readings, progress
) -> tuple[Chain | Tree, ContactCandidates | None, np.ndarray, JointReadings | None]:
    """The chain, the contact's candidates (or None), the candidates ``(N, n)``, the readings.

    ``asked``: the measure, its contact (or None), the marker, the parameter level and the
    orientation weight. With a contact, the candidates are postures on it (the chain checked
    for it, the readings those of the postures kept); else drawn or the user's, checked.
    """
    measure, contact, marker, params, orientation_weight = asked
    if contact is None:
        q_all = _instrument_candidates(chain, candidates, seed, margin)
        check_model_arguments(measure, params, orientation_weight, chain.is_tree)
        return chain, None, q_all, readings
    chain = checked_contact_chain(chain, contact, marker, params)
    if orientation_weight != 1.0:
        raise InvalidArgumentError(
            f"orientation_weight weighs the orientation rows of pose data: a "
            f"{contact.label} design weighs no row"
        )
    with phase(progress, "design: candidates on the contact"):
        cands = contact_candidates(chain, contact, candidates, seed, margin)
    readings = None if readings is None else readings.take(cands.rows)
    return chain, cands, cands.q, readings


def _observation(chain, cands, asked: tuple, seed: int) -> ObservationModel:
    """The observation model of the calibration: on the contact, or of the measure."""
    measure, contact, marker, params, orientation_weight = asked
    if cands is not None and isinstance(chain, Chain) and contact is not None:
        return contact_observation_model(chain, cands, contact)
    return observation_model(chain, measure, marker, params, orientation_weight, seed=seed)


def _reference(model: ObservationModel, q: np.ndarray, rng, check, filters: tuple) -> Reference:
    """The reference set of I and G: ``REFERENCE_CONFIGS`` random candidates the checks pass.

    ``filters``: the lazy checks and the number of configurations asked, k.

    Raises:
        InvalidArgumentError: Fewer than k (or ``REFERENCE_CONFIGS``) pass, every one checked.
    """
    lazy, k = filters
    rows = _draw(len(q), REFERENCE_CONFIGS, rng, check)
    if len(rows) < min(k, REFERENCE_CONFIGS):  # every candidate checked: too few pass
        raise _too_few(lazy.report(), k)
    return reference(model, q[rows])


def _exchanged(J: np.ndarray, asked: tuple, ref: Reference, progress, check, lazy):
    """The greedy start and exchanges (:func:`optimal_subset`); ``asked``: k, the criterion.

    Raises:
        InvalidArgumentError: The checks rejected so many candidates that fewer than k pass.
    """
    k, criterion = asked
    try:
        return optimal_subset(J, k, criterion, ref.mean, progress, check)
    except CandidatesExhaustedError:
        raise _too_few(lazy.report(), k) from None


def _random_indices(J: np.ndarray, ref: Reference, sizes: tuple, rng, check, progress) -> tuple:
    """The indices of the random sets; ``sizes``: their size k and their number (checked)."""
    k, random_sets = sizes
    n_random = check_count(random_sets, "the number of random sets")
    sets = steps(progress, range(n_random), "design: random sets", n_random)
    return tuple(_indices_rows(J, rows, ref) for rows in _random_sets(len(J), k, rng, check, sets))


def _timings(clock: list[float]) -> dict[str, float]:
    """The time of each phase [ms], from the clock read at its start and at the end."""
    stages = ("filters", "jacobian", "exchange", "random")
    return {s: 1e3 * (b - a) for s, a, b in zip(stages, clock[:-1], clock[1:], strict=True)}


def _checked_options(criterion: str, constraints, progress) -> Constraints:
    """The constraints (default: none but the self-collisions), the other two checked.

    Raises:
        InvalidArgumentError: An unknown criterion, constraints that are no
            :class:`Constraints`, or a progress that is not callable.
    """
    if not isinstance(criterion, str) or criterion not in EXCHANGE_CRITERIA:
        raise InvalidArgumentError(
            f"unknown criterion {shown(criterion)}: choose {', '.join(EXCHANGE_CRITERIA)}"
        )
    constraints = Constraints() if constraints is None else constraints
    if not isinstance(constraints, Constraints) or not (progress is None or callable(progress)):
        raise InvalidArgumentError(
            f"constraints must be a calib.design.constraints.Constraints and progress a "
            f"callable or None, got {type(constraints).__name__} and {type(progress).__name__}"
        )
    return constraints


def _instrument_candidates(chain: Chain | Tree, candidates, seed: int, margin: float):
    """Random candidates within the limits, or the user's ``(N, n)`` checked."""
    if isinstance(candidates, int | np.integer) and not isinstance(candidates, bool):
        warn_default_ranges(chain, "give your own candidates")
        return candidate_configurations(chain, int(candidates), seed, margin)
    return _within_limits(chain, candidates, "the candidates")


def _within_limits(chain: Chain | Tree, q, what: str) -> np.ndarray:
    """The user's configurations ``(K, n)``, refused far past a limit as a file's are."""
    q = chain.check_configurations(q)
    check_limits(chain, q, what, np.arange(1, len(q) + 1), warn=False)  # degrees?
    return q


def _checked_readings(chain: Chain | Tree, candidates, readings) -> JointReadings | None:
    """The readings of joints off the chain at the given candidates, checked, or None.

    Raises:
        InvalidArgumentError: Readings that are no :class:`JointReadings`, with drawn
            candidates or a tree, or that do not fit the candidates (names or rows).
    """
    if readings is None:
        return None
    drawn = isinstance(candidates, int | np.integer)
    if not isinstance(readings, JointReadings) or drawn or not isinstance(chain, Chain):
        raise InvalidArgumentError(
            f"readings are a calib.kinematics.standing.JointReadings of the joints off a "
            f"chain at the candidates given, got {type(readings).__name__} on a "
            f"{type(chain).__name__} with {'drawn' if drawn else 'given'} candidates"
        )
    readings.configurations(chain, candidates)  # names and rows
    return readings


def _filtered(chain, q_all: np.ndarray, markers, constraints: Constraints, k: int, readings):
    """The candidates the margin and workspace keep ``(N, n)`` (at least ``k``), the checks.

    The checks (collision, line of sight) are made on the candidates the design considers,
    the joints off the chain as ``readings`` hold them (or at zero).
    """
    keep, lazy = cheap_filters(chain, q_all, robot_markers(chain, markers), constraints, readings)
    if int(np.count_nonzero(keep)) < k:
        raise _too_few(lazy.report(), k)
    return q_all[keep], lazy


def _too_few(report: FilterReport, k: int) -> InvalidArgumentError:
    """The error of filters that leave fewer than k candidates.

    It says why when the line of sight hid every candidate it looked at.
    """
    hidden = report.kept == 0 and dict(report.rejected).get("line_of_sight", 0) > 0
    why = (
        ": the line of sight hid every candidate it checked: is the measured point inside a "
        "link's collision geometry (a flange's origin often is: give a point on the tool's "
        "surface, --marker)?"
    )
    return InvalidArgumentError(
        f"{_passing(report)}, fewer than the {k} configurations asked: draw more candidates "
        f"or relax the constraints{why if hidden else ''}"
    )


def _passing(report: FilterReport) -> str:
    """How many candidates pass the filters, and what each filter rejects."""
    rejects = ", ".join(f"{name} rejects {n}" for name, n in report.rejected)
    return f"{report.kept} of {report.candidates} candidates pass the filters ({rejects})"


def _lazily_rejected(report: FilterReport) -> int:
    """Candidates the collision and line-of-sight checks rejected."""
    return sum(n for name, n in report.rejected if name in ("collision", "line_of_sight"))


def _random_sets(n: int, k: int, rng: np.random.Generator, check, sets) -> Iterator[np.ndarray]:
    """Random sets of ``k`` of ``n`` candidates, one per item of ``sets``.

    Without a check, each drawn apart; with one, each a random k of a pool of
    ``RANDOM_POOL k`` candidates the check accepts (drawn once, at the first set).
    """
    pool = None
    for _ in sets:
        if check is None:
            yield _subset(n, k, rng)
            continue
        if pool is None:
            pool = _draw(n, RANDOM_POOL * k, rng, check)
        yield pool[_subset(len(pool), k, rng)]


def _draw(n: int, k: int, rng: np.random.Generator, check) -> np.ndarray:
    """``min(n, k)`` random candidates (sorted); with ``check``, those it accepts.

    With a check, the candidates are checked in a random order until k pass (fewer if the
    candidates run out).
    """
    if check is None:
        return _subset(n, k, rng)
    order = rng.permutation(n)
    kept: list[np.ndarray] = []
    got, start = 0, 0
    while got < k and start < n:
        chunk = order[start : start + (k - got)]
        good = chunk[check(chunk)]
        kept.append(good)
        got, start = got + len(good), start + len(chunk)
    return np.sort(np.concatenate(kept)) if kept else np.zeros(0, dtype=int)


def _contact_of(measure) -> Contact | None:
    """The contact kind a measure names, or None for an instrument's measure."""
    if isinstance(measure, str) and measure in CONTACT_MEASURES:
        return contact_kind(measure)
    return measure if isinstance(measure, Contact) else None


def _indices_rows(J: np.ndarray, rows: np.ndarray, ref: Reference) -> Indices:
    return indices_of(J[rows], ref)


def evaluate(
    chain: Chain | Tree | str | Path,
    q: np.ndarray,
    measure: str = DEFAULT_MEASURE,
    marker=None,
    params: str = DEFAULT_SET,
    seed: int = 0,
    orientation_weight: float = 1.0,
    *,
    candidates: int | np.ndarray | None = None,
    constraints: Constraints | None = None,
    readings: JointReadings | None = None,
    seen: np.ndarray | None = None,
) -> Indices:
    """Observability indices of a user's configurations ``(K, n)`` of a chain or tree.

    The reference set of I and G: ``REFERENCE_CONFIGS`` random configurations within the
    joint limits (seed ``seed``), or, given ``candidates``, ``constraints`` or
    ``readings`` (:func:`design`'s), the design's own: as many of the candidates the
    constraints keep, drawn as :func:`design` draws them (the same seed and limits: the
    same figure as the design's). The independent columns are chosen at random
    configurations, so that the set's own rank deficiency shows. ``seen`` ``(K, markers)``:
    the markers each configuration measured (None: all; a measurement file's partial
    marker rows, :func:`!calib.design.configurations.markers_seen`).

    Args:
        chain: The chain or tree, or a catalog name or URDF path (as :func:`design`'s).
        q: The configurations to score ``(K, n)`` [rad or m].
        measure: ``position`` or ``pose`` (a tree: ``position``).
        marker: Measured points in the tool frame ``(3,)`` or ``(K, 3)`` [m] (as
            :func:`design`'s).
        params: The calibration's parameter level (as :func:`design`'s).
        seed: Seed of the reference set and of the configurations of the independent columns.
        orientation_weight: Weight of the orientation rows of pose data [m/rad].
        candidates: As :func:`design`'s; given, the reference set is the design's own.
        constraints: As :func:`design`'s; given, the reference set is the design's own.
        readings: As :func:`design`'s; given, the reference set is the design's own.
        seen: The markers each configuration measured ``(K, markers)``, or None: all.

    Returns:
        The observability indices of ``q`` (I and G over the reference set).

    Raises:
        InvalidArgumentError: A bad argument, a contact (its postures are not scored yet), or
            limits no candidate passes.
    """
    chain = robot_argument(chain, "chain")
    contact = _contact_of(measure)
    if contact is not None:
        raise InvalidArgumentError(
            f"evaluate scores a measured campaign (pose or position), not yet a "
            f"{contact.label} contact's postures; to choose them: "
            f"calib.design(chain, K, measure='{contact.label}')"
        )
    q = _within_limits(chain, q, "the configurations")
    if not len(q):
        raise InvalidArgumentError("no configuration to evaluate: q has no row")
    model = observation_model(chain, measure, marker, params, orientation_weight, seed=seed)
    if candidates is None and constraints is None and readings is None:
        ref_q = candidate_configurations(chain, REFERENCE_CONFIGS, seed)
    else:
        ref_q = _design_reference(chain, marker, seed, candidates, constraints, readings)
    return indices(model, q, reference(model, ref_q), seen)


def _design_reference(chain, marker, seed: int, candidates, constraints, readings) -> np.ndarray:
    """The reference postures :func:`design` averages over with these arguments.

    Raises:
        InvalidArgumentError: Limits that no candidate passes.
    """
    limits = _checked_options("D", constraints, None)
    drawn = DEFAULT_CANDIDATES if candidates is None else candidates
    readings = _checked_readings(chain, drawn, readings)
    q_all = _instrument_candidates(chain, drawn, check_count(seed, "the seed", 0), limits.margin)
    keep, lazy = cheap_filters(chain, q_all, robot_markers(chain, marker), limits, readings)
    check = lazy.ok if lazy.active else None
    rows = _draw(
        int(np.count_nonzero(keep)), REFERENCE_CONFIGS, np.random.default_rng([seed, 6]), check
    )
    if not len(rows):
        raise InvalidArgumentError(
            f"no reference posture: {_passing(lazy.report())}; the prediction averages over "
            f"the postures the limits keep: draw more candidates or relax the constraints"
        )
    return q_all[keep][rows]


__all__ = [
    "DEFAULT_CANDIDATES",
    "Design",
    "candidate_configurations",
    "design",
    "design_text",
    "evaluate",
    "indices_table",
    "least_i",
]
