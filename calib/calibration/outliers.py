"""Robust fitting: configurations whose error is far from the others' are set aside.

After the registration, the error of each configuration (the largest of its points) is
compared with the median over the configurations: one more than ``FACTOR`` times the median
(and, when the instrument noise is given, more than ``NOISE_FACTOR`` times it) is an outlier
(a marker swap, a bad reading). Outliers are listed by file row and dropped, and the
registration is repeated without them, until none is left (at most ``PASSES`` times). A
robust loss (``--loss soft_l1|huber``, scale ``--noise-mm``) further limits the pull of the
rows that remain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

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
        error: Its largest point error after the registration [m].
        median: The median configuration error then [m].
    """

    row: int
    error: float
    median: float

    def to_dict(self) -> dict:
        """JSON-ready form (metres)."""
        return {"row": self.row, "error": self.error, "median": self.median}


def configuration_errors(residual: np.ndarray, n_markers: int) -> np.ndarray:
    """Largest point error of each configuration ``(m,)`` [m] from residuals ``(m, rows)``."""
    pts = residual[:, : 3 * n_markers].reshape(len(residual), n_markers, 3)
    return np.max(np.linalg.norm(pts, axis=2), axis=1)


def find_outliers(errors: np.ndarray, noise: float | None) -> np.ndarray:
    """Boolean mask of the outliers among configuration errors [m]."""
    median = float(np.median(errors))
    bad = errors > FACTOR * median
    if noise is not None:
        bad &= errors > NOISE_FACTOR * noise
    if np.sum(~bad) < max(3, len(errors) // 2):  # not outliers: the data are bad as a whole
        return np.zeros(len(errors), dtype=bool)
    return bad
