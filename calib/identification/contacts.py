"""Contact kinds: a constraint holds instead of an instrument measuring the tool.

The unknown plane, point or pose plays the role of the base frame (frame -1, whose six
complete parameters the model carries) and the contact frame the role of the tool (frame
n+1): a touch's residual is the gap of the contact frame's placement ``(R, p)`` in that
frame, and its Jacobian rows come from the tool's pose-error Jacobian in the base frame
(``W6``: displacement of the contact origin [m], then rotation [rad], both in the base frame).

* ``plane``: the contact frame lies flush on the plane z = 0: gap (height, roll, pitch), the
  height of its origin and its two tilts about its own x and y axes, read from the plane's
  normal seen from the contact frame (:func:`tilts`; with the contact's rotation
  ``Rz(yaw) Ry(pitch) Rx(roll)`` in the plane's frame, the roll and pitch of that
  decomposition, whatever the yaw); its yaw and its position in the plane are free.
* ``plane-point``: a probe tip on the plane: gap height.
* ``fixed-point``: the tip at the point's origin: gap (x, y, z).
* ``fixed-pose``: the contact frame on the fixed frame: gap (x, y, z, rotation vector).

Configurations where a contact holds, and a chain's model in the frame of its constraint,
are in :mod:`~calib.identification.contact_postures`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.so3 import (
    inverse_right_jacobian,
    rotation_vector,
    tilt_derivatives,
    tilts,
)
from .measures import CONTACT_NAMES, count_joints
from .planar import Layout, planar_contact_theory

CONTACT_TOL = 1e-12
"""Largest gap [m or rad] of a posture :func:`contact_postures` keeps: the contact holds."""


@dataclass(frozen=True)
class Contact:
    """What every contact kind shares: no marker (the contact frame is the tool frame).

    Attributes:
        label: ``plane``, ``plane-point``, ``fixed-point`` or ``fixed-pose``.
    """

    label: str

    object_name: ClassVar[str] = "contact"
    """What a touch touches (``plane``, ``point``, ``pose``): the report's group."""

    object_dofs: ClassVar[tuple[int, ...]] = ()
    """The object's unknowns: components of a twist in its own frame (0-2 translation [m],
    3-5 rotation [rad]) that the touches see; as many as :meth:`unknown_constants`."""

    contact_dofs: ClassVar[tuple[int, ...]] = ()
    """The contact frame's unknowns: components of a twist in its own frame that the touches
    see beside the object's (the others are invisible or regroup with the object's)."""

    @property
    def angular(self) -> tuple[bool, ...]:
        """Whether each gap row is an angle [rad] (else a length [m])."""
        raise NotImplementedError  # pragma: no cover (every kind below defines it)

    @property
    def marker(self) -> tuple[float, float, float]:
        """The contact frame's origin: the tool origin."""
        return (0.0, 0.0, 0.0)

    @property
    def is_contact(self) -> bool:
        """True: nothing is measured but the joints."""
        return True

    @property
    def row_names(self) -> tuple[str, ...]:
        """One name per gap row."""
        raise NotImplementedError  # pragma: no cover (every kind below defines it)

    @property
    def n_rows(self) -> int:
        """Rows per touch."""
        return len(self.row_names)

    @property
    def unseen(self) -> tuple[str, ...]:
        """What such contacts can never identify, one sentence each (for the reports)."""
        return ()

    def same_side(self, R: np.ndarray) -> np.ndarray:
        """Whether a zero gap is the contact itself ``(m,)`` (not a flipped frame)."""
        return np.ones(len(R), dtype=bool)

    def unknown_constants(self, n_markers: int = 1) -> int:
        """Unknowns of one plane, point or pose: as many as its :attr:`object_dofs`."""
        return len(self.object_dofs)

    def residual(self, R, p, measured=None) -> np.ndarray:
        """Gap of each touch ``(m, n_rows)`` (every kind below defines it)."""
        raise NotImplementedError  # pragma: no cover

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray:
        """Jacobian rows of the gap (every kind below defines it)."""
        raise NotImplementedError  # pragma: no cover

    def theoretical_count(
        self, sigma: np.ndarray, on_axes: tuple[int, ...], layout: Layout | None = None
    ) -> int | None:
        """Closed-form identifiable count, None where there is none (:meth:`theory`)."""
        found = self.theory(sigma, on_axes, layout)
        return found if isinstance(found, int) else None

    def theory(
        self, sigma: np.ndarray, on_axes: tuple[int, ...], layout: Layout | None = None
    ) -> int | str:
        """Closed-form identifiable count, or why there is none (every kind below defines it).

        A planar arm (``layout.planar``: every revolute axis parallel) has its own
        (:func:`~calib.identification.planar.planar_contact_theory`).
        """
        raise NotImplementedError  # pragma: no cover

    def newton_system(
        self, W6: np.ndarray, R: np.ndarray, p: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """What :func:`project` drives to zero and its rows: the gap, unless a kind says more.

        Args:
            W6: Pose-error Jacobian of the contact frame in the constraint's frame
                ``(m, 6, k)``.
            R: Contact frame rotations ``(m, 3, 3)``.
            p: Contact frame origins ``(m, 3)`` [m].

        Returns:
            The residual ``(m, r)`` and its Jacobian rows ``(m, r, k)``.
        """
        return self.residual(R, p), self.jacobian_rows(W6, R)


@dataclass(frozen=True)
class PlaneContact(Contact):
    """The contact frame flush on an unknown plane: height and two tilts (3 rows).

    The plane brings 3 unknowns (its height and tilts; its in-plane placement is invisible).
    Closed form of the identifiable count: 4R + 2P - 1, 4R - 2 without a prismatic joint
    (see docs/method.md), for 4 joints or more.
    """

    label: str = "plane"
    object_name = "plane"
    object_dofs: ClassVar[tuple[int, ...]] = (2, 3, 4)  # its height and two tilts
    contact_dofs: ClassVar[tuple[int, ...]] = (3, 4)

    @property
    def row_names(self) -> tuple[str, ...]:
        """Height [m], roll and pitch [rad] of the contact frame in the plane's frame."""
        return ("height", "roll", "pitch")

    @property
    def angular(self) -> tuple[bool, ...]:
        """The height is a length, roll and pitch angles."""
        return (False, True, True)

    @property
    def unseen(self) -> tuple[str, ...]:
        """What these contacts can never identify."""
        return (
            "the plane's position within itself and its yaw (x, y and rz of frame -1): a "
            "plane is the same plane after them",
            "the contact frame's position within the plane and its yaw (x, y, rz of the "
            "tool frame): the contact slides and turns on the plane",
            "the plane's height along its normal against any length along the contact "
            "frame's normal (r0 with the tool's r): one sum only",
            "without a prismatic joint, the scale: a robot and a plane scaled about a point of "
            "the plane touch it at the same joint positions",
        )

    def same_side(self, R: np.ndarray) -> np.ndarray:
        """The contact frame's z axis along the plane's normal, not against it."""
        return R[:, 2, 2] > 0

    def residual(self, R, p, measured=None) -> np.ndarray:
        """Gap ``(m, 3)``: the height ``p_z`` and :func:`tilts` of ``s = R^T e_z``."""
        return np.column_stack([p[:, 2], tilts(R[:, 2, :])])

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The gap's rows: a rotation dphi turns ``s`` by ``R^T (e_z x dphi)`` (exact)."""
        ez_cross = np.stack([-W6[:, 4], W6[:, 3], np.zeros_like(W6[:, 3])], axis=1)
        ds = np.swapaxes(R, 1, 2) @ ez_cross
        return np.concatenate([W6[:, 2:3], tilt_derivatives(R[:, 2, :]) @ ds], axis=1)

    def newton_system(self, W6, R, p) -> tuple[np.ndarray, np.ndarray]:
        """Height and the tilts over ``(1 + n_z)``: ``tan(angle / 2)`` times the tilt axis.

        The tilts are those of the contact's normal ``n`` (third column of R), ``(-n_y, n_x)``,
        scaled: zero on the plane only, not on its flipped side (Newton steps on unscaled
        tilts would land a random start upside down half the time). Newton's system only:
        the gap is :meth:`residual`.
        """
        n = R[:, :, 2]  # the contact's normal; its tilts (-n_y, n_x) vanish with the gap's
        gap = np.stack([p[:, 2], -n[:, 1], n[:, 0]], axis=1)
        J = np.stack(
            [
                W6[:, 2],
                n[:, 2, None] * W6[:, 3] - n[:, 0, None] * W6[:, 5],
                n[:, 2, None] * W6[:, 4] - n[:, 1, None] * W6[:, 5],
            ],
            axis=1,
        )
        s = 1.0 / np.maximum(1.0 + n[:, 2], 1e-9)
        dn_z = n[:, 1, None] * W6[:, 3] - n[:, 0, None] * W6[:, 4]  # (dphi x n)_z
        J[:, 1:] = (
            s[:, None, None] * J[:, 1:]
            - (s**2)[:, None, None] * gap[:, 1:, None] * (dn_z[:, None, :])
        )
        gap[:, 1:] *= s[:, None]
        return gap, J

    def theory(self, sigma, on_axes, layout=None) -> int | str:
        """4R + 2P - 1 with a prismatic joint, 4R - 2 without (see docs/method.md).

        2 fewer when the last joint is revolute about the contact's normal: its motion turns
        and slides the contact within the plane, which the plane cannot see. The contact
        origin on the last axis changes nothing.

        Why not where calib has no proved formula: a prismatic joint first or last among the
        joints the plane sees, the contact origin on another joint axis, another axis along
        the normal, fewer than 4 joints that the plane sees, 2 runs of parallel revolute axes
        or fewer among them (their sums cannot turn), or ``along`` unknown. A
        planar arm: :func:`~calib.identification.planar.planar_contact_theory`.
        """
        planar = None if layout is None else layout.planar
        if planar is not None and not planar.through:
            return planar_contact_theory(self.label, planar, on_axes)
        revolute, prismatic, n = count_joints(sigma)
        if layout is None:
            return "the joint axes along the normal unknown"
        along = layout.along
        if any(k != n for k in on_axes):
            return f"the contact origin on {_axes(on_axes)}: the formula covers the last only"
        if any(k != n for k in along):
            return f"{_axes(along)} along the normal: the formula covers the last only"
        blind = 1 if n in along else 0
        seen = sigma[: n - blind]  # the joints the plane sees
        if len(seen) <= 3:
            unseen = ", the last axis along the normal unseen" if blind else ""
            return f"the plane sees {len(seen)} joints{unseen}: the formula needs 4"
        if prismatic and (seen[0] == 1 or seen[-1] == 1):
            return f"prismatic {'first' if seen[0] == 1 else 'last'} joint"
        runs = _runs(layout, len(seen), seen)
        if runs <= 2:  # two tilts hold the sums of their runs: they cannot turn
            return f"{_revolute(runs)} the plane sees: the formula needs 3"
        return 4 * revolute + 2 * prismatic - (1 if prismatic else 2) - 2 * blind


@dataclass(frozen=True)
class PlanePointContact(Contact):
    """A probe tip on an unknown plane: its height (1 row).

    Closed form: 4R + 2P (2 fewer with the tip on the last, revolute, axis).
    """

    label: str = "plane-point"
    object_name = "plane"
    object_dofs: ClassVar[tuple[int, ...]] = (2, 3, 4)
    contact_dofs = (0, 1, 2)

    @property
    def row_names(self) -> tuple[str, ...]:
        """The tip's height [m]."""
        return ("height",)

    @property
    def angular(self) -> tuple[bool, ...]:
        """A length."""
        return (False,)

    @property
    def unseen(self) -> tuple[str, ...]:
        """What these contacts can never identify."""
        return (
            "the plane's position within itself and its yaw (x, y and rz of frame -1)",
            "the tip's orientation: only the tip point is constrained",
            "without a prismatic joint, the scale about a point of the plane",
        )

    def residual(self, R, p, measured=None) -> np.ndarray:
        """Gap ``(m, 1)``: the tip's height."""
        return p[:, 2:3].copy()

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The z row of the tip's displacement."""
        return W6[:, 2:3]

    def theory(self, sigma, on_axes, layout=None) -> int | str:
        """4R + 2P, 4R - 1 without a prismatic joint, 2 fewer with the tip on the last axis.

        Why not with a prismatic first joint, the tip on another axis, fewer than 2 joints
        that move the tip (the last one does not when the tip is on its axis), or a
        prismatic one among 2 such joints.
        """
        planar = None if layout is None else layout.planar
        if planar is not None:
            return planar_contact_theory(self.label, planar, on_axes)
        revolute, prismatic, n = count_joints(sigma)
        moving = n - (n in on_axes)
        if any(k != n for k in on_axes):
            return f"the tip on {_axes(on_axes)}: the formula covers the last only"
        if moving <= 1:
            return f"{_moving(moving)} the tip: the formula needs 2"
        if sigma[0] == 1:
            return "prismatic first joint"
        if moving < n and moving <= 2 and prismatic:
            return "a prismatic joint among the 2 that move the tip"  # no proved formula
        return 4 * revolute + 2 * prismatic - (0 if prismatic else 1) - (2 if on_axes else 0)


def _axes(rows: tuple[int, ...]) -> str:
    """``joint axis 3``, ``joint axes 1, 2``: joint rows, in words."""
    return f"joint ax{'is' if len(rows) == 1 else 'es'} {', '.join(map(str, rows))}"


def _revolute(runs: int) -> str:
    """``1 run of parallel revolute axes``, ``2 runs ...``: in words."""
    return f"{runs} run{'' if runs == 1 else 's'} of parallel revolute axes"


def _runs(layout: Layout | None, rows: int, sigma: np.ndarray) -> int:
    """Runs of parallel revolute axes among joint rows 1..rows (:func:`~.planar.turning_rows`).

    Without a layout (a chain, not a model), each revolute joint is a run.
    """
    if layout is None:
        return int(np.sum(np.asarray(sigma)[:rows] == 0))
    return sum(1 for k in layout.turns if k <= rows)


def _moving(joints: int) -> str:
    """``1 joint moves``, ``3 joints move``: the joints that move the tip, in words."""
    return f"{joints} joint moves" if joints == 1 else f"{joints} joints move"


@dataclass(frozen=True)
class FixedPointContact(Contact):
    """A tip held at an unknown fixed point (3 rows).

    Closed form: 4R + 2P (2 fewer with the tip on the last, revolute, axis).
    """

    label: str = "fixed-point"
    object_name = "point"
    object_dofs = (0, 1, 2)  # its position
    contact_dofs = (0, 1, 2)

    @property
    def row_names(self) -> tuple[str, ...]:
        """The tip's position [m]."""
        return ("x", "y", "z")

    @property
    def angular(self) -> tuple[bool, ...]:
        """Lengths."""
        return (False, False, False)

    @property
    def unseen(self) -> tuple[str, ...]:
        """What these contacts can never identify."""
        return (
            "the point frame's orientation (rx, ry, rz of frame -1): the tip is held at its origin",
            "the tip's orientation: only the tip point is constrained",
            "without a prismatic joint, the scale about the point",
        )

    def residual(self, R, p, measured=None) -> np.ndarray:
        """Gap ``(m, 3)``: the tip's position in the point's frame."""
        return p.copy()

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray:
        """The position rows of the tip's displacement."""
        return W6[:, :3]

    def theory(self, sigma, on_axes, layout=None) -> int | str:
        """4R + 2P, 4R - 1 without a prismatic joint, 2 fewer with the tip on the last axis.

        Why not with the tip on another axis, or 3 joints or fewer that move the tip (the
        last one does not when the tip is on its axis): the tip cannot stay on the point
        and move; 2 runs of parallel revolute axes or fewer among them; a planar arm.
        """
        planar = None if layout is None else layout.planar
        if planar is not None:
            return planar_contact_theory(self.label, planar, on_axes)
        revolute, prismatic, n = count_joints(sigma)
        moving = n - (n in on_axes)
        if any(k != n for k in on_axes):
            return f"the tip on {_axes(on_axes)}: the formula covers the last only"
        if moving <= 3:
            return f"{_moving(moving)} the tip: it cannot stay on the point and move"
        if _runs(layout, moving, sigma) <= 2:
            return f"{_revolute(_runs(layout, moving, sigma))} move the tip: no proved formula"
        return 4 * revolute + 2 * prismatic - (0 if prismatic else 1) - (2 if on_axes else 0)


@dataclass(frozen=True)
class FixedPoseContact(Contact):
    """The contact frame held on an unknown fixed frame, a closed loop (6 rows).

    Closed form: 4R + 2P, for a chain with at least 7 joints (6 for the loop, one to move).
    """

    label: str = "fixed-pose"
    object_name = "pose"
    object_dofs = (0, 1, 2, 3, 4, 5)  # all six
    contact_dofs = ()

    @property
    def row_names(self) -> tuple[str, ...]:
        """Position [m] and rotation vector [rad] of the contact frame in the fixed frame."""
        return ("x", "y", "z", "rx", "ry", "rz")

    @property
    def angular(self) -> tuple[bool, ...]:
        """Lengths, then angles."""
        return (False, False, False, True, True, True)

    @property
    def unseen(self) -> tuple[str, ...]:
        """What these contacts can never identify."""
        return (
            "the fixed frame and the contact frame apart: only their relative placement (6) "
            "is seen",
            "without a prismatic joint, the scale about the fixed frame's origin",
        )

    def residual(self, R, p, measured=None) -> np.ndarray:
        """Gap ``(m, 6)``: position and rotation vector ``log R``."""
        return np.concatenate([p, rotation_vector(R)], axis=1)

    def jacobian_rows(self, W6: np.ndarray, R: np.ndarray) -> np.ndarray:
        """Position rows, and the rotation rows through the inverse left Jacobian of log."""
        inv = inverse_right_jacobian(-rotation_vector(R))  # Jl^-1(phi) = Jr^-1(-phi)
        return np.concatenate([W6[:, :3], inv @ W6[:, 3:]], axis=1)

    def theory(self, sigma, on_axes, layout=None) -> int | str:
        """4R + 2P (4R - 1 without a prismatic joint) where the loop can move (n >= 7).

        Why not for a loop of 6 joints or fewer (it cannot move: finitely many postures), 3
        runs of parallel revolute axes or fewer (their sums cannot turn), other
        neighbouring parallel revolute axes in a loop of 7 (one degree of freedom), or a
        planar arm.
        """
        planar = None if layout is None else layout.planar
        if planar is not None and not planar.through:
            return planar_contact_theory(self.label, planar, on_axes)
        revolute, prismatic, n = count_joints(sigma)
        if n < 7:
            return f"a {n}-joint loop cannot move"
        runs = _runs(layout, n, sigma)
        if runs <= 3:  # the loop's orientation holds the sums of their runs: they cannot turn
            return f"{_revolute(runs)} in the loop: the formula needs 4"
        if runs < revolute and n == 7:  # counts found below the formula there
            return "neighbouring revolute axes parallel in a 7-joint loop: no proved formula"
        return 4 * revolute + 2 * prismatic - (0 if prismatic else 1)


@dataclass(frozen=True)
class KnownPlaneContact(PlaneContact):
    """The contact frame flush on a plane given (a floor): the plane has no unknown.

    The contact frame's height along its normal, which a plane fitted takes in its own
    height, is seen then (3 unknowns: its height and two tilts).
    """

    object_dofs = ()
    contact_dofs = (2, 3, 4)

    @property
    def unseen(self) -> tuple[str, ...]:
        """What these contacts can never identify."""
        return (
            "the contact frame's position within the plane and its yaw (x, y, rz of the "
            "tool frame): the contact slides and turns on the plane",
        )

    def theory(self, sigma, on_axes, layout=None) -> int | str:
        """Why not: calib has no proved formula with the plane given."""
        return "no proved formula with the plane given"


@dataclass(frozen=True)
class KnownPlanePointContact(PlanePointContact):
    """A probe tip on a plane given: the plane has no unknown, the tip's 3 stay."""

    object_dofs = ()

    @property
    def unseen(self) -> tuple[str, ...]:
        """What these contacts can never identify."""
        return ("the tip's orientation: only the tip point is constrained",)

    def theory(self, sigma, on_axes, layout=None) -> int | str:
        """Why not: calib has no proved formula with the plane given."""
        return "no proved formula with the plane given"


def known_plane(kind: Contact) -> Contact:
    """The kind touching a plane given (no unknown of its own) instead of a plane fitted.

    Raises:
        InvalidArgumentError: Not a plane kind.
    """
    if isinstance(kind, KnownPlaneContact | KnownPlanePointContact):
        return kind
    if isinstance(kind, PlaneContact):
        return KnownPlaneContact()
    if isinstance(kind, PlanePointContact):
        return KnownPlanePointContact()
    raise InvalidArgumentError(
        f"a known plane is touched by plane or plane-point, not {kind.label}"
    )


_KINDS = {
    k.label: k
    for k in (PlaneContact(), PlanePointContact(), FixedPointContact(), FixedPoseContact())
}


def contact_kind(name: str) -> Contact:
    """The contact kind of a name (see :data:`~calib.identification.measures.CONTACT_NAMES`).

    Raises:
        InvalidArgumentError: Not a contact's name.
    """
    if name not in _KINDS:
        raise InvalidArgumentError(f"unknown contact '{name}': choose {', '.join(CONTACT_NAMES)}")
    return _KINDS[name]


__all__ = [
    "CONTACT_TOL",
    "Contact",
    "FixedPointContact",
    "FixedPoseContact",
    "KnownPlaneContact",
    "KnownPlanePointContact",
    "PlaneContact",
    "PlanePointContact",
    "contact_kind",
    "known_plane",
]
