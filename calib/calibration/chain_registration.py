"""A chain calibration's registration: the measurement frame and markers on the nominal model.

The registration is the closed-form fit refined by Levenberg-Marquardt (frame and markers only),
preceded by the diagnosis of the usual mistakes in the data (swapped joint columns, degrees,
millimetres, quaternion order) and followed by the outlier rows set aside. The orientation
weight is estimated from it when not given.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable

import numpy as np

from ..exceptions import DataError
from ..identification.parameters import ParameterSet, parameter_set
from ..measurements.csvfile import Measurements
from . import determined, diagnosis, outliers, validation, weighting
from .model import ErrorModel, moved
from .options import Options
from .registration import register
from .solve import Fit, fit, row_weights

__all__ = [
    "checked_registration",
    "frames_model",
    "held_out_outliers",
    "proposals",
]


def frames_model(data: Measurements, opts: Options) -> ErrorModel:
    """The registration's free parameters: frame, markers (and measured-frame rotation)."""
    return ErrorModel(
        ParameterSet("none", ()),
        (),
        np.zeros((0, 0)),
        frame="frame" not in opts.fix,
        markers="markers" not in opts.fix,
        tool="tool" not in opts.fix,
        n_markers=data.n_markers,
        kind=data.kind,
    )


def _registration(nominal, data, guess, opts, kin=None) -> Fit:
    """Closed-form registration refined by Levenberg-Marquardt (frame and markers only).

    ``kin``: the nominal kinematics at the data's joints, if already made (the fit's is
    that: it moves no geometry).
    """
    if kin is None:
        kin = nominal.kinematics(data.q)
    start = register(nominal, data.q, data.points, data.rotations, guess, kin)
    if "frame" in opts.fix:
        start = dataclasses.replace(start, frame=np.eye(4))
    if "markers" in opts.fix:
        start = dataclasses.replace(start, markers=guess)
    return fit(
        frames_model(data, opts),
        start,
        data,
        None,
        opts.orientation_weight,
        max_iterations=opts.max_iterations,
        kin=kin,
    )


def _registrations(nominal, data, guess, opts) -> Callable[[float], Fit]:
    """The registration of one data set at an orientation weight, each weight run once.

    The nominal kinematics at the data's joints are made once for all.
    """
    kin = nominal.kinematics(data.q)

    @functools.cache
    def at(weight: float) -> Fit:
        w_opts = dataclasses.replace(opts, orientation_weight=weight)
        return _registration(nominal, data, guess, w_opts, kin)

    return at


_WORDS = diagnosis.Words(mistakes="swapped joint columns, degrees, millimetres, quaternion order")


def _diagnose(chain, nominal, data, guess, opts, at) -> list[str]:
    """Raise the likely mistake if the data cannot be registered; a note if none explains it.

    It runs at the default orientation weight: an estimated weight would let wrong
    orientations (e.g. quaternions in the wrong order) weigh nothing and go unnoticed. The
    points are diagnosed first, then the orientations (on the orientation error).
    """
    opts = dataclasses.replace(opts, orientation_weight=weighting.DEFAULT_WEIGHT)

    def errors(d):
        return validation.stats(_registration(nominal, d, guess, opts).state, d, None)

    def position(d) -> float:
        return errors(d).position_rms

    reg = at(weighting.DEFAULT_WEIGHT)
    first = validation.stats(reg.state, data, None, reg.kin)
    revolute = chain.sigma == 0
    notes = diagnosis.explain(
        data, revolute, position, first.position_rms, opts.noise, _WORDS, joints_only=False
    )
    if notes:  # the positions are suspect (else no note): the orientations are not read
        return notes
    rot = first.orientation_rms
    if rot is not None and rot > diagnosis.ORIENTATION_SUSPECT:
        cause = diagnosis.likely_cause(
            data, revolute, lambda d: errors(d).orientation_rms, rot, orientation=True
        )
        if cause is not None:
            raise DataError(
                data.source,
                f"the data look like {cause[0]}: the registration's orientation error drops "
                f"from {np.degrees(rot):.4g} deg to {np.degrees(cause[1]):.4g} deg RMS once "
                f"corrected",
            )
        return [
            f"the registration leaves {np.degrees(rot):.4g} deg RMS of orientation error, far "
            f"above geometric errors, and no usual mistake (quaternion order, degrees, rpy "
            f"order) explains it: check the orientation columns"
        ]
    return []


def checked_registration(chain, nominal, train, checked, guess, opts):
    """Weight, registration, outliers set aside, then the diagnosis (data and ``checked``).

    The outliers are set aside before any diagnosis: one bad row is not a mistake of the
    whole file.

    Returns:
        The options with the orientation weight, the registration state, the mask of the
        outlier rows of ``train`` and the notes.
    """
    at = _registrations(nominal, train, guess, opts)
    opts = _weighted(train, opts, at)
    reg, bad, suspect = _cleaned(chain, nominal, train, guess, opts, at)
    diagnosed = _diagnose_validation(chain, nominal, checked, guess, opts)
    if not reg.converged:
        raise DataError(train.source, f"the registration did not converge ({reg.message})")
    return opts, reg.state, bad, suspect + diagnosed


def _diagnose_validation(chain, nominal, held, guess, opts) -> list[str]:
    """The diagnosis of validation data (``held``: (data, label) or None), noted by label."""
    if held is None:
        return []
    frames = frames_model(held[0], opts)
    if held[0].m * frames.rows <= frames.size():  # too few rows to register on their own
        return []
    at = _registrations(nominal, held[0], guess, opts)
    notes = _cleaned(chain, nominal, held[0], guess, opts, at, frames)[2]
    return [f"{held[1]}: {n}" for n in notes]


def _cleaned(chain, nominal, data, guess, opts, at, frames=None):
    """The registration without its outlier rows, their mask, the diagnosis of the rest."""
    reg, bad = _register(nominal, data, guess, opts, at, frames)
    kept = data.subset(~bad) if bad.any() else data
    same = at if kept is data else _registrations(nominal, kept, guess, opts)
    return reg, bad, _diagnose(chain, nominal, kept, guess, opts, same)


def _weighted(data, opts: Options, at) -> Options:
    """The options with the orientation weight: given, or estimated from the registration."""
    if opts.orientation_weight is not None:
        return opts
    weight = weighting.DEFAULT_WEIGHT
    if data.quaternion is not None:
        weight = weighting.estimate_weight(
            lambda w: at(w).state.residuals(data, None, at(w).kin), data.n_markers
        )
    return dataclasses.replace(opts, orientation_weight=weight)


def _register(nominal, data, guess, opts, at, frames=None) -> tuple[Fit, np.ndarray]:
    """The registration (``at``: the data set's by weight) without the outlier rows (a mask).

    ``frames``: the registration's model, when the outliers may not leave fewer equations
    than its unknowns (validation data: no error, the outliers stay); else that is an error.
    """

    def refit(keep: np.ndarray) -> Fit:
        if keep.all():
            return at(opts.orientation_weight)
        sub = data.subset(keep)
        frames = frames_model(sub, opts)
        what = "measurement frame and marker parameters once the outliers are set aside"
        determined.check_equations(sub.m, frames.rows, frames.size(), what, sub.source)
        return _registration(nominal, sub, guess, opts)

    nominal_kin = at(opts.orientation_weight).kin  # every registration's, on the data

    def errors(reg: Fit) -> outliers.Errors:
        return outliers.point_errors(reg.state.residuals(data, None, nominal_kin), data.n_markers)

    def allowed(bad: np.ndarray) -> bool:
        return frames is None or int(np.sum(~bad)) * frames.rows > frames.size()

    rows = data.rows or tuple(range(1, data.m + 1))
    reg, bad, _ = outliers.until_stable(refit, errors, opts.noise, rows, allowed=allowed)
    return reg, bad


def proposals(nominal, reg, data: Measurements, opts) -> np.ndarray:
    """Rows a robust fit of every identifiable parameter, linearised, finds outlying.

    None where no row of the registration is far from the others
    (:func:`.outliers.spread_out`): outliers that could mask each other stand out there.
    """
    kin = reg.kinematics(data.q)  # x = 0 is the registration
    residuals = reg.residuals(data, None, kin)
    if not outliers.spread_out(outliers.point_errors(residuals, data.n_markers)):
        return np.zeros(data.m, dtype=bool)
    pset = parameter_set(nominal, "complete")
    base, lift = moved(pset, nominal)
    wide = frames_model(data, opts).with_(params=pset, base=base, lift=lift)
    w = row_weights(wide, opts.orientation_weight)
    J = wide.jacobian(reg, np.zeros(wide.size()), data, None, reg, kin) * w[None, :, None]
    rows = data.rows or tuple(range(1, data.m + 1))
    return outliers.robust_proposals(
        J[:, :, determined.determined_columns(J)],
        residuals * w,
        lambda r: outliers.point_errors(r, data.n_markers),
        opts.noise,
        rows,
    )


def held_out_outliers(reg, train, held, opts, notes: list[str]):
    """The held-out rows without their outliers (:func:`.outliers.held_out_outliers`)."""
    if held is None:
        return None
    data, label = held
    k = train.n_markers
    rows = data.rows or tuple(range(1, data.m + 1))
    bad, dropped = outliers.held_out_outliers(
        outliers.point_errors(reg.residuals(train), k),
        outliers.point_errors(reg.residuals(data), k),
        opts.noise,
        rows,
    )
    if not dropped:
        return held
    notes.append(outliers.held_out_note(dropped))
    return data.subset(~bad), label
