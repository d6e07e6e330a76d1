"""`calib calibrate --measure plane|plane-point|fixed-point|fixed-pose`: from contacts."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from ..core.fileio import check_outputs, written_in_place
from ..core.progress import terminal
from ..exceptions import InvalidArgumentError
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree
from .common import (
    PLANE_METAVAR,
    compliance_path,
    cross_validated,
    look_outputs,
    named_planes,
    refuse_unused_weight,
    write_calibration,
)

__all__ = ["add_contact_arguments", "calibrate_contacts_command", "check_contact"]


def add_contact_arguments(p: argparse._ActionsContainer) -> None:
    """The ``--contact`` flag of ``calibrate``."""
    p.add_argument(
        "--contact",
        nargs="+",
        type=float,
        metavar="X",
        help="contacts: guess of the contact frame in the tool frame, X Y Z [RX RY RZ] "
        "[m, rad] (default: the tool frame)",
    )
    p.add_argument(
        "--known-plane",
        dest="known_planes",
        nargs=7,
        action="append",
        metavar=PLANE_METAVAR,
        help="contacts: a plane known (the floor under the base foot), held, not fitted: the "
        "id the touches name it, a point and its normal in the base frame [m]; repeat for "
        "several (default: every plane fitted)",
    )
    p.add_argument(
        "--other-foot",
        nargs="+",
        metavar="ARG",
        help="with --elastic: a second foot on the ground, FRAME [SHARE]: it carries its own "
        "leg, or SHARE (0 to 1) of the robot's weight (default: the base foot carries all)",
    )


def check_contact(values: list[float] | None) -> None:
    """``--contact X Y Z [RX RY RZ]``: 3 or 6 numbers, metres and radians.

    Raises:
        InvalidArgumentError: Another count, NaN or infinity, a point farther from the tool
            frame than a target may be from its link (millimetres?), or an angle beyond a
            turn (degrees?).
    """
    from ..measurements.pixels import MAX_TARGET_DISTANCE

    if values is None:
        return
    if len(values) not in (3, 6):
        raise InvalidArgumentError("--contact takes X Y Z [RX RY RZ] (3 or 6 numbers)")
    if not all(map(math.isfinite, values)):
        raise InvalidArgumentError("--contact takes finite numbers: X Y Z [m], RX RY RZ [rad]")
    far = max(abs(v) for v in values[:3])
    if far > MAX_TARGET_DISTANCE:
        raise InvalidArgumentError(
            f"--contact's X Y Z are metres: {far:g} m from the tool frame is more than "
            f"{MAX_TARGET_DISTANCE:g} m (millimetres? {far:g} mm is {far / 1000:g} m)"
        )
    turned = max((abs(v) for v in values[3:]), default=0.0)
    if turned > math.tau:
        raise InvalidArgumentError(
            f"--contact's RX RY RZ are radians: {turned:g} is more than a turn (degrees? "
            f"{turned:g} deg is {math.radians(turned):.4g} rad)"
        )


def _check_args(args: argparse.Namespace) -> None:
    check_contact(args.contact)


def _support(args: argparse.Namespace):
    """``--other-foot FRAME [SHARE]`` as a :class:`~calib.kinematics.standing.Support`."""
    from ..kinematics.standing import Support

    given = getattr(args, "other_foot", None)
    if given is None:
        return None
    if not args.elastic:
        raise InvalidArgumentError("--other-foot splits the load of --elastic: give --elastic too")
    if len(given) > 2:
        raise InvalidArgumentError("--other-foot takes FRAME [SHARE] (a frame, then 0 to 1)")
    share = None
    if len(given) == 2:
        try:
            share = float(given[1])
        except ValueError:
            raise InvalidArgumentError(
                f"--other-foot's share is a number from 0 to 1, got '{given[1]}'"
            ) from None
    return Support(given[0], share)


def calibrate_contacts_command(args: argparse.Namespace, chain: Chain | Tree, recorded=()) -> int:
    """Calibrate from a contact CSV; write the URDF (if accepted) and the report.

    ``recorded``: the warnings raised on the way, for the report's ``warnings``.

    Raises:
        CalibrationRefusedError: The model was refused (the report only is written).
    """
    from ..measurements.contact_campaign import read_contacts

    if not isinstance(chain, Chain) or chain.is_tree:
        raise InvalidArgumentError("contacts are calibrated on one chain: give one --tool")
    _check_args(args)
    out, report = Path(args.out), Path(args.report) if args.report else None
    comp = None
    if args.elastic:
        if written_in_place(out):
            raise InvalidArgumentError(
                f"--out {out} is no regular file: --elastic writes the compliance file next to it"
            )
        comp = compliance_path(out)
    inputs = {"the nominal URDF": chain.urdf_path, "the data (--data)": args.data}
    if args.validate:
        inputs["the validation data (--validate)"] = args.validate
    outputs = {"--out": out, "--report": report, "the compliance file": comp}
    check_outputs({**outputs, **look_outputs(args)}, inputs)
    data = read_contacts(args.data, chain, args.measure)
    refuse_unused_weight(args, any(data.kind.angular), f"--measure {args.measure}: lengths")
    check = read_contacts(args.validate, chain, args.measure) if args.validate else None
    weight = args.orientation_weight if isinstance(args.orientation_weight, float) else None
    support = _support(args)
    result = _engine(args, chain, data, check, weight, support)

    def urdf() -> dict[Path, str | bytes]:
        files: dict[Path, str | bytes] = {out: result.urdf()}
        if comp is not None:
            files.update(result.compliance_files(out))
        return files

    return write_calibration(
        args,
        result.to_dict(),
        result.summary,
        result.refusal,
        urdf,
        (out, report),
        recorded,
        result,
    )


def _engine(args: argparse.Namespace, chain: Chain, data, check, weight, support):
    """One chain's touches fitted by the joint engine (:mod:`calib.calibration.engine`)."""
    from ..calibration.engine import calibrate_contact_chains

    def fit(rows: list, held: list | None):
        return calibrate_contact_chains(
            [chain],
            rows,
            contact=args.contact,
            params=args.params,
            validate=held,
            orientation_weight=weight,
            max_iterations=args.max_iterations,
            holdout=args.holdout,
            seed=args.seed,
            progress=terminal(args.quiet),
            elastic=args.elastic,
            support=support,
            known_planes=named_planes(args.known_planes, "--known-plane"),
            fix=tuple(args.fix),
            free=tuple(args.free),
        )

    return cross_validated(args, fit, [data], None if check is None else [check])
