"""Registration: the measurement frame and the markers in closed form, from the nominal model.

Before any geometric error is fitted, the instrument's frame and the marker offsets are
estimated with the nominal kinematics, so that the nonlinear fit starts a few millimetres
from its solution whatever the frame's rotation and distance:

1. with the markers at their guess (the tool origin, or ``--marker``), the rigid motion that
   best maps the predicted points onto the measured ones (Horn's / Umeyama's closed form:
   the SVD of the cross-covariance of the centred point sets, with the determinant sign
   fixed so that it is a rotation);
2. with that frame, each marker by linear least squares
   (``R^T (y_ik - t) - p_i = R_i m_k`` stacked over the configurations);
3. repeat until the markers move less than 1e-12 m (at most ``ITERATIONS`` times);
4. for pose data, the measured frame's rotation in the tool frame: the rotation nearest (in
   the Frobenius norm) to the mean of ``R_i^T R^T R_meas,i``.

The result then seeds a Levenberg-Marquardt fit of the same parameters (``frames`` level).

References: B. K. P. Horn, "Closed-form solution of absolute orientation using unit
quaternions", JOSA A 4(4), 1987; S. Umeyama, "Least-squares estimation of transformation
parameters between two point patterns", IEEE TPAMI 13(4), 1991.
"""

from __future__ import annotations

import numpy as np

from ..kinematics.mdh import MDHModel
from .model import State, registration_state

__all__ = ["ITERATIONS", "nearest_rotation", "register", "rigid_fit"]

ITERATIONS = 50
"""Most alternations between the frame and the markers."""


def rigid_fit(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t minimising ``sum |B_i - (R A_i + t)|^2`` (points ``(N, 3)``)."""
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    H = (A - ca).T @ (B - cb)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    return R, cb - R @ ca


def nearest_rotation(M: np.ndarray) -> np.ndarray:
    """The rotation nearest to a 3x3 matrix in the Frobenius norm."""
    U, _, Vt = np.linalg.svd(M)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    return U @ D @ Vt


def register(
    mdh: MDHModel,
    q: np.ndarray,
    points: np.ndarray,
    rotations: np.ndarray | None = None,
    markers: np.ndarray | None = None,
) -> State:
    """Closed-form measurement frame and markers for the nominal geometry.

    Args:
        mdh: The geometry (nominal model, URDF base frame).
        q: Joint positions the geometry sees ``(m, n)`` [rad or m].
        points: Measured points ``(m, K, 3)`` [m], measurement frame.
        rotations: Measured orientations ``(m, 3, 3)``, or None.
        markers: Guess of the markers in the tool frame ``(K, 3)`` [m] (default: zeros).

    Returns:
        The nominal geometry with the estimated frame, markers (and measured-frame rotation).
    """
    kin = mdh.kinematics(q)
    Rt, pt = kin.R[:, -1], kin.p[:, -1]
    K = points.shape[1]
    mk = np.zeros((K, 3)) if markers is None else np.array(markers, dtype=float).reshape(K, 3)
    A = Rt.reshape(-1, 3)
    for _ in range(ITERATIONS):
        pred = pt[:, None, :] + np.einsum("mij,kj->mki", Rt, mk)
        R, t = rigid_fit(pred.reshape(-1, 3), points.reshape(-1, 3))
        local = (points - t) @ R - pt[:, None, :]  # R^T (y - t) - p, (m, K, 3)
        new = np.linalg.lstsq(A, local.transpose(0, 2, 1).reshape(-1, K), rcond=None)[0].T
        done = np.max(np.abs(new - mk)) < 1e-12
        mk = new
        if done:
            break
    pred = pt[:, None, :] + np.einsum("mij,kj->mki", Rt, mk)
    R, t = rigid_fit(pred.reshape(-1, 3), points.reshape(-1, 3))
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = R, t
    tool = None
    if rotations is not None:
        tool = nearest_rotation(np.sum(np.swapaxes(Rt, 1, 2) @ R.T @ rotations, axis=0))
    return registration_state(mdh, frame, mk, tool)
