"""The engine's outlier loop: each term's outliers set aside after each fit, until stable.

Rationale and measurements: docs/developers/engine.md#chain_outliers
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable
from typing import cast

import numpy as np

from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from . import determined, term_checks
from .chain_registration import MeasuredState
from .choice import chains_model
from .contact_checks import enough_touches, length_errors
from .contact_model import ContactState
from .engine_model import ChainsData, ChainsState
from .engine_result import ChainContacts, ContactChainsCalibration
from .measured_options import compliance_torques
from .measured_view import MeasuredChain
from .outliers import (
    Errors,
    find_outliers,
    point_errors,
    records,
    robust_proposals,
    set_aside_note,
    spread_out,
    stable_set,
)
from .pixel_chain import PixelPart, PixelTermState, pixel_parts
from .pixel_chain_result import PixelChain
from .pixel_fit import ROUND_OFF_PX
from .register import Registered, Run, drawn, register_contact_chains

__all__ = ["fit_terms_until_stable", "proposals"]


def proposals(start: ChainsState, c: int, data: Measurements, noise: float | None) -> np.ndarray:
    """Rows a robust fit of term ``c``'s identifiable parameters at ``start`` finds outlying.

    None (an all-False mask) where no row of the registration is far from the others
    (:func:`~.outliers.spread_out`); ``noise``: the instrument's [m], or None.
    """
    state = cast(MeasuredState, start.states[c])
    residuals = state.inner.residuals(data, None, state.frames_at(data))  # the registration's
    if not spread_out(point_errors(residuals, data.n_markers)):
        return np.zeros(data.m, dtype=bool)
    alone = dataclasses.replace(start, chains=(start.chains[c],), states=(state,), scales=None)
    names = start.placements.names()
    wide = chains_model(alone, (0,), range(len(names)), names)
    J = wide.jacobian(alone, np.zeros(wide.size()), ChainsData((data,)))
    seen = data.seen_rows(residuals.shape[1])  # a marker not seen: its rows 0 (no equation)
    return robust_proposals(
        J[:, :, determined.determined_columns(J)],
        (residuals if seen is None else np.where(seen, residuals, 0.0)) * state.row_weights(),
        lambda r: point_errors(r, data.n_markers),
        noise,
        term_checks.file_lines(data),
    )


def fit_terms_until_stable(
    run: Run, fit: Callable[[Registered], ContactChainsCalibration]
) -> ContactChainsCalibration:
    """The run's fit without the rows each term's errors under it find outlying.

    Each term's outliers in the fit returned are the loop's and its registration's.
    """
    first = register_contact_chains(run)
    again, train = _drawn(run)
    torque = compliance_torques(run.chains, train, [None] * len(train), run.options, first.load)
    ends = np.cumsum([0, *(d.m for d in train)])
    parts = [slice(a, b) for a, b in itertools.pairwise(ends)]
    rows = [d.rows.lines if isinstance(d, PixelPart) else term_checks.file_lines(d) for d in train]
    noise = [  # the rule's floor [m]: none for touches, a pixel term's as checked_pixels's
        None
        if isinstance(d, ContactData)
        else ROUND_OFF_PX * s.weight
        if isinstance(d, PixelPart)
        else run.options.noise
        for d, s in zip(train, first.start.states, strict=True)
    ]
    errors = _term_errors(train, torque[0][0])
    terms = zip(train, first.start.states, first.dropped, rows, noise, strict=True)
    masks = [_aside(*t, first.start, c) for c, t in enumerate(terms)]
    retest = any(isinstance(s, MeasuredState) for s in first.start.states)
    inner, start = (np.concatenate([m[k] for m in masks]) for k in (0, 1))
    fitted: list[ContactChainsCalibration] = []

    def refit(keep: np.ndarray) -> ContactChainsCalibration:
        if np.array_equal(~keep, inner):  # those that stay aside alone: the first fit
            fitted[:] = fitted or [fit(first)]
            return fitted[0]
        kept = [_as_data(d.subset(keep[p])) for d, p in zip(train, parts, strict=True)]
        return fit(register_contact_chains(dataclasses.replace(again, data=kept)))

    def rule(result: ContactChainsCalibration) -> np.ndarray | None:
        if result.stalled:  # gaps where a fit stopped, or of the parameters held after: none
            return None
        found = zip(errors(result), noise, rows, strict=True)
        return inner | np.concatenate([find_outliers(e, n, r)[0] for e, n, r in found])

    def allowed(bad: np.ndarray) -> bool:
        pairs = zip(train, parts, strict=True)
        return all(enough_touches(d)(bad[p]) for d, p in pairs if isinstance(d, ContactData))

    result, bad = stable_set(refit, rule, start, allowed)
    if np.array_equal(bad, inner) and not retest:
        return result
    return _recorded(result, errors(result), [bad[p] for p in parts], rows)


def _aside(data, state, dropped, rows, noise, start, c) -> tuple[np.ndarray, np.ndarray]:
    """A term's rows that stay aside, and those the loop starts without (masks of ``rows``)."""
    if isinstance(state, MeasuredState):
        return np.zeros(len(rows), dtype=bool), proposals(start, c, data, noise)
    inner = np.isin(rows, [o.row for o in dropped])
    return inner, inner


def _drawn(run: Run) -> tuple[Run, list]:
    """The run with its held-out rows drawn (given as validation rows), and its training rows."""
    opts = run.options
    parts = pixel_parts(run.chains, run.data)
    if opts.holdout == 0:
        return run, parts
    splits = drawn(parts, opts.holdout, opts.seed)  # as the registration draws them
    once = dataclasses.replace(opts, holdout=0.0)  # drawn here, not again
    held = [_as_data(s[1]) for s in splits]
    again = dataclasses.replace(run, validate=held, options=once, held_label="holdout")
    return again, [s[0] for s in splits]


def _as_data(rows):
    """A term's rows as a run's data: a pixel term's as PixelData (others, None: as they are)."""
    return rows.as_data() if isinstance(rows, PixelPart) else rows


def _term_errors(train: list, torque) -> Callable[[ContactChainsCalibration], list[Errors]]:
    """Each term's errors at every training row under a fit (the last one's kept)."""
    last: list = []

    def errors(result: ContactChainsCalibration) -> list[Errors]:
        if last and last[0] is result:
            return last[1]
        solution = result.solution
        if solution is None:  # fit_registered always keeps it
            raise ValueError("a joint fit's result without its solution")
        parts = result.chains  # measured parts keep their fitted states (settled once)
        measured = all(isinstance(p, MeasuredChain) for p in parts)
        states = (
            [p.state for p in cast(tuple[MeasuredChain, ...], parts)]
            if measured
            else solution.fit.state.settled().states
        )
        found = []
        for c, (s, d, part) in enumerate(zip(states, train, parts, strict=True)):
            tau = torque if c == 0 else None
            if isinstance(s, ContactState):
                found.append(length_errors(s, d, tau))
            elif isinstance(s, PixelTermState):  # each point's reprojection error at the target
                found.append(Errors(np.linalg.norm(s.residuals(d), axis=1), None, (2, 3)))
            else:  # a measured term's: its fit's own (kept by its part) if it fitted d, rigid
                r = part.residuals if isinstance(part, MeasuredChain) and part.data is d else None
                r = s.inner.residuals(d, tau) if r is None or tau is not None else r
                found.append(point_errors(r, d.n_markers))
        last[:] = [result, found]
        return found

    return errors


def _recorded(result: ContactChainsCalibration, found: list[Errors], bad: list, rows: list):
    """The result with each term's outliers recorded anew (the fit's errors), notes replaced."""
    chains, notes = list(result.chains), list(result.notes)
    for c, part in enumerate(result.chains):
        inner = np.isin(rows[c], [o.row for o in part.outliers])
        new = tuple(records(found[c], bad[c] | inner, rows[c]))
        if isinstance(part, PixelChain):  # set aside on pixels; seen from behind stays so
            behind = {o.row: o for o in part.outliers if o.kind == "from behind"}
            new = tuple(behind.get(o.row, dataclasses.replace(o, kind="pixels")) for o in new)
        if not new or new == part.outliers:
            continue
        words = ("touches", "gap") if isinstance(part, ChainContacts) else ()
        head = f"{part.chain.base_frame} -> {part.chain.tool_frame}: "
        old = head + set_aside_note(part.outliers, *words) if part.outliers else None
        notes = [n for n in notes if n != old] + [head + set_aside_note(new, *words)]
        chains[c] = dataclasses.replace(part, outliers=new)
    return dataclasses.replace(result, chains=tuple(chains), notes=tuple(notes))
