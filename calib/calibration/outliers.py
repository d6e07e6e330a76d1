"""Robust fitting: configurations whose error is far from the others' are set aside.

After the registration, the error of each configuration (the largest of its points) is
compared with the median over the configurations: one more than ``FACTOR`` times the median
(and, when the instrument noise is given, more than ``NOISE_FACTOR`` times it) is an outlier
(a marker swap, a bad reading). With pose data, the orientation error of each configuration
is tested the same way against the median orientation error, so that one bad orientation is
set aside like one bad point. Outliers are listed by file row and dropped, and the
registration is repeated without them, until none is left (at most ``PASSES`` times). A
robust loss (``--loss soft_l1|huber``, scale ``--noise-mm``) further limits the pull of the
rows that remain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "FACTOR",
    "NOISE_FACTOR",
    "PASSES",
    "Outlier",
    "find_outliers",
    "find_pose_outliers",
    "set_aside_note",
]

FACTOR = 5.0
"""An outlier's error is more than this many times the median configuration error."""

NOISE_FACTOR = 6.0
"""... and more than this many times the instrument noise, when it is given."""

PASSES = 3
"""Most rounds of outlier removal."""


@dataclass(frozen=True)
class Outlier:
    """A configuration set aside.

    Attributes:
        row: Its row in the data file.
        error: Its largest point error after the registration [m] (or its orientation
            error [rad], ``kind`` ``orientation``).
        median: The median configuration error then [m or rad].
        kind: ``position`` or ``orientation``: which error set it aside.
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


def set_aside_note(dropped, unit: str = "row(s)", gap: str = "error") -> str:
    """The note listing the outliers set aside (one line).

    For example ``2 outlier row(s) set aside (error > 5 x the median): row 4 (5.3 mm), row 9
    (6.1 mm)``.

    Args:
        dropped: The outliers (:class:`Outlier`).
        unit: What one is: ``row(s)`` of measurements, ``touch(es)`` of contacts.
        gap: What exceeded the bound: ``error`` (measurements) or ``gap`` (contacts).
    """
    return f"{len(dropped)} outlier {unit} set aside ({gap} > {FACTOR:g} x the median): " + (
        ", ".join(o.text() for o in dropped)
    )


def _configuration_errors(residual: np.ndarray, n_markers: int) -> np.ndarray:
    """Largest point error of each configuration ``(m,)`` [m] from residuals ``(m, rows)``."""
    pts = residual[:, : 3 * n_markers].reshape(len(residual), n_markers, 3)
    return np.max(np.linalg.norm(pts, axis=2), axis=1)


def _find_outliers(errors: np.ndarray, noise: float | None) -> np.ndarray:
    """Boolean mask of the outliers among configuration errors [m]."""
    median = float(np.median(errors))
    bad = errors > FACTOR * median
    if noise is not None:
        bad &= errors > NOISE_FACTOR * noise
    if np.sum(~bad) < max(3, len(errors) // 2):  # not outliers: the data are bad as a whole
        return np.zeros(len(errors), dtype=bool)
    return bad


def find_pose_outliers(
    residual: np.ndarray, n_markers: int, noise: float | None, rows: tuple[int, ...]
) -> tuple[np.ndarray, list[Outlier]]:
    """Outliers of residuals ``(m, 3 K [+ 3])``: by point error, and by orientation error.

    Args:
        residual: Residuals of the registration [m, rad].
        n_markers: K.
        noise: Instrument position noise [m], or None.
        rows: File row of each configuration.

    Returns:
        The boolean mask of the outliers and the outliers (the point error first where both).
    """
    rot = None
    if residual.shape[1] == 3 * n_markers + 3:
        rot = np.linalg.norm(residual[:, 3 * n_markers :], axis=1)
    return find_outliers(_configuration_errors(residual, n_markers), rot, noise, rows)


def find_outliers(
    errors: np.ndarray, orientation: np.ndarray | None, noise: float | None, rows: tuple[int, ...]
) -> tuple[np.ndarray, list[Outlier]]:
    """Outliers of per-configuration errors: by position error, and by orientation error.

    Args:
        errors: Position error of each configuration ``(m,)`` [m].
        orientation: Orientation error of each ``(m,)`` [rad], or None.
        noise: Instrument position noise [m], or None.
        rows: File row of each configuration.

    Returns:
        The boolean mask of the outliers and the outliers (the position error first where
        both).
    """
    bad = _find_outliers(errors, noise)
    found = [
        Outlier(rows[i], float(errors[i]), float(np.median(errors))) for i in np.flatnonzero(bad)
    ]
    if orientation is not None:
        bad_rot = _find_outliers(orientation, None) & ~bad
        median = float(np.median(orientation))
        found += [
            Outlier(rows[i], float(orientation[i]), median, "orientation")
            for i in np.flatnonzero(bad_rot)
        ]
        bad = bad | bad_rot
    if np.sum(~bad) < max(3, len(errors) // 2):
        return np.zeros(len(errors), dtype=bool), []
    return bad, found
