"""A pixel term's registration and outliers: its camera placed, the term fitted alone.

Both fits are the engine's (:func:`~.solve.fit`) on one chain, the rows in pixels.
How and why: docs/developers/engine.md#pixel_fit
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..core.words import counted, noun
from ..exceptions import DataError
from ..identification.pinhole import Pinhole
from ..kinematics.placement_export import camera_placement
from ..kinematics.robot import Chain
from . import determined, diagnosis, outliers, term_checks
from .engine_model import ChainsData, ChainsState
from .pixel_chain import (
    PixelKind,
    PixelPart,
    PixelTermState,
    camera_points,
    free_columns,
    pixel_block,
    pixel_jacobian,
)
from .placements import Placements
from .registration import nearest_rotation
from .solve import fit, unconverged
from .term_checks import Aside

__all__ = [
    "MAX_EVALUATIONS",
    "ROUND_OFF_PX",
    "checked_pixels",
]

UNDISTORT_ITERATIONS = 20
"""Newton steps that invert the distortion (each pixel's ray)."""

MAX_EVALUATIONS = 200
"""Most residual evaluations of a fit."""

ROUND_OFF_PX = 1e-6
"""Pixel errors below 6 times this [px] are round-off, never outliers (a noise-free fit leaves
1e-12 px, of which one may be 5 times the median), far below any detector's noise."""


def _rays(camera: Pinhole, pixels: np.ndarray) -> np.ndarray:
    """Each pixel's ray ``(a, b)`` ``(m, 2)``: Newton on ``pinhole((a, b, 1)) = pixel``."""
    ab = (pixels - [camera.cx, camera.cy]) / [camera.fx, camera.fy]
    for _ in range(UNDISTORT_ITERATIONS):
        seen = camera.projection(np.column_stack([ab, np.ones(len(ab))]), derivatives=True)
        J = np.asarray(seen.d_point)[:, :, :2]
        step = np.linalg.solve(J, (pixels - seen.pixels)[..., None])[..., 0]
        ab = ab + step
        if np.max(np.abs(step), initial=0.0) < 1e-15:
            break
    return ab


def _camera_from_rays(points: np.ndarray, ab: np.ndarray, source: str) -> np.ndarray:
    """The camera's placement in the points' frame ``(4, 4)`` from their rays (DLT, closed form).

    Raises:
        DataError: Fewer than 6 points, or points on one plane or line (no unique solution).
    """
    if len(points) < 6:
        raise DataError(source, f"{len(points)} observations cannot place a camera (at least 6)")
    centre = points.mean(axis=0)
    scale = np.sqrt(3) / max(float(np.mean(np.linalg.norm(points - centre, axis=1))), 1e-12)
    P = np.column_stack([(points - centre) * scale, np.ones(len(points))])
    A = np.zeros((2 * len(P), 12))
    A[0::2, 0:4], A[0::2, 8:12] = -P, ab[:, :1] * P
    A[1::2, 4:8], A[1::2, 8:12] = -P, ab[:, 1:] * P
    _, s, Vt = np.linalg.svd(A, full_matrices=False)
    if s[-2] < 1e-6 * s[0]:
        raise DataError(
            source, "the points seen lie on one plane or line: give the camera's placement"
        )
    normalise = np.eye(4)
    normalise[:3, :3] *= scale
    normalise[:3, 3] = -scale * centre
    M = Vt[-1].reshape(3, 4) @ normalise
    if np.median(np.column_stack([points, np.ones(len(points))]) @ M[2]) < 0:
        M = -M
    seen = np.eye(4)  # the points' frame in the camera
    seen[:3, :3] = nearest_rotation(M[:, :3])
    seen[:3, 3] = M[:, 3] / np.linalg.svd(M[:, :3], compute_uv=False).mean()
    return np.linalg.inv(seen)


@dataclass(frozen=True, eq=False)
class _Steps:
    """The columns ``free`` of :func:`~.pixel_chain.pixel_jacobian` as a model of one term."""

    free: tuple[int, ...]

    def size(self) -> int:
        return len(self.free)

    def _moves(self, start: ChainsState, x: np.ndarray):
        """Joint-column mask, their components, others' own places, own unknowns."""
        n, free = start.placements.y.size, np.asarray(self.free, dtype=int)
        joint = (free >= 6) & (free < 6 + n)
        own_cols = _term(start).own_columns(n)
        at = np.searchsorted(own_cols, free[~joint])
        own = np.zeros(own_cols.size)
        own[at] = x[~joint]
        return joint, free[joint] - 6, at, own

    def apply(self, start: ChainsState, x: np.ndarray) -> ChainsState:
        joint, comps, _, own = self._moves(start, x)
        dy = np.zeros(start.placements.y.size)
        dy[comps] = x[joint]
        placements, term = start.placements.shifted(dy), _term(start).moved(own)
        return dataclasses.replace(start, placements=placements, states=(term,))

    def jacobian(self, start: ChainsState, x, data: ChainsData, torque=None, state=None, kin=None):
        """d(pixel)/dx ``(m, 2, free)`` [px per unit] (``state``, ``kin``: at x, if made)."""
        if state is None:
            state = self.apply(start, x)
        if kin is None:
            kin = state.kinematics(data)
        joint, comps, at, own = self._moves(start, x)
        lift = np.eye(start.placements.y.size)[comps]
        J = np.empty((data.m, 2, len(self.free)))
        by_own, J[:, :, joint] = pixel_block(
            state.placements,
            start.chains[0],
            _term(state),
            _term(start),
            own,
            data.parts[0],
            lift,
            kin[0],
        )
        J[:, :, ~joint] = by_own[:, :, at]
        return J


def _term(state: ChainsState) -> PixelTermState:
    return cast(PixelTermState, state.states[0])


def _fitted(chain: Chain, placements, term: PixelTermState, part: PixelPart, free, kin):
    """One pixel term fitted alone, weight 1 (rows in pixels), on its columns ``free``."""
    start = ChainsState((chain,), placements, (dataclasses.replace(term, weight=1.0),))
    return fit(
        _Steps(tuple(free)),
        start,
        ChainsData((part,)),
        None,
        max_iterations=MAX_EVALUATIONS,
        kin=(kin,),
    )


def _registered(chain: Chain, part: PixelPart, strict: bool = True) -> PixelTermState:
    """The camera placed on the nominal robot (given, the URDF's, or closed form), refined.

    Raises:
        DataError: Rows whose point is at or behind the camera so placed (the first's line),
            or (``strict``) a refinement stopped by its cap, as a measured chain's registration.
    """
    cam, rows = part.data.camera, part.rows
    placements = Placements.of((chain,))
    kin = placements.frames(chain, rows.q)
    lens, X = cam.intrinsics.camera, part.data.target.position
    guess, check = cam.placement, "check the camera's link and the placement given"
    if guess is None:
        guess, check = camera_placement(chain, cam.name, cam.link), "check the camera's link"
    if guess is None:
        p_link = camera_points(kin, np.eye(4), X[rows.point])[1]
        guess = _camera_from_rays(p_link, _rays(lens, rows.pixels), part.source)
        check = (
            "the camera placed from the pixels alone does not see them in front of it: check "
            "the camera's link and the target's points in the tool frame, or give the "
            "camera's placement (--camera NAME LINK INTRINSICS X Y Z RX RY RZ; Python: "
            "PixelCamera(..., placement))"
        )
    behind = np.flatnonzero(camera_points(kin, guess, X[rows.point])[0][:, 2] <= 0)
    if len(behind):
        raise DataError(
            part.source,
            f"{counted(len(behind), 'observations')} {noun(len(behind), 'see', 'sees')} a point "
            f"behind the camera on the starting model (first: row {rows.lines[behind[0]]}): "
            f"{check}",
        )
    mdh = placements.chain_models((chain,))[0]
    start = PixelTermState(mdh, guess, X, lens, 1.0)
    refined = _fitted(chain, placements, start, part, range(6), kin)
    stopped = strict and unconverged(refined, f"camera {cam.name}'s registration", hint=False)
    if stopped:
        raise DataError(part.source, stopped)
    camera = _term(refined.state).camera
    p_cam = camera_points(kin, camera, X[rows.point])[0]
    weight = float(np.median(p_cam[:, 2])) / (0.5 * (lens.fx + lens.fy))
    return PixelTermState(mdh, camera, X, lens, weight, part.data.what)


@dataclass(frozen=True, eq=False)
class _Joints:
    """A pixel term's joint columns, as the usual mistakes (:mod:`.diagnosis`) read them."""

    joint_names: tuple[str, ...]
    q: np.ndarray
    source: str
    path: str | None = None
    rows: tuple[int, ...] | None = None

    @property
    def m(self) -> int:
        return len(self.q)


def _rms_m(state: PixelTermState, part: PixelPart) -> float:
    """RMS reprojection error of the rows [m at the target]."""
    return float(np.sqrt(2 * np.mean(state.pixel_errors(part) ** 2)) * state.weight)


_WORDS = diagnosis.Words(
    "pixels",
    "row of the pixels",
    "error at the target",
    check="the pixels, the camera's link and the target",
    ends=("camera", "target"),
)


def _explain(chain: Chain, part: PixelPart, first: float) -> list[str]:
    """:func:`~.diagnosis.explain` of the rows' joint columns (``first``: error [m])."""

    def error(fixed: object, on: Chain = chain) -> float:  # the registration's, joints corrected
        data = part.data
        if on.base_frame != data.camera.link:  # on the link beyond, placed from the pixels
            moved = dataclasses.replace(data.camera, link=on.base_frame, placement=None)
            data = dataclasses.replace(data, camera=moved)
        rows = PixelPart(data, dataclasses.replace(part.rows, q=cast(_Joints, fixed).q))
        return _rms_m(_registered(on, rows, strict=False), rows)

    def other(longer: Chain):
        return lambda fixed: error(fixed, longer)

    obs = part.data.obs
    joints = _Joints(chain.joint_names, part.rows.q, part.source, obs.path, part.rows.lines)
    notes = diagnosis.explain(joints, chain, error, first, None, _WORDS, other=other)
    return [f"camera {part.data.camera.name}: {n}" for n in notes]


def _from_behind(state: PixelTermState, part: PixelPart) -> np.ndarray:
    """Rows whose point's outward normal (the target's) faces away from the camera."""
    normals = part.data.target.normal
    if normals is None:
        return np.zeros(part.m, dtype=bool)
    kin = state.mdh.kinematics(part.rows.q)
    n_cam = np.einsum("ji,mjk,mk->mi", state.camera[:3, :3], kin.R[:, -1], normals[part.rows.point])
    return np.einsum("mi,mi->m", n_cam, state.seen(part, kin)) >= 0


def _judged(chain: Chain, state: PixelTermState, part: PixelPart, held):
    """Each row's error [m at the target] on the term's own fit, the held-out rows', why stopped."""
    placements = Placements.of((chain,))
    kin = placements.frames(chain, part.rows.q)
    J = pixel_jacobian(placements, state, chain, part.rows, kin=kin)[1]
    free = free_columns(J.reshape(-1, J.shape[2]), placements, state.what)
    own = _fitted(chain, placements, state, part, free, kin)
    stopped = not own.converged and (
        f"camera {part.data.camera.name}: the term's own fit did not converge "
        f"({own.message}): it proposed no outliers"
    )
    judged = (part,) if held is None or stopped else (part, held)  # stopped: no held verdict
    errors = [
        np.linalg.norm(own.state.residuals(ChainsData((p,))), axis=1) * state.weight for p in judged
    ]
    return errors[0], errors[1] if len(errors) > 1 else None, stopped or None


def _size(part: PixelPart) -> int:
    """The camera's unknowns (placement, mounting, target points) of a pixel term."""
    return len(PixelKind(len(part.data.target.position), 0, part.data.what).names())


@dataclass(frozen=True, eq=False)
class _Camera:
    """A pixel term's steps (:class:`~.term_checks.Steps`); ``held``: held-out rows or None."""

    chain: Chain
    rows: PixelPart
    held: PixelPart | None

    diagnose_first = True

    def register(self) -> PixelTermState:
        """The camera registered; a failed registration is diagnosed too.

        Raises:
            DataError: The mistake named, or the registration's own error.
        """
        try:
            return _registered(self.chain, self.rows)
        except DataError:
            _explain(self.chain, self.rows, np.inf)
            raise

    def diagnose(self, rows: PixelPart, state: PixelTermState) -> list[str]:
        return _explain(self.chain, rows, _rms_m(state, rows))

    def set_aside(self, state: PixelTermState) -> Aside[PixelPart, PixelTermState]:
        """Rows seen from behind or far off the own fit set aside (:func:`checked_pixels`)."""
        chain, part, held = self.chain, self.rows, self.held
        behind = _from_behind(state, part)
        notes: list[str] = []
        away = None if held is None else _from_behind(state, held)
        if held is not None and away is not None and away.any():  # no held-out verdict on them
            notes.append(f"held out: {_behind_note(np.asarray(held.rows.lines)[away], part)}")
            held = None if away.all() else held.subset(~away)
        errors, e_held, stopped = _judged(chain, state, part, held)
        floor = ROUND_OFF_PX * state.weight  # as the instrument noise: 6 x it, never an outlier
        pixel = outliers.Errors(errors, None, (2, 3))
        none: tuple = (np.zeros(part.m, dtype=bool), [])  # a stopped fit's errors: not the data's
        bad, found = none if stopped else outliers.find_outliers(pixel, floor, part.rows.lines)
        found = [dataclasses.replace(o, kind="pixels") for o in found]  # set aside on pixels
        found += [
            outliers.Outlier(
                part.rows.lines[i], float(errors[i]), float(np.median(errors)), "from behind"
            )
            for i in np.flatnonzero(behind & ~bad)
        ]
        bad = bad | behind
        kept = part
        if bad.any():
            if part.m - int(bad.sum()) < _size(part):
                raise DataError(part.source, f"camera {part.data.camera.name}: too few rows kept")
            kept = part.subset(~bad)
            state = _registered(chain, kept)
        notes += [stopped] if stopped else []
        if held is not None and e_held is not None:
            fitted, other = (outliers.Errors(e, None, (2, 3)) for e in (errors[~bad], e_held))
            held = term_checks.held_out(fitted, other, held, held.rows.lines, notes)
        found.sort(key=lambda o: o.row)
        return Aside(state, bad, kept, tuple(found), held, tuple(notes))


def checked_pixels(chain: Chain, part: PixelPart, held):
    """A pixel term's registration and outliers, as :func:`~.measured_term.checked_measured`."""
    what = f"unknowns of camera {part.data.camera.name}'s placement"
    determined.check_equations(
        part.m,
        2,
        _size(part),
        what,
        part.source,
        held=0 if held is None else held.m,
        unit="observations",
    )
    aside, notes = term_checks.checked(_Camera(chain, part, held))
    found = list(aside.found)
    far = [o for o in found if o.kind != "from behind"]
    away = [o.row for o in found if o.kind == "from behind"]
    notes += [outliers.set_aside_note(far)] if far else []
    notes += [_behind_note(np.array(away), part)] if away else []
    return aside.state, aside.kept, found, notes, aside.held


def _behind_note(lines: np.ndarray, part: PixelPart) -> str:
    """``3 rows seen from behind set aside (...): rows 4, 9, 12``: file ``lines``."""
    rows = outliers.listed([str(line) for line in lines])
    return (
        f"{counted(len(lines), 'rows')} seen from behind set aside (the target's normals face "
        f"away from camera {part.data.camera.name}): {noun(len(lines), 'rows')} {rows}"
    )
