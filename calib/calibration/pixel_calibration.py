"""Calibrate a robot from what a camera fixed to one of its links sees, in pixels.

The camera (:class:`PixelCamera`: a name, the link it is fixed to, its intrinsics, optionally
its placement) sees a target (:class:`~calib.measurements.pixels.Target`) on a tool; the
chain runs from the camera's link to the tool (:mod:`.pixel_term`). :func:`calibrate_pixels`
places the camera, fits the unknowns the pixels determine (:func:`~.pixel_fit.fit_pixels`),
sets aside the gross outliers (named by their line), refuses a model worse than the camera's
registration on the held-out rows, and gives the URDF with the joints' origins moved and the
camera a link fixed to its link (its optical frame).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import CalibrationRefusedError, DataError, InvalidArgumentError
from ..kinematics.placement_export import camera_placement, camera_urdf
from ..kinematics.robot import Chain
from ..measurements.intrinsics import Intrinsics
from ..measurements.pixels import PixelObservations, Target
from .pixel_fit import PixelFit, fit_pixels, target_residuals
from .pixel_term import KNOWN, PixelRows, PixelState, Unknowns, target_points
from .placements import Placements

__all__ = [
    "OUTLIER_FACTOR",
    "PixelCalibration",
    "PixelCamera",
    "calibrate_pixels",
    "pixel_rows",
    "reprojection_errors",
]

OUTLIER_FACTOR = 6.0
"""A row is an outlier when its reprojection error exceeds this many robust standard
deviations (1.4826 times the median error) and 1 px."""

ROUND_OFF_PX = 1e-9
"""Held-out errors within this of the registration's are not worse [px]."""


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


def pixel_rows(chain: Chain, obs: PixelObservations, target: Target, camera: str) -> PixelRows:
    """The camera's rows of the observations, joints in the chain's order.

    Raises:
        DataError: A chain joint without a column, a point not in the target, no row of the
            camera.
    """
    missing = [j for j in chain.joint_names if j not in obs.joint_names]
    if missing:
        raise DataError(obs.source, f"no column for joint {missing[0]} of the camera's chain")
    keep = np.array([c == camera for c in obs.camera])
    if not keep.any():
        raise DataError(obs.source, f"no observation of camera {camera}")
    index = target.index
    lines = obs.rows or tuple(range(2, obs.m + 2))
    for p, line in zip(obs.point, lines, strict=True):
        if p not in index:
            raise DataError(obs.source, f"point {p!r} is not in the target {target.source}", line)
    columns = [obs.joint_names.index(j) for j in chain.joint_names]
    return PixelRows(
        np.asarray(obs.q)[keep][:, columns],
        np.array([index[p] for p in obs.point])[keep],
        np.asarray(obs.pixels)[keep],
        tuple(n for n, k in zip(lines, keep, strict=True) if k),
    )


def reprojection_errors(state: PixelState, chain, camera: PixelCamera, rows: PixelRows) -> dict:
    """RMS and largest reprojection error [px] and the position error they mean [mm].

    The millimetres are each row's error times its depth over the mean focal length.
    """
    pin = state.lens
    r = np.linalg.norm(target_residuals(state, chain, rows), axis=1)
    depth = target_points(state, chain, rows)[0][:, 2]
    mm = 1e3 * r * depth / (0.5 * (pin.fx + pin.fy))
    return {
        "rows": int(rows.m),
        "reprojection_rms_px": float(np.sqrt(np.mean(r**2))),
        "reprojection_max_px": float(np.max(r)),
        "position_rms_mm": float(np.sqrt(np.mean(mm**2))),
    }


@dataclass(frozen=True, eq=False)
class PixelCalibration:
    """A calibrated pixel term.

    Attributes:
        chain: The camera's link to the target's tool (nominal robot).
        camera: The camera (its starting placement as given).
        fit: The fit (its ``start``: the camera registered on the nominal robot).
        rows: The training rows kept.
        held: The held-out rows, or None.
        outliers: Lines of the rows set aside.
        what: The optional unknowns fitted.
    """

    chain: Chain
    camera: PixelCamera
    fit: PixelFit
    rows: PixelRows
    held: PixelRows | None
    outliers: tuple[int, ...]
    what: Unknowns = KNOWN

    @property
    def n_unknowns(self) -> int:
        """The unknowns offered (the target's mounting only when it is one)."""
        return len(self.fit.names) - 6 * (not self.what.mount)

    @property
    def count(self) -> int:
        """Unknowns the pixels determine (the rank of the rows' Jacobian)."""
        return len(self.fit.free)

    def errors(self) -> dict:
        """Reprojection errors of the registration and of the calibration, train and held out."""
        out: dict[str, dict | None] = {}
        for which, rows in (("train", self.rows), ("held_out", self.held)):
            out[which] = None if rows is None else {
                "registration": reprojection_errors(self.fit.start, self.chain, self.camera, rows),
                "calibrated": reprojection_errors(self.fit.state, self.chain, self.camera, rows),
            }  # fmt: skip
        return out

    def urdf(self) -> bytes:
        """The URDF: the joints' origins moved, the camera a link fixed to its link."""
        errors = self.fit.state.placements.errors()
        camera = (self.camera.name, self.camera.link, self.fit.state.camera)
        return camera_urdf(self.chain, errors, (camera,))


def _held_out(rows: PixelRows, holdout: float, seed: int) -> tuple[PixelRows, PixelRows | None]:
    """Postures set aside (a seeded fraction of the distinct joint rows)."""
    if holdout <= 0:
        return rows, None
    postures, which = np.unique(rows.q, axis=0, return_inverse=True)
    rng = np.random.default_rng([seed, 32])
    out = rng.permutation(len(postures))[: round(holdout * len(postures))]
    held = np.isin(which.ravel(), out)
    if not out.size or held.all():
        raise InvalidArgumentError(f"holdout {holdout:g} leaves no posture to fit or to check")
    return rows.subset(~held), rows.subset(held)


def _outliers(fit: PixelFit, chain, camera, rows: PixelRows) -> np.ndarray:
    r = np.linalg.norm(target_residuals(fit.state, chain, rows), axis=1)
    return (r > OUTLIER_FACTOR * 1.4826 * np.median(r)) & (r > 1.0)


def calibrate_pixels(
    chain: Chain,
    camera: PixelCamera,
    target: Target,
    obs: PixelObservations,
    *,
    validate: PixelObservations | None = None,
    holdout: float = 0.0,
    what: Unknowns = KNOWN,
    seed: int = 0,
) -> PixelCalibration:
    """Calibrate the robot and the camera's placement from the camera's pixels.

    Args:
        chain: From the camera's link to the tool that carries the target.
        camera: The camera.
        target: The target points in the tool frame [m].
        obs: The observations (the camera's rows are used).
        validate: Held-out observations, or None.
        holdout: Fraction of the postures held out when there is no ``validate``.
        what: The optional unknowns: the target's mounting on its link (``--params
            complete``; the fitted points are the report's ``targets``), the target points
            after the first three (``--refine-targets``), the intrinsics
            (``--refine-intrinsics``).
        seed: Seed of the holdout.

    Raises:
        DataError: See :func:`pixel_rows` and :func:`~.pixel_fit.fit_pixels`.
        CalibrationRefusedError: The held-out reprojection error is worse than the camera's
            registration's on the nominal robot.
    """
    if chain.base_frame != camera.link:
        raise InvalidArgumentError(f"the chain must start at the camera's link {camera.link}")
    rows = pixel_rows(chain, obs, target, camera.name)
    held = None if validate is None else pixel_rows(chain, validate, target, camera.name)
    if held is None:
        rows, held = _held_out(rows, holdout, seed)
    guess = camera.placement
    if guess is None:
        guess = camera_placement(chain, camera.name, camera.link)
    pin = camera.intrinsics.camera
    placements = Placements.of((chain,))
    dropped: tuple[int, ...] = ()
    for _ in range(3):
        fit = fit_pixels(placements, target.position, guess, chain, pin, rows, what, obs.source)
        bad = _outliers(fit, chain, pin, rows)
        if not bad.any():
            break
        dropped += tuple(n for n, b in zip(rows.lines, bad, strict=True) if b)
        rows = rows.subset(~bad)
    result = PixelCalibration(chain, camera, fit, rows, held, tuple(sorted(dropped)), what)
    if held is not None:
        before = reprojection_errors(fit.start, chain, camera, held)["reprojection_rms_px"]
        after = reprojection_errors(fit.state, chain, camera, held)["reprojection_rms_px"]
        if after > before + ROUND_OFF_PX:
            raise CalibrationRefusedError(
                f"camera {camera.name}: held-out reprojection error {after:.3f} px is worse than "
                f"the camera's registration on the nominal robot ({before:.3f} px): no URDF written"
            )
    return result
