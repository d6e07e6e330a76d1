"""What a camera's pixels determine (``calib analyze --measure pixels``).

The rank of the pixel rows' Jacobian (:func:`~.pixel_term.pixel_jacobian`) on the nominal
robot at random postures where the camera sees the target: the camera's 6, every joint
placement component of the chain and, with ``--params complete``, the target's mounting.
"""

from __future__ import annotations

import numpy as np

from ..measurements.pixel_simulation import simulate_pixels
from ..measurements.pixels import Target
from .pixel_term import PixelCamera, PixelState, Unknowns, free_columns, pixel_jacobian, pixel_rows
from .placements import Placements

__all__ = ["pixel_count"]


def pixel_count(
    chain, camera: PixelCamera, target: Target, configs: int, seed: int, params: str | None
) -> dict:
    """The unknowns a camera's pixels determine at random postures where it sees the target.

    The rank of the rows' Jacobian on the nominal robot (``n_base``), with the target's
    mounting an unknown when ``params`` is ``complete``.
    """
    q = chain.random_configurations(configs, seed)
    obs = simulate_pixels(chain, camera.name, camera.placement, camera.intrinsics, target, q)
    rows = pixel_rows(chain, obs, target, camera.name)
    placements = Placements.of((chain,))
    mount = params == "complete"
    lens = camera.intrinsics.camera
    state = PixelState(placements, np.asarray(camera.placement), target.position, lens)
    J = pixel_jacobian(state, chain, rows, Unknowns(mount=mount))[1]
    free = free_columns(J.reshape(-1, J.shape[2]), placements, Unknowns(mount=mount))
    return {
        "kind": "pixels",
        "camera": camera.name,
        "link": camera.link,
        "tool": chain.tool_frame,
        "rows": int(rows.m),
        "postures": len(np.unique(rows.q, axis=0)),
        "mount": mount,
        "n_unknowns": 6 + placements.y.size + 6 * mount,
        "n_base": len(free),
    }
