"""The pixel kind: a camera fixed to a link sees target points fixed to a tool, in pixels.

``pixel = pinhole(C^-1 T(q) X)``; the unknowns (the columns of :func:`pixel_jacobian`): the
camera's 6, the joint placements, the optional blocks of :class:`Unknowns` (the target's
mounting, target points, intrinsics). Model and units: docs/developers/engine.md#pixel_term
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..kinematics.robot import Chain
from ..kinematics.so3 import skew
from ..measurements.cameras import PixelCamera, PixelRows, pixel_rows
from .determined import determined_columns
from .placements import Placements, joint_twists, offset_component

if TYPE_CHECKING:  # the term's state, whose module imports this one
    from .pixel_chain import PixelTermState

__all__ = [
    "CAMERA_NAMES",
    "GAUGE_POINTS",
    "KNOWN",
    "MOUNT_NAMES",
    "PixelCamera",
    "PixelRows",
    "Unknowns",
    "camera_points",
    "free_columns",
    "pixel_jacobian",
    "pixel_rows",
]

CAMERA_NAMES = ("camera.x", "camera.y", "camera.z", "camera.rx", "camera.ry", "camera.rz")
"""The camera placement's unknowns (in the camera frame)."""

MOUNT_NAMES = ("mount.x", "mount.y", "mount.z", "mount.rx", "mount.ry", "mount.rz")
"""The target mounting's unknowns (in the tool frame)."""

GAUGE_POINTS = 3
"""Target points kept as given when the target is refined (the gauge and the scale)."""


@dataclass(frozen=True)
class Unknowns:
    """The optional unknowns of a pixel term.

    Attributes:
        mount: The target's mounting on its link (6).
        targets: The target points after the first :data:`GAUGE_POINTS` (3 each).
        intrinsics: The camera's intrinsics (4 + the distortion coefficients).
    """

    mount: bool = False
    targets: bool = False
    intrinsics: bool = False


KNOWN = Unknowns()
"""No optional unknown: the target and the intrinsics as given."""


def camera_points(kin, camera: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points ``X`` ``(m, 3)`` of the tool, in the camera ``(m, 3)`` and the base link [m]."""
    p_link = kin.p[:, -1] + np.einsum("mij,mj->mi", kin.R[:, -1], X)
    return (p_link - camera[:3, 3]) @ camera[:3, :3], p_link


def pixel_jacobian(
    placements: Placements,
    state: PixelTermState,
    chain: Chain,
    rows: PixelRows,
    robot: bool = True,
    kin=None,
) -> tuple[np.ndarray, np.ndarray]:
    """The residuals ``pixel - observed`` ``(m, 2)`` [px] and their derivatives ``(m, 2, c)``.

    Columns in the module's order, the mounting's 6 always, the target points' and the
    intrinsics' per ``state.what``; ``robot`` False: the joint placement columns are zero.
    """
    if kin is None:
        kin = placements.frames(chain, rows.q)
    X = state.target[rows.point]
    p_cam, p_link = camera_points(kin, state.camera, X)
    seen = state.lens.projection(p_cam, derivatives=True)
    D = np.asarray(seen.d_point)  # (m, 2, 3) [px/m]
    RcT = state.camera[:3, :3].T
    m = rows.m
    moving = np.zeros((m, 3, len(placements.joints), 6))  # the point's motion in the base link
    if robot:
        columns = placements.path(chain).columns
        ang, lin = joint_twists(placements, chain, kin)
        moving[:, :, columns] = np.moveaxis(lin - skew(p_link)[:, None] @ ang, 1, 2)
    by_camera = np.concatenate([-np.broadcast_to(np.eye(3), (m, 3, 3)), skew(p_cam)], axis=2)
    mount = RcT @ kin.R[:, -1]  # d(point in the camera) / d(point in the tool)
    by_mount = mount @ np.concatenate([np.broadcast_to(np.eye(3), (m, 3, 3)), -skew(X)], axis=2)
    parts = [D @ by_camera, D @ (RcT @ moving.reshape(m, 3, -1)), D @ by_mount]
    k = len(state.target)
    if state.what.targets and k > GAUGE_POINTS:
        by_point = np.zeros((m, 3, k, 3))
        by_point[np.arange(m), :, rows.point] = mount
        parts.append(D @ by_point[:, :, GAUGE_POINTS:].reshape(m, 3, -1))
    if state.what.intrinsics:
        parts.append(np.asarray(seen.d_parameters))
    return seen.pixels - rows.pixels, np.concatenate(parts, axis=2)


def free_columns(
    W: np.ndarray, placements: Placements, what: Unknowns, cameras: int = 1
) -> tuple[int, ...]:
    """The columns of ``W`` ``(r, c)`` the rows determine, in order of preference.

    ``W``'s columns: each camera's 6, the joint placements, the mounting (never free without
    ``what.mount``), the target points, the intrinsics.
    Order of preference: docs/developers/engine.md#pixel_term
    """
    norms = np.linalg.norm(W, axis=0)
    used = norms > 0
    n = 6 * cameras + placements.y.size
    if not what.mount:
        used[n : n + 6] = False
    scaled = np.where(used, W / np.where(used, norms, 1.0), 0.0)
    offsets: list[int] = []
    others: list[int] = []
    for j, jid in enumerate(placements.ids):
        off = ("x", "y", "z", "rx", "ry", "rz").index(offset_component(placements.nominal, jid))
        for c in range(6):
            (offsets if c == off else others).append(6 * cameras + 6 * j + c)
    preferred = [*range(6 * cameras), *range(n, n + 6), *offsets, *others, *range(n + 6, len(W.T))]
    order = [c for c in preferred if used[c]]
    return tuple(sorted(order[i] for i in determined_columns(scaled[:, order])))
