"""Independent references for the tests: Pinocchio look-ups and draws made without calib."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin


def pin_frame(model: pin.Model, name: str) -> int:
    """Frame id by name: the BODY (link) frame when there is one, as the catalog says."""
    bare = name.split(":", 1)[1] if name.startswith(("link:", "joint:")) else name
    ids = [i for i, f in enumerate(model.frames) if f.name == bare]
    assert ids, f"no frame {bare} in the Pinocchio model"
    bodies = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
    return bodies[0] if bodies else ids[0]


def pin_config(model: pin.Model, joint_ids, q: np.ndarray, q_full: np.ndarray | None = None):
    """Pinocchio configuration with URDF positions q on the given joints."""
    out = pin.neutral(model) if q_full is None else q_full.copy()
    for jid, qk in zip(joint_ids, q, strict=True):
        joint = model.joints[jid]
        if joint.nq == 2:
            out[joint.idx_q : joint.idx_q + 2] = (math.cos(qk), math.sin(qk))
        else:
            out[joint.idx_q] = qk
    return out


def own_random_q(sigma, m: int, seed: int) -> np.ndarray:
    """Configurations drawn by the test, not by calib (wider than most joint limits)."""
    rng = np.random.default_rng(seed)
    sigma = np.asarray(sigma)
    q = rng.uniform(-math.pi, math.pi, (m, len(sigma)))
    q[:, sigma == 1] = rng.uniform(-0.3, 0.3, (m, int(np.sum(sigma == 1))))
    return q


def rigid_error_columns(frames, E: np.ndarray) -> np.ndarray:
    """Pose-error columns ``(6, 6 len(frames))`` of a 6-DOF error at each frame, seen at point E.

    For every frame (a pin.SE3 in the base frame) and each of its axes a: a translation along a
    ([a; 0]) and a rotation about a through the frame's origin ([a x (E - o); a]).
    """
    cols = []
    for F in frames:
        for i in range(3):
            a = F.rotation[:, i]
            cols.append(np.hstack([a, np.zeros(3)]))
            cols.append(np.hstack([np.cross(a, E - F.translation), a]))
    return np.array(cols).T


def file_chain_poses(path, base: str, tool: str, q: np.ndarray):
    """Pinocchio reads a URDF file itself and poses the chain between two frames.

    Yields, per row of ``q`` (URDF positions of the chain joints), the base placement
    ``bMo`` (world to base), the tool placement in the base, and the chain joints' placements
    in the base (pin.SE3).
    """
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    b, t = pin_frame(model, base), pin_frame(model, tool)
    jb, jt = model.frames[b].parentJoint, model.frames[t].parentJoint
    support = list(model.supports[jt])
    joints = support[support.index(jb) + 1 :]
    for qi in q:
        pin.framesForwardKinematics(model, data, pin_config(model, joints, qi))
        bMo = data.oMf[b].inverse()
        yield bMo, bMo * data.oMf[t], [bMo * data.oMi[j] for j in joints]
