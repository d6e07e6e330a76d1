"""Validation: held-out configurations, predicted uncertainty, and the checks a model must pass.

A model is written only if it converged, fits the training data no worse than the
registration, has every fitted parameter identified and is no worse held out (:func:`worse`);
data that no calibration brings near the robot stop with a DataError
(:func:`check_fitted_errors`).

Rationale and measurements: docs/developers/engine.md#validation
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol, Self, TypeVar

import numpy as np
from scipy.spatial import cKDTree

from ..core.words import counted
from ..exceptions import DataError, InvalidArgumentError
from ..kinematics.robot import Chain
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from ..measurements.pixels import PixelObservations
from ..measurements.postures import posture_groups
from .diagnosis import suspect
from .residuals import ResidualStats
from .solve import FitState

__all__ = [
    "ORIENTATION_REFUSED",
    "RANK_TOL",
    "ROUND_OFF",
    "ROWS",
    "SAME",
    "TOUCHES",
    "check_fitted_errors",
    "check_held_out",
    "check_held_out_errors",
    "predicted_std",
    "split",
    "stats",
    "worse",
]

COPY = 1e-6
"""Largest difference [rad, m, px] of every value of a validation row from a training row's
that makes it that row (a copy, perhaps rounded to 6 decimals); an instrument's repeated
reading of one posture differs by its noise, far more."""

SAME = 1e-6
"""Relative difference of two RMS errors under which they are the same (solver round-off)."""

ROUND_OFF = 1e-12
"""Absolute difference [m, rad] under which two RMS errors are the same: a noise-free fit's
errors (a few 1e-13) are round-off, not a worse model."""

ROWS = (
    "validation rows",
    "model",
    "they look measured in another measurement frame (the instrument moved?) or on another robot",
)
"""Held-out rows of an instrument far off (:func:`check_held_out_errors`' words)."""

TOUCHES = ("held-out touches", "contact", "touched another object, or on another robot?")
"""Held-out touches far off (:func:`check_held_out_errors`' words)."""


def worse(after: float, before: float, unit: float = 1.0) -> bool:
    """Whether an RMS error is worse than another beyond round-off (the one refusal rule).

    ``after``: the calibrated model's, ``before``: the registration's, in ``unit`` [m or rad].
    """
    return after > before * (1 + SAME) + ROUND_OFF / unit


RANK_TOL = 1e-9
"""Smallest singular value, relative to the largest, of the unit-norm columns of a fit."""


class _Rows(Protocol):
    """Rows recorded at postures: measurements, or a pixel term's rows."""

    @property
    def q(self) -> np.ndarray: ...

    @property
    def tool(self) -> Any: ...

    @property
    def m(self) -> int: ...

    def subset(self, keep: np.ndarray) -> Self: ...


_R = TypeVar("_R", bound=_Rows)


def split(data: _R, fraction: float, seed: int) -> tuple[_R, _R | None]:
    """Set aside a seeded random ``fraction`` of the postures (training, held out).

    A posture recorded several times (:func:`~calib.measurements.postures.posture_groups`)
    is held out with all its rows: none of its repeats is left to train on, nor (a tree) the
    rows of its other tools. ``data``: measurements, or a pixel term's rows (every point seen
    in an image: one posture).

    Raises:
        InvalidArgumentError: ``fraction`` outside [0, 1), or > 0 but holding out no row.
    """
    if not (0.0 <= fraction < 1.0):
        raise InvalidArgumentError(f"the holdout fraction must be in [0, 1), got {fraction!r}")
    groups = posture_groups(data.q)  # a tree's tools at one posture: one posture
    postures = int(groups.max(initial=-1)) + 1
    n_out = round(fraction * postures)
    if n_out == 0 and fraction > 0.0:
        distinct = f" ({counted(postures, 'postures')})" if postures < data.m else ""
        raise InvalidArgumentError(
            f"holdout {fraction:g} of {data.m} rows{distinct} holds out no row: give at least "
            f"{1.0 / postures:.3g} (one {'posture' if distinct else 'row'}), or 0 for no holdout"
        )
    if n_out == 0:
        return data, None
    out = np.random.default_rng([seed, 3]).permutation(postures)[:n_out]
    held = np.isin(groups, out)
    return data.subset(~held), data.subset(held)


def _same_file(a: str, b: str) -> bool:
    try:
        return Path(a).is_file() and Path(b).is_file() and Path(a).samefile(b)
    except OSError:
        return False


def _values(data) -> tuple[np.ndarray, tuple[str, ...] | None]:
    """Each row's numbers (joints, points, quaternion; pixels) and label (tool, id; camera)."""
    if isinstance(data, ContactData):
        return data.q, data.ids
    if isinstance(data, PixelObservations):
        labels = tuple(f"{c}\0{p}" for c, p in zip(data.camera, data.point, strict=True))
        return np.hstack([data.q, data.pixels]), labels
    parts = [data.q, data.position]
    if data.quaternion is not None:
        parts.append(data.quaternion)
    return np.hstack(parts), data.tool


def _row(data, i: int) -> int:
    """Row of configuration (or touch) i in its source (i + 1 without a file)."""
    return data.rows[i] if data.rows is not None else i + 1


def check_held_out(data, held) -> None:
    """Refuse validation data that are the training data: the file, or any of its rows.

    Measurements, touches and pixels alike (:class:`Measurements`, :class:`ContactData` or
    :class:`PixelObservations` of any kind): a validation row that is a training row (the
    same joint values, and the same measurements, tool or touched object; or the same
    camera, point and pixel; each number within :data:`COPY`: a copy rounded to 6
    decimals) is refused.

    Raises:
        DataError: ``held`` comes from the training file, or a row of it is a training row.
    """
    # rows of one file split by the caller (cross-validation folds) are held out; without row
    # numbers the rows themselves are compared (below)
    shared = set(data.rows or ()) & set(held.rows or ())
    if shared and _same_file(data.source, held.source):
        raise DataError(
            held.source,
            "the validation file is the data file: held out must mean held out (give other "
            "configurations, or a holdout fraction)",
        )
    (a, la), (b, lb) = _values(data), _values(held)
    if la is not None and lb is not None:
        index = {t: float(i) for i, t in enumerate(sorted(set(la) | set(lb)))}
        a = np.hstack([a, [[index[t]] for t in la]])
        b = np.hstack([b, [[index[t]] for t in lb]])
    if a.shape[1] != b.shape[1]:
        return
    gap, nearest = cKDTree(a).query(b, p=np.inf, distance_upper_bound=COPY)
    repeated = np.isfinite(gap)
    if np.any(repeated):
        i = int(np.argmax(repeated))
        j = int(nearest[i])
        raise DataError(
            held.source,
            f"{int(repeated.sum())} of the {held.m} validation rows are rows of the data "
            f"(row {_row(held, i)} is row {_row(data, j)} of {data.source}): held out must "
            f"mean held out",
        )


def check_held_out_errors(
    fitted: float, held: float, source: str, words: tuple[str, str, str] = ROWS
) -> None:
    """Stop on held-out errors far above any geometric error while the data fit well.

    Each file passed the usual-mistake diagnosis on its own registration: held-out rows that
    the training registration still misses by more than ``diagnosis.SUSPECT`` were measured
    in another frame or of another robot: a DataError names ``source`` (the held-out data)
    when their error is absurd and the fitted rows' is not.

    Args:
        fitted: The fitted rows' RMS position error (a touch's: gap) [m].
        held: The held-out rows' [m].
        source: The held-out data.
        words: The held-out rows, the registered thing they miss and the likely cause
            (:data:`ROWS`; touches: :data:`TOUCHES`).
    """
    if suspect(held, None) and not suspect(fitted, None):
        rows, missed, cause = words
        raise DataError(
            source,
            f"the {rows} are {1e3 * held:.4g} mm RMS from the registered {missed} (the data "
            f"{1e3 * fitted:.4g} mm): {cause}",
        )


ORIENTATION_REFUSED = 0.5
"""RMS orientation error [rad] (29 deg) over which orientations that the registration and the
calibrated model both miss are refused (:func:`check_fitted_errors`).
Rationale and measurements: docs/developers/engine.md#orientation_refused"""


def check_fitted_errors(
    stats: dict, n_markers: int | None, noise: float | None, source: str, chain: Chain
) -> None:
    """Stop on data whose fitted rows the calibrated model still misses absurdly.

    Registration suspect (:func:`~.diagnosis.suspect`), no usual mistake found, and the
    calibrated model suspect too on its training rows: a DataError names ``source`` and the
    way out (the instrument's noise). Orientations registered and calibrated over
    :data:`ORIENTATION_REFUSED` are refused on their own (way out: the positions alone).
    Rationale and measurements: docs/developers/engine.md#check_fitted_errors

    Args:
        stats: A term's ``train_registration`` and ``train`` errors
            (:func:`~.contact_result.part_stats`).
        n_markers: The points of an instrument's row (their RMS position error is read), or
            None (touches: their gap's RMS length).
        noise: The instrument's noise [m], or None.
        source: The data.
        chain: The chain they were fitted to (its base and tool named).
    """

    def rms(key: str) -> tuple[float, float | None]:  # [m], [rad] (None: positions only)
        if n_markers is None:
            return 1e-3 * stats[key].length_rms_mm, None
        found = ResidualStats.of(stats[key].residuals, n_markers)
        return found.position_rms, found.orientation_rms

    (registration, turned), (calibrated, turns) = rms("train_registration"), rms("train")
    ends = f"{chain.base_frame} -> {chain.tool_frame}: the calibrated model still misses them by"
    if suspect(registration, noise) and suspect(calibrated, noise):
        way_out = (
            "two objects logged under one id?"
            if n_markers is None
            else "an instrument this noisy? give its noise (noise_mm)"
            if noise is None
            else "an instrument noisier than the noise given?"
        )
        raise DataError(
            source,
            f"the data do not match {ends} {1e3 * calibrated:.4g} mm RMS (registered: "
            f"{1e3 * registration:.4g} mm): another robot's data, another tool or arm, or "
            f"{way_out}",
        )
    if turned is not None and turns is not None and min(turned, turns) > ORIENTATION_REFUSED:
        raise DataError(
            source,
            f"the orientations do not match {ends} {np.degrees(turns):.4g} deg RMS "
            f"(registered: {np.degrees(turned):.4g} deg): another frame's orientations, or "
            "another convention? fit the positions alone (the data's position_only())",
        )


def stats(
    state: FitState, data: Measurements, torque: np.ndarray | None, kin=None
) -> ResidualStats:
    """Errors measured - model of a state on some data.

    ``kin``: its kinematics at the data's joints, if already made (a fit's
    :attr:`~.solve.Fit.kin`).
    """
    return ResidualStats.of(state.residuals(data, torque, kin), data.n_markers)


def predicted_std(J_points: np.ndarray, covariance: np.ndarray, n_markers: int) -> float:
    """RMS over configurations and points of the predicted position std [m].

    sqrt(mean over points of trace(J_k C J_k^T)): the RMS distance between the predicted and
    the true point that the parameter uncertainty alone explains. ``J_points`` ``(m, rows,
    p)``: its first 3 K rows are points (``n_markers``: K); ``covariance`` ``(p, p)``.
    """
    if covariance.size == 0:
        return 0.0
    if not np.all(np.isfinite(covariance)):
        return float("inf")
    Jp = J_points[:, : 3 * n_markers]
    var = np.einsum("mrp,pq,mrq->m", Jp, covariance, Jp) / n_markers
    return float(np.sqrt(np.mean(var)))
