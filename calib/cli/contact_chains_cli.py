"""`calib calibrate --measure plane --chain BASE TOOL DATA ...`: several contact chains, one fit.

Each ``--chain`` names a chain of the robot and its touches (and optionally touches to
validate on): ``--chain left_sole_link gripper_left_base_link left.csv``. Each ``--loop``
names a closed loop, a ``fixed-pose`` chain, and the file of its postures (a plane contact CSV
that records its joints, or a ``fixed-pose`` one; every row a touch of one pose,
:func:`~calib.measurements.contact_loops.read_loop`): ``--loop left_sole_link right_sole_link
left.csv``. Joints on several chains (a humanoid's torso) are fitted once; one URDF of the
whole robot is written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..core.fileio import check_outputs
from ..core.progress import terminal
from ..exceptions import InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.tree import load_robot
from .common import write_calibration

__all__ = ["add_chain_arguments", "calibrate_chains_command"]


def add_chain_arguments(p: argparse.ArgumentParser) -> None:
    """The ``--chain``, ``--loop`` and ``--shared-planes`` flags of ``calibrate``."""
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


def _check(args: argparse.Namespace) -> list[tuple[str, str, str, str | None, bool]]:
    """The chains asked for: (base, tool, data, validation or None, is a loop)."""
    if not args.chain:
        raise InvalidArgumentError("--loop is fitted with plane chains: give --chain too")
    if args.pose_weight is not None and not args.loop:
        raise InvalidArgumentError("--pose-weight weighs the rows of --loop: give --loop too")
    if args.measure != "plane":
        raise InvalidArgumentError("--chain takes --measure plane")
    if args.params == "paper":
        raise InvalidArgumentError("--params paper is a chain's MDH set: not with --chain")
    if args.contact is not None and len(args.contact) not in (3, 6):
        raise InvalidArgumentError("--contact takes X Y Z [RX RY RZ] (3 or 6 numbers)")
    out = []
    for flag, given in (("--chain", args.chain), ("--loop", getattr(args, "loop", None) or [])):
        for items in given:
            if len(items) not in (3, 4):
                raise InvalidArgumentError(
                    f"{flag} takes BASE TOOL DATA [VALIDATION], got {len(items)} values"
                )
            check = items[3] if len(items) == 4 else None
            out.append((items[0], items[1], items[2], check, flag == "--loop"))
    return out


def calibrate_chains_command(args: argparse.Namespace, recorded=()) -> int:
    """Calibrate several chains from contact CSVs; write the URDF (if accepted) and the report.

    ``recorded``: the warnings raised on the way, for the report's ``warnings``.

    Raises:
        CalibrationRefusedError: The model was refused (the report only is written).
    """
    from ..calibration.contact_chains import calibrate_contact_chains
    from ..measurements.contact_campaign import read_contacts
    from ..measurements.contact_loops import read_loop

    asked = _check(args)
    chains: list[Chain] = []
    for base, tool, _, _, _ in asked:
        robot = load_robot(args.robot, base, tool)
        if not isinstance(robot, Chain) or robot.is_tree:
            raise InvalidArgumentError("--chain names one base and one tool per chain")
        chains.append(robot)
    out, report = Path(args.out), Path(args.report) if args.report else None
    inputs: dict[str, str | Path] = {"the nominal URDF": chains[0].urdf_path}
    for k, (_, _, path, check, _) in enumerate(asked):
        inputs[f"the data of chain {k + 1}"] = path
        if check:
            inputs[f"the validation data of chain {k + 1}"] = check
    check_outputs({"--out": out, "--report": report}, inputs)

    def read(path, chain, loop):
        return read_loop(path, chain) if loop else read_contacts(path, chain, "plane")

    data = [read(d, c, loop) for c, (_, _, d, _, loop) in zip(chains, asked, strict=True)]
    checks = [
        read(v, c, loop) if v else None for c, (_, _, _, v, loop) in zip(chains, asked, strict=True)
    ]
    weight = args.orientation_weight if isinstance(args.orientation_weight, float) else None
    result = calibrate_contact_chains(
        chains,
        data,
        contact=args.contact,
        params=args.params,
        validate=checks if any(v is not None for v in checks) else None,
        orientation_weight=weight,
        shared_planes=args.shared_planes,
        pose_weight=1.0 if args.pose_weight is None else args.pose_weight,
        max_iterations=args.max_iterations,
        holdout=args.holdout,
        seed=args.seed,
        progress=terminal(args.quiet),
    )
    return write_calibration(
        args,
        result.to_dict(),
        result.summary,
        result.refusal,
        lambda: {out: result.urdf()},
        (out, report),
        recorded,
    )
