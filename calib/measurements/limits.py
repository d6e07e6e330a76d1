"""Measurements against their chain or tree: same joints, joint values near limits, known tools."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..exceptions import DataError, InvalidArgumentError, warn_user
from ..kinematics.frames import urdf_limits
from ..kinematics.limits import (
    LIMIT_MARGIN,
    LIMIT_TOL,
    joint_bounds,
    joint_unit,
    refuse_far_past_limits,
)
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
    "warn_default_ranges",
]


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
    past = refuse_far_past_limits(chain, q, source, rows)
    near = past > LIMIT_TOL
    if warn and np.any(near):
        worst = [
            f"{chain.joint_names[k]} by up to {np.max(past[:, k]):.3g} "
            f"{joint_unit(int(chain.sigma[k]))}"
            for k in np.flatnonzero(np.any(near, axis=0))
        ]
        n = int(np.sum(np.any(near, axis=1)))
        warn_user(
            f"{source}: {n} row{'s' if n != 1 else ''} read past the URDF joint limits "
            f"({'; '.join(worst)}): accepted (kinematics does not need the limits)",
            DataWarning,
        )


def warn_default_ranges(robot: Chain | Tree, remedy: str | None = None) -> None:
    """Warn that joints without usable URDF limits are drawn in calib's default range.

    A posture drawn there may be out of the real robot's reach (a quill of 0..0.2 m drawn in
    +-0.1 m); continuous joints (a full turn) and mimic joints (they follow) are not named.
    ``design``'s random candidates and the simulations' random postures say it alike.

    Args:
        robot: A chain or a tree.
        remedy: The other way out than adding the ``<limit>`` ("give your own candidates"),
            if any.
    """
    mimic = set() if robot.coupling is None else {mj.joint for mj in robot.coupling.mimic}
    named = [
        f"{robot.joint_names[k]} (drawn in [{robot.lower[k]:.6g}, {robot.upper[k]:.6g}] "
        f"{joint_unit(int(robot.sigma[k]))})"
        for k, jid in enumerate(robot.joint_ids)
        if k not in mimic
        and robot.model.joints[jid].nq == 1
        and urdf_limits(robot.model, jid) is None
    ]
    other = f", or {remedy}" if remedy else ""
    if named:
        warn_user(
            f"no usable <limit> in the URDF for {', '.join(named)}: calib's default range, "
            f"which the robot may not reach (add the <limit>{other})",
            DataWarning,
        )
