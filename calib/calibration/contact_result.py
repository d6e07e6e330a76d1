"""A term's part of a result (:class:`TermPart`) and its rows by part (:class:`GapStats`).

Parts: ``train``, ``held_out``, each also ``_registration`` and (compliance) ``_urdf``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..core.words import counted
from ..kinematics.robot import Chain
from .report import URDF_ALONE, mm_or_deg, term_errors

__all__ = ["GapStats", "TermPart", "gap_stats", "part_stats", "row_stats", "units"]


@dataclass(frozen=True)
class GapStats:
    """Gaps of ``m`` touches by the kind's row (``names``, ``angular``): mm and degrees.

    ``rms`` and ``max`` (absolute) of each row, also read as ``height_rms_mm``, ``roll_max_deg``,
    ...; ``per_row``: each touch's weighted gap norm [mm] (angles times the orientation weight),
    ``weighted_mm`` their RMS; ``residuals``: the rows ``(m, rows)`` [m, rad], or None.
    """

    m: int
    names: tuple[str, ...]
    angular: tuple[bool, ...]
    rms: tuple[float, ...]
    max: tuple[float, ...]
    weighted_mm: float
    per_row: np.ndarray | None = field(default=None, compare=False, repr=False)
    residuals: np.ndarray | None = field(default=None, compare=False, repr=False)

    def figures(self) -> tuple[str, ...]:
        """``<row>_rms_<unit>`` and ``<row>_max_<unit>`` of every row, in row order."""
        pairs = zip(self.names, self.angular, strict=True)
        return tuple(f"{n}_{s}_{mm_or_deg(a)[0]}" for n, a in pairs for s in ("rms", "max"))

    def __getattr__(self, key: str) -> float:
        """A row's figure by its key (:meth:`figures`), e.g. ``height_rms_mm``."""
        if key.startswith("__") or key in self.__dataclass_fields__:  # not set yet (a copy)
            raise AttributeError(key)
        keys = self.figures()
        if key not in keys:
            raise AttributeError(f"GapStats has no {key!r}: {', '.join(keys)}")
        i = keys.index(key)
        return (self.max if i % 2 else self.rms)[i // 2]

    @property
    def length_rms_mm(self) -> float:
        """RMS over touches of the norm of the length rows [mm]."""
        lengths = [r for r, a in zip(self.rms, self.angular, strict=True) if not a]
        return math.sqrt(sum(v**2 for v in lengths))

    def in_mm(self) -> dict:
        """The report's form (format 3): ``configs``, each row's figures, ``weighted_mm``."""
        return {"configs": self.m, **{k: v for k, v in self.to_dict().items() if k != "m"}}

    def to_dict(self) -> dict:
        """JSON-ready form: ``m``, each row's RMS and largest value, ``weighted_mm``."""
        pairs = zip(self.rms, self.max, strict=True)
        values = [None if math.isnan(v) else v for pair in pairs for v in pair]  # none seen
        figures = dict(zip(self.figures(), values, strict=True))
        return {"m": self.m, **figures, "weighted_mm": self.weighted_mm}


class TermPart:
    """What every term's part of a result offers, whatever its kind: errors, report, lines.

    Each kind's frozen dataclass adds :meth:`!heading`, :meth:`!_own` and :attr:`!rows`.

    Attributes:
        chain: The nominal chain.
        source: Its rows' file (or description).
        kind: The term's layout (its ``label``, ``row_names`` and ``angular``).
        stats: Its errors by part (:class:`GapStats`: ``train``, ``held_out``, ...).
        held_source: Its held-out rows' source (``holdout`` or the validation file), or None.
        held_rows: Its held-out rows scored, by their line in that file (None: none held out).
        compliance: Its fitted joint compliance ``(n,)`` [rad/(N m) or m/N], or None (rigid).
    """

    chain: Chain
    source: str
    kind: Any
    stats: dict[str, GapStats]
    held_source: str | None
    held_rows: tuple[int, ...] | None
    compliance: np.ndarray | None = None
    rows: ClassVar[str] = "configurations"

    def errors(self) -> dict:
        """The report's ``errors.terms`` entry: ``train`` and ``held_out`` errors (format 3)."""
        return term_errors(self.stats, self.held_source, self.held_rows)

    def configs(self) -> int:
        """Its fitted postures (the report's ``terms[k].configs``): a row is one."""
        return self.stats["train"].m

    def to_dict(self) -> dict:
        """Format 2's ``chains`` entry: base, tool, data, kind, then its kind's own keys."""
        ends = {"base": self.chain.base_frame, "tool": self.chain.tool_frame}
        return {**ends, "data": self.source, "kind": self.kind.label, **self._own()}

    def _own(self) -> dict:
        """Its kind's own keys of :meth:`to_dict`."""
        raise NotImplementedError

    def named(self, k: int) -> str:
        """The term as texts name it, ``k`` its index: ``term 2 (base_link -> tool0, plane)``."""
        ends = f"{self.chain.base_frame} -> {self.chain.tool_frame}"
        return f"term {k + 1} ({ends}, {self.kind.label})"

    def heading(self) -> str:
        """What the summary says the term is, after its base and tool frames."""
        raise NotImplementedError

    def lines(self) -> list[str]:
        """The summary's lines: what the term is, then each part's RMS errors by row."""
        labels = {}  # each part's label (with compliance: which model it is), padded
        for key in self.stats:
            label = key.replace("_urdf", f", {URDF_ALONE}")
            if self.compliance is not None and not key.endswith(("_urdf", "_registration")):
                label += ", whole model (URDF + compliance)"
            labels[key] = label
        width = max(22, *map(len, labels.values()))
        return [f"{self.chain.base_frame} -> {self.chain.tool_frame}, {self.heading()}"] + [
            f"  {labels[key]:{width}s} {'  '.join(f'{v:8.3f}' for v in s.rms)}  "
            f"({counted(s.m, self.rows)})"
            for key, s in self.stats.items()
        ]


def units(kind) -> str:
    """A kind's rows with their units: ``x [mm], y [mm], z [mm], rx [deg], ...``."""
    return ", ".join(
        f"{n} [{mm_or_deg(a)[0]}]" for n, a in zip(kind.row_names, kind.angular, strict=True)
    )


def part_stats(stat, registered, state, train, held) -> dict:
    """``stat(s, rows)`` of the fitted and the registered states on ``train`` and ``held``."""
    parts = {"train": train} if held is None else {"train": train, "held_out": held}
    return {
        key + suffix: stat(s, rows)
        for key, rows in parts.items()
        for suffix, s in (("", state), ("_registration", registered))
    }


def gap_stats(state, q: np.ndarray, ids=None, torque: np.ndarray | None = None) -> GapStats:
    """:class:`GapStats` of a :class:`~.contact_model.ContactState` at touches ``q`` of ``ids``."""
    return row_stats(state.gaps(q, ids, torque), state.kind, state.row_weights())


def row_stats(g: np.ndarray, kind, weights: np.ndarray) -> GapStats:
    """:class:`GapStats` of rows ``g`` ``(m, rows)`` [m, rad], ``weights`` [1, m/rad] each.

    NaN: a marker not seen in a configuration, no row of its figures (none of the rows sees
    it: its figures NaN, ``null`` in the report).
    """
    scale = np.array([mm_or_deg(a)[1] for a in kind.angular])
    unseen = np.isnan(g).any()
    mean, big = (np.nanmean, np.nanmax) if unseen else (np.mean, np.max)
    with warnings.catch_warnings():  # a column all NaN (a marker none sees): NaN, not a warning
        warnings.simplefilter("ignore", RuntimeWarning)
        rms = tuple(float(v) for v in np.sqrt(mean(g**2, axis=0)) * scale)
        top = tuple(float(v) for v in big(np.abs(g), axis=0) * scale)
    per_row = 1e3 * np.linalg.norm((np.nan_to_num(g) if unseen else g) * weights, axis=1)
    weighted = float(np.sqrt(np.mean(per_row**2)))
    return GapStats(len(g), kind.row_names, kind.angular, rms, top, weighted, per_row, g)
