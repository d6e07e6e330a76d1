"""Survey of identifiable sets across many chains and trees (the catalog and extra URDFs)."""

from __future__ import annotations

import csv
import io
import time
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ..core.checks import check_count, check_work, shown
from ..core.choices import DEFAULT_MEASURE, VERDICT_SET
from ..core.progress import steps
from ..core.words import counted
from ..exceptions import CalibError, InvalidArgumentError, RobotNotFoundError
from ..identification.identifiability import DEFAULT_CONFIGS, analyze
from ..identification.kinds import kind_of
from ..identification.measures import MeasureKind, Measurement
from ..kinematics.catalog import catalog, catalog_entry
from ..kinematics.robot import check_robot
from ..kinematics.tree import load_robot

__all__ = [
    "COLUMNS",
    "VERDICT_SET",
    "MarkerCount",
    "SweepRow",
    "marker_count",
    "rows_table",
    "rows_to_csv",
    "sweep",
]


@dataclass(frozen=True)
class SweepRow:
    """One chain (or tree) of a sweep.

    Attributes:
        robot: Catalog name or URDF path.
        chain: ``base -> tool`` (a tree: ``base -> tool1, tool2, ...``).
        revolute: Number R of revolute joints (shared joints of a tree once).
        prismatic: Number P of prismatic joints.
        tools: Number T of tools (1 for a chain).
        n_standard: Standard parameters of the paper set.
        n_base_paper: Base parameters of the paper set.
        n_base_complete: Base parameters of the complete set.
        n_complete: Rank of the complete reference model.
        n_theory: 4R + 2P + 6T (pose) or + 3T (position; 2 fewer on the last axis).
        verdict: ``complete`` or ``misses N`` (for the set the sweep was asked about), or
            ``error``.
        time_ms: Time to load and analyse the chain with both sets [ms].
        error: Why the chain could not be analysed, else None.
        note: What else a reader should know (point on joint axes, why there is no theory,
            rank warnings).
    """

    robot: str
    chain: str
    revolute: int | None = None
    prismatic: int | None = None
    tools: int | None = None
    n_standard: int | None = None
    n_base_paper: int | None = None
    n_base_complete: int | None = None
    n_complete: int | None = None
    n_theory: int | None = None
    verdict: str = "error"
    time_ms: float = 0.0
    error: str | None = None
    note: str = ""


def _sweep_one(
    robot: str,
    base: str | None,
    tool: str | tuple[str, ...] | None,
    measurement: MeasureKind,
    configs: int,
    seed: int,
    params: str = "paper",
    markers: int | None = None,
) -> SweepRow:
    """Analyse one chain or tree with the paper and the complete sets; errors become a row.

    ``markers``: count instead what that many measured points identify (:func:`_markers_row`).
    """
    t0 = time.perf_counter()
    tools = (tool,) if tool is None or isinstance(tool, str) else tool
    label = f"{base or '?'} -> {', '.join(t or '?' for t in tools)}"
    try:
        chain = load_robot(robot, base, tool)
        tools = chain.tool_frames
        label = f"{chain.base_frame} -> {', '.join(tools)}"
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # kept in the results' .warnings, shown as a note
            kw: dict[str, Any] = {
                "measure": measurement,
                "configs": configs,
                "seed": seed,
            }
            if markers is not None:
                return _markers_row(str(robot), label, chain, markers, kw, t0)
            paper = analyze(chain, params="paper", **kw)
            full = analyze(chain, params="complete", **kw)
    except CalibError as exc:
        return SweepRow(str(robot), label, time_ms=1e3 * (time.perf_counter() - t0), error=str(exc))
    missing = full.n_complete - (paper if params == "paper" else full).n_base
    on_axes = (
        full.on_axes if isinstance(measurement, Measurement) and measurement.is_position else ()
    )
    notes = [f"point on axes {', '.join(map(str, on_axes))}"] if on_axes else []
    if full.mimic:  # the formula is for independent joints
        notes.append(f"{counted(len(full.mimic), 'coupled (mimic) joints')}: no theory")
    elif full.n_theory is None and full.theory_note:
        notes.append(f"no theory: {full.theory_note}")
    notes += list(dict.fromkeys(paper.warnings + full.warnings))
    return SweepRow(
        robot=str(robot),
        chain=label,
        revolute=chain.n_revolute,
        prismatic=chain.n_prismatic,
        tools=len(tools),
        n_standard=paper.n_standard,
        n_base_paper=paper.n_base,
        n_base_complete=full.n_base,
        n_complete=full.n_complete,
        n_theory=full.n_theory,
        verdict="complete" if missing <= 0 else f"misses {missing}",
        time_ms=1e3 * (time.perf_counter() - t0),
        note="; ".join(notes),
    )


@dataclass(frozen=True)
class MarkerCount:
    """What a calibration with K measured points identifies (``calib analyze --markers K``).

    Attributes:
        names: The identifiable parameters: frame, markers (and tool), then the MDH base.
        held: The first marker's coordinates a calibration holds, not counted (0-based).
        theory: 4R + 2P + 3K (+ 3 for a pose), or None: mimic joints, or a tool that does
            not turn about every direction (coordinates held).
    """

    names: tuple[str, ...]
    held: tuple[int, ...]
    theory: int | None


def marker_count(
    chain, k: int, measure: str = DEFAULT_MEASURE, configs: int = DEFAULT_CONFIGS, seed: int = 0
) -> MarkerCount:
    """Count what K points measured per configuration identify, frame and markers free.

    Args:
        chain: The chain.
        k: Number K of points measured per configuration.
        measure: ``position`` (the points) or ``pose`` (the tool's orientation too).
        configs: Random configurations of the count.
        seed: Seed of the configurations.

    Returns:
        The identifiable parameters, the coordinates held and the theory.

    Raises:
        InvalidArgumentError: Not a chain (a tree: the count is for one), a measure other than
            position or pose, or a count too large.
    """
    from ..calibration.chain_registration import held_markers
    from ..design.observability import identifiable_parameters
    from ..kinematics.mdh import from_chain

    kind = kind_of(measure)
    if not isinstance(kind, Measurement) or not kind.is_campaign:
        raise InvalidArgumentError("markers are counted with measure position or pose")
    if check_robot(chain, "chain").is_tree:
        raise InvalidArgumentError("markers are counted for one chain: give one tool")
    held = held_markers(chain, from_chain(chain).idealized())  # as calibrate holds them
    names = identifiable_parameters(chain, k, kind.label, configs, seed, held)
    if chain.coupling is not None or held:  # the formula: independent joints, a turning tool
        return MarkerCount(names, held, None)
    return MarkerCount(names, held, kind.marker_count(chain.sigma, k))


def _markers_row(robot: str, label: str, chain, k: int, kw: dict, t0: float) -> SweepRow:
    """The row of K measured points: :func:`marker_count`'s count (complete set) and theory.

    The paper set's count is not made; the verdict compares the count with the theory.
    """
    count = marker_count(chain, k, kw["measure"].label, kw["configs"], kw["seed"])
    n, theory = len(count.names), count.theory
    return SweepRow(
        robot=robot,
        chain=label,
        revolute=chain.n_revolute,
        prismatic=chain.n_prismatic,
        tools=1,
        n_base_complete=n,
        n_theory=theory,
        verdict="-" if theory is None else "complete" if n >= theory else f"misses {theory - n}",
        time_ms=1e3 * (time.perf_counter() - t0),
        note=_marker_note(chain, count),
    )


def _marker_note(chain, count: MarkerCount) -> str:
    """Why a row of :func:`_markers_row` has no theory: mimic joints, or coordinates held."""
    from ..calibration.chain_registration import held_note

    notes = [] if chain.coupling is None else ["coupled (mimic) joints: no theory"]
    if count.held:
        notes.append(f"no theory: {held_note(count.held, None)}")
    return "; ".join(notes)


def sweep(
    robots: Iterable[str] | None = None,
    extra: Sequence[str] = (),
    measure: str = DEFAULT_MEASURE,
    marker=None,
    configs: int = DEFAULT_CONFIGS,
    seed: int = 0,
    progress: Callable[[Iterable], Iterable] | None = None,
    params: str = VERDICT_SET,
    markers: int | None = None,
) -> list[SweepRow]:
    """Analyse every catalog chain and tree (or the given names) and extra URDF files.

    A chain that cannot be analysed is a row with its reason, never skipped.

    Args:
        robots: Catalog names (default: the whole catalog); a URDF file among them is
            analysed as ``extra``'s are.
        extra: URDF paths (default frames) analysed after the catalog.
        measure: ``position`` (default: a point measured, as ``calib sweep`` and
            :func:`calib.analyze`), ``pose``, rows
            (``x,y,rz``) or a contact (``plane``, ``plane-point``, ``fixed-point``,
            ``fixed-pose``; a tree or a chain through mimic joints is then a row with its
            reason).
        marker: Measured point in the tool frame [m].
        configs: Random configurations per chain.
        seed: Seed of the configurations.
        progress: Wraps the iterable of jobs (e.g. a progress bar).
        params: Set the verdict is about: ``paper`` (default, ``VERDICT_SET``, as
            ``calib sweep``) or ``complete``. Unlike ``analyze``'s default (``complete``): the
            complete set reaches the rank on every chain, so a verdict on it says nothing;
            each row has the counts of both sets whatever the verdict's.
        markers: Count instead what K points measured per configuration identify, the
            measurement frame and the markers free (:func:`marker_count`, as ``calib analyze
            --markers K``): each chain's row has that count in ``n_base_complete``, its theory
            in ``n_theory`` and the verdict compares them (``params`` is not used; the paper
            set is not counted; a tree is a row with its reason). Default None: one point.

    Returns:
        One row per chain, in order.

    Raises:
        RobotNotFoundError: A name of ``robots`` is neither in the catalog nor a file (before
            any work).
        InvalidArgumentError: A bad argument (before any work).
    """
    measurement = kind_of(measure, marker)
    if markers is not None:
        _check_markers(markers, measurement, marker)
    check_count(configs, "the number of configurations")
    check_count(seed, "the seed", minimum=0)
    check_work(configs, 1, "even a 1-joint chain")  # what no chain can afford
    if not isinstance(params, str) or params not in ("paper", "complete"):
        raise InvalidArgumentError(
            f"unknown parameter set {shown(params)}: choose paper or complete"
        )
    jobs: list[tuple[str, str | None, str | tuple[str, ...] | None]]
    if robots is None:
        jobs = [(e.name, e.base, e.tool) for e in catalog()]
    else:
        jobs = [_job(n) for n in robots]
    jobs += [(str(Path(p)), None, None) for p in extra]
    it = steps(progress, jobs, "calib sweep", len(jobs))
    return [_sweep_one(r, b, t, measurement, configs, seed, params, markers) for r, b, t in it]


def _check_markers(markers: int, measurement: MeasureKind, marker) -> None:
    """Refuse, before any work, what a count of K markers cannot take.

    Raises:
        InvalidArgumentError: A bad count, a measure other than position or pose, or a marker
            given (the K markers' places are unknown).
    """
    check_count(markers, "the number of markers")
    if not isinstance(measurement, Measurement) or not measurement.is_campaign:
        raise InvalidArgumentError("markers are counted with measure position or pose")
    if marker is not None:
        raise InvalidArgumentError(
            "marker with markers: the count is of K markers at unknown places, give no marker"
        )


def _job(name: str) -> tuple[str, str | None, str | tuple[str, ...] | None]:
    """The robot, base and tool of a name of ``robots``: its catalog entry's, or a URDF file's.

    A URDF file given among the names (before ``--``) is analysed as it was, as ``extra``'s.

    Raises:
        RobotNotFoundError: Neither a catalog name nor a file (the closest names).
    """
    try:
        entry = catalog_entry(name)
    except RobotNotFoundError:
        if not Path(name).is_file():
            raise
        return str(Path(name)), None, None
    return entry.name, entry.base, entry.tool


COLUMNS = (
    "robot",
    "chain",
    "revolute",
    "prismatic",
    "tools",
    "n_standard",
    "n_base_paper",
    "n_base_complete",
    "n_complete",
    "n_theory",
    "verdict",
    "time_ms",
    "error",
    "note",
)


def rows_to_csv(rows: Sequence[SweepRow]) -> str:
    """The rows as CSV text (one header line)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        d = asdict(row)
        d["time_ms"] = f"{row.time_ms:.1f}"
        writer.writerow(d)
    return buf.getvalue()


def rows_table(rows: Sequence[SweepRow]) -> str:
    """The rows as a plain-text table (errors and notes in the last column)."""
    from ..identification.report import format_table

    def num(v: int | None) -> str:
        return "-" if v is None else str(v)

    def chain(r: SweepRow) -> str:
        if r.tools is None or r.tools < 2:
            return r.chain
        return f"{r.chain.split(' -> ')[0]} -> {r.tools} tools"  # the list: CSV, JSON, `list`

    body = [
        [
            r.robot,
            chain(r),
            num(r.revolute),
            num(r.prismatic),
            num(r.tools),
            num(r.n_standard),
            num(r.n_base_paper),
            num(r.n_base_complete),
            num(r.n_complete),
            num(r.n_theory),
            r.verdict,
            f"{r.time_ms:.0f}",
            r.error or r.note,
        ]
        for r in rows
    ]
    header = [
        "robot",
        "chain",
        "R",
        "P",
        "T",
        "std",
        "paper",
        "complete",
        "model",
        "theory",
        "verdict",
        "ms",
        "note",
    ]
    return format_table(header, body)
