"""``analyze``: which parameters a robot's instrument, or a calibration problem, determines.

A robot's analysis imports no more than :mod:`~calib.identification.identifiability` (``calib
analyze`` starts without SciPy). Rationale: docs/developers/engine.md#analysis
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast, overload

from ..core.choices import DEFAULT_CONFIGS, DEFAULT_MEASURE, DEFAULT_SET
from ..core.words import counted
from ..exceptions import InvalidArgumentError
from ..identification import identifiability
from ..identification.identifiability import Identifiability
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree

if TYPE_CHECKING:
    from .problem import Problem

__all__ = ["ProblemAnalysis", "analyze"]


@dataclass(frozen=True)
class ProblemAnalysis:
    """What the terms of a problem determine together, on the nominal robot at their rows.

    Attributes:
        robot: The robot's name.
        shape: The problem's shape (``chain``, ``tree``, ``contacts``, ``chains``).
        terms: Each term, in one line (its chain, rows and kind).
        unknowns: Every unknown the rows depend on: each term's objects, contact, measuring
            or camera frame and markers, then every joint placement component (``joint:rz``).
        base: The unknowns determined (a basis of what the rows see, in the same order).
    """

    robot: str
    shape: str
    terms: tuple[str, ...]
    unknowns: tuple[str, ...]
    base: tuple[str, ...]

    @property
    def n_base(self) -> int:
        """Unknowns the rows determine (the rank)."""
        return len(self.base)

    def __repr__(self) -> str:
        """One line (the names are in the attributes, the full text in ``summary()``)."""
        return (
            f"<ProblemAnalysis {self.robot}: {self.shape}, {counted(len(self.terms), 'terms')}, "
            f"{self.n_base} of {self.n_unknowns} unknowns determined>"
        )

    @property
    def n_unknowns(self) -> int:
        """Unknowns the rows depend on."""
        return len(self.unknowns)

    def to_dict(self) -> dict:
        """The analysis as plain data (what ``--json`` would print)."""
        return {
            "robot": self.robot,
            "shape": self.shape,
            "terms": list(self.terms),
            "n_base": self.n_base,
            "n_unknowns": self.n_unknowns,
            "base": list(self.base),
        }

    def summary(self) -> str:
        """The analysis in a few lines: the terms, then the count and what is determined."""
        lines = [f"{self.robot}: {counted(len(self.terms), 'terms')}, {self.shape}"]
        lines += [f"  {t}" for t in self.terms]
        lines.append(
            f"unknowns determined: {self.n_base} of {self.n_unknowns} (objects, frames and "
            "markers, then every joint placement component)"
        )
        lines.append("  " + ", ".join(self.base))
        return "\n".join(lines)


def _count(problem: Problem) -> ProblemAnalysis:
    """The joint fit's count of a problem's terms (a tree: one measured term per tool)."""
    from ..measurements.data import Measurements
    from .engine import Run, determined_unknowns
    from .instrument import prepare_tree
    from .options import Options

    terms = problem.terms
    guesses = [t.guess for t in terms if t.touches and t.guess is not None]
    if problem.shape == "tree":
        tree = cast(Tree, terms[0].robot)
        rows = cast(Measurements, terms[0].data)
        chains, data = list(tree.chains), prepare_tree(tree, rows, None, 0.0, 0)[0]
    else:
        chains, data = [cast(Chain, t.robot) for t in terms], [t.data for t in terms]
    run = Run(
        chains,
        data,
        None,
        Options(max_iterations=problem.max_iterations),  # every row, as registered
        guesses[0] if guesses else None,
        shared_planes=problem.shared_planes,
        pose_weight=problem.pose_weight,
        instrument=problem.shape in ("chain", "tree"),
        known_planes=problem.known_planes,
    )
    base, unknowns = determined_unknowns(run)
    return ProblemAnalysis(
        terms[0].robot.name, problem.shape, tuple(repr(t) for t in terms), unknowns, base
    )


@overload
def analyze(robot: Problem) -> ProblemAnalysis: ...


@overload
def analyze(
    robot: str | Path | Chain | Tree,
    base: str | None = None,
    tool: str | Sequence[str] | None = None,
    measure: str = DEFAULT_MEASURE,
    marker=None,
    params: str = DEFAULT_SET,
    configs: int = DEFAULT_CONFIGS,
    seed: int = 0,
) -> Identifiability: ...


def analyze(
    robot,
    base=None,
    tool=None,
    measure=DEFAULT_MEASURE,
    marker=None,
    params=DEFAULT_SET,
    configs=DEFAULT_CONFIGS,
    seed=0,
):
    """Which parameters a robot's instrument, or a calibration problem, determines.

    Args:
        robot: A :class:`~.problem.Problem` (its terms' rows say what is measured: nothing
            else is given), or a catalog name, URDF path, chain or tree.
        base: Base frame (default: the catalog's or the URDF root).
        tool: Tool frame, or several: a tree (default: the catalog's or the deepest tip).
        measure: ``position`` (default: a point measured, as the command line's), ``pose``,
            rows (``x,y,z,rx``) or a contact kind (``plane``, ...).
        marker: Measured point in the tool frame, 3 numbers [m].
        params: ``complete`` (default: the set ``calibrate`` chooses from) or ``paper``.
        configs: Number of random configurations m (>= 1).
        seed: Seed of the configurations.

    Returns:
        A robot's :class:`~calib.identification.identifiability.Identifiability` (what
        ``calib analyze`` prints), or a problem's
        :class:`~calib.calibration.analysis.ProblemAnalysis`.

    Raises:
        InvalidArgumentError: A problem given with other arguments; a bad argument;
            ``measure="pixels"`` (a camera's count:
            :func:`~calib.calibration.pixel_chain.pixel_count`).
        DataError: A problem's rows that cannot be registered (too few, not its chain's).
    """
    problem = sys.modules.get(f"{__package__}.problem")  # loaded if a Problem exists
    if problem is not None and isinstance(robot, problem.Problem):
        defaults = (None, None, None, DEFAULT_MEASURE, DEFAULT_SET, DEFAULT_CONFIGS, 0)
        if (base, tool, marker, measure, params, configs, seed) != defaults:
            raise InvalidArgumentError(
                "a problem says its robot, rows and kinds: give analyze(problem) alone"
            )
        return _count(robot)
    if problem is not None and isinstance(robot, problem.Term):
        raise InvalidArgumentError("a term is analysed in its problem: analyze(Problem((term,)))")
    if isinstance(measure, str) and measure == "pixels":
        raise InvalidArgumentError(
            "calib.analyze takes no camera: a camera's pixels are counted by "
            "calib.calibration.pixel_chain.pixel_count(chains, cameras, target)"
        )
    return identifiability.analyze(robot, base, tool, measure, marker, params, configs, seed)
