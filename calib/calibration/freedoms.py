"""What a chain's calibration is asked to fit, refused where the data or the URDF cannot.

``fix`` and ``free`` name parameters, ``elastic`` asks for joint compliance and ``marker``
guesses the measured points: each is checked here before the fit, in one line that says why
(:func:`~calib.calibration.entry.calibrate`).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InvalidArgumentError
from ..identification.identifiability import independent_columns
from .options import Options

__all__ = ["check_compliance", "check_free", "marker_guess"]


def marker_guess(marker, k: int) -> np.ndarray:
    """The markers' guess ``(k, 3)`` [m]: zeros, one point for all, or one per marker."""
    if marker is None:
        return np.zeros((k, 3))
    try:
        mk = np.array(marker, dtype=float).reshape(-1, 3)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"a marker is 3 numbers [m], got {marker!r}") from None
    if not np.all(np.isfinite(mk)) or np.max(np.abs(mk)) > 1e3:
        raise InvalidArgumentError(f"a marker is 3 finite numbers within 1000 m, got {marker!r}")
    if len(mk) == 1:
        mk = np.repeat(mk, k, axis=0)
    if len(mk) != k:
        raise InvalidArgumentError(f"{len(mk)} marker guesses for {k} measured points")
    return mk


def check_compliance(chain, torque, loaded: list[int], opts: Options) -> None:
    """Refuse compliance asked for where gravity loads no joint (no masses) or not the one named.

    Raises:
        InvalidArgumentError: ``elastic`` (or a compliance in ``free``) on a chain whose URDF
            gives its joints no gravity torque, or ``free`` naming an unloaded joint's.
    """
    if torque is None:
        return
    if not loaded:
        raise InvalidArgumentError(
            f"elastic (or a compliance in free) needs gravity torques, and {chain.urdf_path} "
            f"gives none on the chain (no masses beyond it): drop elastic and the compliances"
        )
    for name in opts.free:
        if name[:1] == "c" and name[1:].isdigit() and int(name[1:]) - 1 not in loaded:
            raise InvalidArgumentError(
                f"free {name} cannot be fitted: gravity loads joint {name[1:]} at none of the "
                f"configurations (a compliance only shows under a torque); drop it from free"
            )


def check_free(free, cand, names, J: np.ndarray, fixed: int) -> None:
    """Refuse a ``--free`` parameter the data cannot fit on its own, saying why.

    Args:
        free: ``--free`` names.
        cand: The identifiable names (independent columns, in preference order).
        names: Every column's name; the first ``fixed`` are the frame's and markers'.
        J: The weighted Jacobian ``(rows, columns)``.
        fixed: Number of frame and marker columns.

    Raises:
        InvalidArgumentError: A name whose column the frame and markers carry, or that is
            regrouped with parameters kept before it.
    """
    for name in free:
        if name in cand or name not in names:
            continue  # fitted; or a group name (frame, markers, tool)
        col = names.index(name)
        _, _, kept, _ = independent_columns(J[:, [*range(fixed), col]], list(range(fixed + 1)))
        why = (
            "the measurement frame and markers carry it (they are always fitted)"
            if fixed not in kept
            else "it is regrouped with parameters kept before it (not identifiable on its own)"
        )
        raise InvalidArgumentError(f"free {name} cannot be fitted: {why}; drop it from free")
