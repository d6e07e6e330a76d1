"""The options of a calibration, their defaults and their one check: cheap to import.

The command line builds its parser from them without importing the calibration itself;
chains and trees check the options they share with :func:`check_run_options`.
"""

from __future__ import annotations

import numbers

from ..exceptions import InvalidArgumentError

__all__ = [
    "DEFAULT_LEVEL",
    "DEFAULT_MAX_ITERATIONS",
    "LEVELS",
    "LOSSES",
    "check_run_options",
]

LEVELS = ("auto", "frames", "offsets", "paper", "complete")
"""Parameter levels: ``frames`` = measurement frame + markers; ``offsets`` adds the joint
offsets; ``paper`` and ``complete`` add the base parameters of those sets; ``auto`` (the
default) keeps the ones the data support (:mod:`calib.calibration.selection`)."""

DEFAULT_LEVEL = "auto"

DEFAULT_MAX_ITERATIONS = 100
"""Most residual evaluations of each solver run."""

LOSSES = ("linear", "soft_l1", "huber")
"""Losses of the fit: least squares, or a robust loss (scipy's, scale ``--noise-mm``)."""


def _integer(value) -> bool:
    """An integer that is not a bool (numpy integers included)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def check_run_options(max_iterations, holdout, seed) -> None:
    """The options every calibration takes, chain or tree: one check, one-line errors.

    Args:
        max_iterations: Most residual evaluations of each solver run (an integer >= 1).
        holdout: Fraction of the rows set aside, in [0, 1).
        seed: Seed of the holdout draw (an integer >= 0).

    Raises:
        InvalidArgumentError: A value out of its range or of the wrong type.
    """
    if not _integer(max_iterations) or max_iterations < 1:
        raise InvalidArgumentError(
            f"max_iterations must be an integer >= 1, got {max_iterations!r}"
        )
    if not _integer(seed) or seed < 0:
        raise InvalidArgumentError(f"the seed must be an integer >= 0, got {seed!r}")
    if (
        isinstance(holdout, bool)
        or not isinstance(holdout, numbers.Real)
        or not (0.0 <= float(holdout) < 1.0)
    ):
        raise InvalidArgumentError(f"the holdout fraction must be in [0, 1), got {holdout!r}")
