"""Joint values against a robot's limits: how far past them a value may read.

Kept in the lowest layer so that a calibrated model (:mod:`.elastic`) refuses configurations
far past a limit (degrees for radians) as a measurements or configurations file does
(:func:`calib.measurements.limits.check_limits` builds its warnings on this).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import DataError
from .frames import urdf_limits
from .robot import Chain
from .tree import Tree

__all__ = [
    "LIMIT_MARGIN",
    "LIMIT_TOL",
    "joint_bounds",
    "joint_unit",
    "reading_bounds",
    "refuse_far_past_limits",
]


LIMIT_TOL = 1e-9
"""Slack [rad or m] allowed beyond a joint limit (values written at the limit, rounded)."""


LIMIT_MARGIN = (0.1, 0.01)
"""Margin [rad, m] beyond a joint limit that a reading may have with only a warning.

Real encoders read a little past the limits the URDF gives for motion planning; kinematics
does not need the limits. Farther out is an error (a wrong column, degrees for radians).
"""


def joint_bounds(robot: Chain | Tree) -> tuple[np.ndarray, np.ndarray]:
    """Limits a measured joint position must respect [rad or m]: infinite for continuous joints."""
    lower = np.where(robot.continuous, -np.inf, robot.lower)
    upper = np.where(robot.continuous, np.inf, robot.upper)
    return lower, upper


def reading_bounds(robot: Chain | Tree) -> tuple[np.ndarray, np.ndarray]:
    """The URDF's limits of each joint [rad or m]: infinite where it gives none it can use.

    A joint without usable limits (continuous, or a ``<limit>`` missing, equal or infinite) is
    sampled in a default range (:func:`~calib.kinematics.frames.sampling_bounds`), but a
    reading outside that range is no mistake: only limits the URDF gives are checked.
    """
    limits = [urdf_limits(robot.model, j) for j in robot.joint_ids]
    lower = np.array([-np.inf if b is None else b[0] for b in limits])
    upper = np.array([np.inf if b is None else b[1] for b in limits])
    return lower, upper


def joint_unit(sigma: int) -> str:
    """The unit of a joint's position: ``m`` for a prismatic joint (sigma 1), else ``rad``."""
    return "m" if sigma == 1 else "rad"


def refuse_far_past_limits(
    robot: Chain | Tree, q: np.ndarray, source: str, rows: np.ndarray
) -> np.ndarray:
    """How far each joint value ``(m, n)`` reads past its limits [rad or m] (mimic joints -inf).

    Args:
        robot: A chain or a tree.
        q: Joint positions ``(m, n)`` [rad or m].
        source: What holds them, for the message (a file, ``"the configurations"``).
        rows: The row number of each configuration in ``source`` ``(m,)``.

    Raises:
        DataError: A value farther than ``LIMIT_MARGIN`` outside its limits (the first one).
    """
    lower, upper = reading_bounds(robot)
    margin = np.where(robot.sigma == 1, LIMIT_MARGIN[1], LIMIT_MARGIN[0])
    past = np.maximum(lower - q, q - upper)
    if robot.coupling is not None:  # a mimic joint's position is computed, not read
        past[:, [mj.joint for mj in robot.coupling.mimic]] = -np.inf
    far = past > margin + LIMIT_TOL
    if np.any(far):
        i, k = (int(v) for v in np.argwhere(far)[0])
        unit = joint_unit(int(robot.sigma[k]))
        mistake = "degrees for radians?"
        if unit == "m":  # the points' --units never scales a joint reading
            mistake = (
                "millimetres for metres? joint readings are in m and rad: --units scales "
                "the measured points only"
            )
        raise DataError(
            source,
            f"joint value {q[i, k]:.9g} {unit} is outside the joint limits "
            f"[{lower[k]:.9g}, {upper[k]:.9g}] {unit} by more than "
            f"{margin[k]:g} {unit} (a wrong column, or {mistake})",
            row=int(rows[i]),
            column=robot.joint_names[k],
        )
    return past
