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

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..exceptions import CalibrationRefusedError, DataError, InvalidArgumentError
from ..kinematics.placement_export import camera_placement, camera_urdf
from ..kinematics.robot import Chain
from ..measurements.intrinsics import Intrinsics
from ..measurements.pixels import PixelObservations, Target
from .pixel_fit import PixelFit, PixelView, fit_pixels, target_residuals
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
deviations (1.4826 times the median error) and 1 px, or when the target gives normals and the
point is seen from behind its normal."""

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


def pixel_rows(
    chain: Chain,
    obs: PixelObservations,
    target: Target,
    camera: str,
    keep: np.ndarray | None = None,
) -> PixelRows:
    """The camera's rows of the observations (where ``keep``), joints in the chain's order.

    Raises:
        DataError: A chain joint without a column, a point not in the target, no row of the
            camera.
    """
    missing = [j for j in chain.joint_names if j not in obs.joint_names]
    if missing:
        raise DataError(obs.source, f"no column for joint {missing[0]} of the camera's chain")
    mine = np.array([c == camera for c in obs.camera])
    if not mine.any():
        raise DataError(obs.source, f"no observation of camera {camera}")
    if keep is not None:
        mine &= keep
    index = target.index
    lines = obs.rows or tuple(range(2, obs.m + 2))
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


def _row_errors(state: PixelState, chain, rows: PixelRows) -> tuple[np.ndarray, np.ndarray]:
    """Each row's reprojection error [px] and the position error it means [mm]."""
    r = np.linalg.norm(target_residuals(state, chain, rows), axis=1)
    depth = target_points(state, chain, rows)[0][:, 2]
    return r, 1e3 * r * depth / (0.5 * (state.lens.fx + state.lens.fy))


def reprojection_errors(states, views) -> dict:
    """RMS and largest reprojection error [px] and the position error they mean [mm].

    Over every camera's rows (``states`` and ``views`` one per camera); the millimetres are
    each row's error times its depth over the mean focal length.
    """
    parts = [_row_errors(s, v.chain, v.rows) for s, v in zip(states, views, strict=True)]
    r = np.concatenate([p[0] for p in parts])
    mm = np.concatenate([p[1] for p in parts])
    return {
        "rows": len(r),
        "reprojection_rms_px": float(np.sqrt(np.mean(r**2))),
        "reprojection_max_px": float(np.max(r)),
        "position_rms_mm": float(np.sqrt(np.mean(mm**2))),
    }


@dataclass(frozen=True, eq=False)
class PixelCalibration:
    """A calibrated pixel problem: one or several cameras seeing one target.

    Attributes:
        cameras: The cameras (their starting placements as given).
        views: Each camera's chain (nominal robot) and training rows kept.
        held: Each camera's held-out rows (None: none).
        fit: The fit (its ``starts``: the cameras registered on the nominal robot).
        outliers: Lines of the rows set aside.
        what: The optional unknowns fitted.
        refusal: Why the model must not be written (a camera's held-out error worse than
            its registration's), or None.
    """

    cameras: tuple[PixelCamera, ...]
    views: tuple[PixelView, ...]
    held: tuple[PixelView | None, ...]
    fit: PixelFit
    outliers: tuple[int, ...]
    what: Unknowns = KNOWN
    refusal: str | None = None

    @property
    def chain(self) -> Chain:
        """The first camera's chain."""
        return self.views[0].chain

    @property
    def rows(self) -> PixelRows:
        """The first camera's training rows."""
        return self.views[0].rows

    @property
    def n_unknowns(self) -> int:
        """The unknowns offered (the target's mounting only when it is one)."""
        return len(self.fit.names) - 6 * (not self.what.mount)

    @property
    def count(self) -> int:
        """Unknowns the pixels determine (the rank of the rows' Jacobian)."""
        return len(self.fit.free)

    def _held_views(self, which: str) -> tuple[PixelView | None, ...]:
        return self.views if which == "train" else self.held

    def errors(self) -> dict:
        """Reprojection errors of the registration and of the calibration, train and held out.

        Over every camera; ``terms``: each camera's, calibrated.
        """
        out: dict[str, dict | None] = {}
        for which in ("train", "held_out"):
            found = [
                (c.name, a, b, v)
                for c, a, b, v in zip(
                    self.cameras, self.fit.starts, self.fit.states, self._held_views(which),
                    strict=True,
                )
                if v is not None
            ]  # fmt: skip
            if not found:
                out[which] = None
                continue
            views = [f[3] for f in found]
            out[which] = {
                "registration": reprojection_errors([f[1] for f in found], views),
                "calibrated": reprojection_errors([f[2] for f in found], views),
                "terms": {f[0]: reprojection_errors([f[2]], [f[3]]) for f in found},
            }
        return out

    def urdf(self) -> bytes:
        """The URDF: the joints' origins moved, each camera a link fixed to its link."""
        errors = self.fit.state.placements.errors()
        cameras = tuple(
            (c.name, c.link, s.camera) for c, s in zip(self.cameras, self.fit.states, strict=True)
        )
        return camera_urdf(self.chain, errors, cameras)


def _held_postures(obs: PixelObservations, holdout: float, seed: int) -> np.ndarray | None:
    """The observations' rows of the postures set aside (a seeded fraction), or None."""
    if holdout <= 0:
        return None
    postures, which = np.unique(np.asarray(obs.q), axis=0, return_inverse=True)
    rng = np.random.default_rng([seed, 32])
    out = rng.permutation(len(postures))[: round(holdout * len(postures))]
    held = np.isin(which.ravel(), out)
    if not out.size or held.all():
        raise InvalidArgumentError(f"holdout {holdout:g} leaves no posture to fit or to check")
    return held


def _views(chains, cameras, target, obs, validate, holdout, seed):
    """Each camera's training and held-out views."""
    held = None if validate is not None else _held_postures(obs, holdout, seed)
    train, check = [], []
    for chain, camera in zip(chains, cameras, strict=True):
        if chain.base_frame != camera.link:
            raise InvalidArgumentError(
                f"camera {camera.name}: its chain must start at its link {camera.link}"
            )
        keep = None if held is None else ~held
        train.append(PixelView(chain, pixel_rows(chain, obs, target, camera.name, keep)))
        rows: PixelRows | None = None
        if validate is not None:
            rows = pixel_rows(chain, validate, target, camera.name)
        elif held is not None:
            rows = pixel_rows(chain, obs, target, camera.name, held)
        check.append(None if rows is None or not rows.m else PixelView(chain, rows))
    return tuple(train), tuple(check)


def _from_behind(state: PixelState, view: PixelView, normals: np.ndarray) -> np.ndarray:
    """Rows whose point's outward normal faces away from the camera (seen from behind)."""
    kin = target_points(state, view.chain, view.rows)
    p_cam, tool = kin[0], kin[2][2].R[:, -1]
    n_cam = np.einsum("ji,mjk,mk->mi", state.camera[:3, :3], tool, normals[view.rows.point])
    return np.einsum("mi,mi->m", n_cam, p_cam) >= 0


def _outliers(fit: PixelFit, views, normals: np.ndarray | None) -> list[np.ndarray]:
    """Each camera's outlier rows: a gross error, or a point seen from behind its normal."""
    out = []
    for state, view in zip(fit.states, views, strict=True):
        r = np.linalg.norm(target_residuals(state, view.chain, view.rows), axis=1)
        bad = (r > OUTLIER_FACTOR * 1.4826 * np.median(r)) & (r > 1.0)
        if normals is not None:
            bad |= _from_behind(state, view, normals)
        out.append(bad)
    return out


def _refusal(result: PixelCalibration) -> str | None:
    """Why a camera's held-out reprojection error refuses the model, or None."""
    fit = result.fit
    for camera, a, b, view in zip(result.cameras, fit.starts, fit.states, result.held, strict=True):
        if view is None:
            continue
        before = reprojection_errors([a], [view])["reprojection_rms_px"]
        after = reprojection_errors([b], [view])["reprojection_rms_px"]
        if after > before + ROUND_OFF_PX:
            return (
                f"camera {camera.name}: held-out reprojection error {after:.3f} px is worse than "
                f"the camera's registration on the nominal robot ({before:.3f} px)"
            )
    return None


def _starts(chains, cameras):
    """Each camera's starting placement (given, the URDF's link, or None), lens and name."""
    guesses = tuple(
        c.placement if c.placement is not None else camera_placement(ch, c.name, c.link)
        for ch, c in zip(chains, cameras, strict=True)
    )
    return guesses, tuple(c.intrinsics.camera for c in cameras), tuple(c.name for c in cameras)


def calibrate_pixels(
    chain: Chain | tuple[Chain, ...],
    camera: PixelCamera | tuple[PixelCamera, ...],
    target: Target,
    obs: PixelObservations,
    *,
    validate: PixelObservations | None = None,
    holdout: float = 0.0,
    what: Unknowns = KNOWN,
    seed: int = 0,
    refuse: bool = True,
) -> PixelCalibration:
    """Calibrate the robot and the cameras' placements from the cameras' pixels.

    Several cameras (a camera in the cell and one on the head) see one target; every joint
    placement is shared by the chains through it, fitted once.

    Args:
        chain: From each camera's link to the tool that carries the target (one per camera).
        camera: The camera, or one per chain.
        target: The target points in the tool frame [m].
        obs: The observations (each camera's rows are used).
        validate: Held-out observations, or None.
        holdout: Fraction of the postures held out when there is no ``validate``.
        what: The optional unknowns: the target's mounting on its link (``--params
            complete``; the fitted points are the report's ``targets``), the target points
            after the first three (``--refine-targets``), the intrinsics
            (``--refine-intrinsics``).
        seed: Seed of the holdout.
        refuse: Raise on a refused model; False: return it with its ``refusal``.

    Raises:
        DataError: See :func:`pixel_rows` and :func:`~.pixel_fit.fit_pixels`.
        CalibrationRefusedError: A camera's held-out reprojection error is worse than its
            registration's on the nominal robot (with ``refuse``).
    """
    chains = chain if isinstance(chain, tuple) else (chain,)
    cameras = camera if isinstance(camera, tuple) else (camera,)
    if len(chains) != len(cameras) or len({c.name for c in cameras}) != len(cameras):
        raise InvalidArgumentError("give one chain per camera, and each camera once")
    views, held = _views(chains, cameras, target, obs, validate, holdout, seed)
    guesses, lenses, names = _starts(chains, cameras)
    start = (Placements.of(chains), target.position, guesses)
    dropped: tuple[int, ...] = ()
    for _ in range(3):
        fit = fit_pixels(*start, views, lenses, names, what, obs.source)
        bad = _outliers(fit, views, target.normal)
        if not any(b.any() for b in bad):
            break
        for view, b in zip(views, bad, strict=True):
            dropped += tuple(n for n, x in zip(view.rows.lines, b, strict=True) if x)
        views = tuple(
            PixelView(v.chain, v.rows.subset(~b)) for v, b in zip(views, bad, strict=True)
        )
    result = PixelCalibration(cameras, views, held, fit, tuple(sorted(dropped)), what)
    refusal = _refusal(result)
    if refusal is not None and refuse:
        raise CalibrationRefusedError(f"{refusal}: no URDF written")
    return dataclasses.replace(result, refusal=refusal)
