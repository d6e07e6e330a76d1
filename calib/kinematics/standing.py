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

Joints outside the chain are at the chain's reference configuration (``q_ref``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..exceptions import InvalidArgumentError
from .frames import motion_axis, resolve_frame
from .robot import Chain

__all__ = ["StandingLoad", "Support", "standing_gravity", "standing_load"]


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


def standing_gravity(model: pin.Model, q: np.ndarray, base_id: int) -> np.ndarray:
    """Gravity ``(3,)`` [m/s^2] in Pinocchio's world: ``-|g|`` along z of the base frame.

    Args:
        model: The Pinocchio model (its gravity's magnitude is used).
        q: A Pinocchio configuration ``(nq,)``.
        base_id: The base frame's index in ``model.frames``.
    """
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return -float(np.linalg.norm(model.gravity.linear)) * data.oMf[base_id].rotation[:, 2]


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

    def torques(self, q: np.ndarray) -> np.ndarray:
        """Gravity torque of each chain joint ``(m, n)`` [N m or N] at URDF positions ``(m, n)``."""
        Q = self.chain.pin_configurations(q)
        return np.array([self._one(row) for row in Q]).reshape(-1, self.chain.n)

    def _one(self, qp: np.ndarray) -> np.ndarray:
        model, chain = self.model, self.chain
        data = model.createData()
        pin.framesForwardKinematics(model, data, qp)
        pin.centerOfMass(model, data, qp, True)
        # subtree centres of mass: Pinocchio gives them in each joint's frame
        com = [data.oMi[j].act(data.com[j]) for j in range(model.njoints)]
        g = standing_gravity(model, qp, chain.base_id)
        total = data.mass[0] * g  # force [N]
        moment0 = data.mass[0] * com[0]  # first moment [kg m]
        force_pt, force = np.zeros(3), np.zeros(3)
        if self.excluded:
            e = self.excluded
            total = total - data.mass[e] * g
            moment0 = moment0 - data.mass[e] * com[e]
        if self.foot_id >= 0 and self.support.share is not None:
            force = -self.support.share * data.mass[0] * g
            force_pt = data.oMf[self.foot_id].translation
        out = np.zeros(chain.n)
        for k, (jid, s) in enumerate(zip(chain.joint_ids, chain.sign, strict=True)):
            sub = self._subtree_load(data, com, jid, g)
            if s > 0:
                weight, first, holds = sub[0], sub[1], self._in_subtree(jid)
            else:
                weight, first, holds = total - sub[0], moment0 - sub[1], not self._in_subtree(jid)
            o = data.oMi[jid].translation
            S = motion_axis(model.joints[jid])
            a = data.oMi[jid].rotation @ (S[3:] if chain.sigma[k] == 0 else S[:3])
            if chain.sigma[k] == 0:
                wrench = np.cross(first, g) - np.cross(o, weight)
                if holds:
                    wrench = wrench + np.cross(force_pt - o, force)
            else:
                wrench = weight + (force if holds else 0.0)
            out[k] = -s * float(a @ wrench)
        return out

    def _subtree_load(self, data, com, jid: int, g) -> tuple[np.ndarray, np.ndarray]:
        """Weight [N] and first moment of mass [kg m] of a joint's subtree, the other leg out."""
        weight, first = data.mass[jid] * g, data.mass[jid] * com[jid]
        e = self.excluded
        if e and self._descends(e, jid):
            weight = weight - data.mass[e] * g
            first = first - data.mass[e] * com[e]
        return weight, first

    def _descends(self, j: int, ancestor: int) -> bool:
        while j > ancestor:
            j = self.model.parents[j]
        return j == ancestor

    def _in_subtree(self, jid: int) -> bool:
        """Whether the other foot (where its force acts) is in the joint's subtree."""
        if self.foot_id < 0:
            return False
        return self._descends(self.model.frames[self.foot_id].parentJoint, jid)


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
        InvalidArgumentError: The other foot is unknown, on the chain's path, or its leg holds
            a joint of the chain.
    """
    support = Support() if support is None else support
    model = chain.model
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
