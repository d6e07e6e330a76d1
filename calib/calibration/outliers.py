"""Robust fitting: configurations whose error is far from the others' are set aside.

Rationale and measurements: docs/developers/engine.md#outliers
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple, TypeVar

import numpy as np

from ..core.words import counted
from ..exceptions import DataError

__all__ = [
    "FACTOR",
    "IRLS_ROUNDS",
    "LISTED",
    "NOISE_FACTOR",
    "PROPOSAL_SPREAD",
    "ROUNDS",
    "Errors",
    "Outlier",
    "find_outliers",
    "listed",
    "point_errors",
    "records",
    "robust_proposals",
    "set_aside_note",
    "spread_out",
    "stable_set",
    "until_stable",
]

T = TypeVar("T")


class Errors(NamedTuple):
    """Each unit's position [m] and orientation [rad] errors, norms of ``dims`` components.

    ``position`` and ``orientation`` ``(m,)``; ``orientation`` None without angle rows.
    """

    position: np.ndarray
    orientation: np.ndarray | None = None
    dims: tuple[int, int] = (3, 3)


FACTOR = 5.0
"""An outlier's error exceeds this many times the median (3 components; else :func:`factor`)."""

NOISE_FACTOR = 6.0
"""... and more than this many times the instrument noise, when it is given."""

ROUNDS = 10
"""Most refits of the outlier loop (:func:`until_stable`); it keeps the last set."""

IRLS_ROUNDS = 60
"""Most reweightings of the robust fit of :func:`robust_proposals`."""

LISTED = 10
"""Most rows a note names one by one (the result's ``outliers`` hold every one)."""


@dataclass(frozen=True)
class Outlier:
    """A configuration set aside: its file row, error and the median then [m, or rad].

    ``kind``: ``position`` or ``orientation``, which error set it aside (its unit: m or rad).
    """

    row: int
    error: float
    median: float
    kind: str = "position"

    def to_dict(self) -> dict:
        """JSON-ready form (metres, or radians for an orientation)."""
        return {"row": self.row, "error": self.error, "median": self.median, "kind": self.kind}

    def text(self) -> str:
        """``row 12 (5.3 mm)`` or ``row 12 (orientation 31 deg)``."""
        if self.kind == "orientation":
            return f"row {self.row} (orientation {np.degrees(self.error):.3g} deg)"
        return f"row {self.row} ({1e3 * self.error:.3g} mm)"


def listed(items: list[str]) -> str:
    """The first :data:`LISTED` of ``items`` joined by commas, and how many more."""
    more = len(items) - LISTED
    return ", ".join(items[:LISTED]) + (f" and {more} more" if more > 0 else "")


def set_aside_note(dropped, unit: str = "rows", gap: str = "error") -> str:
    """``2 outlier rows set aside (error > 5 x the median): row 4 (5.3 mm), row 9 (6.1 mm)``."""
    outliers = counted(len(dropped), f"outlier {unit}")
    return f"{outliers} set aside ({gap} > {FACTOR:g} x the median): " + listed(
        [o.text() for o in dropped]
    )


def point_errors(residual: np.ndarray, n_markers: int) -> Errors:
    """Each configuration's largest point error [m] and orientation error [rad] (or None).

    A marker not seen in a row (NaN) is not among its points.
    """
    rot = None
    if residual.shape[1] == 3 * n_markers + 3:
        rot = np.linalg.norm(residual[:, 3 * n_markers :], axis=1)
    pts = np.linalg.norm(residual[:, : 3 * n_markers].reshape(len(residual), n_markers, 3), axis=2)
    return Errors(np.nanmax(pts, axis=1) if np.isnan(pts).any() else np.max(pts, axis=1), rot)


@functools.cache
def factor(dims: int) -> float:
    """The outlier factor for errors that are norms of ``dims`` components (``FACTOR``: 3)."""
    if dims == 3:
        return FACTOR
    from scipy.stats import chi  # 1.5 s to import: only for errors that are no 3-vectors

    tail = chi.sf(FACTOR * chi.median(3), 3)
    return float(chi.isf(tail, dims) / chi.median(dims))


def _find_outliers(errors: np.ndarray, noise: float | None, dims: int = 3) -> np.ndarray:
    """Boolean mask of the outliers among configuration errors [m]."""
    median = float(np.median(errors))
    bad = errors > factor(dims) * median
    if noise is not None:
        bad &= errors > NOISE_FACTOR * noise
    if np.sum(~bad) < max(3, len(errors) // 2):  # not outliers: the data are bad as a whole
        return np.zeros(len(errors), dtype=bool)
    return bad


def find_outliers(
    found: Errors, noise: float | None, rows: tuple[int, ...]
) -> tuple[np.ndarray, list[Outlier]]:
    """Outliers of per-configuration errors (by position, and by orientation): mask, records."""
    errors, orientation, dims = found
    bad = _find_outliers(errors, noise, dims[0])
    if orientation is not None:
        bad = bad | _find_outliers(orientation, None, dims[1])
    if np.sum(~bad) < max(3, len(errors) // 2):
        return np.zeros(len(errors), dtype=bool), []
    return bad, records(found, bad, rows)


def until_stable(
    refit: Callable[[np.ndarray], T],
    errors: Callable[[T], Errors],
    noise: float | None,
    rows: tuple[int, ...],
    allowed: Callable[[np.ndarray], bool] | None = None,
    converged: Callable[[T], bool] | None = None,
) -> tuple[T, np.ndarray, list[Outlier]]:
    """Refit without the outliers and test every unit again, until the set stops changing.

    Returns the last fit, the mask of the outliers it was fitted without, and the outliers.
    """

    def rule(result: T) -> np.ndarray | None:
        if converged is not None and not converged(result):
            return None
        return find_outliers(errors(result), noise, rows)[0]

    result, bad = stable_set(refit, rule, np.zeros(len(rows), dtype=bool), allowed)
    return result, bad, records(errors(result), bad, rows)


def stable_set(
    refit: Callable[[np.ndarray], T],
    rule: Callable[[T], np.ndarray | None],
    start: np.ndarray,
    allowed: Callable[[np.ndarray], bool] | None = None,
) -> tuple[T, np.ndarray]:
    """:func:`until_stable`'s loop: the outliers ``rule`` finds under a fit (a mask) each round.

    Returns the last fit and the mask of the units it was fitted without (how it ends:
    docs/developers/engine.md#outliers).

    Raises:
        DataError: The first fit's.
    """
    bad = start
    result = refit(~bad)
    before = (result, bad)
    for _ in range(ROUNDS):
        new = rule(result)
        if new is None:  # the fit stalled: the round before (the first: itself)
            return before
        if np.array_equal(new, bad) or (allowed is not None and not allowed(new)):
            break
        try:
            refitted = refit(~new)
        except DataError:  # the new set refused: the last set (its fit passed them) stays
            break
        before, result, bad = (result, bad), refitted, new
    return result, bad


def records(found: Errors, bad: np.ndarray, rows: tuple[int, ...]) -> list[Outlier]:
    """The outliers a mask sets aside, with their errors (position first, as the rule)."""
    pos, rot, dims = found
    median = float(np.median(pos))
    out = []
    for i in np.flatnonzero(bad):
        if rot is None or pos[i] > factor(dims[0]) * median:
            out.append(Outlier(rows[i], float(pos[i]), median))
        else:
            out.append(Outlier(rows[i], float(rot[i]), float(np.median(rot)), "orientation"))
    return out


PROPOSAL_SPREAD = 2.5
"""Multiple of the median some unit's error must exceed for a robust fit's proposals.
Rationale and measurements: docs/developers/engine.md#proposal_spread"""


def spread_out(errors: Errors) -> bool:
    """Whether some unit's error exceeds :data:`PROPOSAL_SPREAD` times the median."""
    for e in (errors.position, errors.orientation):
        if e is not None and len(e) and np.max(e) > PROPOSAL_SPREAD * np.median(e):
            return True
    return False


def robust_proposals(
    J: np.ndarray,
    residual: np.ndarray,
    errors: Callable[[np.ndarray], Errors],
    noise: float | None,
    rows: tuple[int, ...],
) -> np.ndarray:
    """The units a robust fit (IRLS) of a linearised model finds outlying (a boolean mask)."""
    m, rows_each = residual.shape
    if m * rows_each < 2 * J.shape[2]:  # nearly interpolated: nothing to tell
        return np.zeros(m, dtype=bool)
    w = np.ones(m)
    fitted = residual
    for _ in range(IRLS_ROUNDS):
        s = np.sqrt(w)[:, None]  # the least squares of J x ~ residual, unit i weighted by w[i]
        A = (J * s[:, :, None]).reshape(-1, J.shape[2])
        fitted = residual - J @ np.linalg.lstsq(A, (residual * s).ravel(), rcond=None)[0]
        pos, rot, _ = errors(fitted)
        ratio = _ratio(pos) if rot is None else np.maximum(_ratio(pos), _ratio(rot))
        new = np.minimum(1.0, 1.0 / np.maximum(ratio, 1e-300))
        if np.allclose(new, w, rtol=1e-6, atol=1e-9):
            break
        w = new
    return find_outliers(errors(fitted), noise, rows)[0]


def _ratio(errors: np.ndarray) -> np.ndarray:
    """Each error over their median (1 where the median is 0)."""
    median = float(np.median(errors))
    return errors / median if median > 0 else np.ones_like(errors)
