"""What cameras' pixels determine (``calib analyze --measure pixels``).

The rank of the rows' Jacobian on the nominal robot at postures where the cameras see the target.
"""

from __future__ import annotations

import numpy as np

from ..measurements.pixel_simulation import simulate_cameras
from ..measurements.pixels import Target
from .pixel_chain import PixelTermState
from .pixel_term import PixelCamera, Unknowns, free_columns, pixel_jacobian, pixel_rows
from .placements import Placements

__all__ = ["pixel_count"]


def _stacked(names, cameras, rows, chains, placements: Placements, target, what) -> np.ndarray:
    """The rows' Jacobian ``(r, c)``: each camera's 6 (one per name), the joints', the mounting."""
    blocks = []
    models = placements.chain_models(tuple(chains))
    for chain, camera, part, mdh in zip(chains, cameras, rows, models, strict=True):
        lens = camera.intrinsics.camera
        state = PixelTermState(mdh, np.asarray(camera.placement), target.position, lens, 1.0, what)
        J = pixel_jacobian(placements, state, chain, part)[1]
        W = np.zeros((part.m, 2, 6 * len(names) + J.shape[2] - 6))
        i = names.index(camera.name)
        W[:, :, 6 * i : 6 * i + 6] = J[:, :, :6]
        W[:, :, 6 * len(names) :] = J[:, :, 6:]
        blocks.append(W.reshape(-1, W.shape[2]))
    return np.concatenate(blocks)


def pixel_count(
    chains, cameras: tuple[PixelCamera, ...], target: Target, joints, q, params: str | None
) -> dict:
    """The unknowns cameras' pixels determine (``n_base``) at postures ``q`` [rad or m].

    ``chains``: each camera's chain to the target's tool (a target on several links: a chain
    per link, the camera given once per chain); ``joints``: ``q``'s columns; ``params``
    ``complete``: the target's mounting is an unknown too.
    """
    views = tuple((camera.name, camera.placement, camera.intrinsics) for camera in cameras)
    obs = simulate_cameras(chains, views, target, joints, q)
    placements = Placements.of(tuple(chains))
    what = Unknowns(mount=params == "complete")
    rows = [pixel_rows(c, obs, target, cam.name) for c, cam in zip(chains, cameras, strict=True)]
    names = tuple(dict.fromkeys(c.name for c in cameras))
    W = _stacked(names, cameras, rows, chains, placements, target, what)
    free = free_columns(W, placements, what, len(names))
    first = cameras[0]
    return {
        "kind": "pixels",
        "camera": first.name,
        "link": first.link,
        "cameras": [
            {"name": c.name, "link": c.link, "rows": r.m}
            for c, r in zip(cameras, rows, strict=True)
        ],
        "tool": chains[0].tool_frame,
        "rows": int(obs.m),
        "postures": len(np.unique(obs.q, axis=0)),
        "mount": what.mount,
        "n_unknowns": 6 * len(names) + placements.y.size + 6 * what.mount,
        "n_base": len(free),
    }
