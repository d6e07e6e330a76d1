"""``calibrate``: one entry for every problem, whatever the robot's shape and the data's kind.

``calibrate(problem)`` fits a :class:`~.problem.Problem`; ``calibrate(robot, data, **options)``
is the problem of one term. Every shape is fitted by the one joint engine
(:func:`~.engine.calibrate_contact_chains`). docs/developers/engine.md#entry
"""

from __future__ import annotations

import dataclasses
from typing import Any, cast

from ..core.checks import MAX_ROWS, check_size
from ..core.progress import Progress
from ..exceptions import InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree
from ..measurements.contact_campaign import ContactData
from ..measurements.data import Measurements
from .chain_outliers import fit_terms_until_stable
from .delivery import read_files
from .engine import (
    Registered,
    Run,
    calibrate_contact_chains,
    check_readings,
    fit_registered,
    fit_run,
)
from .engine_result import ContactChainsCalibration
from .instrument import prepare_tree
from .measured_term import check_measured
from .options import (
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_TREE_LEVEL,
    check_tree_level,
    checked_arguments,
    options_given,
)
from .problem import Problem, Term
from .validation import split

__all__ = ["calibrate", "calibrate_contacts", "calibrate_tree", "measured_chain"]


@checked_arguments
def calibrate(
    robot: Problem | Chain | Tree,
    data: Measurements | ContactData | None = None,
    *,
    params: str | None = None,
    marker=None,
    validate=None,
    fix: tuple[str, ...] = (),
    free: tuple[str, ...] = (),
    elastic: bool | None = None,
    loss: str = "linear",
    noise_mm: float | None = None,
    orientation_weight: float | None = None,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
    holdout: float = 0.0,
    seed: int = 0,
    known_planes=None,
    progress: Progress | None = None,
) -> ContactChainsCalibration:
    """Calibrate a robot from what was recorded on it: a model that predicts unseen postures.

    Steps: check the data, set rows aside (``holdout``), register the measurement frame and
    the markers (or the objects touched) in closed form (naming a likely mistake if the data
    cannot be registered, setting outlier rows aside), choose the free parameters
    (``params``), fit them, and validate the result on held-out rows.

    Args:
        robot: A :class:`~.problem.Problem` (its options inside it; no ``data``), or the
            nominal chain or tree of a problem of one term.
        data: What was recorded on ``robot``: measurements (joints in chain order; see
            :mod:`!calib.measurements.csvfile`) or touches
            (:class:`~calib.measurements.contact_campaign.ContactData`).
        params: Parameter level, one of ``LEVELS`` (default ``auto``; a tree:
            ``TREE_LEVELS``, default ``complete``).
        marker: Guess of each measured point in the tool frame, 3 numbers or ``(K, 3)``
            [m], or of a contact frame (:attr:`~calib.Term.guess`; default: the tool
            origin).
        validate: Data of other postures to score the result on (never fitted).
        fix: Parameter names held at their start, as the printed table names them
            (``elbow_joint:d3``, ``d3``, a compliance ``c2``; the instrument's frame and the
            markers are fitted, but a marker coordinate no posture separates from the frame,
            held at ``marker``: a gantry's first marker).
        free: Parameter names (a compliance ``c1``.. included) always fitted.
        elastic: Fit joint compliance under gravity, which the URDF cannot hold (default:
            no, unless ``free`` names a compliance).
        loss: ``linear``, ``soft_l1`` or ``huber`` (scale ``noise_mm``).
        noise_mm: Instrument noise [mm] (default: unknown).
        orientation_weight: Weight of the orientation rows [m/rad] (default: estimated from
            the data, :mod:`!calib.calibration.weighting`).
        max_iterations: Most residual evaluations of each solver run.
        holdout: Fraction of the rows set aside (seeded); not with ``validate``.
        seed: Seed of the holdout draw and of the generic configurations of the rank check.
        known_planes: Touches: planes given, held (:attr:`~calib.Problem.known_planes`).
        progress: Progress bars of the registration, the selection and the fit
            (:mod:`!calib.core.progress`; e.g. ``tqdm.tqdm``), or None.

    Returns:
        The result: check ``accepted`` (or call its ``check()``).

    Raises:
        DataError: The data do not belong to the robot, are too few, or match it only under
            a usual mistake (which is named).
        InvalidArgumentError: A bad argument, one that does not apply to the problem's shape
            (:data:`!options.APPLIES`), an unknown one, or one given by position after
            ``data``.
    """
    options: dict[str, Any] = dict(
        params=params,
        fix=fix,
        free=free,
        elastic=elastic,
        loss=loss,
        noise_mm=noise_mm,
        orientation_weight=orientation_weight,
        max_iterations=max_iterations,
        holdout=holdout,
        seed=seed,
        known_planes=known_planes,
    )
    if isinstance(robot, Problem):
        _alone(data, options_given(dict(marker=marker, validate=validate, **options)))
        return solve(robot, progress)
    if data is None:
        raise InvalidArgumentError(
            "calibrate takes a Problem, or a robot and its data: missing a required argument: "
            "'data'"
        )
    return solve(Problem((Term(robot, data, validate, marker),), **options), progress)


def _alone(data, named: list[str]) -> None:
    """Refuse data or options (``named``) given beside a problem: they are in it."""
    if data is not None or named:  # an option beside the problem was ignored
        raise InvalidArgumentError(
            "calibrate(problem) takes the problem alone: its data and options are in it"
            + (f" ({', '.join(named)} given beside it)" if named else "")
        )


def solve(problem: Problem, progress: Progress | None = None) -> ContactChainsCalibration:
    """Fit a problem: the joint engine's run of its terms (module text)."""
    for t in problem.terms:
        if isinstance(t.data, Measurements):
            check_size(t.data.m, MAX_ROWS, "rows", t.data.source)
        check_readings(t.robot, t.data, t.validate)  # past a limit: warned; far: refused
    terms = problem.terms
    files = read_files(*zip(*((t.robot, t.data, t.validate) for t in terms), strict=True))
    if problem.shape == "tree":
        return dataclasses.replace(_tree(problem, progress), inputs=files)
    chain = problem.shape == "chain"
    held = [t.validate for t in terms]
    guess = next((t.guess for t in terms if t.guess is not None), None)  # a chain's: markers'
    run = Run(
        [cast(Chain, t.robot) for t in terms],
        [t.data for t in terms],
        held if any(h is not None for h in held) else None,
        problem.options(),
        contact=None if chain else guess,
        marker=guess if chain else None,
        shared_planes=problem.shared_planes,
        pose_weight=problem.pose_weight,
        progress=progress,
        known_planes=problem.known_planes,
    )
    return dataclasses.replace(measured_chain(run) if chain else fit_run(run), inputs=files)


calibrate_tree = calibrate
"""The name :func:`calibrate` had for trees (a tree is one of its problems)."""


def calibrate_contacts(
    chain: Chain, data: ContactData, *, validate: ContactData | None = None, **options
) -> ContactChainsCalibration:
    """One chain touching: :func:`~.engine.calibrate_contact_chains` of one term.

    Its other arguments as they are (``contact``, ``params``, ``elastic``, ``support``, ...).

    Raises:
        InvalidArgumentError: A bad or unknown argument.
        DataError: Touches that do not belong to the chain or determine too little.
    """
    held = None if validate is None else [validate]
    return calibrate_contact_chains([chain], [data], validate=held, **options)


def _tree(problem: Problem, progress: Progress | None) -> ContactChainsCalibration:
    """A tree measured by one instrument: a joint fit of one measured term per tool."""
    term = problem.terms[0]  # a tree's robot and data (Problem checks them)
    if term.guess is not None:
        raise InvalidArgumentError(
            "marker is for one chain: a tree's markers are registered in closed form"
        )
    tree = cast(Tree, term.robot)
    level = DEFAULT_TREE_LEVEL if problem.params is None else problem.params
    check_tree_level(level)  # the other options: the problem's (APPLIES)
    validate = cast(Measurements | None, term.validate)
    data, held = prepare_tree(
        tree, cast(Measurements, term.data), validate, problem.holdout, problem.seed
    )
    options = dataclasses.replace(problem.options(), params=level, holdout=0.0)  # drawn
    label = "holdout" if validate is None else None
    run = Run(
        list(tree.chains), data, held, options, instrument=True, held_label=label, progress=progress
    )
    return dataclasses.replace(fit_run(run), shape="tree")


def measured_chain(run: Run) -> ContactChainsCalibration:
    """One chain measured by an instrument, fitted by the joint engine as a one-term run.

    Held-out rows drawn first, then the fit made again until its outliers are stable.

    Raises:
        InvalidArgumentError: A bad option (an unknown parameter name, compliance without
            gravity torques, a free parameter the data cannot fit).
    """
    chain, data, opts = run.chains[0], cast(Measurements, run.data[0]), run.options
    given = None if run.validate is None else cast(Measurements | None, run.validate[0])
    if opts.holdout > 0:  # the postures it leaves (the fit counts them with none)
        check_measured(chain, data, None, True, opts.holdout)
    train, held = (
        (data, given)
        if given is not None or opts.holdout == 0  # no posture to draw
        else split(data, opts.holdout, opts.seed)
    )
    run = dataclasses.replace(
        run,
        data=[train],
        validate=None if held is None else [held],
        options=dataclasses.replace(opts, holdout=0.0),  # drawn
        instrument=True,
        held_label="holdout" if given is None else None,
    )

    def fit(registered: Registered) -> ContactChainsCalibration:
        return dataclasses.replace(fit_registered(registered), shape="chain")

    return fit_terms_until_stable(run, fit)
