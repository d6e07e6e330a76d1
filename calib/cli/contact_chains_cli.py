"""`calib calibrate --term KIND BASE TOOL DATA ...`: several terms of one robot, one fit.

Each ``--term`` names a kind, a chain of the robot and its data (and optionally data to
validate on): ``--term plane left_sole_link gripper_left_base_link left.csv`` (touches of a
plane), ``--term loop left_sole_link right_sole_link left.csv`` (a closed loop, a
``fixed-pose`` chain: a plane contact CSV that records its joints, or a ``fixed-pose`` one;
every row a touch of one pose, :func:`~calib.measurements.contact_loops.read_loop`),
``--term position rgbd_optical_frame gripper_left_base_link head.csv`` (a measurement CSV of
points measured in BASE, a frame of the robot: a head camera; ``pose`` with its orientations).
``--chain BASE TOOL DATA`` (with ``--measure plane``) is ``--term plane ...`` and ``--loop``
is ``--term loop ...``. Joints on several chains (a humanoid's torso) are fitted once; one URDF
of the whole robot is written. The terms make a :class:`~calib.calibration.problem.Problem`,
fitted by :func:`~calib.calibration.entry.calibrate`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..core.fileio import check_outputs
from ..core.progress import terminal
from ..exceptions import DataError, InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.tree import load_robot
from . import pixels_cli
from .common import (
    fold_seed,
    given_options,
    look_outputs,
    orientation_wanted,
    write_calibration,
)
from .contact_cli import check_contact

__all__ = [
    "TERM_KINDS",
    "add_chain_arguments",
    "asked_terms",
    "calibrate_chains_command",
    "read_terms",
    "term_chains",
]


TERM_KINDS = ("plane", "loop", "position", "pose", "pixels")
"""Kinds a ``--term`` may name."""


def add_chain_arguments(p: argparse._ActionsContainer) -> None:
    """The ``--term``, ``--chain``, ``--loop`` and ``--shared-planes`` flags of ``calibrate``."""
    p.add_argument(
        "--term",
        action="append",
        nargs="+",
        metavar="ARG",
        help="one term of a joint fit (joints the terms share fitted once, one URDF): KIND "
        f"BASE TOOL DATA [VALIDATION], KIND one of {', '.join(TERM_KINDS)}; once per term, "
        "at least two, instead of --base, --tool, --data; pixels: BASE is the NAME of a "
        "--camera NAME LINK INTRINSICS (its chain runs from LINK), with --target TARGET.csv",
    )
    p.add_argument(
        "--chain",
        action="append",
        nargs="+",
        metavar="ARG",
        help="contacts on several chains fitted together (joints they share fitted once, one "
        "URDF): BASE TOOL DATA [VALIDATION], once per chain, instead of --base, --tool, --data",
    )
    p.add_argument(
        "--loop",
        action="append",
        nargs="+",
        metavar="ARG",
        help="with --chain: a closed loop (a fixed pose of TOOL in BASE at every touch, e.g. "
        "both soles on the ground) fitted with the chains: BASE TOOL DATA [VALIDATION], DATA "
        "a contact CSV recording its joints (every row a touch of the one pose)",
    )
    p.add_argument(
        "--pose-weight",
        type=float,
        default=None,
        metavar="W",
        help="with --loop: factor of the loops' rows against the chains' (default 1)",
    )
    p.add_argument(
        "--shared-planes",
        action="store_true",
        help="with --chain: chains of one base frame whose touches name the same plane touch "
        "one plane (default: a plane per chain)",
    )


def _check(args: argparse.Namespace) -> list[tuple[str, str, str, str, str | None]]:
    """The terms asked for: (kind, base, tool, data, validation or None)."""
    terms = [_term(items, "--term") for items in args.term or []]
    terms += [_term(["plane", *items], "--chain") for items in args.chain or []]
    terms += [_term(["loop", *items], "--loop") for items in args.loop or []]
    kinds = {t[0] for t in terms}
    if args.chain and args.measure != "plane":
        raise InvalidArgumentError("--chain takes --measure plane")
    if kinds <= {"loop"}:
        raise InvalidArgumentError(
            "--loop is fitted with other terms: give --chain too (or --term plane|position|pose)"
        )
    if len(terms) < 2 and not args.chain:
        raise InvalidArgumentError(
            "a joint fit has two terms or more (one term: --base, --tool and --data)"
        )
    if not args.chain and given_options(args, ("measure",)):
        raise InvalidArgumentError(
            f"{given_options(args, ('measure',))[0]} is not for --term or --loop: each term "
            f"names its kind (--term KIND BASE TOOL DATA)"
        )
    if args.pose_weight is not None and "loop" not in kinds:
        raise InvalidArgumentError("--pose-weight weighs the rows of --loop: give --loop too")
    if args.params == "paper":
        raise InvalidArgumentError("--params paper is a chain's MDH set: not with --chain")
    if args.shared_planes and len(terms) < 2:
        raise InvalidArgumentError("--shared-planes is for several terms: give two or more")
    check_contact(args.contact)
    _refuse_folds(args, terms)
    return terms


def _refuse_folds(args: argparse.Namespace, terms: list) -> None:
    """``--folds`` with a term it cannot fold: a pixels term, or one with its validation file."""
    if args.folds is None:
        return
    if any(kind == "pixels" for kind, *_ in terms):
        raise InvalidArgumentError(
            "--folds is not for a pixels term (--term pixels): pixels have no folds yet; hold "
            "rows out with --holdout, or give the term its validation file"
        )
    if any(check is not None for *_, check in terms):
        from ..design.folds import NOT_WITH  # numpy: only on this error

        raise InvalidArgumentError(NOT_WITH)  # said with the flags: calib.cli.flags.FLAGS


def _term(items: list[str], flag: str) -> tuple[str, str, str, str, str | None]:
    """One term's (kind, base, tool, data, validation or None), checked."""
    if items[0] not in TERM_KINDS:
        raise InvalidArgumentError(
            f"{flag} takes KIND BASE TOOL DATA [VALIDATION], KIND one of "
            f"{', '.join(TERM_KINDS)}: got '{items[0]}'"
        )
    if len(items) not in (4, 5):
        what = "KIND BASE TOOL DATA" if flag == "--term" else "BASE TOOL DATA"
        raise InvalidArgumentError(
            f"{flag} takes {what} [VALIDATION], got {len(items) - (flag != '--term')} values"
        )
    return items[0], items[1], items[2], items[3], items[4] if len(items) == 5 else None


def calibrate_chains_command(args: argparse.Namespace, recorded=()) -> int:
    """Calibrate several chains from contact CSVs; write the URDF (if accepted) and the report.

    ``recorded``: the warnings raised on the way, for the report's ``warnings``.

    Raises:
        CalibrationRefusedError: The model was refused (the report only is written).
    """
    from ..calibration.entry import calibrate
    from ..calibration.problem import Problem
    from ..design.folds import cross_validate

    asked = _check(args)
    chains = term_chains(args, asked)
    out, report = Path(args.out), Path(args.report) if args.report else None
    inputs: dict[str, str | Path] = {"the nominal URDF": chains[0].urdf_path}
    for k, (_, _, _, path, check) in enumerate(asked):
        inputs[f"the data of term {k + 1}"] = path
        if check:
            inputs[f"the validation data of term {k + 1}"] = check
    if getattr(args, "target", None):  # a pixel term's target, read with the terms below
        inputs["--target"] = args.target
    check_outputs({"--out": out, "--report": report, **look_outputs(args)}, inputs)
    terms = read_terms(args, asked, chains)
    weight = args.orientation_weight if isinstance(args.orientation_weight, float) else None
    problem = Problem(
        tuple(terms),
        params=args.params,
        orientation_weight=weight,
        shared_planes=args.shared_planes,
        pose_weight=1.0 if args.pose_weight is None else args.pose_weight,
        max_iterations=args.max_iterations,
        holdout=args.holdout,
        seed=args.seed,
    )
    result = (
        calibrate(problem, progress=terminal(args.quiet))  # each term's validation data
        if args.folds is None
        else cross_validate(
            problem, folds=args.folds, seed=fold_seed(args), progress=terminal(args.quiet)
        )
    )
    return write_calibration(
        args,
        result.to_dict(),
        result.summary,
        result.refusal,
        lambda: {out: result.urdf()},
        (out, report),
        recorded,
        result,
    )


def asked_terms(args: argparse.Namespace) -> list[tuple[str, str, str, str, str | None]]:
    """The ``--term`` flags alone (``calib analyze``): (kind, base, tool, data, validation)."""
    return [_term(items, "--term") for items in args.term or []]


def term_chains(args: argparse.Namespace, asked) -> list[Chain]:
    """Each asked term's chain (a pixel term's: from its camera's link)."""
    chains: list[Chain] = []
    for kind, base, tool, _, _ in asked:  # --term pixels NAME: the camera's link
        link = pixels_cli.camera_link(args, base) if kind == "pixels" else base
        robot = load_robot(args.robot, link, tool)
        if not isinstance(robot, Chain) or robot.is_tree:
            raise InvalidArgumentError("a term names one base and one tool (a chain)")
        chains.append(robot)
    return chains


def read_terms(args: argparse.Namespace, asked, chains: list[Chain]) -> tuple:
    """Each asked term's :class:`~calib.calibration.problem.Term`: its data read."""
    from ..calibration.problem import Term

    terms = []
    for chain, (kind, name, _, path, check) in zip(chains, asked, strict=True):
        data = _read(kind, path, chain, args, name)
        validate = _read(kind, check, chain, args, name) if check else None
        guess = getattr(args, "contact", None) if kind == "plane" else None
        terms.append(Term(chain, data, validate, guess))
    return tuple(terms)


def _read(kind: str, path: str, chain: Chain, args: argparse.Namespace, name: str):
    """A term's data of its kind, read from a file (``name``: a pixel term's camera)."""
    from ..measurements.contact_campaign import read_contacts
    from ..measurements.contact_loops import read_loop
    from ..measurements.csvfile import read_measurements

    if kind == "pixels":
        return pixels_cli.pixel_term_data(args, name, chain, path)
    if kind == "loop":
        return read_loop(path, chain)
    if kind not in ("position", "pose"):
        return read_contacts(path, chain, kind)
    data = read_measurements(path, chain)
    if kind == "position":
        return data.position_only()
    if data.quaternion is None:
        raise DataError(path, orientation_wanted("--term pose", renamed=False))
    return data
