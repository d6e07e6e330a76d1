"""Theoretical counts of identifiable parameters (Everett, Driels, Mooring 1987), chains and trees.

The independent parameters of a complete minimal model, and the joint axes through the measured
point that lower them.
"""

from __future__ import annotations

import functools

import numpy as np

from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..kinematics.tree_model import TreeMDH
from .measures import MeasureKind, Measurement
from .planar import Layout, planar_layout, turning_rows

__all__ = [
    "ON_AXIS_TOL",
    "axes_along_tool_z",
    "axes_through_point",
    "per_tool_theory",
    "point_on_last_axis",
    "theoretical_count",
    "theory_note",
    "theory_of",
    "tree_axes",
    "tree_theoretical_count",
]


ON_AXIS_TOL = 1e-9
"""Distance [m] under which the measured point lies on the last joint axis."""


def theoretical_count(
    chain_or_mdh: Chain | MDHModel | TreeMDH,
    measurement: MeasureKind,
    on_axes: tuple[int, ...] = (),
) -> int | None:
    """Independent parameters of a complete minimal model (Everett, Driels, Mooring 1987).

    The kind's own formula (:meth:`Measurement.theoretical_count`: 4R + 2P + 6 for the full
    pose, 4R + 2P + 3 for the position of one point, 2 fewer when the point lies on the last
    (revolute) axis; the contacts' in :mod:`calib.identification.contacts`). None where the
    formula says nothing. A tree model gets :func:`tree_theoretical_count`.

    Args:
        chain_or_mdh: The chain or its model (for sigma).
        measurement: What is measured.
        on_axes: Joints whose axis passes through the measured point.

    A model also gives the joints whose axis lies along the tool's z axis
    (:func:`axes_along_tool_z`): a plane contact cannot see a last joint that turns about its
    normal. A chain does not (contact kinds then say nothing).
    """
    found = theory_of(chain_or_mdh, measurement, on_axes)
    return found if isinstance(found, int) else None


def _theory_arguments(chain_or_mdh: Chain | MDHModel, on_axes: tuple[int, ...]) -> tuple:
    """A kind's theory's arguments: the joints' types, the axes through the point, the layout.

    The layout (:class:`~.planar.Layout`): the axes along the tool's z, the planar layout and
    where runs of parallel revolute axes start. A chain (not a model) has none.
    """
    sigma = np.asarray(chain_or_mdh.sigma)
    if not isinstance(chain_or_mdh, MDHModel):
        return sigma[sigma >= 0], tuple(on_axes), None
    layout = Layout(
        axes_along_tool_z(chain_or_mdh),
        planar_layout(chain_or_mdh, tuple(on_axes)),
        turning_rows(chain_or_mdh),
    )
    return sigma[sigma >= 0], tuple(on_axes), layout


def theory_note(
    chain_or_mdh: Chain | MDHModel | TreeMDH,
    measurement: MeasureKind,
    on_axes: tuple[int, ...] = (),
) -> str:
    """Why :func:`theoretical_count` is None, in a few words (empty where it is a count).

    The kind's own reason (:meth:`Measurement.theory`, the contacts' in
    :mod:`calib.identification.contacts`). A tree: only rows that are neither the pose nor a
    point (its points on axes are the report's own note).
    """
    found = theory_of(chain_or_mdh, measurement, on_axes)
    return found if isinstance(found, str) else ""


def theory_of(
    chain_or_mdh: Chain | MDHModel | TreeMDH,
    measurement: MeasureKind,
    on_axes: tuple[int, ...] = (),
) -> int | str:
    """:func:`theoretical_count`, or where it is None :func:`theory_note`'s reason: one call.

    The kind's :meth:`Measurement.theory` (a chain), :func:`tree_theoretical_count` (a tree:
    no reason for the pose or a point, whose points on axes are the report's own note).

    Args:
        chain_or_mdh: The chain or its model (for sigma).
        measurement: What is measured.
        on_axes: Joints whose axis passes through the measured point.
    """
    if not isinstance(chain_or_mdh, TreeMDH):
        return measurement.theory(*_theory_arguments(chain_or_mdh, on_axes))
    count = tree_theoretical_count(chain_or_mdh, measurement)
    if count is not None:
        return count
    if isinstance(measurement, Measurement) and (measurement.is_pose or measurement.is_position):
        return ""
    return f"the formula is for the pose or a point, not the rows {measurement.label}"


@functools.lru_cache(maxsize=16)
def tree_axes(model: TreeMDH, measurement: MeasureKind) -> tuple[tuple[int, ...], ...]:
    """Per tool of a tree, the revolute joint rows whose axis passes through its point."""
    out = []
    for t in range(model.n_tools):
        rows = model.path_rows(t)
        on = axes_through_point(model.path_model(t), measurement)
        out.append(tuple(int(rows[k]) for k in on))
    return tuple(out)


def tree_theoretical_count(model: TreeMDH, measurement: MeasureKind) -> int | None:
    """Independent parameters of a tree's complete model: 4R + 2P + 6T (pose of T tools).

    Each joint is counted once however many tools it carries: the placement of each joint
    and tool in its antecedent (6 each) and of the base (6), minus 6 for the base (the base
    link's children absorb it) and, per joint, the errors its motion absorbs (2 revolute,
    4 prismatic). Position of one point per tool: 3 fewer per tool (rotations about the
    point), and 2 fewer per joint whose only children are tools with their points on its
    axis. None for other row subsets or a point on another axis.
    """
    R, P, T = int(np.sum(model.sigma == 0)), int(np.sum(model.sigma == 1)), model.n_tools
    if not isinstance(measurement, Measurement):
        return None
    if measurement.is_pose:
        return 4 * R + 2 * P + 6 * T
    if not measurement.is_position:
        return None
    axes = tree_axes(model, measurement)
    lost = 0
    for k in sorted({k for rows in axes for k in rows}):
        children = np.flatnonzero(model.antecedent == k)
        tools = [t for t, row in enumerate(model.tool_rows) if row in children]
        if len(tools) < len(children) or any(k not in axes[t] for t in tools):
            return None
        lost += 2
    return 4 * R + 2 * P + 3 * T - lost


def axes_through_point(mdh: MDHModel | TreeMDH, measurement: MeasureKind) -> tuple[int, ...]:
    """Revolute joints (1..n) whose axis passes through the measured point.

    An axis counts only if it does so at every configuration: it is tested at the zero
    configuration and four fixed others. For a tree: through the point of a tool it carries.
    """
    if isinstance(mdh, TreeMDH):
        return tuple(sorted({k for rows in tree_axes(mdh, measurement) for k in rows}))
    q = np.vstack([np.zeros(mdh.n), np.random.default_rng(12345).uniform(-3.0, 3.0, (4, mdh.n))])
    kin = mdh.kinematics(q)
    E = kin.p[:, -1] + np.einsum("mij,j->mi", kin.R[:, -1], np.array(measurement.marker))
    out = []
    for k in range(1, mdh.n + 1):
        if mdh.sigma[k] != 0:
            continue
        v = E - kin.p[:, k]
        z = kin.R[:, k, :, 2]
        off = v - np.sum(v * z, axis=1)[:, None] * z
        if np.all(np.linalg.norm(off, axis=1) < ON_AXIS_TOL):
            out.append(k)
    return tuple(out)


def axes_along_tool_z(mdh: MDHModel) -> tuple[int, ...]:
    """Revolute joints (1..n) whose axis lies along the tool frame's z axis, at every posture.

    Tested like :func:`axes_through_point`: at the zero configuration and four fixed others.
    """
    q = np.vstack([np.zeros(mdh.n), np.random.default_rng(12345).uniform(-3.0, 3.0, (4, mdh.n))])
    kin = mdh.kinematics(q)
    zt = kin.R[:, -1, :, 2]
    out = []
    for k in range(1, mdh.n + 1):
        if mdh.sigma[k] == 0:
            cross = np.cross(kin.R[:, k, :, 2], zt)
            if np.all(np.linalg.norm(cross, axis=1) < ON_AXIS_TOL):
                out.append(k)
    return tuple(out)


def point_on_last_axis(mdh: MDHModel, measurement: MeasureKind) -> bool:
    """Whether the measured point lies on the last joint axis (a revolute one)."""
    return mdh.n in axes_through_point(mdh, measurement)


def per_tool_theory(mdh: TreeMDH, measurement: MeasureKind) -> tuple[tuple[str, int | None], ...]:
    """Each tool's chain alone: its name and theoretical count (see :func:`theoretical_count`)."""
    out = []
    axes = tree_axes(mdh, measurement)
    for t, name in enumerate(mdh.tool_frames):
        rows = list(mdh.path_rows(t))
        on = tuple(rows.index(k) for k in axes[t])
        out.append((name, theoretical_count(mdh.path_model(t), measurement, on)))
    return tuple(out)
