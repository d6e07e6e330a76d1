"""``calib simulate``: a simulated measurement campaign (CSV and true errors).

Of a chain, a tree, or contacts (joints only).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from ..core.choices import (
    CAMPAIGN_MEASURES,
    CONTACT_MEASURES,
    DEFAULT_CONFIGS,
    DEFAULT_MEASURE,
    DEFAULT_SET,
    PARAMETER_SETS,
)
from ..core.fileio import json_text, written_in_place
from ..core.words import counted
from ..exceptions import InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree, load_robot
from . import pixels_cli
from .common import (
    PLANE_METAVAR,
    Group,
    add_chain_args,
    add_marker_arg,
    check_output_paths,
    command_parser,
    given_options,
    named_planes,
    nonnegative_number,
    tool_arg,
    write_outputs,
)

if TYPE_CHECKING:
    import numpy as np

    from ..identification.measures import Measurement

__all__ = [
    "add_simulate_parser",
    "cmd_simulate",
]


def _simulate_contacts(args: argparse.Namespace) -> int:
    """``calib simulate --measure plane|...``: touches of the true robot, joints only."""
    from ..measurements.contact_campaign import contacts_csv, simulate_contacts
    from ..measurements.simulation import robot_words

    for given, option in (
        (args.marker is not None, "--marker"),
        (args.configs_file is not None, "--configs-file"),
        (args.noise_mm != 0.0, "--noise-mm"),
    ):
        if given:
            raise InvalidArgumentError(
                f"{option} is for measured campaigns: a contact records the joints alone "
                f"(--noise-mrad: the joints' noise)"
            )
    out = Path(args.out)
    if args.truth is None and written_in_place(out):
        raise InvalidArgumentError(f"--out {out} is no regular file: give --truth FILE too")
    truth_path = Path(args.truth) if args.truth else out.with_suffix(".truth.json")
    planes = named_planes(args.plane, "--plane")
    if planes and args.measure not in ("plane", "plane-point"):
        raise InvalidArgumentError(
            f"--plane is for --measure plane|plane-point, not {args.measure}"
        )
    if planes and args.contacts not in (1, len(planes)):  # the library's check, in flags
        raise InvalidArgumentError(
            f"--contacts {args.contacts} for {counted(len(planes), 'planes')} given (--plane): "
            "give as many --plane, or leave --contacts out"
        )
    chain = load_robot(args.robot, args.base, tool_arg(args))
    if chain.is_tree:
        raise InvalidArgumentError("a contact campaign is simulated on one chain: one --tool")
    check_output_paths({"--out": out, "--truth": truth_path}, {"the URDF": chain.urdf_path})
    campaign = simulate_contacts(
        chain,
        args.configs,
        args.measure,
        contacts=args.contacts,
        error_mm=args.error_mm,
        error_mrad=args.error_mrad,
        noise_mrad=args.noise_mrad or 0.0,
        seed=args.seed,
        params=args.params,
        objects=planes,
        robot_seed=args.robot_seed,
    )
    truth = campaign.truth
    write_outputs({out: contacts_csv(campaign.data), truth_path: json_text(truth.to_dict())})
    objects = counted(len(campaign.data.contacts), f"{campaign.data.id_column}s")
    print(
        f"{chain.name}: {counted(campaign.data.m, 'touches')}, measure {args.measure}, "
        f"{objects}, {len(truth.params)} "
        f"{truth.params.label} parameters perturbed ({truth.error_mm:g} mm, "
        f"{truth.error_mrad:g} mrad), joint noise {truth.noise_mrad:g} mrad, seed {truth.seed}"
        f"{robot_words(truth.robot_seed)}"
    )
    print(f"wrote {out} and {truth_path} (true errors and {campaign.data.id_column}s)")
    return 0


def _configs(args: argparse.Namespace, robot: Chain | Tree) -> int | np.ndarray:
    """``simulate``'s configurations: ``--configs`` random ones, or ``--configs-file``'s."""
    if not args.configs_file:
        return args.configs
    from ..design.configurations import read_configurations

    return read_configurations(args.configs_file, robot)


def cmd_simulate(args: argparse.Namespace) -> int:
    """Simulate a measurement campaign; write the CSV and the true errors (JSON)."""
    both = given_options(args, ("configs", "configs_file"))
    if len(both) == 2:
        raise InvalidArgumentError(
            f"{both[0]} draws random configurations; {both[1]} gives them: use one"
        )
    if args.measure == "pixels":
        return pixels_cli.simulate_pixels_command(args)
    pixels_cli.refuse_pixel_options(args)
    if args.measure in CONTACT_MEASURES:
        return _simulate_contacts(args)
    kind = _campaign_kind(args)
    out = Path(args.out)
    if args.truth is None and written_in_place(out):
        raise InvalidArgumentError(f"--out {out} is no regular file: give --truth FILE too")
    truth_path = Path(args.truth) if args.truth else out.with_suffix(".truth.json")
    chain = load_robot(args.robot, args.base, tool_arg(args))
    if chain.is_tree and not kind.is_position:
        raise InvalidArgumentError("a tree campaign measures positions: add --measure position")
    check_output_paths(
        {"--out": out, "--truth": truth_path},
        {"the URDF": chain.urdf_path, "--configs-file": args.configs_file},
    )
    configs = _configs(args, chain)
    if chain.is_tree:
        return _simulate_tree(args, chain, configs, (out, truth_path))
    return _simulate_chain(args, chain, kind, configs, (out, truth_path))


def _campaign_kind(args: argparse.Namespace) -> Measurement:
    """What ``--measure`` records of a chain or tree, the options that do not apply refused."""
    from ..identification.kinds import campaign_kind

    kind = campaign_kind(args.measure, _first_marker(args))
    typed = given_options(args, ["contacts", "plane"])
    if typed:
        raise InvalidArgumentError(
            f"{typed[0]} gives the planes or points of a contact campaign, not of --measure "
            f"{args.measure}"
        )
    if given_options(args, ["noise_mrad"]) and not kind.is_pose:  # a tree: positions only
        from ..core.checks import angle_mrad

        angle_mrad(args.noise_mrad, "noise_mrad")  # the range's message first
        raise InvalidArgumentError(
            f"--noise-mrad is the orientation noise of --measure pose (a contact's: the joints'): "
            f"--measure {args.measure} records no orientation"
        )
    return kind


def _first_marker(args: argparse.Namespace) -> list[float] | None:
    """The first ``--marker`` (the one that names the measured kind), or None."""
    return args.marker[0] if args.marker else None


def _simulate_chain(
    args: argparse.Namespace, chain: Chain, kind: Measurement, configs, paths
) -> int:
    """`simulate` of one chain: its rows and its true errors.

    ``kind``: what is measured; ``configs``: a count or joint positions; ``paths``:
    ``(--out, --truth)``, checked.
    """
    from ..measurements.csvfile import measurements_csv
    from ..measurements.simulation import robot_words, simulate

    out, truth_path = paths
    campaign = simulate(
        chain,
        configs,
        kind.label,
        args.marker,
        args.error_mm,
        args.error_mrad,
        args.noise_mm,
        args.noise_mrad,
        args.seed,
        args.params,
        robot_seed=args.robot_seed,
    )
    truth = campaign.truth
    write_outputs(
        {out: measurements_csv(campaign.measurements), truth_path: json_text(truth.to_dict())}
    )
    print(
        f"{chain.name}: {counted(campaign.measurements.m, 'configurations')}, measure "
        f"{args.measure}, "
        f"{len(truth.params)} {truth.params.label} parameters perturbed "
        f"({truth.error_mm:g} mm, {truth.error_mrad:g} mrad), noise {truth.noise_mm:g} mm"
        + (f", {truth.noise_mrad:g} mrad" if kind.is_pose else "")
        + f", seed {truth.seed}{robot_words(truth.robot_seed)}"
    )
    of = " of marker 1" if args.marker and len(args.marker) > 1 else ""
    print(f"wrote {out} and {truth_path} (true errors, {truth.analysis.n_base} base values{of})")
    return 0


def _simulate_tree(args: argparse.Namespace, tree: Tree, configs, paths) -> int:
    """`simulate` with several tools: every tool at each configuration, a ``tool`` column.

    ``configs``: a count or joint positions; ``paths``: ``(--out, --truth)``, checked.
    """
    from ..measurements.csvfile import measurements_csv
    from ..measurements.simulation import robot_entry, robot_words
    from ..measurements.tree_campaign import simulate_tree

    out, truth_path = paths
    camp = simulate_tree(
        tree,
        configs,
        _first_marker(args) if args.marker and len(args.marker) == 1 else args.marker,
        args.error_mm,
        args.error_mrad,
        args.noise_mm,
        args.seed,
        args.params,
        robot_seed=args.robot_seed,
    )
    truth = {
        "robot": tree.name,
        "base_frame": tree.base_frame,
        "tools": list(tree.tool_frames),
        "params": camp.params.label,
        "errors": dict(zip(camp.params.names, camp.errors.tolist(), strict=True)),
        "markers": camp.markers.tolist(),
        "seed": args.seed,
    } | robot_entry(camp.robot_seed)
    write_outputs({out: measurements_csv(camp.measurements), truth_path: json_text(truth)})
    print(
        f"{tree.name}: {counted(camp.measurements.m // tree.n_tools, 'configurations')} x "
        f"{tree.n_tools} tools "
        f"({', '.join(tree.tool_frames)}), {len(camp.params)} {camp.params.label} parameters "
        f"perturbed ({args.error_mm:g} mm, {args.error_mrad:g} mrad), noise {args.noise_mm:g} mm"
        f"{robot_words(camp.robot_seed)}"
    )
    print(f"wrote {out} and {truth_path}")
    return 0


def add_simulate_parser(sub) -> None:
    """``simulate``."""
    p = command_parser(
        sub,
        "simulate",
        "simulate a measurement campaign (CSV + true errors)",
        [
            "calib simulate ur5 --out meas.csv --noise-mm 0.05 --marker 0.01 0.02 0.05",
            "calib simulate ur5 --measure pose --out poses.csv --noise-mm 0.05 --noise-mrad 0.1",
            "calib simulate ur5 --configs-file configs.csv --out meas.csv  # from calib design",
            "calib simulate ur5 --measure plane --contacts 2 --out touches.csv",
            "calib simulate talos --base torso_2_link --tool left_sole_link --measure plane "
            "--plane floor 0 0 -1.1 0 0 1 --out left.csv",
        ],
    )
    add_chain_args(p.add_argument_group("robot"), trees=True)
    _add_instrument_args(p.add_argument_group("instrument"))
    g = p.add_argument_group("configurations")
    g.add_argument(
        "--configs",
        type=int,
        default=DEFAULT_CONFIGS,
        help=f"random configurations m (default: {DEFAULT_CONFIGS})",
    )
    g.add_argument(
        "--configs-file",
        help="CSV of the configurations to simulate (joint columns, e.g. from calib design); "
        "not with --configs",
    )
    g.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the configurations and noise, and of the errors unless --robot-seed "
        "(default: 0)",
    )
    _add_error_args(p.add_argument_group("errors and noise"))
    pixels_cli.add_pixel_arguments(p.add_argument_group("cameras (--measure pixels)"))
    g = p.add_argument_group("outputs")
    g.add_argument("--out", required=True, help="measurement CSV to write ('-': stdout)")
    g.add_argument(
        "--truth",
        help="JSON of the true errors (default: OUT with .truth.json; needed if OUT is '-')",
    )
    p.set_defaults(func=cmd_simulate)


def _add_instrument_args(g: Group) -> None:
    """The instrument group of ``simulate``: what is measured, and where."""
    g.add_argument(
        "--measure",
        choices=(*CAMPAIGN_MEASURES, *CONTACT_MEASURES, "pixels"),
        default=DEFAULT_MEASURE,
        help="position (a point), pose (point + orientation), or a contact: touches recorded "
        "by the joints alone, on the true robot; or pixels: what --camera sees of --target "
        f"(default: {DEFAULT_MEASURE}, as analyze and design)",
    )
    add_marker_arg(g, several=True)
    g.add_argument(
        "--contacts",
        type=int,
        default=1,
        help="planes or points the touches share, with --measure plane|... (default: 1)",
    )
    g.add_argument(
        "--plane",
        nargs=7,
        action="append",
        metavar=PLANE_METAVAR,
        help="with --measure plane|plane-point: a plane touched, given (a floor, a known "
        "table): its name, a point and its normal in the base frame [m]; repeat for several "
        "(default: --contacts planes, each where the true contact is at a random posture)",
    )


def _add_error_args(g: Group) -> None:
    """The true robot's errors and the instrument's noise."""
    g.add_argument(
        "--robot-seed",
        type=int,
        help="seed of the true robot's errors (default: --seed): --seed 2 --robot-seed 1 "
        "measures the true robot of --seed 1 at the configurations of --seed 2",
    )
    g.add_argument(
        "--params",
        choices=PARAMETER_SETS,
        default=DEFAULT_SET,
        help=f"parameter set perturbed (default: {DEFAULT_SET})",
    )
    g.add_argument(
        "--error-mm",
        type=nonnegative_number,
        default=1.0,
        help="std of every length error [mm] (default: 1)",
    )
    g.add_argument(
        "--error-mrad",
        type=nonnegative_number,
        default=1.0,
        help="std of every angle error [mrad] (default: 1)",
    )
    g.add_argument(
        "--noise-mm",
        type=nonnegative_number,
        default=0.0,
        help="std of the position noise per axis [mm] (default: 0)",
    )
    g.add_argument(
        "--noise-mrad",
        type=nonnegative_number,
        default=None,
        help="std of the orientation noise per axis [mrad] (default: NOISE_MM)",
    )
