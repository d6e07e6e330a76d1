"""The pixel kind: a camera fixed to a link sees target points fixed to a tool, in pixels.

A camera is fixed to a link of the robot (the root link for a camera in the cell, a flange for
a camera on the wrist, a head link). Its chain runs from that link (the chain's base frame)
to the tool that carries the target (the root link for a target in the cell: the chain then
traverses the arm backwards). A target point ``X`` in the tool frame is seen at::

    p = C^-1 T(q) X,    pixel = pinhole(p)

with ``T(q)`` the tool in the link's frame on the robot with its joint placement errors
(:mod:`.placements`), ``C`` the camera's optical frame (z forward, x right, y down) in the
link's frame. The residual is the reprojection error ``pixel - observed`` [px].

Unknowns, in this order (the columns of :func:`pixel_jacobian`):

* the camera's placement: ``C -> C [R(w) | v]`` (``v`` [m], ``w`` [rad], in the camera
  frame), 6;
* every joint placement error of the chain's joints (``<joint>:x ... :rz``, 6 each);
* with ``mount``, the target's mounting on its link: ``X -> R(w) X + v`` for every point
  (``v`` [m], ``w`` [rad], in the tool frame), 6 (the tool's own placement, which no joint
  placement holds: ``--params complete``; by default the target file's points are exact);
* with ``refine_targets``, the target points beyond the first three (3 each [m]): moving the
  whole target rigidly is moving the tool, and its size is the only scale the pixels have,
  so the first three points stay as given (the gauge);
* with ``refine_intrinsics``, the camera's intrinsics (``fx, fy, cx, cy`` [px] and the
  distortion coefficients, :attr:`~calib.identification.pinhole.Pinhole.parameter_names`);
  otherwise they stay fixed.

:class:`Unknowns` says which of the optional blocks are unknowns. The Jacobian is analytic:
the pinhole's derivative by the point
(:meth:`~calib.identification.pinhole.Pinhole.projection`) times the point's motion per
unknown (:func:`~.placements.joint_twists` for the joint placements).
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
    """Points ``X`` ``(m, 3)`` of the tool, in the camera ``(m, 3)`` and the base link [m].

    ``kin``: each row's kinematics of the chain; ``camera``: its frame ``(4, 4)`` [m].
    """
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
    """The residuals ``(m, 2)`` and their derivatives by every unknown ``(m, 2, c)``.

    Columns: the unknowns in the module's order, the mounting's 6 always, the target points'
    and the intrinsics' those of ``state.what`` (``state``'s MDH model unused). ``robot``
    False: the joint placement columns are zero (a fit moving none); ``kin``:
    :meth:`~.placements.Placements.frames` at the rows, if made. ``pixel - observed`` [px],
    its derivatives [px per m, rad or px].
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

    ``W``'s columns: each camera's 6, the joint placements, the mounting, the target points,
    each camera's intrinsics. They are scaled to unit length first (metres and radians,
    pixels per each). Without ``what.mount``, the target's mounting is known (its columns
    are never free). Preferred: the cameras, the mounting, the joints' offsets, their other
    components, the target points, the intrinsics (the camera and the mounting absorb what
    the chain's end joints also explain).
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
