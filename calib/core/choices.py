"""Choices and defaults of the command line's options, in a module without numpy.

:mod:`calib.cli.commands` builds its parser from these constants, so that ``calib --help`` and every
command start without importing the modules of the other commands (the design, the
calibration, the measurements). The modules that use them import them from here.
"""

from __future__ import annotations

import numbers
from collections.abc import Iterable

from ..exceptions import InvalidArgumentError

__all__ = [
    "CAMPAIGN_MEASURES",
    "CONTACT_MEASURES",
    "DEFAULT_CANDIDATES",
    "DEFAULT_CONFIGS",
    "DEFAULT_MEASURE",
    "DEFAULT_SET",
    "DESIGN_LEVELS",
    "EXCHANGE_CRITERIA",
    "MARKERS",
    "ORIENTATION_FORMATS",
    "PARAMETER_SETS",
    "UNITS",
    "VERDICT_SET",
    "checked_points",
]

DEFAULT_CONFIGS = 100
"""Random configurations drawn by default."""

PARAMETER_SETS = ("paper", "complete")
"""Parameter sets of the analysis: the paper's (joint offsets fixed by the model) or complete."""

DEFAULT_MEASURE = "position"
"""What ``analyze``, ``sweep``, ``simulate`` and ``design`` assume is measured unless told:
the position of a point (a laser tracker, a motion-capture marker), what every instrument
gives. ``calibrate`` reads it from the data's columns."""

DEFAULT_SET = "complete"
"""The parameter set ``analyze``, ``simulate`` and ``design`` default to: the one
``calibrate --params auto`` (its default) chooses its parameters from. (``sweep`` prints the
counts of both sets; its verdict column judges the paper's set by default.)"""

VERDICT_SET = "paper"
"""The set a sweep's verdict judges by default (``calib sweep --params``, ``calib.sweep``): the
paper's, since the complete set reaches the rank on every chain (both sets' counts are in every
row)."""

ORIENTATION_FORMATS = ("quat-xyzw", "quat-wxyz", "rotvec", "rpy")
"""How orientation columns are written: quaternion (scalar last or first), rotation vector
[rad], or roll-pitch-yaw [rad] (``R = Rz(yaw) Ry(pitch) Rx(roll)``, Pinocchio's ``rpy``)."""

MARKERS = "markers"
"""Orientation format: no columns, the orientation of the K >= 3 measured points."""

UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3}
"""Position units a file may use, and their size in metres."""

CAMPAIGN_MEASURES = ("pose", "position")
"""What a campaign can measure."""

CONTACT_MEASURES = ("plane", "plane-point", "fixed-point", "fixed-pose")
"""Contacts: what a touch without an instrument says (:mod:`calib.identification.contacts`)."""

DEFAULT_CANDIDATES = 2000
"""Random candidates a design draws by default."""

EXCHANGE_CRITERIA = ("D", "A", "I")
"""Criteria the exchange optimises."""

DESIGN_LEVELS = ("frames", "offsets", "paper", "complete")
"""Parameter levels a design can target (``calib calibrate --params``; ``auto`` chooses from
the data, so a design targets ``complete``, the largest set it may keep)."""


def checked_points(points: Iterable[int]) -> tuple[int, ...]:
    """Measured points chosen by their number in a file (1: ``x1, y1, z1``), checked.

    Args:
        points: Point numbers, 1 or more, each once, in the order they are to be read.

    Returns:
        The numbers as a tuple.

    Raises:
        InvalidArgumentError: No number, one that is no integer or below 1, or one given twice.
    """
    wrong = (  # "must be integers, got 1" read as a contradiction
        f"points are a sequence of point numbers ((1,) for x1, y1, z1; (1, 3)), got {points!r:.60}"
    )
    if isinstance(points, str | bytes):
        raise InvalidArgumentError(wrong)
    try:
        chosen = tuple(points)
    except TypeError:
        raise InvalidArgumentError(wrong) from None
    if not chosen:
        raise InvalidArgumentError("points: choose at least one point (1 for x1, y1, z1)")
    for p in chosen:
        if isinstance(p, bool) or not isinstance(p, numbers.Integral) or p < 1:
            raise InvalidArgumentError(
                f"points are numbered from 1 (1 for x1, y1, z1), got {p!r:.60}"
            )
    chosen = tuple(int(p) for p in chosen)
    twice = next((p for i, p in enumerate(chosen) if p in chosen[:i]), None)
    if twice is not None:
        raise InvalidArgumentError(f"point {twice} is chosen twice: give each point once")
    return chosen
