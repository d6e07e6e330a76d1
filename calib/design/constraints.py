"""What a real campaign can measure: filters on candidate configurations.

Each filter keeps a candidate or rejects it, in this order:

1. ``margin``: every joint at least ``margin`` [rad or m] inside its limits (continuous
   joints have none);
2. ``workspace``: every measured point inside a box of the base frame (the instrument's
   volume);
3. ``collision``: no self-collision (unless ``collision`` is off), no contact with an
   obstacle box (always)
   (:mod:`calib.design.collision`; a URDF without collision geometry is accepted with a note);
4. ``line_of_sight``: no geometry between the instrument and any measured point.

The joints off the chain (another arm, the other leg) are at zero in the last two, or at each
candidate's recorded positions when they are given (``readings``: a recorded touch's).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.checks import real_array
from ..exceptions import InvalidArgumentError
from ..identification.jacobian import measured_point
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain
from ..kinematics.standing import JointReadings
from ..kinematics.tree import Tree
from ..kinematics.tree_model import from_tree


@dataclass(frozen=True)
class Constraints:
    """The limits of a campaign.

    Attributes:
        margin: Distance [rad or m] every joint keeps from its limits.
        workspace: Box ``(xmin, ymin, zmin, xmax, ymax, zmax)`` [m] of the base frame that
            holds every measured point, or None.
        collision: Reject self-collisions.
        obstacles: Boxes ``(xmin, ymin, zmin, xmax, ymax, zmax)`` [m] of the base frame;
            candidates touching one are rejected, whatever ``collision`` says.
        srdf: SRDF of the disabled collision pairs (default: found beside the URDF).
        line_of_sight: Instrument position [m] in the base frame: every measured point must
            be in its view, or None.
    """

    margin: float = 0.0
    workspace: tuple[float, ...] | None = None
    collision: bool = True
    obstacles: tuple[tuple[float, ...], ...] = ()
    srdf: str | Path | None = None
    line_of_sight: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        ok = isinstance(self.margin, int | float) and np.isfinite(self.margin)
        if not ok or self.margin < 0:
            raise InvalidArgumentError(f"the margin must be a number >= 0, got {self.margin!r}")
        if self.workspace is not None:
            box = real_array(self.workspace, "the workspace box", (6,), 1e3)
            if not np.all(box[:3] < box[3:]):
                raise InvalidArgumentError(
                    "the workspace box is xmin ymin zmin xmax ymax zmax with min < max"
                )
            object.__setattr__(self, "workspace", tuple(float(v) for v in box))
        boxes = tuple(
            tuple(float(v) for v in real_array(b, "an obstacle box", (6,), 1e3))
            for b in self.obstacles
        )
        object.__setattr__(self, "obstacles", boxes)
        if self.line_of_sight is not None:
            eye = real_array(self.line_of_sight, "the instrument position", (3,), 1e3)
            object.__setattr__(self, "line_of_sight", tuple(float(v) for v in eye))


@dataclass(frozen=True)
class FilterReport:
    """What the filters did.

    Attributes:
        candidates: Candidates given.
        rejected: ``(filter, count)`` per filter applied, in order.
        notes: Remarks (collision pairs disabled, no geometry, ...).
        checked: Candidates the collision and line-of-sight checks looked at (a design
            checks those it considers, :class:`!LazyChecks`), or None (no such check).
    """

    candidates: int
    rejected: tuple[tuple[str, int], ...] = ()
    notes: tuple[str, ...] = field(default=())
    checked: int | None = None

    @property
    def kept(self) -> int:
        """Candidates left."""
        return self.candidates - sum(n for _, n in self.rejected)

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return {
            "candidates": self.candidates,
            "kept": self.kept,
            "rejected": dict(self.rejected),
            "notes": list(self.notes),
        } | ({} if self.checked is None else {"checked": self.checked})


def _shrunk(lower, upper, continuous, names, margin: float) -> tuple[np.ndarray, np.ndarray]:
    m = np.where(continuous, 0.0, margin)
    lo, hi = lower + m, upper - m
    if np.any(lo >= hi):
        k = int(np.argmax(lo >= hi))
        raise InvalidArgumentError(
            f"a margin of {margin:g} leaves no room in the limits of joint "
            f"'{names[k]}' [{lower[k]:.6g}, {upper[k]:.6g}]"
        )
    return lo, hi


def margin_bounds(robot: Chain | Tree, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Sampling bounds of each joint with the margin (continuous joints: a full turn).

    Raises:
        InvalidArgumentError: The margin leaves no room in some joint's range.
    """
    return _shrunk(robot.lower, robot.upper, robot.continuous, robot.joint_names, margin)


def variable_bounds(robot: Chain | Tree, margin: float) -> tuple[np.ndarray, np.ndarray]:
    """Sampling bounds of the independent joints (``robot.variable_names``) with the margin.

    The joints themselves, or, for a chain with mimic joints, the joints they follow
    (:mod:`calib.kinematics.mimic`): configurations are drawn there and
    ``robot.joint_values`` maps them.

    Raises:
        InvalidArgumentError: The margin leaves no room in some joint's range.
    """
    coupling = robot.coupling
    if coupling is None:
        return margin_bounds(robot, margin)
    endless = {n for n, c in zip(robot.joint_names, robot.continuous, strict=True) if c}
    continuous = np.array([n in endless for n in coupling.names], dtype=bool)
    return _shrunk(coupling.lower, coupling.upper, continuous, coupling.names, margin)


def measured_points(robot: Chain | Tree, q: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """Measured points in the base frame ``(m, K, 3)`` [m] (nominal geometry).

    Args:
        robot: A chain (K markers on its tool) or a tree (K = T: marker t on tool t).
        q: Joint positions ``(m, n)``.
        markers: Markers in their tool's frame ``(K, 3)`` [m].
    """
    if robot.is_tree:
        F = from_tree(robot).forward(q)
        return F[..., :3, 3] + np.einsum("mtij,tj->mti", F[..., :3, :3], markers)
    kin = from_chain(robot).kinematics(q)
    return np.stack([measured_point(kin, mk) for mk in markers], axis=1)


def filter_candidates(
    chain: Chain | Tree,
    q: np.ndarray,
    markers: np.ndarray,
    constraints: Constraints,
    readings: JointReadings | None = None,
) -> tuple[np.ndarray, FilterReport]:
    """Keep the candidate configurations a campaign can measure (every filter, every one).

    Args:
        chain: The chain or tree.
        q: Candidate joint positions ``(N, n)``.
        markers: Measured points in the tool frame ``(K, 3)`` [m] (a tree: one per tool).
        constraints: The limits.
        readings: Positions of the joints off the chain, a row per candidate, where the
            collision and line-of-sight checks hold them (a chain), or None: at zero.

    Returns:
        A mask of the kept candidates ``(N,)`` and the report.
    """
    keep, lazy = cheap_filters(chain, q, markers, constraints, readings)
    keep[np.flatnonzero(keep)] = lazy.ok(np.arange(int(np.count_nonzero(keep))))
    return keep, lazy.report()


def cheap_filters(
    chain: Chain | Tree,
    q: np.ndarray,
    markers: np.ndarray,
    constraints: Constraints,
    readings: JointReadings | None = None,
) -> tuple[np.ndarray, LazyChecks]:
    """The margin and workspace filters applied, the costly ones (:class:`LazyChecks`) not.

    The arguments are :func:`filter_candidates`'s.

    Returns:
        A mask of the candidates the margin and the workspace keep ``(N,)``, and the checks
        of collisions and lines of sight of those candidates (indexed among them), made on
        demand.
    """
    keep = np.ones(len(q), dtype=bool)
    rejected: list[tuple[str, int]] = []

    def apply(name: str, ok: np.ndarray, where: np.ndarray) -> None:
        before = int(np.sum(keep))
        keep[where[~ok]] = False
        rejected.append((name, before - int(np.sum(keep))))

    lower, upper = margin_bounds(chain, constraints.margin)
    inside = np.all((q >= lower - 1e-12) & (q <= upper + 1e-12) | chain.continuous, axis=1)
    apply("margin", inside, np.arange(len(q)))
    need_points = constraints.workspace is not None or constraints.line_of_sight is not None
    points = measured_points(chain, q, markers) if need_points else None
    if constraints.workspace is not None:
        box = np.asarray(constraints.workspace)
        ok = np.all((points >= box[:3]) & (points <= box[3:]), axis=(1, 2))
        apply("workspace", ok[keep], np.flatnonzero(keep))
    points = None if points is None else points[keep]
    kept = None if readings is None else readings.take(keep)
    return keep, LazyChecks(chain, q[keep], points, constraints, len(q), tuple(rejected), kept)


class LazyChecks:
    """The costly filters (collision, line of sight), checked on demand and remembered.

    A candidate is checked once, when :meth:`ok` is first asked about it: collisions first,
    then (if it passes) the line of sight. :meth:`report` counts the candidates checked and
    those each filter rejected.

    Args:
        chain: The chain or tree.
        q: The candidates to check ``(N, n)``.
        points: Measured points of those candidates ``(N, K, 3)`` [m], or None (no line of
            sight).
        constraints: The limits.
        total: Candidates given.
        rejected: ``(filter, count)`` of the filters already applied (margin, workspace).
        readings: Positions of the joints off the chain, a row per candidate of ``q``, or
            None (at zero).
    """

    def __init__(
        self, chain, q, points, constraints: Constraints, total, rejected, readings=None
    ) -> None:
        self.q, self.points, self.total, self.cheap = q, points, total, rejected
        self.readings: JointReadings | None = readings
        self.collision = bool(constraints.collision or constraints.obstacles)
        self.eye = constraints.line_of_sight
        self.status = np.zeros(len(q), dtype=np.int8)  # 0 unchecked, 1 kept, -1 collision, -2 sight
        self.checker = None
        self.notes: tuple[str, ...] = ()
        if self.collision or self.eye is not None:
            from .collision import collision_checker

            self.checker = collision_checker(
                chain, constraints.srdf, constraints.obstacles, self_collision=constraints.collision
            )
            self.notes = tuple(self.checker.notes)
            if readings is not None:
                self.notes += (
                    f"{len(readings.names)} joints off the chain at each candidate's recorded "
                    f"positions",
                )

    @property
    def active(self) -> bool:
        """Whether there is anything to check."""
        return self.checker is not None

    @property
    def checked(self) -> int:
        """Candidates checked so far."""
        return int(np.count_nonzero(self.status))

    def ok(self, idx: np.ndarray) -> np.ndarray:
        """Whether each candidate of ``idx`` passes the checks ``(len(idx),)``."""
        idx = np.asarray(idx, dtype=int)
        todo = np.unique(idx[self.status[idx] == 0])
        checker = self.checker
        if todo.size and checker is None:
            self.status[todo] = 1
        elif todo.size and checker is not None:
            bad = np.zeros(todo.size, dtype=bool)
            if self.collision:
                bad = checker.colliding(self.q[todo], self._readings(todo))
            self.status[todo[bad]] = -1
            rest = todo[~bad]
            if self.eye is not None and rest.size and self.points is not None:
                eye = np.asarray(self.eye)
                hidden = checker.blocked(self.q[rest], self.points[rest], eye, self._readings(rest))
                self.status[rest[hidden]] = -2
                rest = rest[~hidden]
            self.status[rest] = 1
        return self.status[idx] > 0

    def _readings(self, idx: np.ndarray) -> JointReadings | None:
        """The readings of the candidates ``idx``, or None."""
        return None if self.readings is None else self.readings.take(idx)

    def report(self) -> FilterReport:
        """What the filters did: the cheap ones on every candidate, these on those checked."""
        rejected = list(self.cheap)
        if self.collision:
            rejected.append(("collision", int(np.count_nonzero(self.status == -1))))
        if self.eye is not None:
            rejected.append(("line_of_sight", int(np.count_nonzero(self.status == -2))))
        checked = self.checked if self.active else None
        return FilterReport(self.total, tuple(rejected), self.notes, checked)


__all__ = [
    "Constraints",
    "FilterReport",
    "LazyChecks",
    "cheap_filters",
    "filter_candidates",
    "margin_bounds",
    "measured_points",
    "variable_bounds",
]
