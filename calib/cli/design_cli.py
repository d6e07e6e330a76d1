"""The ``calib design`` command: choose the configurations to measure, or evaluate a set.

Kept beside :mod:`calib.cli.commands` (which registers it) so that the command's options and output
live with the feature.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from ..core.choices import (
    CAMPAIGN_MEASURES,
    CONTACT_MEASURES,
    DEFAULT_CANDIDATES,
    DEFAULT_MEASURE,
    DEFAULT_SET,
    DESIGN_LEVELS,
    EXCHANGE_CRITERIA,
)
from ..core.progress import terminal
from ..core.words import counted
from ..exceptions import InvalidArgumentError
from .common import (
    BooleanOnce,
    Group,
    add_chain_args,
    add_marker_arg,
    check_output_paths,
    command_parser,
    given_options,
    positive_number,
    print_json,
    tool_arg,
    write_outputs,
)

__all__ = ["CHOOSING", "REFERENCE", "add_design_parser", "cmd_design"]

CHOOSING = ("configs", "criterion", "out")
"""Options of the choice of configurations, which ``--evaluate`` does not take."""

REFERENCE = (
    "candidates",
    "candidates_file",
    "margin",
    "workspace",
    "line_of_sight",
    "obstacle",
    "srdf",
    "collision",
)
"""Options of the candidates and their limits: with ``--evaluate``, those of the reference set."""


def _check_design_options(args: argparse.Namespace) -> None:
    """Refuse options the chosen mode would ignore, or that contradict each other.

    Raises:
        InvalidArgumentError: A choice option with ``--evaluate``, ``--candidates`` with
            ``--candidates-file``, ``--srdf`` with ``--no-collision``.
    """
    if args.evaluate:
        ignored = given_options(args, CHOOSING)
        if ignored:
            raise InvalidArgumentError(
                f"{ignored[0]} is for choosing configurations; --evaluate takes only --tool, "
                f"--base, --measure, --marker, --params, --orientation-weight, --noise-mm, "
                f"--seed and the limits of the reference postures (--candidates, "
                f"--candidates-file, --margin, --workspace, --line-of-sight, --obstacle, "
                f"--srdf, --collision)"
            )
    count = given_options(args, ("candidates",))
    if count and args.candidates_file:
        raise InvalidArgumentError(
            f"{count[0]} draws random candidates; --candidates-file gives them: use one"
        )
    noise = given_options(args, ("noise_mm",))
    if noise and args.json:
        raise InvalidArgumentError(
            f"{noise[0]} scales the printed error prediction: --json prints the indices (I and "
            f"G per unit noise), not the prediction"
        )
    weight = given_options(args, ("orientation_weight",))
    if weight and args.measure != "pose":
        from ..core.checks import MAX_WEIGHT, check_number  # the range's message first

        check_number(args.orientation_weight, "the orientation weight", 0.0, MAX_WEIGHT, above=True)
        raise InvalidArgumentError(
            f"{weight[0]} weighs the orientation rows of --measure pose: --measure "
            f"{args.measure} has none the design weighs"
        )
    if args.srdf and not args.collision:
        raise InvalidArgumentError(
            "--srdf disables pairs of the self-collision check, which --no-collision turns off"
        )


def cmd_design(args: argparse.Namespace) -> int:
    """Choose the configurations to measure, or evaluate a given set (``--evaluate``)."""
    from ..design.configurations import configurations_csv
    from ..design.design import design, design_text
    from ..kinematics.tree import load_robot

    _check_design_options(args)
    chain = load_robot(args.robot, args.base, tool_arg(args))
    if args.evaluate:
        return _evaluate(args, chain)
    if args.configs is None:
        raise InvalidArgumentError("give --configs K (or --evaluate CONFIGS.csv)")
    out = Path(args.out) if args.out else None
    candidates, readings = _candidates(args, chain, out)
    result = design(
        chain,
        args.configs,
        candidates=candidates,
        criterion=args.criterion,
        measure=args.measure,
        marker=args.marker,
        params=args.params,
        orientation_weight=args.orientation_weight,
        constraints=_constraints(args),
        seed=args.seed,
        progress=terminal(args.quiet),
        readings=readings,
    )
    if out is not None:
        write_outputs({out: configurations_csv(chain, result.q, result.readings)})
    if args.json:
        print_json(result.to_dict())
    else:
        print(design_text(result, args.noise_mm))
        if out is not None:
            print(f"wrote {out} ({counted(len(result.q), 'configurations')})")
    return 0


def _candidates(args: argparse.Namespace, chain, out: Path | None):
    """``(candidates, readings)``: ``--candidates`` K, or ``--candidates-file``'s rows.

    With a file, ``readings`` are the joints off the chain it records (:func:`_off_chain`),
    else None. ``--out`` is checked first against every input (the URDF, the candidates file,
    the SRDF given or found beside the URDF).
    """
    from ..design.collision import find_srdf
    from ..design.configurations import read_configurations

    found = find_srdf(chain.urdf_path, chain.model.name) if args.collision else None
    inputs = {
        "the URDF": chain.urdf_path,
        "--candidates-file": args.candidates_file,
        "--srdf": args.srdf,
        "the SRDF found beside the URDF": found,
    }
    check_output_paths({"--out": out}, inputs)
    if not args.candidates_file:
        return args.candidates, None
    candidates = read_configurations(args.candidates_file, chain)
    return candidates, _off_chain(args.candidates_file, chain, candidates)


def _constraints(args: argparse.Namespace):
    """The design's constraints from the command line (margin, workspace, collisions, sight)."""
    from ..design.constraints import Constraints

    return Constraints(
        margin=args.margin,
        workspace=tuple(args.workspace) if args.workspace else None,
        collision=args.collision,
        obstacles=tuple(tuple(b) for b in args.obstacle),
        srdf=args.srdf,
        line_of_sight=tuple(args.line_of_sight) if args.line_of_sight else None,
    )


def _off_chain(path: str, chain, candidates):
    """The joints off the chain the candidates file records, one row per candidate, or None.

    None (those joints at zero in the checks) for a tree, a file without such columns, or one
    whose rows are not one per candidate (a tree's or a camera's measurements).
    """
    from ..design.configurations import recorded_off_chain
    from ..kinematics.robot import Chain

    readings = recorded_off_chain(path, chain) if isinstance(chain, Chain) else None
    if readings is None or len(readings.values) != len(candidates):
        return None
    return readings


def _evaluate(args: argparse.Namespace, chain) -> int:
    """``calib design --evaluate``: the indices of a given set of configurations."""
    from ..design.configurations import markers_seen, read_configurations
    from ..design.design import evaluate, indices_table
    from ..design.observability import CRITERIA

    if args.measure in CONTACT_MEASURES:
        raise InvalidArgumentError(
            f"--evaluate scores a measured campaign (pose or position), not yet touches "
            f"(--measure {args.measure}): --configs K chooses postures on the contact"
        )
    q = read_configurations(args.evaluate, chain)
    _check_points(args, chain)
    limits: dict[str, Any] = {}
    if given_options(args, REFERENCE):  # the design's reference postures, these limits'
        candidates, readings = _candidates(args, chain, None)
        limits = {"candidates": candidates, "constraints": _constraints(args), "readings": readings}
    ind = evaluate(
        chain,
        q,
        args.measure,
        args.marker,
        args.params,
        args.seed,
        args.orientation_weight,
        **limits,
        seen=None if chain.is_tree else markers_seen(args.evaluate, chain),
    )
    if args.json:
        print_json({"robot": chain.name, "configs_file": args.evaluate, **ind.to_dict()})
    else:
        print(
            f"{chain.name}: {counted(len(q), 'configurations')} from {args.evaluate}, "
            f"{ind.parameters} parameters, rank {ind.rank}"
        )
        print(indices_table({"set": [ind.value(c) for c in CRITERIA]}))
        if ind.rank < ind.parameters:  # I is infinite: say why, and what to do
            print(
                f"\nrank {ind.rank} of {ind.parameters} parameters: these configurations leave "
                f"{counted(ind.parameters - ind.rank, 'parameter directions')} unseen, no error "
                "prediction; measure more (or more varied) configurations"
            )
        elif ind.i is not None and math.isfinite(ind.i):
            print(
                f"\npredicted RMS position error after calibration at {args.noise_mm:g} mm noise: "
                f"{args.noise_mm * ind.i:.4g} mm"
                + (" (over the postures these limits keep)" if limits else "")
            )
    return 0


def _check_points(args: argparse.Namespace, chain) -> None:
    """Refuse to score another number of points than the measurement file measures.

    The file's points are fitted (their places are not in it): the user says where they
    are, one ``--marker`` each; none is one point at the tool origin.

    Raises:
        InvalidArgumentError: A chain's position file of K points and another number of
            ``--marker``.
    """
    from ..design.configurations import points_in_file

    if chain.is_tree or args.measure != "position":
        return
    k, given = points_in_file(args.evaluate, chain), len(args.marker or [None])
    if k and k != given:
        how = "once (its place in the tool frame; none: the tool origin)"
        if k > 1:
            how = f"{k} times, each point's approximate place in the tool frame"
        raise InvalidArgumentError(
            f"{args.evaluate} measures {counted(k, 'points')}, the score would be of "
            f"{counted(given, 'points')}: give --marker X Y Z {how}"
        )


def add_design_parser(sub) -> None:
    """The ``design`` subcommand's options."""
    p = command_parser(
        sub,
        "design",
        "choose the configurations to measure (experiment design)",
        [
            "calib design panda --configs 30 --out configs.csv",
            "calib design panda --evaluate configs.csv            # the indices of a given set",
            "calib design ur5 --configs 20 --measure pose --criterion A",
            "calib design ur5 --configs 30 --line-of-sight 2 0 1 --workspace -1 -1 0 1 1 1.5",
        ],
    )
    add_chain_args(p.add_argument_group("robot"), trees=True)
    g = p.add_argument_group("configurations")
    g.add_argument("--configs", type=int, help="number of configurations K to choose")
    g.add_argument(
        "--evaluate",
        metavar="CONFIGS.csv",
        help="print the observability indices of these configurations instead (given the "
        "candidates or their limits, averaged over the design's reference postures they keep)",
    )
    g.add_argument(
        "--candidates",
        type=int,
        default=DEFAULT_CANDIDATES,
        help=f"random candidates within the joint limits (default: {DEFAULT_CANDIDATES})",
    )
    g.add_argument(
        "--candidates-file",
        help="CSV of candidate configurations known to be reachable; the joints off the chain "
        "it records (a recorded touch's other arm and legs) are where the collision and "
        "line-of-sight checks hold them (otherwise, and with random candidates, at zero)",
    )
    g.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the candidates, reference and random sets (default: 0)",
    )
    _add_model_args(p.add_argument_group("instrument and model"))
    _add_limit_args(p.add_argument_group("limits of the campaign"))
    g = p.add_argument_group("outputs")
    g.add_argument(
        "--out",
        help="CSV of the chosen configurations (joint columns; then the joints off the chain "
        "--candidates-file records)",
    )
    g.add_argument(
        "--noise-mm",
        type=positive_number,
        default=0.05,
        help="the instrument's noise per axis (std, as simulate's) for the printed error "
        "prediction [mm]; the design does not depend on it (default: 0.05)",
    )
    g.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_design)


def _add_model_args(p: Group) -> None:
    """What is measured and fitted: criterion, measure, markers, weight, level."""
    p.add_argument(
        "--criterion",
        choices=EXCHANGE_CRITERIA,
        default="D",
        help="D: log det of the information; A: mean parameter variance; I: mean "
        "predicted position error (default: D)",
    )
    p.add_argument(
        "--measure",
        choices=CAMPAIGN_MEASURES + CONTACT_MEASURES,
        default=DEFAULT_MEASURE,
        help=f"position or pose (default: {DEFAULT_MEASURE}, as analyze and simulate), or a "
        "contact: postures on it",
    )
    add_marker_arg(p, several=True)
    p.add_argument(
        "--orientation-weight",
        type=float,
        default=1.0,
        metavar="W",
        help="weight of the orientation rows of pose data [m/rad]: position noise / "
        "orientation noise, e.g. 0.05 mm / 0.1 mrad = 0.5 (default: 1; calibrate "
        "estimates it from the data)",
    )
    p.add_argument(
        "--params",
        choices=DESIGN_LEVELS,
        default=DEFAULT_SET,
        help="what the calibration fits (calibrate --params; a tree: frames or complete; "
        f"default: {DEFAULT_SET})",
    )


def _add_limit_args(p: Group) -> None:
    """Limits of the campaign: margin, workspace, line of sight, obstacles, collisions."""
    p.add_argument(
        "--margin",
        type=float,
        default=0.0,
        help="distance kept from the joint limits [rad or m] (default: 0)",
    )
    p.add_argument(
        "--workspace",
        nargs=6,
        type=float,
        metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
        help="box of the base frame that must hold the measured points [m]",
    )
    p.add_argument(
        "--line-of-sight",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="instrument position in the base frame [m]: points must be in view",
    )
    p.add_argument(
        "--obstacle",
        nargs=6,
        type=float,
        action="append",
        default=[],
        metavar=("XMIN", "YMIN", "ZMIN", "XMAX", "YMAX", "ZMAX"),
        help="box of the environment in the base frame [m] (repeatable)",
    )
    p.add_argument(
        "--srdf", help="SRDF of the disabled collision pairs (default: found beside the URDF)"
    )
    p.add_argument(
        "--collision",
        action=BooleanOnce,
        default=True,
        help="reject self-colliding candidates (default: yes; the joints off the chain at zero, "
        "or as --candidates-file records them)",
    )
