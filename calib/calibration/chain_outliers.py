"""One chain measured by an instrument: outliers set aside after each fit, until stable.

The joint engine sets a measured term's outliers aside at its registration
(:func:`~.measured_term.checked_measured`), where the geometric errors not yet fitted hide
them (20 mm among 3.6 mm of them is not five times the median). As the chain's calibration
always has (issue 29), the rows are tested again under each fit (every row: those set aside
too, predicted) and the fit is made again without the outliers found, until the set stops
changing (:func:`~.outliers.until_stable`), from the rows a robust fit of every identifiable
parameter, linearised at the registration, finds outlying (outliers that could mask each
other: :func:`proposals`). The held-out rows are drawn once, before
(:func:`fit_until_stable` takes the training rows).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import cast

import numpy as np

from ..identification.parameters import parameter_set
from ..measurements.data import Measurements
from . import determined
from .chain_registration import frames_model
from .contact_chains_result import ContactChainsCalibration
from .contact_register import Registered
from .measured_term import MeasuredState
from .measured_view import gravity_torque
from .model import moved
from .options import Options
from .outliers import (
    point_errors,
    records,
    robust_proposals,
    set_aside_note,
    spread_out,
    until_stable,
)
from .solve import row_weights

__all__ = ["fit_until_stable", "proposals"]


def fit_until_stable(
    register: Callable[[Measurements], Registered],
    fit: Callable[[Registered], ContactChainsCalibration],
    train: Measurements,
    noise_mm: float | None,
) -> ContactChainsCalibration:
    """The fit of the training rows without the outliers its errors find (module text).

    The proposals read the registration of every row only: the fit of every row is made
    only if the loop comes to it (no proposal, or a later round keeping every row).

    Args:
        register: The joint fit's checks and registration of some of the rows (one chain
            measured by an instrument: :func:`~.contact_chains.register_contact_chains`).
        fit: The rest of the joint fit (:func:`~.contact_chains.fit_registered`).
        train: Every training row.
        noise_mm: Instrument noise [mm], or None (unknown).

    Returns:
        The last fit; its outliers (and their note) every row set aside, by the loop or by
        the last fit's registration.
    """
    rows = train.rows or tuple(range(1, train.m + 1))
    every = register(train)
    first: list[ContactChainsCalibration] = []

    def refit(keep: np.ndarray) -> ContactChainsCalibration:
        if not keep.all():
            return fit(register(train.subset(keep)))
        if not first:
            first.append(fit(every))
        return first[0]

    last: list = []  # the last fit and its errors: the loop and its end read them again

    def errors(result: ContactChainsCalibration):
        if last and last[0] is result:
            return last[1]
        state = result.state  # with fitted compliance: deflected by the rows' gravity torques
        torque = gravity_torque(result.chain, state, train)
        part = result.one_chain()  # its rigid residuals, when it fitted every row
        residuals = part.residuals if torque is None and part.data is train else None
        if residuals is None:
            residuals = state.residuals(train, torque)
        last[:] = [result, point_errors(residuals, train.n_markers)]
        return last[1]

    registered = cast(MeasuredState, every.start.states[0])  # as its fit's result reports it
    opts = Options(orientation_weight=registered.weight, noise_mm=noise_mm)
    kin = registered.frames_at(train)  # the registration's, at every row
    start = proposals(registered.inner.mdh, registered.inner, train, opts, kin)
    result, bad, _ = until_stable(refit, errors, opts.noise, rows, start)
    part = result.one_chain()
    inner = np.isin(rows, [o.row for o in part.outliers])
    found = tuple(records(errors(result), bad | inner, rows))
    if not found or found == part.outliers:
        return result
    head = f"{part.chain.base_frame} -> {part.chain.tool_frame}: "
    old = head + set_aside_note(part.outliers) if part.outliers else None
    notes = (*(n for n in result.notes if n != old), head + set_aside_note(found))
    chains = (dataclasses.replace(part, outliers=found), *result.chains[1:])
    return dataclasses.replace(result, chains=chains, notes=notes)


def proposals(nominal, reg, data: Measurements, opts, kin=None) -> np.ndarray:
    """Rows a robust fit of every identifiable parameter, linearised, finds outlying.

    None where no row of the registration is far from the others
    (:func:`.outliers.spread_out`): outliers that could mask each other stand out there.
    ``kin``: ``reg``'s kinematics at ``data``'s joints, if already made.
    """
    if kin is None:
        kin = reg.kinematics(data.q)  # x = 0 is the registration
    residuals = reg.residuals(data, None, kin)
    if not spread_out(point_errors(residuals, data.n_markers)):
        return np.zeros(data.m, dtype=bool)
    pset = parameter_set(nominal, "complete")
    base, lift = moved(pset, nominal)
    wide = frames_model(data.n_markers, data.kind).with_(params=pset, base=base, lift=lift)
    w = row_weights(wide, opts.orientation_weight)
    J = wide.jacobian(reg, np.zeros(wide.size()), data, None, reg, kin) * w[None, :, None]
    rows = data.rows or tuple(range(1, data.m + 1))
    return robust_proposals(
        J[:, :, determined.determined_columns(J)],
        residuals * w,
        lambda r: point_errors(r, data.n_markers),
        opts.noise,
        rows,
    )
