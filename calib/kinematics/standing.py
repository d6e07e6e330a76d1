"""Gravity torques of a robot standing on its chain's base frame (a sole flat on the ground).

A humanoid calibrated from its foot (the chain runs from the sole up the leg backwards, through
the torso, to a hand) stands on that foot: the sole is fixed, gravity points along ``-z`` of
the sole's frame, and every joint of the chain carries the weight on its far side, the side
away from the sole:

* a joint traversed forwards (sign +1: the arm, the torso) carries its subtree, as a robot
  hanging from a fixed base does;
* a joint traversed backwards (sign -1: the standing leg) carries the rest of the robot, every
  body but its own subtree (which holds the sole).

The torque is the derivative of the potential energy with the sole held fixed,
``tau_j = dV/dq_j`` [N m, or N for a prismatic joint], in the convention of Pinocchio's
generalized gravity (the torque the joint exerts to hold the load; ``q`` the URDF joint
position). With the sole as the root of the tree this is Pinocchio's
``computeGeneralizedGravity`` (tested that way and by finite differences of the energy).

With both feet on the ground the load split between the feet is statically indeterminate;
:class:`Support` states the assumption:

* ``foot=None``: the base foot carries the whole robot (the other foot, if any, carries
  nothing);
* ``foot=F, share=None``: the other foot ``F`` carries its own leg (the subtree of the first
  joint on the way from the common trunk to ``F``), the base foot everything else;
* ``foot=F, share=s``: the other foot pushes up with ``s`` times the robot's weight, a
  vertical force at ``F``'s origin.

Joints outside the chain do not move the tool, but they move the load (an arm raised on the
other side): they are at their recorded positions where the touches give them
(:class:`JointReadings`, a contact file's other joint columns), else at the chain's reference
configuration (``q_ref``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..exceptions import InvalidArgumentError
from .frames import motion_axis, resolve_frame
from .robot import Chain, pin_configurations

__all__ = ["JointReadings", "StandingLoad", "Support", "standing_load"]


@dataclass(frozen=True, eq=False)
class JointReadings:
    """Recorded positions of joints off a chain: they load its joints but do not move its tool.

    Attributes:
        names: The joints (URDF names), one degree of freedom each, none on the chain.
        values: Their positions ``(m, k)`` [rad or m], a row per configuration.
    """

    names: tuple[str, ...]
    values: np.ndarray

    def take(self, rows) -> JointReadings:
        """The readings of some configurations (indices or a boolean mask)."""
        return JointReadings(self.names, self.values[rows])

    def configurations(self, chain: Chain, q: np.ndarray) -> np.ndarray:
        """Pinocchio configurations ``(m, nq)``: the chain at ``q``, these joints as read.

        Raises:
            InvalidArgumentError: A joint that is not in the URDF, is on the chain or has
                more than one degree of freedom, or a row count that is not ``q``'s.
        """
        model = chain.model
        ids = []
        for name in self.names:
            jid = model.getJointId(name) if model.existJointName(name) else 0
            if jid == 0 or name in chain.joint_names or model.joints[jid].nv != 1:
                raise InvalidArgumentError(
                    f"joint reading '{name}' is not a one-degree-of-freedom joint off the chain"
                )
            ids.append(jid)
        configs = chain.pin_configurations(q)
        if self.values.shape != (len(configs), len(ids)):
            raise InvalidArgumentError(
                f"joint readings of shape {self.values.shape} for {len(configs)} "
                f"configurations of {len(ids)} joints"
            )
        return pin_configurations(model, configs, tuple(ids), self.values)


@dataclass(frozen=True)
class Support:
    """How the weight is shared with a second foot on the ground.

    Attributes:
        foot: The other foot's frame, or None (the base foot carries the whole robot).
        share: None: the other foot carries its own leg; a number in [0, 1]: the other foot
            carries that fraction of the robot's weight, a vertical force at its origin.
    """

    foot: str | None = None
    share: float | None = None

    def __post_init__(self) -> None:
        if self.foot is not None and not isinstance(self.foot, str):
            raise InvalidArgumentError(f"the other foot is a frame name, got {self.foot!r:.40}")
        if self.share is not None:
            if self.foot is None:
                raise InvalidArgumentError("a share of the weight needs the other foot's frame")
            if not (isinstance(self.share, (int, float)) and 0.0 <= self.share <= 1.0):
                raise InvalidArgumentError(f"the other foot's share is in [0, 1], got {self.share}")

    def label(self) -> str:
        """A short description, for reports."""
        if self.foot is None:
            return "the base foot carries the whole robot"
        if self.share is None:
            return f"{self.foot} carries its own leg, the base foot the rest"
        return f"{self.foot} carries {self.share:g} of the weight, the base foot the rest"

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return {"foot": self.foot, "share": self.share}


@dataclass(frozen=True, eq=False)
class StandingLoad:
    """Gravity torques of a chain's joints for the robot standing on the chain's base frame.

    Attributes:
        model: The Pinocchio model whose masses load the joints (never mutated).
        chain: The chain (its joints, signs, base frame and reference configuration).
        support: The load-split assumption with a second foot.
        excluded: The joint whose subtree stands on the other foot, or 0 (none).
        foot_id: The other foot's frame index, or -1.
    """

    model: pin.Model
    chain: Chain
    support: Support
    excluded: int
    foot_id: int

    def torques(self, q: np.ndarray, readings: JointReadings | None = None) -> np.ndarray:
        """Gravity torque of each chain joint ``(m, n)`` [N m or N] at URDF positions ``(m, n)``.

        ``readings``: the recorded positions of joints off the chain (default: the others at
        the reference configuration).
        """
        model, chain = self.model, self.chain
        axes = []
        for jid, sigma in zip(chain.joint_ids, chain.sigma, strict=True):
            S = motion_axis(model.joints[jid])
            axes.append(S[3:] if sigma == 0 else S[:3])
        # per chain joint: does the far side hold the other foot, or the other leg?
        foot = model.frames[self.foot_id].parentJoint if self.foot_id >= 0 else -1
        e = self.excluded
        flags = [
            (
                (foot >= 0 and self._descends(foot, j)) == (s > 0),
                bool(e) and (self._descends(e, j) if s > 0 else not self._descends(j, e)),
            )
            for j, s in zip(chain.joint_ids, chain.sign, strict=True)
        ]
        data = model.createData()
        configs = (
            chain.pin_configurations(q) if readings is None else readings.configurations(chain, q)
        )
        rows = [self._one(data, row, axes, flags) for row in configs]
        return np.array(rows).reshape(-1, chain.n)

    def _one(self, data, qp: np.ndarray, axes: list, flags: list) -> np.ndarray:
        model, chain, e = self.model, self.chain, self.excluded
        pin.centerOfMass(model, data, qp, True)  # the joint placements too
        pin.updateFramePlacements(model, data)
        g = -float(np.linalg.norm(model.gravity.linear)) * data.oMf[chain.base_id].rotation[:, 2]

        def load(j: int) -> tuple[np.ndarray, np.ndarray]:  # weight [N], first moment [kg m]
            # Pinocchio gives a subtree's centre of mass in its joint's frame
            return data.mass[j] * g, data.mass[j] * data.oMi[j].act(data.com[j])

        total = load(0)
        other = load(e) if e else (np.zeros(3), np.zeros(3))
        force, force_pt = np.zeros(3), np.zeros(3)
        if self.foot_id >= 0 and self.support.share is not None:
            force = -self.support.share * data.mass[0] * g
            force_pt = data.oMf[self.foot_id].translation
        n = chain.n
        W, F, P, A = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        for k, (jid, s) in enumerate(zip(chain.joint_ids, chain.sign, strict=True)):
            weight, first = load(jid)
            if s < 0:  # the far side: the rest of the robot
                weight, first = total[0] - weight, total[1] - first
            if flags[k][1]:  # the other leg stands on its own foot
                weight, first = weight - other[0], first - other[1]
            W[k], F[k], P[k] = weight, first, data.oMi[jid].translation
            A[k] = data.oMi[jid].rotation @ axes[k]
        holds = np.array([f[0] for f in flags], dtype=float)[:, None]
        turn = np.cross(F, g) - np.cross(P, W) + holds * np.cross(force_pt - P, force)
        wrench = np.where(chain.sigma[:, None] == 0, turn, W + holds * force)
        return -chain.sign * np.einsum("ki,ki->k", A, wrench)

    def _descends(self, j: int, ancestor: int) -> bool:
        """Whether joint ``j`` is ``ancestor`` or in its subtree."""
        while j > ancestor:
            j = self.model.parents[j]
        return j == ancestor


def _ancestors(model: pin.Model, j: int) -> list[int]:
    out = [j]
    while j > 0:
        j = model.parents[j]
        out.append(j)
    return out


def standing_load(chain: Chain, support: Support | None = None) -> StandingLoad:
    """The standing load of a chain, with the URDF's masses.

    Args:
        chain: The chain; its base frame is the sole the robot stands on.
        support: The load split with a second foot (default: the base foot carries all).

    Raises:
        InvalidArgumentError: The URDF has no masses, or the other foot is on the chain's
            path.
        FrameNotFoundError: The other foot's frame does not exist.
    """
    support = Support() if support is None else support
    model = chain.model
    if sum(model.inertias[j].mass for j in range(1, model.njoints)) <= 0:
        raise InvalidArgumentError(
            f"{chain.urdf_path.name} has no masses: no gravity torques for joint compliance"
        )
    if support.foot is None:
        return StandingLoad(model, chain, support, 0, -1)
    fid = resolve_frame(model, support.foot)
    trunk = set(_ancestors(model, model.frames[chain.base_id].parentJoint))
    trunk |= set(_ancestors(model, model.frames[chain.tool_id].parentJoint))
    leg = [j for j in _ancestors(model, model.frames[fid].parentJoint) if j not in trunk]
    if not leg:
        raise InvalidArgumentError(
            f"the other foot '{support.foot}' is on the chain's path: it has no leg of its own"
        )
    excluded = leg[-1] if support.share is None else 0
    return StandingLoad(model, chain, support, excluded, fid)
