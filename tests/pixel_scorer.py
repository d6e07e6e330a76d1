"""An independent pixel reference: Pinocchio's placements and a textbook pinhole in numpy.

Nothing here calls calib's kinematics or camera: the camera frame and the target are placed
with Pinocchio's forward kinematics, the pixels by OpenCV's 5-coefficient formula written out.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from pinref import pin_config, pin_frame


def textbook_pixels(p: np.ndarray, K: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """OpenCV's pinhole with k1 k2 p1 p2 k3 of points in the camera frame ``(m, 3)`` [px]."""
    k1, k2, p1, p2, k3 = np.concatenate([dist, np.zeros(5)])[:5]
    a, b = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
    r2 = a * a + b * b
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    x = a * radial + 2 * p1 * a * b + p2 * (r2 + 2 * a * a)
    y = b * radial + p1 * (r2 + 2 * b * b) + 2 * p2 * a * b
    return np.column_stack([K[0, 0] * x + K[0, 2], K[1, 1] * y + K[1, 2]])


def link_points(model: pin.Model, base: str, tool: str, joints, q, X) -> np.ndarray:
    """Points ``X`` ``(m, 3)`` of the tool frame in the base frame at joint rows ``q`` [m]."""
    data = model.createData()
    ids = [model.getJointId(n) for n in joints]
    b, t = pin_frame(model, base), pin_frame(model, tool)
    out = []
    for qi, x in zip(q, X, strict=True):
        pin.framesForwardKinematics(model, data, pin_config(model, ids, qi))
        out.append(data.oMf[b].actInv(data.oMf[t].act(x)))
    return np.array(out)


def seen_pixels(model, base, tool, joints, q, X, C, K, dist) -> np.ndarray:
    """Pixels of tool points seen by a camera at ``C`` ``(4, 4)`` in the base frame [px]."""
    p = link_points(model, base, tool, joints, q, X)
    return textbook_pixels((p - C[:3, 3]) @ C[:3, :3], K, dist)


def moved_model(model: pin.Model, joint: str, basis: np.ndarray, y: np.ndarray) -> pin.Model:
    """A copy with joint ``joint``'s origin times ``[exp(B w) | B v]`` (y = v, w)."""
    out = pin.Model(model)
    jid = out.getJointId(joint)
    out.jointPlacements[jid] = out.jointPlacements[jid] * pin.SE3(
        pin.exp3(basis @ y[3:]), basis @ y[:3]
    )
    return out


def numerical_rank(W: np.ndarray, tol: float = 1e-6) -> int:
    """Rank of ``W`` with unit-length columns: singular values above ``tol`` times the largest."""
    norms = np.linalg.norm(W, axis=0)
    W = W[:, norms > 0] / norms[norms > 0]
    s = np.linalg.svd(W, compute_uv=False)
    return int(np.sum(s > tol * s[0]))
