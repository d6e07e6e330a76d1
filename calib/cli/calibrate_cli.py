"""``calib calibrate``: calibration from a measurement CSV.

Writes a calibrated URDF and a report (only the report for a refused model).
"""

from __future__ import annotations

import argparse
import contextlib
import warnings
from collections.abc import Iterator
from pathlib import Path

from ..calibration.options import DEFAULT_LEVEL, DEFAULT_MAX_ITERATIONS, LEVELS, LOSSES
from ..core.choices import (
    CAMPAIGN_MEASURES,
    MARKERS,
    ORIENTATION_FORMATS,
    UNITS,
    checked_points,
)
from ..core.fileio import written_in_place
from ..core.progress import terminal
from ..exceptions import CalibError, DataError, InvalidArgumentError
from ..identification.measures import CONTACT_NAMES
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree, load_robot
from . import contact_chains_cli, contact_cli, pixels_cli
from .common import (
    BooleanOnce,
    Group,
    add_chain_args,
    add_look_args,
    check_applicable,
    check_output_paths,
    command_parser,
    compliance_path,
    cross_validated,
    look_outputs,
    orientation_wanted,
    positive_number,
    refuse_unused_weight,
    tool_arg,
    write_calibration,
)

__all__ = [
    "add_calibrate_parser",
    "cmd_calibrate",
    "compliance_path",
]


def _data_kind(args: argparse.Namespace):
    """The kind ``--measure`` asks a calibration to use, or None for ``auto`` (the data's)."""
    from ..identification.kinds import campaign_kind

    return None if args.measure == "auto" else campaign_kind(args.measure)


def _weight(text: str) -> float | None:
    """``--orientation-weight``: a number [m/rad] or ``auto`` (None)."""
    if text == "auto":
        return None
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or auto, got '{text}'") from None


def _point_list(text: str) -> tuple[int, ...]:
    """``--points``: point numbers separated by commas (``1`` or ``1,3``), checked."""
    cells = [c.strip() for c in text.split(",")]
    if not all(c.isascii() and c.isdigit() for c in cells):
        raise argparse.ArgumentTypeError(
            f"expected point numbers separated by commas (1 for x1, y1, z1; e.g. 1 or 1,3), "
            f"got '{text}'"
        )
    try:
        return checked_points(int(c) for c in cells)
    except InvalidArgumentError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _columns(args: argparse.Namespace):
    from ..measurements.csvfile import Columns

    cols = tuple(args.orientation_columns) if args.orientation_columns else None
    return Columns(args.orientation, cols, args.units, args.points)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Calibrate from a CSV; write the calibrated URDF (if it passes every check) and a report.

    Every warning raised on the way (the data's, the fit's) is printed as usual and goes into
    the report's ``warnings`` too.
    """
    if Path(args.out).suffix.lower() == ".json":  # the report's suffix: --out and --report swapped?
        raise InvalidArgumentError(
            f"--out {args.out} names the calibrated URDF, not the JSON report (--report): give "
            "it a .urdf name"
        )
    with _recorded_warnings() as recorded:
        if args.measure == "pixels":
            return pixels_cli.calibrate_pixels_command(args, recorded)
        if not any(t[0] == "pixels" for t in args.term or []):
            pixels_cli.refuse_pixel_options(args)
        if args.term is not None or args.chain is not None or args.loop is not None:
            check_applicable(args, "chains")
            return contact_chains_cli.calibrate_chains_command(args, recorded)
        if args.data is None:
            raise InvalidArgumentError(
                "--data is required (or --chain BASE TOOL DATA, once per chain, for contacts)"
            )
        chain = load_robot(args.robot, args.base, tool_arg(args))
        if args.measure in CONTACT_NAMES:
            check_applicable(args, "contacts")
            return contact_cli.calibrate_contacts_command(args, chain, recorded)
        check_applicable(args, "tree" if chain.is_tree else "chain")
        if chain.is_tree:
            return _calibrate_tree(args, chain, recorded)
        return _calibrate_chain(args, chain, recorded)


@contextlib.contextmanager
def _recorded_warnings() -> Iterator[list[warnings.WarningMessage]]:
    """The warnings raised inside, in a list that grows as they come; raised again after.

    Raised again on the way out (an error included), so that :func:`main` prints them.
    """
    pending: list[warnings.WarningMessage] = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                yield caught
            finally:
                pending = list(caught)
    finally:
        for w in pending:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _chain_options(args: argparse.Namespace) -> dict:
    """One chain's options of ``calibrate`` (its data and validation data left)."""
    return {
        "params": args.params or DEFAULT_LEVEL,
        "marker": args.marker,
        "fix": tuple(args.fix),
        "free": tuple(args.free),
        "elastic": args.elastic,
        "loss": args.loss,
        "noise_mm": args.noise_mm,
        "orientation_weight": args.orientation_weight,
        "max_iterations": args.max_iterations,
        "holdout": args.holdout,
        "seed": args.seed,
        "progress": terminal(args.quiet),
    }


def _calibrate_chain(args: argparse.Namespace, chain: Chain, recorded) -> int:
    """`calibrate` with one tool."""
    from ..calibration import calibrate  # only this command loads the calibration

    out, report = _calibration_outputs(args, chain.urdf_path)
    comp = None if written_in_place(out) else compliance_path(out)
    if comp is None and args.elastic:
        raise InvalidArgumentError(
            f"--out {out} is no regular file: --elastic writes the compliance file next to it"
        )
    check_output_paths(
        {"--out": out, "--report": report, "the compliance file": comp, **look_outputs(args)},
        {"the nominal URDF": chain.urdf_path, "--data": args.data, "--validate": args.validate},
    )
    data, check = _chain_data(args, chain)

    options = _chain_options(args)

    def fit(rows: list, held: list | None):
        return calibrate(chain, rows[0], validate=None if held is None else held[0], **options)

    result = cross_validated(args, fit, [data], None if check is None else [check])

    def files() -> dict[Path, str | bytes]:
        urdf: dict[Path, str | bytes] = {out: result.urdf(args.world_link, args.on_robot)}
        if result.elastic:
            if comp is None:
                raise InvalidArgumentError(
                    f"--out {out} is no regular file: the fitted compliance cannot be written "
                    f"next to it (give a file, or --no-elastic)"
                )
            urdf.update(result.compliance_files(out, args.on_robot))
        return urdf

    return write_calibration(
        args,
        result.to_dict(args.world_link, args.on_robot),
        result.summary,
        result.refusal,
        files,
        (out, report),
        recorded,
        result,
    )


def _chain_data(args: argparse.Namespace, chain: Chain):
    """The data and validation data of a one-tool calibration, read as ``--measure`` says."""
    from ..measurements.csvfile import read_measurements

    columns = _columns(args)
    try:
        data = read_measurements(args.data, chain, columns)
    except DataError as exc:
        if "missing position column" not in str(exc):
            raise
        raise _touches_named(args.data, chain) or exc from None
    _check_links(chain, data.n_markers, args.world_link, args.on_robot)  # before the fit
    check = read_measurements(args.validate, chain, columns) if args.validate else None
    kind = _data_kind(args)
    if kind is not None and kind.is_position:
        data = data.position_only()
        check = check.position_only() if check is not None else None
    elif kind is not None and kind.is_pose and data.quaternion is None:
        raise DataError(args.data, orientation_wanted("--measure pose", renamed=True))
    refuse_unused_weight(args, data.quaternion is not None, "positions only")
    return data, check


def _touches_named(path: str, chain: Chain) -> DataError | None:
    """The error of a file without coordinates that reads as touches: say their kind."""
    from ..measurements.contact_campaign import read_contacts

    kinds = {
        "plane": "plane (flush) or plane-point (a tip)",
        "fixed-point": "fixed-point (a tip held) or fixed-pose (a frame held)",
    }
    for kind, choice in kinds.items():
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                read_contacts(path, chain, kind)
        except CalibError:
            continue
        return DataError(
            path,
            f"no coordinates, and its '{kind.split('-')[-1]}' column names what was touched: "
            f"a contact file; give its kind, --measure {choice}, and the contact frame's "
            f"guess, --contact X Y Z",
        )
    return None


def _check_links(chain: Chain, n_markers: int, world_link: str | None, on_robot: bool) -> None:
    """Refuse now a URDF the calibration cannot be written to, or new links with taken names."""
    from ..kinematics.placement_export import instrument_joint
    from ..kinematics.urdf_export import (
        check_base_fixed,
        check_exportable,
        child_link,
        edited_joints,
        read_urdf_source,
        tool_on_moving_joint,
        urdf_tool_frame,
    )
    from ..kinematics.urdf_links import check_new_names, marker_joints, marker_link_names

    check_exportable(chain, moving=True)
    root = read_urdf_source(chain)[1]
    tool_link = child_link(edited_joints(root, chain, moving=True)[1])
    if tool_on_moving_joint(chain):  # the markers hang from the calibrated tool's link
        tool_link = urdf_tool_frame(chain)
    kept = marker_joints(root, chain.tool_frame, tool_link, n_markers)
    names = marker_link_names(chain.tool_frame, n_markers)
    check_new_names(root, tuple(n for n in names if n not in kept), "marker links")
    if on_robot:
        if world_link is not None:
            raise InvalidArgumentError(
                "--on-robot and --world-link: the instrument is on the robot or in the world"
            )
        instrument_joint(root, chain)  # its error names on_robot: the CLI's in_flags
    if world_link is not None:
        check_new_names(root, (world_link,), "--world-link")
        check_base_fixed(chain)


def _calibration_outputs(args: argparse.Namespace, urdf: Path) -> tuple[Path, Path | None]:
    """``--out`` and ``--report``, refused now if they cannot be written or are inputs."""
    out, report = Path(args.out), Path(args.report) if args.report else None
    inputs = {"the nominal URDF": urdf, "the data (--data)": args.data}
    if args.validate:
        inputs["the validation data (--validate)"] = args.validate
    check_output_paths({"--out": out, "--report": report, **look_outputs(args)}, inputs)
    return out, report


def _calibrate_tree(args: argparse.Namespace, tree: Tree, recorded) -> int:
    """`calibrate` with several tools: the tree's calibration, URDF of every branch."""
    from ..calibration.entry import calibrate
    from ..calibration.options import DEFAULT_TREE_LEVEL, TREE_LEVELS
    from ..kinematics.urdf_export import check_exportable
    from ..measurements.csvfile import Columns, read_measurements

    if args.params not in (None, *TREE_LEVELS):
        raise InvalidArgumentError(
            f"--params {args.params} is for one chain: a tree is calibrated with --params "
            f"{' or '.join(TREE_LEVELS)} (default: {DEFAULT_TREE_LEVEL})"
        )
    kind = _data_kind(args)
    if kind is not None and kind.is_pose:
        raise InvalidArgumentError(
            "--measure pose is for one chain: a tree is calibrated from one point per row "
            "(x, y, z and a tool)"
        )
    out, report = _calibration_outputs(args, tree.urdf_path)
    for chain in tree.chains:  # before the fit: a URDF it cannot be written to is known now
        check_exportable(chain, moving=True)  # markers hang from the tool's link
    columns = Columns(points=args.points)
    data = read_measurements(args.data, tree, columns)
    check = read_measurements(args.validate, tree, columns) if args.validate else None
    if kind is not None and kind.is_position:
        data = data.position_only()
        check = check.position_only() if check is not None else None

    def fit(rows: list, held: list | None):
        return calibrate(
            tree,
            rows[0],
            params=args.params,  # None: the tree's default
            validate=None if held is None else held[0],
            holdout=args.holdout,
            seed=args.seed,
            max_iterations=args.max_iterations,
        )

    result = cross_validated(args, fit, [data], None if check is None else [check])
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


_EXAMPLES = [
    "calib simulate ur5 --out meas.csv --noise-mm 0.05 --marker 0.01 0.02 0.05",
    "calib calibrate ur5 --data meas.csv --holdout 0.3 --out ur5_cal.urdf --report report.json",
    "calib calibrate data/realdata/tiago/tiago_48_schunk.urdf \\\n"
    "    --base base_footprint --tool wrist_ft_tool_link --points 1 \\\n"
    "    --data data/realdata/tiago/qualisys_2021-11-30_static_postures.csv \\\n"
    "    --validate data/realdata/tiago/qualisys_2021-11-26_static_postures.csv \\\n"
    "    --out tiago_cal.urdf --plot tiago.png",
    "calib calibrate ur5 --measure plane --data touches.csv --contact 0 0 0.05 --out cal.urdf",
]
"""``calibrate --help``'s examples (the TIAGo's: the real data's held-out 2.963 mm RMS)."""


def add_calibrate_parser(sub) -> None:
    """``calibrate``: its options in groups (robot, data, model, validation, contacts, ...)."""
    p = command_parser(
        sub, "calibrate", "calibrate from measurements, write a calibrated URDF", _EXAMPLES
    )
    add_chain_args(p.add_argument_group("robot"), trees=True)
    _add_data_args(p.add_argument_group("data"))
    _add_model_args(p.add_argument_group("model and parameters"))
    g = p.add_argument_group("validation")
    g.add_argument(
        "--validate", help="measurement CSV of other configurations: score the result on it"
    )
    g.add_argument(
        "--holdout",
        type=float,
        default=0.0,
        help="fraction of the rows set aside for validation (default: 0)",
    )
    g.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the holdout split, and with --folds of random folds: the postures "
        "shuffled before they are cut (default: 0; --folds without --seed: contiguous folds)",
    )
    g.add_argument(
        "--folds",
        type=int,
        metavar="K",
        help="K-fold cross-validation: K contiguous folds of the postures, each held out of a "
        "fit on the others; the URDF is the fit on every row (not with --holdout, --validate)",
    )
    g = p.add_argument_group("contacts and several chains (--measure plane|..., --term)")
    contact_cli.add_contact_arguments(g)
    contact_chains_cli.add_chain_arguments(g)
    pixels_cli.add_pixel_arguments(
        p.add_argument_group("cameras (--measure pixels)"), calibrate=True
    )
    _add_output_args(p.add_argument_group("outputs"))
    p.set_defaults(func=cmd_calibrate)


def _add_data_args(g: Group) -> None:
    """What the data are and how they are read: file, kind, points, units, orientation."""
    g.add_argument("--data", help="measurement CSV (joints, x y z or x1..zK, ...) (required)")
    g.add_argument(
        "--measure",
        choices=("auto", *CAMPAIGN_MEASURES, *CONTACT_NAMES, "pixels"),
        default="auto",
        help="auto: pose when the CSV has orientation columns, else position; or a contact "
        "(no coordinates in the CSV); or pixels: a camera's OBS.csv (--camera, --target) "
        "(default: auto)",
    )
    g.add_argument(
        "--points",
        type=_point_list,
        metavar="LIST",
        help="the measured points to fit, by their number in the file (1 for x1, y1, z1), "
        "separated by commas: 1, or 1,3 (default: every point); --validate's too",
    )
    g.add_argument(
        "--units",
        choices=tuple(UNITS),
        default="m",
        help="unit of the position columns (default: m)",
    )
    g.add_argument(
        "--orientation",
        choices=("auto", MARKERS, *ORIENTATION_FORMATS),
        default="auto",
        help="orientation columns: quaternion (xyzw or wxyz), rotation vector or rpy; "
        "markers: the x1..zK points (K >= 3) of one rigid set read as marker 1's position "
        "and the set's orientation (default: from the column names)",
    )
    g.add_argument(
        "--orientation-columns",
        nargs="+",
        metavar="COL",
        help="names of the orientation columns, in the format's order",
    )


def _add_model_args(g: Group) -> None:
    """What is fitted and how: level, guesses, fixed and free, compliance, loss, weights."""
    g.add_argument(
        "--params",
        choices=LEVELS,
        default=None,
        help="parameter level: auto keeps what the data support (cross-validated); frames = "
        "measurement frame + markers; offsets adds joint offsets; paper, complete (default: "
        "auto; a tree takes frames or complete, default complete)",
    )
    g.add_argument(
        "--marker",
        nargs="+",
        type=float,
        metavar="X",
        help="guess of each marker in the tool frame [m]: X Y Z, or 3 K numbers (default: 0)",
    )
    g.add_argument(
        "--fix",
        nargs="+",
        default=[],
        metavar="NAME",
        help="parameters held at their start, named as the printed table (elbow_joint:d3, d3, "
        "c2); not the frame or markers: fitted, but a gantry's first marker, held at --marker",
    )
    g.add_argument("--free", nargs="+", default=[], metavar="NAME", help="parameters always fitted")
    g.add_argument(
        "--elastic",
        action=BooleanOnce,
        default=None,
        help="fit joint compliance under gravity, which the URDF cannot hold (default: no; "
        "needs the URDF's masses)",
    )
    g.add_argument(
        "--loss",
        choices=LOSSES,
        default="linear",
        help="linear, or a robust loss (default: linear)",
    )
    g.add_argument(
        "--noise-mm",
        type=positive_number,
        help="instrument noise [mm]: scale of the robust loss and of the outlier test",
    )
    g.add_argument(
        "--orientation-weight",
        type=_weight,
        default=None,
        metavar="W|auto",
        help="weight of the orientation rows [m/rad] (default: auto, the ratio of the "
        "position and orientation errors of the registration, estimated until it settles)",
    )
    g.add_argument(
        "--max-iterations",
        type=int,
        default=DEFAULT_MAX_ITERATIONS,
        help=f"most residual evaluations of each fit (default: {DEFAULT_MAX_ITERATIONS})",
    )


def _add_output_args(g: Group) -> None:
    """What is written and printed: URDF, report, JSON, figure, origins, the frame's link."""
    g.add_argument("--out", required=True, help="calibrated URDF to write")
    g.add_argument("--report", help="JSON report to write (also when the model is refused)")
    g.add_argument("--json", action="store_true", help="print the report as JSON")
    add_look_args(g)
    g.add_argument(
        "--world-link",
        metavar="NAME",
        help="also write the measurement frame as link NAME, the new root of the URDF: forward "
        "kinematics from NAME gives measured coordinates",
    )
    g.add_argument(
        "--on-robot",
        action="store_true",
        help="the instrument is the base frame itself, on the robot (a head camera measuring "
        "the hand): its calibrated placement is written into the base frame's fixed joint",
    )
