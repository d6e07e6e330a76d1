"""Configurations where a contact holds, and a chain's model in the frame of its contact.

:func:`contact_postures` draws configurations where a contact holds, by Newton projection
with the kind's own Jacobian rows (the ones :mod:`~calib.identification.contacts` defines),
and :func:`contact_model` re-expresses a chain's model in the frame of its constraint (the
plane, point or pose at frame -1).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.mdh import Kinematics, MDHModel, frames_at_zero, from_lines
from .contacts import CONTACT_TOL, Contact
from .parameters import Kind, Parameter, ParameterSet

MAX_STEP_Q = 1e2
"""Largest joint position [rad or m] a projected posture may reach before it is dropped."""

NEWTON_STEPS = 60
"""Newton iterations of :func:`contact_postures` per round."""


def contact_model(mdh: MDHModel, q0: np.ndarray, frame: str = "") -> MDHModel:
    """The chain's model re-expressed in the frame of its contact at ``q0``.

    Frame -1 becomes the tool frame's placement at ``q0`` (the plane, point or pose every
    touch refers to), so the contact holds at ``q0`` for every kind.

    Args:
        mdh: A chain's model (frame -1 its base frame).
        q0: The posture of the reference touch ``(n,)`` [rad or m].
        frame: Name of the new frame -1 (default: ``contact``).
    """
    model = in_frame(mdh, mdh.forward(np.asarray(q0, dtype=float)[None])[0])
    return model.replace(base_frame=frame or "contact", tool_frame=mdh.tool_frame)


def in_frame(mdh: MDHModel, F: np.ndarray, C: np.ndarray | None = None) -> MDHModel:
    """The chain's model in a frame ``F`` ``(4, 4)`` of its base frame (an object touched).

    Args:
        mdh: A chain's model (frame -1 its base frame).
        F: The new frame -1 in the base frame ``(4, 4)`` [m].
        C: The new tool frame in the tool frame ``(4, 4)`` [m] (a contact frame), or None:
            the tool frame.
    """
    T = frames_at_zero(mdh)
    Finv = np.linalg.inv(F)
    joints = Finv @ T[1 : mdh.n + 1]
    return from_lines(
        joints[:, :3, 3],
        joints[:, :3, 2],
        mdh.sigma[1 : mdh.n + 1],
        Finv @ T[-1] if C is None else Finv @ T[-1] @ C,
        tuple(str(x) for x in mdh.joint_names[1 : mdh.n + 1]),
        sign=mdh.sign[1 : mdh.n + 1],
    )


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
    "MAX_STEP_Q",
    "NEWTON_STEPS",
    "contact_configurations",
    "contact_model",
    "contact_postures",
    "in_frame",
    "joint_jacobian",
    "joint_offsets",
    "project",
]
