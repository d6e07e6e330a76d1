"""`calib calibrate --measure plane|plane-point|fixed-point|fixed-pose`: from contacts."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..core.fileio import check_outputs, json_text, written_in_place
from ..core.progress import terminal
from ..exceptions import InvalidArgumentError
from ..identification.measures import CONTACT_NAMES
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree
from .common import compliance_path, write_calibration

__all__ = ["add_contact_arguments", "calibrate_contacts_command", "is_contact_run"]


def add_contact_arguments(p: argparse.ArgumentParser) -> None:
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
        "--other-foot",
        nargs="+",
        metavar="ARG",
        help="with --elastic: a second foot on the ground, FRAME [SHARE]: it carries its own "
        "leg, or SHARE (0 to 1) of the robot's weight (default: the base foot carries all)",
    )


def is_contact_run(args: argparse.Namespace) -> bool:
    """Whether ``calibrate`` was asked for a contact kind (``--contact`` alone is an error).

    Raises:
        InvalidArgumentError: ``--contact`` with a measured kind.
    """
    if args.measure in CONTACT_NAMES:
        return True
    if getattr(args, "other_foot", None) is not None:
        raise InvalidArgumentError(
            f"--other-foot is for contact kinds, not --measure {args.measure}"
        )
    if getattr(args, "contact", None) is not None:
        raise InvalidArgumentError(
            f"--contact is for contact kinds ({', '.join(CONTACT_NAMES)}), not --measure "
            f"{args.measure}"
        )
    return False


_MEASURED_ONLY: dict[str, object] = {
    "marker": None,
    "fix": [],
    "free": [],
    "loss": "linear",
    "noise_mm": None,
    "world_link": None,
}


def _check_args(args: argparse.Namespace) -> None:
    for name, default in _MEASURED_ONLY.items():
        if getattr(args, name, default) not in (default, None, []):
            flag = "--" + name.replace("_", "-")
            raise InvalidArgumentError(f"{flag} is not available with --measure {args.measure}")
    if args.contact is not None and len(args.contact) not in (3, 6):
        raise InvalidArgumentError("--contact takes X Y Z [RX RY RZ] (3 or 6 numbers)")


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


def calibrate_contacts_command(args: argparse.Namespace, chain: Chain | Tree) -> int:
    """Calibrate from a contact CSV; write the URDF (if accepted) and the report.

    Raises:
        CalibrationRefusedError: The model was refused (the report only is written).
    """
    from ..calibration.contact_pipeline import calibrate_contacts
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
    check_outputs({"--out": out, "--report": report, "the compliance file": comp}, inputs)
    data = read_contacts(args.data, chain, args.measure)
    check = read_contacts(args.validate, chain, args.measure) if args.validate else None
    weight = args.orientation_weight if isinstance(args.orientation_weight, float) else None
    result = calibrate_contacts(
        chain,
        data,
        contact=args.contact,
        params=args.params,
        validate=check,
        orientation_weight=weight,
        elastic=args.elastic,
        support=_support(args),
        max_iterations=args.max_iterations,
        holdout=args.holdout,
        seed=args.seed,
        progress=terminal(args.quiet),
    )

    def urdf() -> dict[Path, str | bytes]:
        from ..kinematics.urdf_export import calibrated_urdf

        files: dict[Path, str | bytes] = {
            out: calibrated_urdf(chain, result.nominal, result.calibrated)
        }
        if comp is not None and result.elastic:
            files[comp] = json_text(result.compliance_document(str(out)))
        return files

    return write_calibration(
        args, result.to_dict(), lambda: _text(result), result.refusal, urdf, (out, report)
    )


def _text(result) -> str:
    kind = result.kind
    ids = ", ".join(f"'{k}'" for k in result.objects)
    units = ["deg" if a else "mm" for a in kind.angular]
    lines = [
        f"{result.chain.name}: {result.chain.base_frame} -> {result.chain.tool_frame}, "
        f"{kind.label} contact, {kind.object_name}(s) {ids}, {len(result.free)} robot "
        f"parameters fitted",
        "gaps (RMS): "
        + "  ".join(f"{n} [{u}]" for n, u in zip(kind.row_names, units, strict=True)),
    ]
    labels = {}
    for key in result.stats:
        label = key.replace("_urdf", ", URDF alone (no compliance)")
        if result.elastic and not key.endswith(("_urdf", "_registration")):
            label += ", whole model (URDF + compliance)"
        labels[key] = label
    width = max(map(len, labels.values()))
    for key, s in result.stats.items():
        values = "  ".join(f"{v:8.3f}" for v in s.rms)
        lines.append(f"  {labels[key]:{width}s} {values}  ({s.m} touches)")
    if result.load is not None:
        lines.append(
            f"joint compliance under gravity, standing on {result.chain.base_frame} "
            f"({result.load.support.label()}"
            + (f"; {len(result.readings)} joints off the chain as read" if result.readings else "")
            + "): "
            + ", ".join(f"{k} {v:.3g}" for k, v in result.to_dict()["compliance"].items() if v)
            + " [rad/(N m)]"
        )
    lines += [f"note: {n}" for n in result.notes]
    return "\n".join(lines)
