"""No silent overfit: the rows must determine the parameters a level fits, or calib refuses.

Before the fit: equations and rank; after it: the conditioning of the fitted unknowns.
Rationale and measurements: docs/developers/engine.md#determined
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core.words import counted
from ..exceptions import DataError, InvalidArgumentError
from ..identification.base_columns import independent_columns
from ..measurements.data import Measurements
from ..measurements.postures import posture_groups
from .model import ErrorModel, MeasuredKind, State, generic_measurements
from .solve import condition

__all__ = [
    "CLEAR",
    "FRAMES",
    "ILL_CONDITION",
    "ILL_STD",
    "NAMED",
    "SAMPLE_EQUATIONS",
    "SAMPLE_WORK",
    "SELECTION_WORK",
    "STILL",
    "Direction",
    "check_equations",
    "check_frames",
    "check_rank",
    "determined_columns",
    "generic_jacobian",
    "ill_posed",
    "ill_posed_text",
    "seen_equations",
    "selection_configurations",
    "separating_posture",
    "separating_text",
    "still_axes",
    "undetermined",
]


def _configs_needed(unknowns: int, rows: int) -> int:
    """Fewest configurations of ``rows`` equations each with more equations than ``unknowns``."""
    return unknowns // rows + 1


def check_equations(
    m: int,
    rows: int,
    unknowns: int,
    what: str,
    source: str,
    *,
    held: int = 0,
    unit: str = "",
    equations: int | None = None,
) -> None:
    """Refuse (DataError) fitting ``unknowns`` parameters from ``m * rows <= unknowns`` rows.

    ``equations``: those of the points seen (:func:`seen_equations`), None: ``m * rows``.
    """
    full = equations is None
    equations = m * rows if equations is None else equations
    if equations > unknowns:
        return
    unit, out = unit or "configurations", f" ({held} held out)" if held else ""
    needs = (
        f"at least {_configs_needed(unknowns, rows)} {unit}"
        if full
        else f"more {unit}, or more points seen in them (3 equations each)"
    )
    seen = "" if full else " (the points seen)"
    raise DataError(
        source,
        f"{m} {unit} to fit{out} give {equations} equations{seen} for the {unknowns} {what}: "
        f"it needs {needs} (more equations than unknowns)",
    )


def seen_equations(data: Measurements, rows: int, postures: bool = False) -> int | None:
    """Equations of the points seen (3 each, and each row's others), or None: every point seen.

    ``postures``: a point seen at a posture counts once, as the posture does
    (:func:`~calib.measurements.postures.posture_groups`).
    """
    if not data.partial:
        return None
    seen = data.seen
    if postures:
        groups = posture_groups(data.q, data.tool)
        merged = np.zeros((int(groups.max()) + 1, seen.shape[1]), dtype=bool)
        np.logical_or.at(merged, groups, seen)
        seen = merged
    return 3 * int(seen.sum()) + (rows - 3 * seen.shape[1]) * len(seen)


FRAMES = "measurement frame and marker parameters"
"""A measured chain's own unknowns (:class:`~.model.MeasuredKind`), as the messages name them."""


def check_frames(
    kind: MeasuredKind,
    m: int,
    source: str,
    what: str = FRAMES,
    *,
    held: int = 0,
    equations: int | None = None,
) -> None:
    """Refuse (DataError) ``m`` configurations too few for a measured chain's own unknowns.

    ``equations``: those of the points seen, None: every point seen (:func:`check_equations`).
    """
    check_equations(m, kind.rows, kind.size(), what, source, held=held, equations=equations)


def check_rank(
    determined: int,
    generic: int,
    m: int,
    rows: int,
    level: str,
    source: str,
    unit: str = "",
    lost: tuple[str, ...] = (),
    equations: int | None = None,
    fewest: int | None = None,
) -> None:
    """Refuse (DataError) a level the measured configurations do not determine (rank of W_b).

    ``generic``: what generic configurations determine; ``lost``: the unknowns they alone do;
    ``equations``: those of the points seen, None: every point seen; ``fewest``: the fewest
    generic configurations that determine the ``generic`` (None: unknown, the count's bound).
    """
    what = f"parameters of params {level!r}"
    check_equations(m, rows, generic, what, source, unit=unit, equations=equations)
    if determined >= generic:
        return
    unit = unit or "configurations"
    which = f": they cannot separate {', '.join(lost)}" if lost else ""
    needed = max(_configs_needed(generic, rows), fewest or 0)
    seen = "" if equations is None else " and see every marker"
    moving = f"{unit} that move every joint{seen}"
    more = f"at least {needed} {moving}" if m < needed else f"more {moving}"
    if m >= needed and fewest is not None:
        more += f" ({needed} at generic postures are enough)"
    raise DataError(
        source,
        f"the {m} {unit} determine only {determined} of the {generic} parameters of params "
        f"{level!r} (rank of the identification Jacobian){which}: measure {more}, or choose a "
        f"lower level or fix parameters",
    )


SELECTION_WORK = 4e9
"""Largest ``rows x (fixed + candidates)^2 x candidates`` the selection is run on (else a sample).
Measurements: docs/developers/performance.md#selection_work-determined"""

SAMPLE_WORK = 1e9
"""The work of the sample a campaign beyond :data:`SELECTION_WORK` is chosen on.
Measurements: docs/developers/performance.md#sample_work-determined"""

SAMPLE_EQUATIONS = 200
"""Fewest equations per selection column a sample must keep to be chosen on.
Measurements: docs/developers/performance.md#sample_equations-determined"""


def selection_configurations(m: int, rows: int, fixed: int, candidates: int) -> int:
    """Configurations the selection (``--params auto``) chooses on: ``m``, or a sample's size.

    Raises:
        InvalidArgumentError: The sample would keep under :data:`SAMPLE_EQUATIONS` per column.
    """
    per_configuration = rows * (fixed + candidates) ** 2 * candidates
    if m * per_configuration <= SELECTION_WORK:
        return m
    sample = int(min(SAMPLE_WORK, SELECTION_WORK) // per_configuration)
    if sample * rows < SAMPLE_EQUATIONS * (fixed + candidates):
        raise InvalidArgumentError(
            f"params 'auto' would cross-validate {candidates} parameters on {m} configurations "
            f"x {rows} rows with {fixed} frame and marker columns: "
            f"{m * per_configuration / SELECTION_WORK:.3g} times the work calib runs it on "
            f"(about a minute on one core), and a sample within it too small to choose on; "
            f"give a level (params complete, paper, offsets or frames), or fewer markers"
        )
    return sample


ILL_CONDITION = 1e3
"""Largest over smallest singular value of the fitted unknowns' unit-norm columns over which a
direction of them is undetermined. Rationale: docs/developers/engine.md#ill_condition"""

NAMED = 0.3
"""Smallest component, in an undetermined unit direction, of an unknown it names."""

CLEAR = 1.01
"""Margin over the weak threshold above which :func:`ill_posed` skips the singular vectors."""


@dataclass(frozen=True)
class Direction:
    """A combination of fitted unknowns the data cannot determine (its ``NAMED`` components)."""

    names: tuple[str, ...]
    weights: tuple[float, ...]
    condition: float

    def text(self) -> str:
        """``-0.71 frame.z + 0.71 marker1.z``: the combination the data do not see."""
        text = ""
        for n, w in zip(self.names, self.weights, strict=True):
            sign = ("-" if w < 0 else "") if not text else (" - " if w < 0 else " + ")
            text += f"{sign}{abs(w):.2g} {n}"
        return text


ILL_STD = 1e-4
"""Standard deviation [m or rad] under which a weak direction's unknowns are determined."""


def ill_posed(J: np.ndarray, names: tuple[str, ...], overwrite: bool = False) -> list[Direction]:
    """Directions of the unknowns (columns of ``J``) the rows do not determine, weakest first."""
    if J.shape[1] == 0:
        return []
    norms = np.linalg.norm(J, axis=0)
    scaled = np.divide(J, np.where(norms > 0, norms, 1.0), out=J if overwrite else None)
    s = np.linalg.svd(scaled, compute_uv=False)  # half the time of the vectors'
    if s[-1] > CLEAR * s[0] / ILL_CONDITION:  # none weak, whatever the round-off: no vectors
        return []
    _, s, vt = np.linalg.svd(scaled, full_matrices=False)
    out = []
    for k in np.flatnonzero(s < s[0] / ILL_CONDITION)[::-1]:  # the weakest first
        v = vt[k] * (1.0 if vt[k][np.argmax(np.abs(vt[k]))] > 0 else -1.0)
        named = np.flatnonzero(np.abs(v) >= NAMED)
        cond = float(s[0] / s[k]) if s[k] > 0 else float("inf")
        out.append(Direction(tuple(names[i] for i in named), tuple(v[named]), cond))
    return out


def separating_posture(
    jacobian_at: Callable[[np.ndarray], np.ndarray], q: np.ndarray, direction: np.ndarray
) -> tuple[np.ndarray, float]:
    """The configuration of ``q`` where a direction moves the rows most; the condition at ``q``."""
    J = jacobian_at(q)
    flat = J.reshape(-1, J.shape[2])
    norms = np.linalg.norm(flat, axis=0)
    norms = np.where(norms > 0, norms, 1.0)
    seen = np.linalg.norm(J @ (direction / norms), axis=1) / np.linalg.norm(J / norms, axis=(1, 2))
    return q[int(np.argmax(seen))], condition(flat)


def undetermined(J: np.ndarray, names: tuple[str, ...], std) -> list[Direction]:
    """The directions of :func:`ill_posed` but those whose ``std`` are all under :data:`ILL_STD`."""
    spread = dict(zip(names, std, strict=True))
    return [d for d in ill_posed(J, names) if not all(spread[n] <= ILL_STD for n in d.names)]


def separating_text(
    jacobian_at: Callable[[np.ndarray], np.ndarray],
    q: np.ndarray,
    names: tuple[str, ...],
    direction: Direction,
    joint_names,
) -> str:
    """``postures such as <joint> <q> ...`` that separate a direction, or that none does."""
    v = np.zeros(len(names))
    v[[names.index(n) for n in direction.names]] = direction.weights
    best, cond = separating_posture(jacobian_at, q, v)
    if cond >= ILL_CONDITION:  # e.g. a tool that never turns: its markers and the frame
        return (
            f"no posture separates them (condition {cond:.3g} at {len(q)} random configurations "
            "within the joint limits): these measurements of this robot cannot tell them apart"
        )
    joints = ", ".join(f"{n} {x:.3g}" for n, x in zip(joint_names, best, strict=True))
    return (
        f"postures such as {joints} [rad or m] separate them (random configurations within "
        f"the joint limits: condition {cond:.3g})"
    )


def ill_posed_text(
    found: list[Direction], std: dict[str, float], posture: str | None = None
) -> str | None:
    """The refusal's sentence for undetermined directions (None: none); ``std`` [m or rad]."""
    if not found:
        return None
    d = found[0]
    stds = ", ".join(f"{n} +- {std.get(n, float('inf')):.3g}" for n in d.names)
    text = (
        f"the data cannot separate {' and '.join(d.names)}: the combination {d.text()} is "
        f"undetermined (condition {d.condition:.3g} of the fitted unknowns, over "
        f"{ILL_CONDITION:g}; standard deviations {stds} [m or rad]), so their fitted values "
        f"would be arbitrary"
    )
    if len(found) > 1:
        text += f" ({counted(len(found) - 1, 'more such combinations')})"
    return text + (
        f"; {posture}" if posture else "; fix one of them or measure more varied postures"
    )


STILL = 1e-9
"""Singular value [per rotation entry] of the tool's rotation changes: a direction never turns."""


def still_axes(R: np.ndarray) -> tuple[int, ...]:
    """The tool-frame coordinates (0-based) a marker's offset along axes that never turn hides in.

    ``R`` ``(m, 3, 3)``: the tool's rotations at random configurations. One coordinate per
    such direction (none, one or all three), those they move most.
    Rationale: docs/developers/engine.md#still_axes
    """
    _, s, vt = np.linalg.svd((R[1:] - R[0]).reshape(-1, 3), full_matrices=False)
    still = vt[s < STILL * np.sqrt(len(R))]
    return tuple(sorted(np.argsort(-np.abs(still).sum(axis=0))[: len(still)].tolist()))


def generic_jacobian(
    model: ErrorModel, state: State, joint_names: tuple[str, ...], weight: float = 1.0
) -> Callable[[np.ndarray], np.ndarray]:
    """The weighted Jacobian ``(m, rows, size)`` at configurations ``(m, n)`` (weight [m/rad])."""
    weights = model.own.row_weights(weight)

    def at(q: np.ndarray) -> np.ndarray:
        data = generic_measurements(state, joint_names, q)
        return model.jacobian(state, data) * weights[:, None]

    return at


def determined_columns(J: np.ndarray, order: list[int] | None = None) -> list[int]:
    """The columns of a Jacobian ``(..., p)`` its rows determine, sorted (pivoted QR, ``order``)."""
    p = J.shape[-1]
    order = list(range(p)) if order is None else order
    return sorted(independent_columns(J.reshape(-1, p), order)[2])
