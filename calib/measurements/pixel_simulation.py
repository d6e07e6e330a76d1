"""Simulated pixel observations: a camera on a link sees a target on a tool.

The robot is the chain's (load it from a true robot's URDF, :func:`~.true_robot.true_robot`,
for a simulation with a truth); the camera's optical frame is given in the chain's base link.
A point is kept where it is in front of the camera, inside the image (before and after the
noise) and, when the target has normals, facing the camera.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..core.checks import check_count, check_number, real_array
from ..exceptions import InvalidArgumentError
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain
from .intrinsics import Intrinsics
from .limits import check_limits
from .pixels import PixelObservations, Target, on_link

__all__ = ["MAX_NOISE_PX", "simulate_cameras", "simulate_pixels"]

MAX_NOISE_PX = 1000.0
"""Largest pixel noise a simulation takes [px]."""


def _seen(chain: Chain, placement: np.ndarray, intr: Intrinsics, target: Target, q: np.ndarray):
    """Each (configuration, point) pair's pixel and whether the camera sees it."""
    kin = from_chain(chain).kinematics(q)
    R, p = kin.R[:, -1], kin.p[:, -1]  # (m, 3, 3), (m, 3)
    X = target.position
    p_link = p[:, None] + np.einsum("mij,kj->mki", R, X)
    p_cam = (p_link - placement[:3, 3]) @ placement[:3, :3]  # (m, k, 3)
    seen = intr.camera.projection(p_cam.reshape(-1, 3))
    ok = seen.in_front & intr.inside(np.nan_to_num(seen.pixels, nan=-1e9))
    if target.normal is not None:
        n_cam = np.einsum("ij,mjk,lk->mli", placement[:3, :3].T, R, target.normal)
        ok &= np.einsum("mki,mki->mk", n_cam, p_cam).ravel() < 0
    return seen.pixels, ok


def _simulated(chain, camera, placement, intrinsics, target, q, noise_px, rng):
    """The rows seen: each one's configuration index ``(r,)`` and pixel ``(r, 2)`` [px]."""
    if not isinstance(chain, Chain) or not isinstance(intrinsics, Intrinsics):
        raise InvalidArgumentError("simulate pixels of a Chain with a camera's Intrinsics")
    if not isinstance(target, Target) or not isinstance(camera, str) or not camera:
        raise InvalidArgumentError("simulate pixels of a Target seen by a named camera")
    C = real_array(placement, "camera placement", (4, 4))
    q = chain.check_configurations(q)  # far past a limit (degrees?): refused as simulate's
    check_limits(chain, q, "the configurations", np.arange(1, len(q) + 1), warn=False)
    noise = check_number(noise_px, "noise_px", 0.0, MAX_NOISE_PX)
    pixels, ok = _seen(chain, C, intrinsics, target, q)
    if not ok.any():
        raise InvalidArgumentError(f"camera {camera} sees no target point at these postures")
    pixels = pixels + noise * rng.standard_normal(pixels.shape)
    index = np.flatnonzero(ok & intrinsics.inside(np.nan_to_num(pixels, nan=-1e9)))
    return index, pixels[index]


def simulate_pixels(
    chain: Chain,
    camera: str,
    placement,
    intrinsics: Intrinsics,
    target: Target,
    q,
    *,
    noise_px: float = 0.0,
    seed: int = 0,
) -> PixelObservations:
    """What a camera on the chain's base link sees of a target on its tool, in pixels.

    Args:
        chain: From the camera's link to the target's tool (on the robot simulated).
        camera: The camera's name (the ``camera`` column).
        placement: The camera's optical frame in the chain's base link ``(4, 4)`` [m].
        intrinsics: The camera's intrinsics and image size.
        target: The target points in the tool frame [m].
        q: Joint positions ``(m, n)`` [rad or m], the chain's joints.
        noise_px: Standard deviation of the Gaussian noise on u and v [px].
        seed: Seed of the noise (an integer >= 0).

    Returns:
        One row per point seen, in configuration then point order.

    Raises:
        InvalidArgumentError: Bad arguments, or no point seen at all.
    """
    rng = np.random.default_rng([check_count(seed, "seed", 0), 32])
    index, pixels = _simulated(chain, camera, placement, intrinsics, target, q, noise_px, rng)
    k = len(target.point)
    return PixelObservations(
        chain.joint_names,
        np.asarray(q, dtype=float)[index // k],
        (camera,) * len(index),
        tuple(target.point[i] for i in index % k),
        pixels,
        source="<simulated pixels>",
    )


def simulate_cameras(
    chains: Sequence[Chain],
    cameras: Sequence[tuple[str, np.ndarray | None, Intrinsics]],
    target: Target,
    joints: Sequence[str],
    q,
    *,
    noise_px: float = 0.0,
    seed: int = 0,
) -> PixelObservations:
    """What several cameras see of a target at the same postures, in one set of observations.

    Args:
        chains: Each camera's chain (from its link to the target's tool; a target on several
            links: one chain per link, the camera given once per chain).
        cameras: Each camera's name, optical frame in its chain's base link ``(4, 4)`` [m]
            and intrinsics.
        target: The target points in their link's frame [m] (each chain sees those on its
            tool, :func:`~.pixels.on_link`).
        joints: The columns of ``q``: every joint of the chains.
        q: Joint positions ``(m, len(joints))`` [rad or m].
        noise_px: Standard deviation of the Gaussian noise on u and v [px].
        seed: Seed of the noise (the first camera's draws are :func:`simulate_pixels`').

    Returns:
        Each camera's rows (camera after camera, then configuration then point order), every
        joint of ``joints`` in each row.

    Raises:
        InvalidArgumentError: Bad arguments, a chain joint not in ``joints``, or a camera
            that sees no point.
    """
    if len(chains) != len(cameras) or not chains:
        raise InvalidArgumentError("simulate cameras: one chain per camera")
    joints = tuple(joints)
    q = real_array(q, "joint positions", (None, len(joints)))
    rows, names, points, pixels = [], [], [], []
    for c, (chain, (name, placement, intrinsics)) in enumerate(zip(chains, cameras, strict=True)):
        missing = [j for j in chain.joint_names if j not in joints]
        if missing:
            raise InvalidArgumentError(f"camera {name}: no column for joint {missing[0]}")
        rng = np.random.default_rng([check_count(seed, "seed", 0), 32, *([c] if c else [])])
        mine = q[:, [joints.index(j) for j in chain.joint_names]]
        on = on_link(target, chain.tool_frame)
        index, seen = _simulated(chain, name, placement, intrinsics, on, mine, noise_px, rng)
        rows.append(index // len(on.point))
        names += [name] * len(index)
        points += [on.point[i] for i in index % len(on.point)]
        pixels.append(seen)
    return PixelObservations(
        joints,
        q[np.concatenate(rows)],
        tuple(names),
        tuple(points),
        np.concatenate(pixels),
        source="<simulated pixels>",
    )
