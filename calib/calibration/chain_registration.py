"""A chain calibration's registration: the measurement frame and markers on the nominal model.

The registration is the closed-form fit refined by Levenberg-Marquardt (frame and markers only).
The orientation weight is estimated from it when not given; then the steps of every kind of
term (:mod:`.term_checks`): the outlier rows set aside, the usual mistakes (swapped joint
columns, degrees, millimetres, quaternion order, orientation columns) diagnosed in the rows
kept, the validation rows likewise.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..exceptions import DataError
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..measurements.csvfile import Measurements
from . import determined, diagnosis, outliers, term_checks, validation, weighting
from .model import ErrorModel, moved
from .options import Options
from .registration import register
from .solve import Fit, fit, row_weights
from .term_checks import Aside

__all__ = [
    "checked_registration",
    "frames_model",
    "held_out_outliers",
    "proposals",
]


def frames_model(data: Measurements) -> ErrorModel:
    """The registration's free parameters: frame, markers (and measured-frame rotation).

    The registration fits them all (``fix`` of the frame or the markers is refused before
    any registration, :func:`~.measured_options.asked_of`).
    """
    return ErrorModel(
        ParameterSet("none", ()), (), np.zeros((0, 0)), n_markers=data.n_markers, kind=data.kind
    )


def _registration(nominal, data, guess, opts, kin=None, start=None) -> Fit:
    """Closed-form registration refined by Levenberg-Marquardt (frame and markers only).

    ``kin``: the nominal kinematics at the data's joints, if already made (the fit's is
    that: it moves no geometry). ``start``: the closed-form registration of these rows, if
    already made (it does not depend on the orientation weight).
    """
    if kin is None:
        kin = nominal.kinematics(data.q)
    if start is None:
        start = register(nominal, data.q, data.points, data.rotations, guess, kin)
    model = frames_model(data)
    w, n = opts.orientation_weight, opts.max_iterations
    return fit(model, start, data, None, w, max_iterations=n, kin=kin)


def _registrations(nominal, data, guess, opts) -> Callable[[float], Fit]:
    """The registration of one data set at an orientation weight, each weight run once.

    The nominal kinematics at the data's joints and the closed-form start are made once for
    all weights (the start on the first registration).
    """
    kin = nominal.kinematics(data.q)

    @functools.cache
    def start():
        return register(nominal, data.q, data.points, data.rotations, guess, kin)

    @functools.cache
    def at(weight: float) -> Fit:
        w_opts = dataclasses.replace(opts, orientation_weight=weight)
        return _registration(nominal, data, guess, w_opts, kin, start())

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


@dataclass(frozen=True, eq=False)
class _Rows:
    """A chain's steps on one set of measurements (:class:`~.term_checks.Steps`).

    Attributes:
        chain: The chain.
        nominal: Its nominal model.
        rows: The measurements.
        guess: The markers' guess in the tool frame [m].
        opts: The options (with the orientation weight).
        at: The registrations of ``rows`` by weight (:func:`_registrations`).
        frames: The registration's model, when the outliers may not leave fewer equations
            than its unknowns (validation data: no error, the outliers stay); else None
            (that is an error).
    """

    chain: Chain
    nominal: MDHModel
    rows: Measurements
    guess: np.ndarray
    opts: Options
    at: Callable[[float], Fit]
    frames: ErrorModel | None = None

    diagnose_first = False

    def register(self) -> Fit:
        """The registration of every row at the options' weight."""
        return self.at(cast(float, self.opts.orientation_weight))  # weighted: a number

    def set_aside(self, state: Fit) -> Aside[Measurements, Fit]:
        """The registration without the outlier rows, until stable (:mod:`.outliers`)."""
        nominal, data, guess, opts = self.nominal, self.rows, self.guess, self.opts

        def refit(keep: np.ndarray) -> Fit:
            if keep.all():
                return state
            sub = data.subset(keep)
            frames = frames_model(sub)
            what = "measurement frame and marker parameters once the outliers are set aside"
            determined.check_equations(sub.m, frames.rows, frames.size(), what, sub.source)
            return _registration(nominal, sub, guess, opts)

        def errors(reg: Fit) -> outliers.Errors:  # every registration's kin: the nominal's
            residuals = reg.state.residuals(data, None, state.kin)
            return outliers.point_errors(residuals, data.n_markers)

        def allowed(bad: np.ndarray) -> bool:
            f = self.frames
            return f is None or int(np.sum(~bad)) * f.rows > f.size()

        rows = data.rows or tuple(range(1, data.m + 1))
        reg, bad, _ = outliers.until_stable(refit, errors, opts.noise, rows, allowed=allowed)
        return Aside(reg, bad, data.subset(~bad) if bad.any() else data)

    def diagnose(self, rows: Measurements, state: Fit) -> list[str]:
        """The usual mistakes of the rows kept (:func:`_diagnose`)."""
        nominal, guess, opts = self.nominal, self.guess, self.opts
        same = self.at if rows is self.rows else _registrations(nominal, rows, guess, opts)
        return _diagnose(self.chain, nominal, rows, guess, opts, same)


def checked_registration(chain, nominal, train, checked, guess, opts):
    """Weight, registration, outliers set aside, then the diagnosis (data and ``checked``).

    The steps of every kind of term (:func:`~.term_checks.checked`), the orientation weight
    estimated before.

    Returns:
        The options with the orientation weight, the registration state, the mask of the
        outlier rows of ``train``, the notes and the nominal kinematics at ``train``'s joints
        (the registration's, at every row: its geometry is the nominal one).
    """
    at = _registrations(nominal, train, guess, opts)
    opts = _weighted(train, opts, at)
    steps = _Rows(chain, nominal, train, guess, opts, at)
    validate = _validation_steps(chain, nominal, checked, guess, opts)
    aside, notes = term_checks.checked(steps, validate)
    reg = aside.state
    if not reg.converged:
        raise DataError(train.source, f"the registration did not converge ({reg.message})")
    return opts, reg.state, aside.bad, notes, steps.register().kin


def _validation_steps(chain, nominal, held, guess, opts) -> list[tuple[_Rows, str]]:
    """The steps on validation data (``held``: (data, label) or None), with their label."""
    if held is None:
        return []
    frames = frames_model(held[0])
    if held[0].m * frames.rows <= frames.size():  # too few rows to register on their own
        return []
    at = _registrations(nominal, held[0], guess, opts)
    return [(_Rows(chain, nominal, held[0], guess, opts, at, frames), held[1])]


def _weighted(data, opts: Options, at) -> Options:
    """The options with the orientation weight: given, or estimated from the registration."""
    if opts.orientation_weight is not None:
        return opts
    weight = weighting.DEFAULT_WEIGHT
    if data.quaternion is not None:
        weight = weighting.estimate_weight(
            lambda w: at(w).state.residuals(data, None, at(w).kin),
            weighting.pose_angles(data.n_markers),
        )
    return dataclasses.replace(opts, orientation_weight=weight)


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
    wide = frames_model(data).with_(params=pset, base=base, lift=lift)
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


def held_out_outliers(reg, train, held, opts, notes: list[str], kin=None):
    """The held-out rows without their outliers (:func:`.term_checks.held_out`).

    ``kin``: ``reg``'s kinematics at ``train``'s joints, if already made.
    """
    if held is None:
        return None
    data, label = held
    k = train.n_markers
    rows = data.rows or tuple(range(1, data.m + 1))
    fitted = outliers.point_errors(reg.residuals(train, None, kin), k)
    errors = outliers.point_errors(reg.residuals(data), k)
    kept = term_checks.held_out(fitted, errors, data, rows, data.subset, notes, opts.noise)
    return held if kept is data else (kept, label)
