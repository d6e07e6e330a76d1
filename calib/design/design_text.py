"""What ``calib design`` and ``calib evaluate`` print: a design's summary and index tables."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..core.words import counted
from .observability import CRITERIA, Indices

if TYPE_CHECKING:
    from .design import Design


_LABELS = {
    "cond": "cond (lower is better)",
    "O1": "O1 (higher)",
    "O3": "O3 (higher)",
    "O4": "O4 (higher)",
    "D": "D = log det M (higher)",
    "A": "A = trace M^-1 (lower)",
    "I": "I [per unit noise] (lower)",
    "G": "G [per unit noise] (lower)",
}


def indices_table(columns: dict[str, list[float]]) -> str:
    """A text table of indices: one row per index, one column per set."""
    from ..identification.report import format_table

    rows = [
        [_LABELS[c], *(f"{v:.4g}" for v in values)]
        for c, values in ((c, [col[i] for col in columns.values()]) for i, c in enumerate(CRITERIA))
    ]
    return format_table(["index", *columns], rows)


def _values(ind: Indices) -> list[float]:
    return [ind.value(c) for c in CRITERIA]


def design_text(d: Design, noise_mm: float = 0.05) -> str:
    """What ``calib design`` prints."""
    rejected = ", ".join(f"{n} {name}" for name, n in d.filters.rejected if n)
    if d.filters.checked is not None:
        rejected = f"{rejected or 'none'} of the {d.filters.checked} checked for collisions"
    lines = [
        f"{d.robot}: {counted(len(d.q), 'configurations')} designed from {d.candidates} of "
        f"{d.filters.candidates} candidates"
        + (f" (rejected: {rejected})" if rejected else "")
        + f", criterion {d.criterion}, {counted(d.model.rows, 'rows')} per configuration, "
        f"{d.model.b} parameters",
        *(f"note: {n}" for n in d.filters.notes),
        f"greedy start then {counted(d.exchanges, 'exchanges')} in {counted(d.sweeps, 'sweeps')}; "
        f"angles scaled by L = {d.model.length:.4g} m",
        "",
        indices_table(
            {
                "design": _values(d.indices),
                "greedy": _values(d.greedy),
                f"random (median of {len(d.random)})": [d.random_median(c) for c in CRITERIA],
            }
        ),
        "",
        f"predicted RMS {'gap' if d.contact is not None else 'position'} error after "
        f"calibration at {noise_mm:g} mm noise: "
        f"design {noise_mm * d.indices.value('I'):.4g} mm, random sets "
        f"{noise_mm * d.random_median('I'):.4g} mm (median)",
    ]
    if d.contact is not None:
        where = np.array2string(d.contact[:3, 3], precision=4, separator=", ")
        lines.insert(
            1,
            f"every posture holds the contact, placed at {where} m in the base frame (the "
            f"nominal contact frame at the first candidate; z its normal); rows: the gap",
        )
    return "\n".join(lines)


__all__ = ["design_text", "indices_table"]
