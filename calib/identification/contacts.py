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

:func:`contact_postures` draws configurations where a contact holds, by Newton projection
with the kind's own Jacobian rows, and :func:`contact_model` re-expresses a chain's model in
the frame of its constraint (the plane, point or pose at frame -1).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.mdh import Kinematics, MDHModel, frames_at_zero, from_lines
from ..kinematics.so3 import (
    inverse_right_jacobian,
    rotation_vector,
    tilt_derivatives,
    tilts,
)
from .measures import CONTACT_NAMES, count_joints
from .parameters import Kind, Parameter, ParameterSet

CONTACT_TOL = 1e-12
"""Largest gap [m or rad] of a posture :func:`contact_postures` keeps: the contact holds."""

MAX_STEP_Q = 1e2
"""Largest joint position [rad or m] a projected posture may reach before it is dropped."""

NEWTON_STEPS = 60
"""Newton iterations of :func:`contact_postures` per round."""


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
        self, sigma: np.ndarray, on_axes: tuple[int, ...], along: tuple[int, ...] | None = None
    ) -> int | None:
        """Closed-form identifiable count (every kind below defines it)."""
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
    object_dofs = (2, 3, 4)  # its height and two tilts
    contact_dofs = (3, 4)

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

    def theoretical_count(self, sigma, on_axes, along=None) -> int | None:
        """4R + 2P - 1 with a prismatic joint, 4R - 2 without (see docs/method.md).

        2 fewer when the last joint is revolute about the contact's normal: its motion turns
        and slides the contact within the plane, which the plane cannot see. The contact
        origin on the last axis changes nothing.

        None where calib has no proved formula: a prismatic joint first or last among the
        joints the plane sees, the contact origin on another joint axis, another axis along
        the normal, fewer than 4 joints that the plane sees, or ``along`` unknown.
        """
        revolute, prismatic, n = count_joints(sigma)
        if along is None or any(k != n for k in (*on_axes, *along)):
            return None
        blind = 1 if n in along else 0
        seen = sigma[: n - blind]  # the joints the plane sees
        if len(seen) <= 3 or (prismatic and (seen[0] == 1 or seen[-1] == 1)):
            return None
        return 4 * revolute + 2 * prismatic - (1 if prismatic else 2) - 2 * blind


@dataclass(frozen=True)
class PlanePointContact(Contact):
    """A probe tip on an unknown plane: its height (1 row).

    Closed form: 4R + 2P (2 fewer with the tip on the last, revolute, axis).
    """

    label: str = "plane-point"
    object_name = "plane"
    object_dofs = (2, 3, 4)
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

    def theoretical_count(self, sigma, on_axes, along=None) -> int | None:
        """4R + 2P, 4R - 1 without a prismatic joint, 2 fewer with the tip on the last axis.

        None with a prismatic first joint, the tip on another axis, fewer than 2 joints that
        move the tip (the last one does not when the tip is on its axis), or a prismatic
        one among 2 such joints.
        """
        revolute, prismatic, n = count_joints(sigma)
        moving = n - (n in on_axes)
        if moving <= 1 or any(k != n for k in on_axes) or sigma[0] == 1:
            return None
        if moving < n and moving <= 2 and prismatic:
            return None  # R then P moving a tip on the last axis: no proved formula
        return 4 * revolute + 2 * prismatic - (0 if prismatic else 1) - (2 if on_axes else 0)


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

    def theoretical_count(self, sigma, on_axes, along=None) -> int | None:
        """4R + 2P, 4R - 1 without a prismatic joint, 2 fewer with the tip on the last axis.

        None with the tip on another axis, or 3 joints or fewer that move the tip (the last
        one does not when the tip is on its axis): the tip cannot stay on the point and move.
        """
        revolute, prismatic, n = count_joints(sigma)
        if n - (n in on_axes) <= 3 or any(k != n for k in on_axes):
            return None
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

    def theoretical_count(self, sigma, on_axes, along=None) -> int | None:
        """4R + 2P (4R - 1 without a prismatic joint) where the loop can move (n >= 7).

        None for a loop of 6 joints or fewer (it cannot move: finitely many postures).
        """
        revolute, prismatic, n = count_joints(sigma)
        if n < 7:
            return None
        return 4 * revolute + 2 * prismatic - (0 if prismatic else 1)


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


def contact_model(mdh: MDHModel, q0: np.ndarray, frame: str = "") -> MDHModel:
    """The chain's model re-expressed in the frame of its contact at ``q0``.

    Frame -1 becomes the tool frame's placement at ``q0`` (the plane, point or pose every
    touch refers to), so the contact holds at ``q0`` for every kind.

    Args:
        mdh: A chain's model (frame -1 its base frame).
        q0: The posture of the reference touch ``(n,)`` [rad or m].
        frame: Name of the new frame -1 (default: ``contact``).
    """
    T = frames_at_zero(mdh)
    P = mdh.forward(np.asarray(q0, dtype=float)[None])[0]
    Pinv = np.linalg.inv(P)
    joints = Pinv @ T[1 : mdh.n + 1]
    model = from_lines(
        joints[:, :3, 3],
        joints[:, :3, 2],
        mdh.sigma[1 : mdh.n + 1],
        Pinv @ T[-1],
        tuple(str(x) for x in mdh.joint_names[1 : mdh.n + 1]),
        sign=mdh.sign[1 : mdh.n + 1],
    )
    return model.replace(base_frame=frame or "contact", tool_frame=mdh.tool_frame)


def joint_offsets(mdh: MDHModel) -> ParameterSet:
    """The joint offset of every joint row (theta or r): their columns are d tool / dq."""
    rows = range(1, mdh.n + 1)
    return ParameterSet(
        "joints",
        tuple(Parameter(k, Kind.THETA if mdh.sigma[k] == 0 else Kind.R) for k in rows),
    )


def joint_jacobian(mdh: MDHModel, kin: Kinematics) -> np.ndarray:
    """The pose-error Jacobian of the joints ``(m, 6, n)``: d (tool pose) / dq.

    Rows: displacement of the tool origin [m] then rotation [rad], in the base frame; one
    column per joint, in URDF units (a joint traversed backwards, ``sign`` -1, turns its
    row by -q).

    Args:
        mdh: The model.
        kin: Its kinematics at the configurations (:meth:`MDHModel.kinematics`).
    """
    joints = slice(1, mdh.n + 1)
    z = kin.R[:, joints, :, 2]
    revolute = (mdh.sigma[joints] == 0)[None, :, None]
    lin = np.where(revolute, np.cross(z, kin.p[:, -1, None] - kin.p[:, joints]), z)
    ang = np.where(revolute, z, 0.0)
    return np.concatenate([lin, ang], axis=2).transpose(0, 2, 1) * mdh.sign[joints]


def _newton_step(J: np.ndarray, gap: np.ndarray) -> np.ndarray:
    """Least-norm, lightly damped solutions of ``J dq = -gap`` ``(m, n)``.

    When a configuration's ``J J^T`` is singular to working precision (a singular posture,
    or joints held at their limits leaving too few), the batch takes the pseudo-inverse's
    least-squares, least-norm step instead; that configuration then stays off the contact
    and another start is drawn (:func:`contact_postures`).
    """
    JJ = J @ np.swapaxes(J, 1, 2) + 1e-12 * np.eye(J.shape[1])
    try:
        x = np.linalg.solve(JJ, gap[:, :, None])
    except np.linalg.LinAlgError:  # numerically singular (huge rows near the flipped side)
        finite = np.nan_to_num(JJ, nan=0.0, posinf=0.0, neginf=0.0)
        x = np.linalg.pinv(finite) @ gap[:, :, None]
    return -(np.swapaxes(J, 1, 2) @ x)[:, :, 0]


def project(
    mdh: MDHModel, kind: Contact, q: np.ndarray, steps: int = NEWTON_STEPS, bounds=None
) -> tuple[np.ndarray, np.ndarray]:
    """Newton-project configurations onto the contact (gap 0), all at once.

    Each step moves q by the least-norm solution of ``J dq = -gap`` (the kind's
    :meth:`Contact.newton_system` of :func:`joint_jacobian`), lightly damped, then clips it
    into ``bounds`` (lower and upper joint positions ``(n,)`` each [rad or m]; revolute joints
    are otherwise wrapped into [-pi, pi)). A configuration stops when its gap is under
    :data:`CONTACT_TOL` / 1000, or under :data:`CONTACT_TOL` and no longer halving
    (round-off). Joints a step would push out of ``bounds`` are held for that step (their
    columns dropped, the step solved again), so that the others keep Newton's pace.

    Returns:
        The projected configurations ``(m, n)`` and the largest gap of each ``(m,)``.
    """
    q = np.array(q, dtype=float)
    alive = np.ones(len(q), dtype=bool)  # rows still bounded (a diverging one is dropped)
    moving = np.ones(len(q), dtype=bool)  # rows not yet on the contact
    last = np.full(len(q), np.inf)  # each row's previous gap
    revolute = mdh.sigma[1 : mdh.n + 1] == 0
    for _ in range(steps):
        rows = np.flatnonzero(alive & moving)
        if not rows.size:
            break
        qa = q[rows]
        kin = mdh.kinematics(qa)
        gap, J = kind.newton_system(joint_jacobian(mdh, kin), kin.R[:, -1], kin.p[:, -1])
        size = np.abs(gap).max(axis=1)
        there = (size < 1e-3 * CONTACT_TOL) | ((size < CONTACT_TOL) & (size > 0.5 * last[rows]))
        last[rows] = size
        moving[rows[there]] = False  # on the contact: no further step
        rows, qa, gap, J = rows[~there], qa[~there], gap[~there], J[~there]
        if not rows.size:
            break
        step = qa + _newton_step(J, gap)
        if bounds is not None:
            out = (step < bounds[0]) | (step > bounds[1])
            if out.any():
                step = qa + _newton_step(J * ~out[:, None, :], gap)
            step = np.clip(step, bounds[0], bounds[1])
        else:  # the same postures
            step[:, revolute] = (step[:, revolute] + np.pi) % (2 * np.pi) - np.pi
        q[rows] = step
        alive[rows] = np.isfinite(step).all(axis=1) & (np.abs(step) < MAX_STEP_Q).all(axis=1)
    gaps = np.full(len(q), np.inf)
    if alive.any():
        kin = mdh.kinematics(q[alive])
        gap = np.abs(kind.residual(kin.R[:, -1], kin.p[:, -1])).max(axis=1)
        gaps[alive] = np.where(kind.same_side(kin.R[:, -1]), gap, np.inf)
    return q, gaps


def contact_postures(
    mdh: MDHModel, kind: Contact, draw, m: int, rounds: int = 8, bounds=None
) -> np.ndarray:
    """``m`` configurations where the contact holds (gap under :data:`CONTACT_TOL`).

    Args:
        mdh: The model in the contact's frame (:func:`contact_model`).
        kind: The contact.
        draw: ``draw(count, round)`` returns ``(count, n)`` starting configurations (seeded).
        m: Configurations wanted.
        rounds: Draws tried before giving up.
        bounds: Lower and upper joint positions ``(n,)`` each [rad or m] the postures stay
            within (the joint limits), or None.

    Raises:
        InvalidArgumentError: Too few starting configurations reach the contact.
    """
    found: list[np.ndarray] = []
    total = tried = 0
    for r in range(rounds):
        # a first round of a quarter more than wanted (most starts reach the contact), then
        # twice as many
        count = m + m // 4 + 4 if r == 0 else 2 * m
        q, gap = project(mdh, kind, draw(count, r), bounds=bounds)
        tried += count
        good = q[gap < CONTACT_TOL]
        found.append(good)
        total += len(good)
        if total >= m:
            return np.concatenate(found)[:m]
    raise InvalidArgumentError(
        f"only {total} of {tried} postures reached the {kind.label} contact"
        + (" within the joint limits" if bounds is not None else "")
        + f": the contact cannot hold at {m} postures"
    )


def contact_configurations(
    mdh: MDHModel, kind: Contact, draw, m: int, frame: str = ""
) -> tuple[MDHModel, np.ndarray]:
    """The model in the frame of a contact and ``m`` postures where the contact holds.

    The reference touch is the first configuration ``draw(1, 0)``; the others are projected
    from ``draw(count, round + 1)``.

    Args:
        mdh: A chain's model.
        kind: The contact.
        draw: ``draw(count, round)``: ``(count, n)`` seeded starting configurations.
        m: Postures wanted.
        frame: Name of the contact's frame (frame -1 of the returned model).
    """
    model = contact_model(mdh, draw(1, 0)[0], frame or kind.label)
    q = contact_postures(model, kind, lambda count, r: draw(count, r + 1), m)
    return model, q


__all__ = [
    "CONTACT_TOL",
    "Contact",
    "FixedPointContact",
    "FixedPoseContact",
    "PlaneContact",
    "PlanePointContact",
    "contact_configurations",
    "contact_kind",
    "contact_model",
    "contact_postures",
    "joint_jacobian",
    "joint_offsets",
    "project",
]
