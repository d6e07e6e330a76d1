"""Planar arms: every revolute axis parallel to one direction u, and their contact counts.

A planar arm moves its links in planes across u, and turns its tool about u only, so a
contact's general formula (:mod:`calib.identification.contacts`, which assumes a tool that
turns about every direction) does not hold. Where the touched plane's normal lies along u (the
arm slides on the plane), the counts are proved in docs/method.md §6 and given here; elsewhere
the contacts say why there is none.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..kinematics.mdh import MDHModel

PARALLEL_TOL = 1e-9
"""Sine of the angle [-] under which two joint axes are parallel (or perpendicular)."""


@dataclass(frozen=True)
class Planar:
    """How the joints of a chain whose revolute axes are all parallel to u lie.

    Attributes:
        revolute: Revolute joints (0: the tool does not turn).
        across: Prismatic joints across u: they slide within the arm's plane.
        axial: Prismatic joints along u.
        oblique: Other prismatic joints (the arm is not planar then, but its tool still turns
            about u only).
        normal: Whether the tool's z axis lies along u (a plane touched lies across u).
        last: Row (1..n) of the last revolute joint counted.
        through: Whether the joints whose axis passes through the contact origin are left out
            (the chain is planar only without them, for a point touching: they never move
            it); then the counts above are of the other joints.
    """

    revolute: int
    across: int
    axial: int
    oblique: int
    normal: bool
    last: int
    through: bool = False


@dataclass(frozen=True)
class Layout:
    """What a kind's theory reads of the joint axes, beyond the joints' types.

    Attributes:
        along: Revolute joint rows (1..n) whose axis lies along the tool's z axis.
        planar: The :class:`Planar` layout, None unless every revolute axis is parallel.
        turns: Rows where a run of parallel revolute axes starts (``turning_rows``).
    """

    along: tuple[int, ...]
    planar: Planar | None
    turns: tuple[int, ...]


def planar_layout(mdh: MDHModel, on_axes: tuple[int, ...] = ()) -> Planar | None:
    """The chain's :class:`Planar` layout, None unless every revolute axis is parallel.

    A chain without a revolute joint has one (its prismatic joints oblique, none revolute).
    Where only the joints ``on_axes`` (1..n, their axes through the contact origin) are not
    parallel, the layout of the others, marked ``through``.

    Tested at the zero configuration and four fixed others, like
    :func:`calib.identification.theory.axes_along_tool_z`.
    """
    found = _layout(mdh, ())
    if found is None and on_axes:
        found = _layout(mdh, on_axes)
        return None if found is None else replace(found, through=True)
    return found


def _layout(mdh: MDHModel, skip: tuple[int, ...]) -> Planar | None:
    """:func:`planar_layout` of the joints but those ``skip``."""
    q = np.vstack([np.zeros(mdh.n), np.random.default_rng(12345).uniform(-3.0, 3.0, (4, mdh.n))])
    kin = mdh.kinematics(q)
    rows = np.array([k for k in range(1, mdh.n + 1) if k not in skip], dtype=int)
    revolute = rows[mdh.sigma[rows] == 0]
    if not revolute.size:  # the tool does not turn at all
        return Planar(0, 0, 0, len(rows), False, 0)
    u = kin.R[:, revolute[0], :, 2]
    if not all(_parallel(kin.R[:, k, :, 2], u) for k in revolute):
        return None
    prismatic = [kin.R[:, k, :, 2] for k in rows[mdh.sigma[rows] == 1]]
    across = sum(_across(z, u) for z in prismatic)
    axial = sum(_parallel(z, u) for z in prismatic)
    oblique = len(prismatic) - across - axial
    normal = _parallel(kin.R[:, -1, :, 2], u)
    return Planar(int(revolute.size), across, axial, oblique, normal, int(revolute[-1]))


def turning_rows(mdh: MDHModel) -> tuple[int, ...]:
    """Rows (1..n) where a run of parallel revolute axes starts (the first revolute joint's).

    A run: consecutive revolute joints (prismatic ones between them skipped) whose axes are
    parallel at every posture.

    The tool's orientation depends on the sum of the angles of a run only (a rotation about
    one axis commutes with the fixed rotation that keeps it parallel to the next): a contact
    whose rows hold the orientation freezes those sums unless there are more runs than rows.
    """
    q = np.vstack([np.zeros(mdh.n), np.random.default_rng(12345).uniform(-3.0, 3.0, (4, mdh.n))])
    kin = mdh.kinematics(q)
    out: list[int] = []
    for k in range(1, mdh.n + 1):
        if mdh.sigma[k] == 0 and (
            not out or not _parallel(kin.R[:, k, :, 2], kin.R[:, out[-1], :, 2])
        ):
            out.append(k)
    return tuple(out)


def _parallel(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether unit vectors ``(m, 3)`` are parallel at every row."""
    return bool(np.all(np.linalg.norm(np.cross(a, b), axis=1) < PARALLEL_TOL))


def _across(a: np.ndarray, b: np.ndarray) -> bool:
    """Whether unit vectors ``(m, 3)`` are perpendicular at every row."""
    return bool(np.all(np.abs(np.sum(a * b, axis=1)) < PARALLEL_TOL))


def planar_contact_theory(label: str, planar: Planar, on_axes: tuple[int, ...]) -> int | str:
    """A planar arm's count for a contact kind, or why there is none (docs/method.md §6).

    With the plane's normal along u, the height sees, per group of links that turn alike
    (one more group than revolute joints), a tilt across u times the tip's position in that
    group's frame: 2 new functions per revolute joint (the tip's circle about it), 1 per
    prismatic joint across u (its stroke), and one constant (every length along u and the
    plane's height): ``plane-point`` 2R + P_across + 1, 2 fewer with the tip on the last
    revolute axis. ``plane`` also sees each group's two tilts in its tilt rows, the last
    group's as constants: 2R + P_across + 3.

    Args:
        label: The kind (``plane``, ``plane-point``, ``fixed-point``, ``fixed-pose``).
        planar: The chain's layout.
        on_axes: Joint rows (1..n) whose axis passes through the contact origin.
    """
    if not planar.revolute:
        return "no revolute joint, the tool does not turn: no proved formula"
    if planar.oblique:
        return (
            "the tool turns about one direction only, a prismatic joint oblique to it: "
            "no proved formula"
        )
    on_axes = () if planar.through else on_axes  # those left out are not counted
    in_plane = planar.revolute + planar.across  # the joints that move the contact in its plane
    if label == "fixed-point" and in_plane - (planar.last in on_axes) <= 2:
        moving = in_plane - (planar.last in on_axes)
        verb = "moves" if moving == 1 else "move"
        return (
            f"{_joints(moving)} {verb} the tip in its plane: it cannot stay on the point and move"
        )
    if label == "fixed-pose" and in_plane <= 3:
        return f"a planar loop of {_joints(in_plane)} cannot move"
    words = "revolute axes all parallel" + (" but those through the tip" if planar.through else "")
    if label not in ("plane", "plane-point"):
        return f"{words} (a planar arm): no proved formula for a {label}"
    if not planar.normal:
        return f"{words} (a planar arm), the plane oblique to them: no proved formula"
    if label == "plane":
        return 2 * planar.revolute + planar.across + 3
    if any(k != planar.last for k in on_axes):
        return f"{words}, the tip on joint axes {', '.join(map(str, on_axes))}: no proved formula"
    return 2 * planar.revolute + planar.across + 1 - (2 if on_axes else 0)


def _joints(count: int) -> str:
    """``1 joint``, ``3 joints``."""
    return f"{count} joint" if count == 1 else f"{count} joints"


__all__ = [
    "PARALLEL_TOL",
    "Layout",
    "Planar",
    "planar_contact_theory",
    "planar_layout",
    "turning_rows",
]
