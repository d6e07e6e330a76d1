"""Measurements against their chain or tree: same joints, joint values near limits, known tools."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import DataError, InvalidArgumentError, warn_user
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree
from .data import TOOL_COLUMN, DataWarning, Measurements

__all__ = [
    "LIMIT_MARGIN",
    "LIMIT_TOL",
    "check_against_chain",
    "check_limits",
    "check_tools",
    "joint_bounds",
    "tool_frames",
]


LIMIT_TOL = 1e-9
"""Slack [rad or m] allowed beyond a joint limit (values written at the limit, rounded)."""


LIMIT_MARGIN = (0.1, 0.01)
"""Margin [rad, m] beyond a joint limit that a reading may have with only a warning.

Real encoders read a little past the limits the URDF gives for motion planning; kinematics
does not need the limits. Farther out is an error (a wrong column, degrees for radians).
"""


def joint_bounds(chain: Chain | Tree) -> tuple[np.ndarray, np.ndarray]:
    """Limits a measured joint position must respect [rad or m]: infinite for continuous joints."""
    lower = np.where(chain.continuous, -np.inf, chain.lower)
    upper = np.where(chain.continuous, np.inf, chain.upper)
    return lower, upper


def _unit(sigma: int) -> str:
    return "m" if sigma == 1 else "rad"


def check_against_chain(data: Measurements, chain: Chain | Tree) -> None:
    """Check that measurements belong to a chain: same joints, values near the limits.

    A reading past a joint limit by at most ``LIMIT_MARGIN`` gives a :class:`DataWarning`.

    Raises:
        InvalidArgumentError: ``data`` is no :class:`Measurements` (a path, touches).
        DataError: Other joints, or a joint value farther outside its limits (naming the
            row and the column).
    """
    if not isinstance(data, Measurements):
        hint = ": read the file with read_measurements" if isinstance(data, str | Path) else ""
        raise InvalidArgumentError(
            f"measurements must be Measurements, got {type(data).__name__} {data!r:.40}{hint}"
        )
    if data.joint_names != chain.joint_names:
        raise DataError(
            data.source,
            f"joints {', '.join(data.joint_names)} do not match the chain's "
            f"{', '.join(chain.joint_names)}",
        )
    check_tools(data, tool_frames(chain))
    check_limits(chain, data.q, data.source, data.file_rows())


def tool_frames(chain) -> tuple[str, ...]:
    """The tool frames of a chain (one) or of a tree (several)."""
    return tuple(chain.tool_frames)


def check_tools(data: Measurements, tools: tuple[str, ...]) -> None:
    """Every row's tool is one of the model's; several tools need the ``tool`` column."""
    if data.tool is None:
        if len(tools) > 1:
            raise DataError(
                data.source,
                f"the model has {len(tools)} tools ({', '.join(tools)}): a '{TOOL_COLUMN}' "
                f"column must name the one each row measures",
            )
        return
    for i, name in enumerate(data.tool):
        if name not in tools:
            raise DataError(
                data.source,
                f"unknown tool '{name}': the model's tools are {', '.join(tools)}",
                row=data.row_of(i),
                column=TOOL_COLUMN,
            )


def check_limits(
    chain: Chain | Tree, q: np.ndarray, source: str, rows: np.ndarray, warn: bool = True
) -> None:
    """Raise a DataError naming the first joint value far outside its limits; warn on others."""
    lower, upper = joint_bounds(chain)
    margin = np.where(chain.sigma == 1, LIMIT_MARGIN[1], LIMIT_MARGIN[0])
    past = np.maximum(lower - q, q - upper)
    if chain.coupling is not None:  # a mimic joint's position is computed, not read
        past[:, [mj.joint for mj in chain.coupling.mimic]] = -np.inf
    far = past > margin + LIMIT_TOL
    if np.any(far):
        i, k = (int(v) for v in np.argwhere(far)[0])
        unit = _unit(int(chain.sigma[k]))
        raise DataError(
            source,
            f"joint value {q[i, k]:.9g} {unit} is outside the joint limits "
            f"[{chain.lower[k]:.9g}, {chain.upper[k]:.9g}] {unit} by more than "
            f"{margin[k]:g} {unit} (a wrong column, or degrees for radians?)",
            row=int(rows[i]),
            column=chain.joint_names[k],
        )
    near = past > LIMIT_TOL
    if warn and np.any(near):
        worst = [
            f"{chain.joint_names[k]} by up to {np.max(past[:, k]):.3g} {_unit(int(chain.sigma[k]))}"
            for k in np.flatnonzero(np.any(near, axis=0))
        ]
        warn_user(
            f"{source}: {int(np.sum(np.any(near, axis=1)))} rows read past the URDF joint limits "
            f"({'; '.join(worst)}): accepted (kinematics does not need the limits)",
            DataWarning,
        )
