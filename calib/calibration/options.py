"""The options of a calibration and their defaults: constants only, cheap to import.

The command line builds its parser from them without importing the calibration itself.
"""

from __future__ import annotations

LEVELS = ("auto", "frames", "offsets", "paper", "complete")
"""Parameter levels: ``frames`` = measurement frame + markers; ``offsets`` adds the joint
offsets; ``paper`` and ``complete`` add the base parameters of those sets; ``auto`` (the
default) keeps the ones the data support (:mod:`calib.calibration.selection`)."""

DEFAULT_LEVEL = "auto"

DEFAULT_MAX_ITERATIONS = 100
"""Most residual evaluations of each solver run."""

LOSSES = ("linear", "soft_l1", "huber")
"""Losses of the fit: least squares, or a robust loss (scipy's, scale ``--noise-mm``)."""
