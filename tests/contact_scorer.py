"""Independent scorer of contacts: Pinocchio placements, Pinocchio's roll-pitch-yaw and log.

Uses nothing of calib: the URDF read by Pinocchio, ``oMf[base]^-1 oMf[tool]`` per
configuration, the contact frame and the objects as given, and the contact frame's placement
in its object's frame ``F^-1 T C``, read per kind from its definition:

* ``plane``: height (z), roll and pitch (``pin.rpy.matrixToRpy``);
* ``plane-point``: height;
* ``fixed-point``: position;
* ``fixed-pose``: position and rotation vector (``pin.log3``).

A calibration result is checked by this route, which shares neither calib's MDH rows nor its
residual code.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import pinocchio as pin


def read_joints(path: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    """Plane (or point) ids and joint readings [rad] by URDF joint name, from a contact CSV."""
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    ids = [r["plane"] if "plane" in r else r["point"] for r in rows]
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


def gaps_of(kind: str, rel: pin.SE3) -> np.ndarray:
    """The gap of a contact frame placed at ``rel`` in its object's frame, by definition."""
    p = rel.translation
    if kind == "plane":
        return np.r_[p[2], pin.rpy.matrixToRpy(rel.rotation)[:2]]
    if kind == "plane-point":
        return p[2:3].copy()
    if kind == "fixed-point":
        return p.copy()
    if kind == "fixed-pose":
        return np.r_[p, pin.log3(rel.rotation)]
    raise KeyError(kind)


def contact_gaps(
    kind: str,
    urdf: Path,
    base: str,
    tool: str,
    contact: np.ndarray,
    objects: list[np.ndarray],
    joints: Mapping[str, np.ndarray],
) -> np.ndarray:
    """Gaps ``(m, rows)`` [m, rad] of touches, each of its own object ``objects[i]`` (4x4).

    Args:
        kind: ``plane``, ``plane-point``, ``fixed-point`` or ``fixed-pose``.
        urdf: The robot's URDF.
        base: The chain's base frame (the objects are expressed in it).
        tool: The tool frame (the contact frame is expressed in it).
        contact: Contact frame in the tool frame ``(4, 4)``.
        objects: The object of each touch in the base frame, ``(4, 4)`` each.
        joints: Joint readings [rad] by URDF joint name, each ``(m,)``.
    """
    C = pin.SE3(np.asarray(contact))
    out = []
    for T, F in zip(relative_placements(urdf, base, tool, joints), objects, strict=True):
        out.append(gaps_of(kind, pin.SE3(np.asarray(F)).actInv(T * C)))
    return np.array(out)


def rms(gaps: np.ndarray) -> tuple[float, float, float]:
    """RMS height [mm], roll and pitch [deg] of gaps ``(m, 3)``."""
    r = np.sqrt(np.mean(np.asarray(gaps) ** 2, axis=0))
    return 1e3 * float(r[0]), math.degrees(float(r[1])), math.degrees(float(r[2]))
