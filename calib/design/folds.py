"""K-fold cross-validation of a calibration: every posture held out once, errors pooled.

:func:`cross_validate` splits each term's postures into K contiguous folds (the rows of one
posture together; a chain touching: each object's touches, a repeated touch whole, as the
holdout draws them; given a seed, the postures shuffled by it first), fits the problem K
times, each fold's rows given as its validation data and the others fitted with the same
options, and pools the held-out errors of the K fits (the calibrated model's and the
registration's on the same rows). The model delivered is the fit on every row; it is refused
where the pooled held-out error is worse than the registration's (the rule a held-out file's
errors obey, :func:`~calib.calibration.contact_checks.held_out_refusal`), where a fold's fit
is refused for another reason (it stalled: its held-out errors are no fitted model's), or for
its own reasons.

It is a driver of fits, as :func:`~calib.design.design.evaluate` is a driver of
information matrices: the calibration's pipeline is run as it is, K + 1 times.
"""

from __future__ import annotations

import dataclasses
import numbers
from collections.abc import Callable, Sequence
from typing import Any, cast

import numpy as np

from ..calibration.contact_checks import few_postures, held_out_refusal
from ..calibration.contact_result import GapStats
from ..calibration.engine import NOTHING_HELD
from ..calibration.engine_result import ChainContacts, ContactChainsCalibration
from ..calibration.entry import calibrate
from ..calibration.measured_view import MeasuredChain
from ..calibration.problem import Problem, Term
from ..calibration.solve import unconverged
from ..core.checks import check_count, shown
from ..exceptions import DataError, InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Angles, Measurements
from ..measurements.postures import count, posture_groups

__all__ = ["NOT_WITH", "cross_validate", "fold_of_rows", "k_fold", "pooled"]


def fold_of_rows(data, folds: int, seed: int | None = None) -> np.ndarray:
    """The fold (0 .. ``folds`` - 1) of each row of a term's data ``(m,)``: contiguous postures.

    Measurements: the postures in order of first appearance, split into ``folds``
    runs of sizes differing by one at most (``numpy.array_split``); touches: each object's
    touches so (a touch repeated counts once). ``seed``: the postures shuffled first
    (``numpy.random.default_rng(seed).permutation``, each object's in turn), so that the
    folds are drawn at random; None: contiguous, in file order.

    Raises:
        InvalidArgumentError: ``folds`` under 2 or over the postures (an object's touches),
            or a bad seed.
    """
    if isinstance(folds, bool) or not isinstance(folds, numbers.Integral):
        raise InvalidArgumentError(
            f"the number of folds must be a whole number, got {shown(folds)}"
        )
    if not isinstance(data, Measurements | ContactData):
        raise InvalidArgumentError(
            f"folds are for measurements and touches, not {type(data).__name__} (pixels: "
            "hold rows out with holdout or validate)"
        )
    rng = None if seed is None else np.random.default_rng(check_count(seed, "the seed", 0))
    touches = isinstance(data, ContactData)
    ids = data.ids if isinstance(data, ContactData) else None
    groups = posture_groups(data.q, ids)
    keys = np.zeros(data.m, dtype=int) if ids is None else np.array(ids)
    out = np.zeros(data.m, dtype=int)
    for key in dict.fromkeys(keys.tolist()):
        own = np.unique(groups[keys == key])  # numbered in order of first appearance
        if folds < 2 or folds > len(own):
            what = f"touches of '{key}'" if touches else "postures"
            raise InvalidArgumentError(
                f"the number of folds must be in [2, {len(own)}] (the {what} in "
                f"{data.source}), got {shown(folds)}"
            )
        if rng is not None:
            own = rng.permutation(own)
        for k, part in enumerate(np.array_split(own, folds)):
            out[np.isin(groups, part)] = k
    return out


def pooled(parts: list[GapStats]) -> GapStats:
    """The errors of several sets of rows as one set: RMS over every row, largest of all."""
    m = np.array([p.m for p in parts], dtype=float)

    def rms(values) -> float:
        return float(np.sqrt(np.sum(m * np.asarray(values, dtype=float) ** 2) / np.sum(m)))

    first = parts[0]
    rows = [p.residuals for p in parts if p.residuals is not None]
    per_row = [p.per_row for p in parts if p.per_row is not None]
    return GapStats(
        int(m.sum()),
        first.names,
        first.angular,
        tuple(rms([p.rms[i] for p in parts]) for i in range(len(first.names))),
        tuple(max(p.max[i] for p in parts) for i in range(len(first.names))),
        rms([p.weighted_mm for p in parts]),
        np.concatenate(per_row) if len(per_row) == len(parts) else None,
        np.concatenate(rows) if len(rows) == len(parts) else None,
    )


def _stacked(parts: list[Measurements]) -> Measurements:
    """Measurements of one term's rows one after the other (a measured term's held rows)."""
    first = parts[0]
    angles = first.angles

    def joined(name: str):
        values = [getattr(p, name) for p in parts]
        return None if values[0] is None else np.concatenate(values)

    return dataclasses.replace(
        first,
        q=joined("q"),
        position=joined("position"),
        quaternion=joined("quaternion"),
        rows=tuple(int(r) for p in parts for r in p.file_rows()),
        tool=None if first.tool is None else tuple(t for p in parts for t in p.tool or ()),
        angles=(
            None
            if angles is None
            else Angles(angles.format, np.concatenate([_angles(p) for p in parts]))
        ),
    )


def _angles(data: Measurements) -> np.ndarray:
    """The angle columns of rows read with them ``(m, 3)``."""
    return cast(Angles, data.angles).values


Fit = Callable[[list, list | None], ContactChainsCalibration]
"""A fit of a problem's terms: their data, and their validation data (None: none)."""

NOT_WITH = "folds hold every posture out in turn: not with holdout or validate (a term's too)"
"""The one text of folds with held-out rows of another kind (the command line says it with its
flags: :data:`calib.cli.flags.FLAGS`)."""


def k_fold(
    fit: Fit, data: Sequence, folds: int, seed: int | None = None
) -> ContactChainsCalibration:
    """``fit`` of every row, its held-out errors the pooled ones of ``folds`` fits (module text).

    Args:
        fit: The fit of the terms' data, each given its validation data (or None: none) and
            the same options every time.
        data: Each term's data (measurements or touches).
        folds: K, in [2, postures] (each term's; touches: each object's).
        seed: The postures shuffled by it before they are cut (each term's alike); None:
            contiguous folds, in file order.

    Raises:
        InvalidArgumentError: ``folds`` out of range, a bad seed, or data of another kind
            (pixels).
    """
    labels = [fold_of_rows(d, folds, seed) for d in data]
    full = fit(list(data), None)
    runs = [_fold(fit, data, labels, k, folds) for k in range(folds)]
    label = f"{folds} folds" if seed is None else f"{folds} folds, seed {seed}"
    result = _pooled_result(full, runs, label)
    few = [_few_trained(d, f, folds) for d, f in zip(data, labels, strict=True)]
    return dataclasses.replace(result, notes=(*result.notes, *filter(None, few)))


def _few_trained(data, labels: np.ndarray, folds: int) -> str | None:
    """The note of a term whose smallest fold's fit trains on few postures (few_postures)."""
    fewest = min(
        (data.subset(labels != k) for k in range(folds)),
        key=lambda rows: count(rows.q, rows.ids if isinstance(rows, ContactData) else None),
    )
    return few_postures(fewest, "the folds' verdict is of fits on as few as")


def _fold(fit: Fit, data: Sequence, labels: list, k: int, folds: int):
    """The fit of fold ``k`` held out; a DataError of its rows says which fold it is."""
    pairs = list(zip(data, labels, strict=True))
    try:
        return fit([d.subset(f != k) for d, f in pairs], [d.subset(f == k) for d, f in pairs])
    except DataError as exc:
        where = str(DataError(exc.path, "", exc.row, exc.column))
        reason = str(exc).removeprefix(where)
        raise DataError(
            exc.path, f"fold {k + 1} of {folds}: {reason}", exc.row, exc.column
        ) from None


def cross_validate(
    robot: Problem | Chain | Tree,
    data=None,
    *,
    folds: int = 5,
    seed: int | None = None,
    **options,
) -> ContactChainsCalibration:
    """Calibrate on every row, and score the model by K-fold cross-validation (module text).

    Args:
        robot: A :class:`~calib.calibration.problem.Problem` (its options inside it), or the
            nominal chain or tree of a problem of one term.
        data: Its data (not with a problem).
        folds: K, in [2, postures] (each term's; touches: each object's).
        seed: Random folds: the postures shuffled by it before they are cut (each term's
            alike; with a robot and its data, the problem's ``seed`` too, as ``calibrate``'s).
            None (default): contiguous folds in file order, the problem's seed its own.
        options: :func:`~calib.calibrate`'s (``progress`` included; not
            ``holdout`` nor ``validate``).

    Returns:
        The fit on every row, its held-out errors the pooled ones of the K fits (source
        ``K folds``, each fold's in the report's ``errors.held_out.folds``) and its refusal:
        its own, else a fold's fit's other than by its held-out errors (``fold k of K: ...``),
        else that of the pooled errors.

    Raises:
        InvalidArgumentError: ``folds`` out of range, with ``holdout`` or ``validate``, or a
            bad option.
        DataError: Data a fit of the folds refuses (too few rows left to fit, ...).
    """
    progress = options.pop("progress", None)
    if options.pop("validate", None) is not None:
        raise InvalidArgumentError(NOT_WITH)
    if isinstance(robot, Problem):
        if data is not None or options:
            raise InvalidArgumentError(
                "cross_validate(problem) takes the problem alone: its data and options are in it"
            )
        problem = robot
    else:
        if data is None:
            raise InvalidArgumentError("cross_validate takes a Problem, or a robot and its data")
        marker = options.pop("marker", None)
        if seed is not None:
            options["seed"] = seed
        problem = Problem((Term(robot, data, None, marker),), **options)
    if problem.holdout > 0 or any(t.validate is not None for t in problem.terms):
        raise InvalidArgumentError(NOT_WITH)

    def fit(rows: list, held: list | None) -> ContactChainsCalibration:
        given = [None] * len(rows) if held is None else held
        terms = tuple(
            dataclasses.replace(t, data=d, validate=v)
            for t, d, v in zip(problem.terms, rows, given, strict=True)
        )
        return calibrate(dataclasses.replace(problem, terms=terms), progress=progress)

    return k_fold(fit, [t.data for t in problem.terms], folds, seed)


def _pooled_result(
    full: ContactChainsCalibration, runs: list[ContactChainsCalibration], label: str
) -> ContactChainsCalibration:
    """``full`` with each term's held-out errors the folds' pooled, and its refusal by them.

    ``label``: the held-out rows' source (``K folds``, ``K folds, seed S``).
    """
    folds = len(runs)
    parts, refusal = [], None
    for c, part in enumerate(full.chains):
        own = [r.chains[c] for r in runs]
        stats = dict(part.stats)
        for key in own[0].stats:
            if key.startswith("held_out"):
                stats[key] = pooled([p.stats[key] for p in own])
        extra: dict[str, Any] = {}
        if isinstance(part, MeasuredChain):
            extra["held"] = _stacked([cast(Measurements, cast(MeasuredChain, p).held) for p in own])
        rows = [r for p in own for r in p.held_rows or ()]  # each row held out once
        extra["held_rows"] = tuple(sorted(rows))
        parts.append(dataclasses.replace(part, stats=stats, held_source=label, **extra))
        refusal = refusal or _held_out_refusal(part, stats)
    refused = [_own_refusal(r) for r in runs]
    first = next((f"fold {k + 1} of {folds}: {r}" for k, r in enumerate(refused) if r), None)
    per_fold = tuple(
        tuple((p.stats["held_out_registration"], p.stats["held_out"]) for p in r.chains)
        for r in runs
    )
    refusal = full.refusal or first or refusal
    notes = tuple(n for n in full.notes if not n.startswith(NOTHING_HELD))  # each row held out
    return dataclasses.replace(
        full, chains=tuple(parts), refusal=refusal, folds=per_fold, notes=notes
    )


def _held_out_refusal(part, stats: dict) -> str | None:
    """The held-out rule on a term's ``stats`` (touches: gaps; the others: errors)."""
    what = "gaps" if isinstance(part, ChainContacts) else "errors"
    return held_out_refusal(stats, part.chain, what)


def _own_refusal(run: ContactChainsCalibration) -> str | None:
    """Why a fold's fit is refused other than by its held-out errors (None: it is not).

    Its held-out rule is the pooled one's business; a fit that stalled, or that its data do
    not determine, gives held-out errors of no fitted model. Told by the rule, not by the
    text: a fit whose held-out rule fails on a term is refused by it, before the solver's
    and the rank's reasons (:func:`~calib.calibration.engine._assessed`), so a stall
    it hides is asked of the solution.
    """
    held_out = any(_held_out_refusal(p, p.stats) for p in run.chains if "held_out" in p.stats)
    if run.refusal is not None and not held_out:
        return run.refusal
    return None if run.solution is None else unconverged(run.solution.fit)
