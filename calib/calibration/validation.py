"""Validation: held-out configurations, predicted uncertainty, and the checks a model must pass.

Rationale and measurements: docs/developers/engine.md#validation
"""

from __future__ import annotations

from pathlib import Path
from typing import Protocol, Self, TypeVar

import numpy as np
from scipy.spatial import cKDTree

from ..core.words import counted
from ..exceptions import DataError, InvalidArgumentError, warn_user
from ..kinematics.robot import Chain
from ..measurements.contact_campaign import ContactData
from ..measurements.data import DataWarning, Measurements
from ..measurements.pixels import PixelObservations
from ..measurements.postures import posture_groups
from .diagnosis import suspect
from .residuals import ResidualStats
from .solve import FitState
from .term_checks import file_lines

__all__ = [
    "ABOVE_NOISE",
    "HELD_OUT_RATIO",
    "ORIENTATION_REFUSED",
    "RANK_TOL",
    "ROUND_OFF",
    "ROWS",
    "SAME",
    "TOUCHES",
    "UNMODELLED",
    "check_fitted_errors",
    "check_held_out",
    "check_held_out_errors",
    "far_above_noise",
    "predicted_std",
    "split",
    "stats",
    "worse",
]

COPY = 1e-6
"""Largest difference [rad, m, px] of every value of a validation row from a training row's copy."""

SAME = 1e-6
"""Relative difference of two RMS errors under which they are the same (solver round-off)."""

ROUND_OFF = 1e-12
"""Absolute difference [m, rad] under which two RMS errors are the same (noise-free: 1e-13)."""

ROWS = (
    "validation rows",
    "model",
    "they look measured in another measurement frame (the instrument moved?) or on another robot",
)
"""Held-out rows of an instrument far off (:func:`check_held_out_errors`' words)."""

TOUCHES = ("held-out touches", "contact", "touched another object, or on another robot?")
"""Held-out touches far off (:func:`check_held_out_errors`' words)."""

HELD_OUT_RATIO = 3.0
"""How many times the fitted rows' RMS the held-out rows' must exceed to be of another frame.
Rationale and measurements: docs/developers/engine.md#held_out_ratio"""


def worse(after: float, before: float, unit: float = 1.0) -> bool:
    """Whether an RMS error ``after`` is worse than ``before`` beyond round-off (in ``unit``)."""
    return after > before * (1 + SAME) + ROUND_OFF / unit


RANK_TOL = 1e-9
"""Smallest singular value, relative to the largest, of the unit-norm columns of a fit."""


class _Rows(Protocol):
    """Rows recorded at postures: measurements, or a pixel term's rows."""

    @property
    def q(self) -> np.ndarray: ...

    @property
    def m(self) -> int: ...

    def subset(self, keep: np.ndarray) -> Self: ...


_R = TypeVar("_R", bound=_Rows)


def split(data: _R, fraction: float, seed: int) -> tuple[_R, _R | None]:
    """Set aside a seeded random ``fraction`` of the postures (training, held out).

    A posture recorded several times (or a tree's tools at one posture) leaves with all its rows.

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


UNSEEN = 1e4
"""A coordinate [m] no marker has (beyond ``MAX_COORDINATE``): a marker not seen's, compared."""


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
    parts = [data.q, np.nan_to_num(data.position, nan=UNSEEN)]  # unseen: as another unseen
    if data.quaternion is not None:
        parts.append(data.quaternion)
    return np.hstack(parts), data.tool


def check_held_out(data, held) -> None:
    """Refuse validation data that are the training data: the file, or any of its rows.

    Measurements, touches and pixels alike; a row is the same within :data:`COPY`.

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
            f"(row {file_lines(held)[i]} is row {file_lines(data)[j]} of {data.source}): held out "
            f"must mean held out",
        )
    _warn_seen_postures(data, held)


def _warn_seen_postures(data, held) -> None:
    """Warn of validation rows at postures of the data, measured again (not unseen postures).

    A same seed's simulations draw the same first configurations: a random campaign and a
    check campaign of its seed share them, and the check would score seen postures.
    """
    a, b = np.asarray(data.q, dtype=float), np.asarray(held.q, dtype=float)
    if a.ndim != 2 or b.ndim != 2 or a.shape[1] != b.shape[1] or not len(a) or not len(b):
        return
    groups = posture_groups(np.vstack([a, b]))  # one posture as everywhere else in calib
    seen = int(np.isin(groups[len(a) :], groups[: len(a)]).sum())
    if seen:
        warn_user(
            f"{held.source}: {seen} of the {len(b)} validation rows are at postures of the "
            f"data (the same joint values): their errors are not those of unseen postures",
            DataWarning,
        )


def check_held_out_errors(
    fitted: float, held: float, source: str, words: tuple[str, str, str] = ROWS
) -> None:
    """Stop on held-out errors far above any geometric error and the fitted rows' errors.

    ``fitted``, ``held``: the rows' RMS position errors (touches: gaps) [m]; ``words``:
    :data:`ROWS` or :data:`TOUCHES`.

    Raises:
        DataError: The held-out error is suspect (measured in another frame, or of another
            robot) and the fitted one is not; names ``source`` (the held-out data).
    """
    if suspect(held, None) and not suspect(fitted, None) and held > HELD_OUT_RATIO * fitted:
        rows, missed, cause = words
        raise DataError(
            source,
            f"the {rows} are {1e3 * held:.4g} mm RMS from the registered {missed} (the data "
            f"{1e3 * fitted:.4g} mm): {cause}",
        )


ORIENTATION_REFUSED = 0.5
"""RMS orientation error [rad] (29 deg) both the registration and the model missing is refused.
Rationale and measurements: docs/developers/engine.md#orientation_refused"""


def check_fitted_errors(
    stats: dict, n_markers: int | None, noise: float | None, source: str, chain: Chain
) -> None:
    """Stop on data whose fitted rows the calibrated model still misses absurdly.

    ``stats``: a term's ``train_registration`` and ``train`` errors; ``n_markers``: None for
    touches (their gaps are read); ``noise`` [m] or None.
    Rationale and measurements: docs/developers/engine.md#check_fitted_errors

    Raises:
        DataError: Registered and calibrated errors both suspect, or orientations both over
            :data:`ORIENTATION_REFUSED`; names ``source`` and the way out.
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


ABOVE_NOISE = 10.0
"""Times the noise given [per axis] the calibrated rows' noise estimate must exceed to be said.
Rationale and measurements: docs/developers/engine.md#above_noise"""

UNMODELLED = 0.005
"""RMS error per point [m] a calibrated model of a real robot may leave whatever the noise given
(its errors beyond the geometry): under it nothing is said. Measurements: as ``ABOVE_NOISE``."""


def far_above_noise(
    residuals: np.ndarray, n_markers: int, unknowns: int, noise: float | None
) -> str | None:
    """The warning of fitted rows the calibrated model misses far above the noise given, or None.

    ``residuals``: the rows fitted ``(m, 3 K [+ 3])`` [m, rad] (NaN: a marker not seen);
    ``unknowns``: the fit's; ``noise`` [m per axis] or None (nothing said). With the noise
    right, ``RSS / noise^2`` of the positions is chi-square with their share of the fit's
    ``rows - unknowns`` degrees of freedom.
    """
    if noise is None:
        return None
    positions = residuals[:, : 3 * n_markers]
    seen = positions[~np.isnan(positions)]
    rows = seen.size + len(residuals) * (residuals.shape[1] - positions.shape[1])
    free = seen.size * max(rows - unknowns, 1) / rows
    rss = float(seen @ seen)
    per_point = np.sqrt(3 * rss / seen.size)
    ratio = np.sqrt(rss / free) / noise
    if ratio <= ABOVE_NOISE or per_point <= UNMODELLED:
        return None
    return (
        f"the calibrated model misses the rows fitted by {1e3 * per_point:.4g} mm RMS, "
        f"{ratio:.3g} times the noise given ({1e3 * noise:.3g} mm per axis): the model lacks "
        "something the data show: a joint left out of the chain or one too many, the marker "
        "on another link, a marker moved during the campaign, or lengths in other units? "
        "(or the robot's errors beyond its geometry: compliance, backlash)"
    )


def stats(
    state: FitState, data: Measurements, torque: np.ndarray | None, kin=None
) -> ResidualStats:
    """Errors measured - model of a state on some data (``kin``: its kinematics there, if made)."""
    return ResidualStats.of(state.residuals(data, torque, kin), data.n_markers)


def predicted_std(
    J_points: np.ndarray, covariance: np.ndarray, n_markers: int, seen: int | None = None
) -> float:
    """RMS over configurations and points of the predicted position std [m]: trace(J C J^T).

    ``seen``: the points measured, when some marker was not seen in some row (its rows 0).
    """
    if covariance.size == 0:
        return 0.0
    if not np.all(np.isfinite(covariance)):
        return float("inf")
    Jp = J_points[:, : 3 * n_markers]
    var = np.einsum("mrp,pq,mrq->m", Jp, covariance, Jp)
    if seen is not None:
        return float(np.sqrt(np.sum(var) / seen))
    return float(np.sqrt(np.mean(var / n_markers)))
