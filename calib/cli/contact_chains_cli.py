"""`calib calibrate --measure plane --chain BASE TOOL DATA ...`: several contact chains, one fit.

Each ``--chain`` names a chain of the robot and its touches (and optionally touches to
validate on): ``--chain left_sole_link gripper_left_base_link left.csv``. Joints on several
chains (a humanoid's torso) are fitted once; one URDF of the whole robot is written.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..core.fileio import check_outputs, json_text, write_files_atomic
from ..exceptions import CalibrationRefusedError, InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.tree import load_robot

__all__ = ["add_chain_arguments", "calibrate_chains_command"]


def add_chain_arguments(p: argparse.ArgumentParser) -> None:
    """The ``--chain`` and ``--shared-planes`` flags of ``calibrate``."""
    p.add_argument(
        "--chain",
        action="append",
        nargs="+",
        metavar="ARG",
        help="contacts on several chains fitted together (joints they share fitted once, one "
        "URDF): BASE TOOL DATA [VALIDATION], once per chain, instead of --base, --tool, --data",
    )
    p.add_argument(
        "--shared-planes",
        action="store_true",
        help="with --chain: chains of one base frame whose touches name the same plane touch "
        "one plane (default: a plane per chain)",
    )


_EXCLUDED = {
    "base": "--base",
    "tool": "--tool",
    "data": "--data",
    "validate": "--validate",
    "marker": "--marker",
    "fix": "--fix",
    "free": "--free",
    "elastic": "--elastic",
    "noise_mm": "--noise-mm",
    "world_link": "--world-link",
}


def _check(args: argparse.Namespace) -> list[tuple[str, str, str, str | None]]:
    """The chains asked for: (base, tool, data, validation or None)."""
    if args.measure != "plane":
        raise InvalidArgumentError("--chain takes --measure plane")
    for dest, flag in _EXCLUDED.items():
        if getattr(args, dest, None) not in (None, [], False):
            raise InvalidArgumentError(f"{flag} is not available with --chain")
    if args.loss != "linear":
        raise InvalidArgumentError("--loss is not available with --chain")
    if args.params == "paper":
        raise InvalidArgumentError("--params paper is a chain's MDH set: not with --chain")
    if args.contact is not None and len(args.contact) not in (3, 6):
        raise InvalidArgumentError("--contact takes X Y Z [RX RY RZ] (3 or 6 numbers)")
    out = []
    for items in args.chain:
        if len(items) not in (3, 4):
            raise InvalidArgumentError(
                f"--chain takes BASE TOOL DATA [VALIDATION], got {len(items)} values"
            )
        out.append((items[0], items[1], items[2], items[3] if len(items) == 4 else None))
    return out


def calibrate_chains_command(args: argparse.Namespace) -> int:
    """Calibrate several chains from contact CSVs; write the URDF (if accepted) and the report.

    Raises:
        CalibrationRefusedError: The model was refused (the report only is written).
    """
    from ..calibration.contact_chains import calibrate_contact_chains
    from ..measurements.contact_campaign import read_contacts

    asked = _check(args)
    chains: list[Chain] = []
    for base, tool, _, _ in asked:
        robot = load_robot(args.robot, base, tool)
        if not isinstance(robot, Chain) or robot.is_tree:
            raise InvalidArgumentError("--chain names one base and one tool per chain")
        chains.append(robot)
    out, report = Path(args.out), Path(args.report) if args.report else None
    inputs: dict[str, str | Path] = {"the nominal URDF": chains[0].urdf_path}
    for k, (_, _, path, check) in enumerate(asked):
        inputs[f"the data of chain {k + 1}"] = path
        if check:
            inputs[f"the validation data of chain {k + 1}"] = check
    check_outputs({"--out": out, "--report": report}, inputs)
    data = [read_contacts(d, c, "plane") for c, (_, _, d, _) in zip(chains, asked, strict=True)]
    checks = [
        read_contacts(v, c, "plane") if v else None
        for c, (_, _, _, v) in zip(chains, asked, strict=True)
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
        max_iterations=args.max_iterations,
        holdout=args.holdout,
        seed=args.seed,
    )
    doc = json_text(result.to_dict())
    print(doc if args.json else result.text(), end="" if args.json else "\n")
    files: dict[Path, str | bytes] = {} if report is None else {report: doc}
    if result.refusal is not None:
        write_files_atomic(files)
        raise CalibrationRefusedError(f"calibration refused: {result.refusal}: no URDF written")
    files[out] = result.urdf()
    write_files_atomic(files)
    if not args.json:
        print(f"wrote {', '.join(str(p) for p in files)}")
    return 0
