"""Rotations, vectorised: quaternions (scalar last), rotation vectors, SO(3) Jacobians.

Plain numpy, so that importing calib does not pull in ``scipy.spatial`` (a tenth of a second
at every start of the command line). Checked against ``scipy.spatial.transform.Rotation`` in
the tests.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "SMALL_ANGLE",
    "inverse_right_jacobian",
    "left_jacobian",
    "matrix_to_quaternion",
    "quaternion_to_matrix",
    "rotation_matrix",
    "rotation_vector",
    "rpy_to_matrix",
    "skew",
    "tilt_derivatives",
    "tilts",
]

SMALL_ANGLE = 1e-4
"""Angle [rad] under which series expansions replace the closed forms."""


def skew(v: np.ndarray) -> np.ndarray:
    """Skew matrices ``[v]x`` of vectors ``(..., 3)``, shape ``(..., 3, 3)``."""
    v = np.asarray(v, dtype=float)
    S = np.zeros((*v.shape[:-1], 3, 3))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


def quaternion_to_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices ``(..., 3, 3)`` of quaternions ``(..., 4)`` (x, y, z, w; normalised)."""
    q = np.asarray(quat, dtype=float)
    q = q / _norm(q)[..., None]
    # Entry e of R is 2 (a_e + s_e b_e), one minus that on the diagonal, with a_e and b_e
    # products of two components: all 16 products at once (small arrays: the calls cost).
    qq = (q[..., :, None] * q[..., None, :]).reshape(*q.shape[:-1], 16)
    T = qq[..., _FIRST] + _SIGN * qq[..., _SECOND]
    T *= 2.0
    return np.where(_DIAGONAL, 1.0 - T, T).reshape(*q.shape[:-1], 3, 3)


# Components x y z w are 0 1 2 3, product (i, j) is 4 i + j. R row-major:
# 1 - 2(yy + zz), 2(xy - zw), 2(xz + yw); 2(xy + zw), 1 - 2(xx + zz), 2(yz - xw);
# 2(xz - yw), 2(yz + xw), 1 - 2(xx + yy).
_FIRST = np.array([5, 1, 2, 1, 0, 6, 2, 6, 0])
_SECOND = np.array([10, 11, 7, 11, 10, 3, 7, 3, 5])
_SIGN = np.array([1.0, -1.0, 1.0, 1.0, 1.0, -1.0, -1.0, 1.0, 1.0])
_DIAGONAL = np.array([True, False, False, False, True, False, False, False, True])


def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean norms along the last axis: ``np.linalg.norm``'s sum, without its checks."""
    return np.sqrt(np.add.reduce(v * v, axis=-1))


def matrix_to_quaternion(R: np.ndarray) -> np.ndarray:
    """Unit quaternions ``(..., 4)`` (x, y, z, w with w >= 0) of rotation matrices ``(..., 3, 3)``.

    Shepperd's method: the largest of 4w^2, 4x^2, 4y^2, 4z^2 is taken from the diagonal, the
    others from off-diagonal sums, which is accurate for every rotation.
    """
    R = np.asarray(R, dtype=float)
    m00, m11, m22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    s10, d10 = R[..., 1, 0] + R[..., 0, 1], R[..., 1, 0] - R[..., 0, 1]
    s20, d02 = R[..., 2, 0] + R[..., 0, 2], R[..., 0, 2] - R[..., 2, 0]
    s21, d21 = R[..., 2, 1] + R[..., 1, 2], R[..., 2, 1] - R[..., 1, 2]
    f0, f1 = 1 + m00 - m11 - m22, 1 - m00 + m11 - m22
    f2, f3 = 1 - m00 - m11 + m22, 1 + m00 + m11 + m22
    four = np.stack([f0, f1, f2, f3], axis=-1)  # 4x^2, 4y^2, 4z^2, 4w^2 (up to round-off)
    # Candidate i holds 4 q_i * q for the largest component i: (x, y, z, w) in each row.
    cand = np.stack(
        [f0, s10, s20, d21, s10, f1, s21, d02, s20, s21, f2, d10, d21, d02, d10, f3], axis=-1
    ).reshape(-1, 4, 4)
    best = np.argmax(four, axis=-1).ravel()
    q = cand[np.arange(len(best)), best].reshape(four.shape)
    q = q / _norm(q)[..., None]
    return np.where(q[..., 3:] < 0, -q, q)


def rotation_vector(R: np.ndarray) -> np.ndarray:
    """Rotation vectors ``(..., 3)`` [rad] (angle in [0, pi] times unit axis) of matrices ``R``."""
    q = matrix_to_quaternion(R)
    v, w = q[..., :3], q[..., 3]
    s = _norm(v)
    angle = 2.0 * np.arctan2(s, w)
    small = s < 1e-8
    factor = np.where(small, 2.0 / np.where(small, w, 1.0), angle / np.where(small, 1.0, s))
    return v * factor[..., None]


def rotation_matrix(phi: np.ndarray) -> np.ndarray:
    """Rotation matrices ``exp([phi]x)`` ``(..., 3, 3)`` of rotation vectors ``(..., 3)`` [rad]."""
    phi = np.asarray(phi, dtype=float)
    theta = _norm(phi)
    small = theta < SMALL_ANGLE
    half = np.where(small, 0.5 - theta**2 / 48.0, np.sin(theta / 2) / np.where(small, 1.0, theta))
    quat = np.concatenate([phi * half[..., None], np.cos(theta / 2)[..., None]], axis=-1)
    return quaternion_to_matrix(quat)


def inverse_right_jacobian(phi: np.ndarray) -> np.ndarray:
    """Inverse right Jacobian of SO(3) at rotation vectors ``(..., 3)``, ``(..., 3, 3)``.

    ``Log(Exp(phi) Exp(e)) = phi + Jr^-1(phi) e + O(|e|^2)``.
    """
    phi = np.asarray(phi, dtype=float)
    theta = _norm(phi)
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    coef = np.where(
        small,
        1.0 / 12.0 + theta**2 / 720.0,
        1.0 / t**2 - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)),
    )
    S = skew(phi)
    return np.eye(3) + 0.5 * S + coef[..., None, None] * (S @ S)


def rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    """Rotation matrices ``Rz(yaw) Ry(pitch) Rx(roll)`` of ``(..., 3)`` roll, pitch, yaw [rad].

    The convention of Pinocchio's ``rpy.rpyToMatrix`` (and of URDF's ``rpy`` attribute).
    """
    rpy = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(rpy[..., 0]), np.sin(rpy[..., 0])
    cp, sp = np.cos(rpy[..., 1]), np.sin(rpy[..., 1])
    cy, sy = np.cos(rpy[..., 2]), np.sin(rpy[..., 2])
    R = np.empty((*rpy.shape[:-1], 3, 3))
    R[..., 0, 0], R[..., 0, 1], R[..., 0, 2] = (
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
    )
    R[..., 1, 0], R[..., 1, 1], R[..., 1, 2] = (
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
    )
    R[..., 2, 0], R[..., 2, 1], R[..., 2, 2] = -sp, cp * sr, cp * cr
    return R


def left_jacobian(phi: np.ndarray) -> np.ndarray:
    """Left Jacobian of SO(3) at rotation vectors ``(..., 3)``, ``(..., 3, 3)``.

    ``Exp(phi + e) = Exp(Jl(phi) e) Exp(phi) + O(|e|^2)``.
    """
    phi = np.asarray(phi, dtype=float)
    theta = _norm(phi)
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    a = np.where(small, 0.5 - theta**2 / 24.0, (1.0 - np.cos(t)) / t**2)
    b = np.where(small, 1.0 / 6.0 - theta**2 / 120.0, (t - np.sin(t)) / t**3)
    S = skew(phi)
    return np.eye(3) + a[..., None, None] * S + b[..., None, None] * (S @ S)


def tilts(normals: np.ndarray) -> np.ndarray:
    """Roll and pitch ``(..., 2)`` [rad] of a frame whose ``R^T e_z`` is ``normals`` ``(..., 3)``.

    With ``R = Rz(yaw) Ry(pitch) Rx(roll)``, the last row of ``R`` is
    ``(-sin pitch, cos pitch sin roll, cos pitch cos roll)``: the plane's normal seen from the
    contact frame (a flush contact's gap, :class:`calib.identification.contacts.PlaneContact`).
    Both are zero only where the normal is the contact's z (not its -z).
    """
    roll = np.arctan2(normals[..., 1], normals[..., 2])
    pitch = -np.arcsin(np.clip(normals[..., 0], -1.0, 1.0))
    return np.stack([roll, pitch], axis=-1)


def tilt_derivatives(normals: np.ndarray) -> np.ndarray:
    """Derivatives ``(..., 2, 3)`` of :func:`tilts` with respect to the normal's components."""
    x, y, z = normals[..., 0], normals[..., 1], normals[..., 2]
    D = np.zeros((*normals.shape[:-1], 2, 3))
    yz = y**2 + z**2
    D[..., 0, 1], D[..., 0, 2] = z / yz, -y / yz
    D[..., 1, 0] = -1.0 / np.sqrt(np.maximum(1.0 - x**2, 1e-300))
    return D
