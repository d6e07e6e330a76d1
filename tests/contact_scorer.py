"""Independent scorer of flush contacts: Pinocchio placements and Pinocchio's roll-pitch-yaw.

Uses nothing of calib: the URDF read by Pinocchio, ``oMf[base]^-1 oMf[tool]`` per
configuration, the contact frame and the plane as given, and ``pin.rpy.matrixToRpy`` of the
contact's rotation in the plane's frame. A calibration result is checked by this route, which
shares neither calib's MDH rows nor its residual code.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin


def read_joints(path: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    """Plane ids and joint readings [rad] by URDF joint name, from a contact CSV."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    ids = [r["plane"] for r in rows]
    names = [k for k in rows[0] if k not in ("plane", "spot", "point", "pose")]
    return ids, {k: np.array([float(r[k]) for r in rows]) for k in names}


def _frame(model: pin.Model, name: str) -> int:
    ids = [i for i, f in enumerate(model.frames) if f.name == name]
    bodies = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
    if not ids:
        raise KeyError(name)
    return bodies[0] if bodies else ids[0]


def configurations(model: pin.Model, joints: Mapping[str, np.ndarray]) -> np.ndarray:
    """Pinocchio configurations ``(m, nq)``: the readings on their joints, neutral elsewhere."""
    m = len(next(iter(joints.values())))
    Q = np.tile(pin.neutral(model), (m, 1))
    for name, values in joints.items():
        if not model.existJointName(name):
            continue
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:
            Q[:, joint.idx_q], Q[:, joint.idx_q + 1] = np.cos(values), np.sin(values)
        else:
            Q[:, joint.idx_q] = values
    return Q


def relative_placements(urdf: Path, base: str, tool: str, joints: Mapping[str, np.ndarray]):
    """``oMf[base]^-1 oMf[tool]`` as a list of ``pin.SE3``, one per configuration."""
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    b, t = _frame(model, base), _frame(model, tool)
    out = []
    for q in configurations(model, joints):
        pin.framesForwardKinematics(model, data, q)
        out.append(data.oMf[b].actInv(data.oMf[t]))
    return out


def plane_gaps(
    urdf: Path,
    base: str,
    tool: str,
    contact: np.ndarray,
    plane: np.ndarray,
    joints: Mapping[str, np.ndarray],
) -> np.ndarray:
    """Height [m], roll and pitch [rad] ``(m, 3)`` of the contact frame in the plane's frame.

    Args:
        urdf: The robot's URDF.
        base: The chain's base frame (the plane is expressed in it).
        tool: The tool frame (the contact frame is expressed in it).
        contact: Contact frame in the tool frame ``(4, 4)``.
        plane: Plane in the base frame ``(4, 4)``, z = normal.
        joints: Joint readings [rad] by URDF joint name, each ``(m,)``.
    """
    C, P = pin.SE3(np.asarray(contact)), pin.SE3(np.asarray(plane))
    gaps = []
    for T in relative_placements(urdf, base, tool, joints):
        rel = P.actInv(T * C)
        roll, pitch, _ = pin.rpy.matrixToRpy(rel.rotation)
        gaps.append((rel.translation[2], roll, pitch))
    return np.array(gaps)


def rms(gaps: np.ndarray) -> tuple[float, float, float]:
    """RMS height [mm], roll and pitch [deg] of gaps ``(m, 3)``."""
    r = np.sqrt(np.mean(np.asarray(gaps) ** 2, axis=0))
    return 1e3 * float(r[0]), math.degrees(float(r[1])), math.degrees(float(r[2]))
