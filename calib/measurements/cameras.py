"""A camera of the pixel kind and its rows: the camera as given, its observations on a chain.

:class:`PixelCamera` is a camera fixed to a link of the robot (its name, link, intrinsics and
a guess of its placement); :func:`pixel_rows` selects one camera's observations
(:class:`~calib.measurements.pixels.PixelObservations`) of the points of a target on one chain's
tool, its joint columns in the chain's order (:class:`PixelRows`): what the pixel term of
:mod:`calib.calibration.pixel_chain` fits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..kinematics.robot import Chain
from .intrinsics import Intrinsics
from .pixels import PixelObservations, Target

__all__ = ["PixelCamera", "PixelRows", "pixel_rows"]


@dataclass(frozen=True, eq=False)
class PixelRows:
    """One camera's observations on one chain, one row per point in an image.

    Attributes:
        q: The chain's joint positions of each row ``(m, n)`` [rad or m].
        point: Each row's index into the target ``(m,)``.
        pixels: The observed ``(u, v)`` ``(m, 2)`` [px].
        lines: Each row's line in its file, for messages ``(m,)``.
    """

    q: np.ndarray
    point: np.ndarray
    pixels: np.ndarray
    lines: tuple[int, ...]

    @property
    def m(self) -> int:
        """Number of rows."""
        return len(self.point)

    def subset(self, keep: np.ndarray) -> PixelRows:
        """The rows where ``keep`` is true."""
        lines = tuple(n for n, k in zip(self.lines, keep, strict=True) if k)
        return PixelRows(self.q[keep], self.point[keep], self.pixels[keep], lines)


@dataclass(frozen=True, eq=False)
class PixelCamera:
    """A camera fixed to a link.

    Attributes:
        name: Its name (the ``camera`` column; the calibrated URDF's link of its optical frame).
        link: The link it is fixed to (the robot's root link for a camera in the cell).
        intrinsics: Its intrinsics and image size.
        placement: Its optical frame in ``link`` ``(4, 4)`` [m], or None: the URDF's link
            ``name`` on ``link`` if there is one, else placed from the pixels.
    """

    name: str
    link: str
    intrinsics: Intrinsics
    placement: np.ndarray | None = None

    def __post_init__(self) -> None:
        """Refuse a camera that cannot be one (checked where it is made, not at the fit).

        Raises:
            InvalidArgumentError: A name or link that is not a non-empty text, intrinsics
                that are not an :class:`~calib.measurements.intrinsics.Intrinsics`, or a
                placement that is not a rigid transform ``(4, 4)``.
        """
        for what, value in (("name", self.name), ("link", self.link)):
            if not isinstance(value, str) or not value:
                raise InvalidArgumentError(
                    f"PixelCamera {what} must be a non-empty text, got {value!r}"
                )
        if not isinstance(self.intrinsics, Intrinsics):
            raise InvalidArgumentError(
                f"PixelCamera {self.name}: intrinsics must be read with calib.read_intrinsics, "
                f"got {type(self.intrinsics).__name__}"
            )
        if self.placement is not None and not _rigid(self.placement):
            raise InvalidArgumentError(
                f"PixelCamera {self.name}: placement must be a rigid transform (4, 4) [m]"
            )
        if self.placement is not None:  # a nested list as well (a TypeError in the fit)
            placement = np.array(self.placement, dtype=float)
            placement.flags.writeable = False
            object.__setattr__(self, "placement", placement)

    def __repr__(self) -> str:
        """One line (the intrinsics and the placement are in the attributes)."""
        at = "placed from the URDF or the pixels" if self.placement is None else "placed"
        return f"<PixelCamera {self.name} on {self.link}, {self.intrinsics.source}, {at}>"


def _rigid(T) -> bool:
    """Whether ``T`` is a finite ``(4, 4)`` rigid transform (rotation to 1e-6)."""
    T = np.asarray(T, dtype=float) if not isinstance(T, np.ndarray) else T
    if T.shape != (4, 4) or not np.isfinite(T).all():
        return False
    R = T[:3, :3]
    return bool(
        np.allclose(R.T @ R, np.eye(3), atol=1e-6)
        and abs(np.linalg.det(R) - 1) < 1e-6
        and np.allclose(T[3], [0, 0, 0, 1])
    )


def pixel_rows(
    chain: Chain,
    obs: PixelObservations,
    target: Target,
    camera: str,
    keep: np.ndarray | None = None,
) -> PixelRows:
    """The camera's rows of the observations (where ``keep``), joints in the chain's order.

    A target on several links (its ``link`` column): the rows of the points on the chain's
    tool only (each link is its own chain, from the camera's link).

    Raises:
        DataError: A chain joint without a column, a point not in the target, no row of the
            camera (of a point on the chain's tool).
    """
    missing = [j for j in chain.joint_names if j not in obs.joint_names]
    if missing:
        raise DataError(obs.source, f"no column for joint {missing[0]} of the camera's chain")
    mine = np.array([c == camera for c in obs.camera])
    if target.link is not None:
        tool = chain.tool_frame
        on = {p for p, link in zip(target.point, target.link, strict=True) if link == tool}
        mine &= np.array([p in on for p in obs.point])
    if not mine.any():
        where = "" if target.link is None else f" of a point on {chain.tool_frame}"
        raise DataError(obs.source, f"no observation of camera {camera}{where}")
    if keep is not None:
        mine &= keep
    index = target.index
    lines = obs.rows or tuple(range(1, obs.m + 1))  # without a file: i + 1, as every kind
    for p, line in zip(obs.point, lines, strict=True):
        if p not in index:
            raise DataError(obs.source, f"point {p!r} is not in the target {target.source}", line)
    columns = [obs.joint_names.index(j) for j in chain.joint_names]
    return PixelRows(
        np.asarray(obs.q)[mine][:, columns],
        np.array([index[p] for p in obs.point])[mine],
        np.asarray(obs.pixels)[mine],
        tuple(n for n, k in zip(lines, mine, strict=True) if k),
    )
