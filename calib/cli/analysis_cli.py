"""``calib list``, ``show``, ``analyze``, ``sweep`` and ``demo``: chains, trees, identifiability.

What a chain or tree is and which of its parameters are identifiable.
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
from pathlib import Path

from ..calibration.analysis import analyze
from ..core.checks import least_configurations
from ..core.choices import DEFAULT_SET, PARAMETER_SETS, VERDICT_SET
from ..core.progress import terminal
from ..core.words import counted
from ..exceptions import InvalidArgumentError
from ..identification.report import analysis_text, coupling_lines, mdh_table, tree_table
from ..kinematics.mdh import from_chain
from ..kinematics.robot import load_chain
from ..kinematics.tree import load_robot
from ..kinematics.tree_model import from_tree
from . import contact_chains_cli, pixels_cli
from .common import (
    add_chain_args,
    add_measure_args,
    add_sampling_args,
    check_output_paths,
    command_parser,
    given_options,
    print_json,
    robot_words,
    tool_arg,
    write_outputs,
)
from .listing import catalog_listing

__all__ = [
    "add_analysis_parsers",
    "add_demo_parser",
    "add_sweep_parser",
    "cmd_analyze",
    "cmd_demo",
    "cmd_list",
    "cmd_show",
    "cmd_sweep",
]


def cmd_list(args: argparse.Namespace) -> int:
    """Print the catalog."""
    print(catalog_listing(args.json))
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """Print the MDH table of a chain or tree."""
    robot = load_robot(args.robot, args.base, tool_arg(args))
    model, table = _model_and_table(robot)
    mimic = () if robot.coupling is None else robot.coupling.mimic
    if args.json:
        tools = {"tools": list(robot.tool_frames)} if robot.is_tree else {"tool": model.tool_frame}
        print_json(
            {"robot": robot.name, "base": robot.base_frame}
            | tools
            | {
                "urdf": str(robot.urdf_path),
                "frames": model.rows(),
                "variables": list(robot.variable_names),
                "mimic": [dataclasses.asdict(mj) | {"row": mj.joint + 1} for mj in mimic],
            }
        )
    else:
        print(f"{robot.name}: {robot.base_frame} -> {model.tool_frame} ({robot.urdf_path})")
        print(table)
        for line in coupling_lines(mimic):
            print(line)
    return 0


def _model_and_table(robot):
    """The MDH model of a chain or tree, and its text table."""
    if robot.is_tree:
        tree_model = from_tree(robot)
        return tree_model, tree_table(tree_model)
    mdh = from_chain(robot)
    return mdh, mdh_table(mdh)


def _analyze(args: argparse.Namespace):
    """The analysis ``calib.analyze`` gives for a robot (the Python function the CLI calls)."""
    return analyze(
        args.robot,
        args.base,
        tool_arg(args),
        args.measure,
        args.marker,
        args.params or DEFAULT_SET,
        args.configs,
        args.seed,
    )


def cmd_analyze(args: argparse.Namespace) -> int:
    """Identifiable parameters of one chain, or what the terms of a problem determine."""
    if args.term:
        return _analyze_terms(args)
    if args.measure == "pixels":
        return pixels_cli.analyze_pixels_command(args)
    pixels_cli.refuse_pixel_options(args)
    if args.markers is not None:
        return _analyze_markers(args)
    res = _analyze(args)
    if args.json:
        print_json(res.to_dict())
    else:
        print(analysis_text(res))
        print(_next_step(args, res))
    return 0


def _next_step(args: argparse.Namespace, res) -> str:
    """The closing line of ``calib analyze``: plan the postures, measure (or touch), calibrate.

    K's least value is design's: its rows reach the complete model's rank (the frame and
    markers free make up what the paper set misses; a contact's or a tree's design and
    calibration fit the complete model).
    """
    kind, robot = res.measurement, shlex.join(robot_words(args))
    least = least_configurations(res.n_complete, kind.n_rows * len(res.tool_frames))
    if kind.is_contact:
        measure = f" --measure {kind.label}"
        return (
            f"next: calib design {robot}{measure} --configs K --out touches.csv chooses K >= "
            f"{least} postures on the {kind.label} contact (--candidates-file, a recorded touch "
            f"first, places it where yours is); touch at them, then calib calibrate {robot}"
            f"{measure} --data TOUCHES.csv --out calibrated.urdf"
        )
    paper = res.params.label == "paper" and len(res.tool_frames) == 1  # a tree: complete
    params = " --params paper" if paper else ""
    if not getattr(kind, "is_campaign", False):
        return (
            f"next: calib design and calibrate take a point's position or the pose (--measure "
            f"position or pose), not the rows {kind.label} alone"
        )
    marker = " --marker " + " ".join(f"{x:g}" for x in kind.marker) if any(kind.marker) else ""
    if kind.n_rows == 6 and len(res.tool_frames) > 1:
        return (
            f"next: a tree is designed and calibrated from the positions of a point on each "
            f"tool: calib analyze {robot}{marker} --measure position counts what they identify "
            "and says what then"
        )
    measure = " --measure pose" if kind.n_rows == 6 else ""
    return (
        f"next: calib design {robot}{measure}{marker}{params} --configs K --out plan.csv "
        f"chooses K >= {least} postures (its last line predicts the error for K); measure "
        f"them, then calib calibrate {robot}{marker}{params} --data MEASURED.csv --out "
        "calibrated.urdf"
    )


TERM_REFUSES = ("base", "tool", "measure", "marker", "markers", "configs", "seed")
"""Options of ``analyze`` that ``--term`` replaces: the terms' files say what was measured."""


def _analyze_terms(args: argparse.Namespace) -> int:
    """``analyze --term ...``: what these terms determine together (``calib.analyze(problem)``)."""
    from ..calibration.problem import Problem

    typed = given_options(args, TERM_REFUSES)
    if typed:
        raise InvalidArgumentError(f"{typed[0]} is not for --term: its files say what is measured")
    asked = contact_chains_cli.asked_terms(args)
    if any(t[4] for t in asked):
        raise InvalidArgumentError("analyze --term counts the data: give no VALIDATION file")
    if args.params is not None and all(t[0] != "pixels" for t in asked):
        raise InvalidArgumentError("--params with --term is for a pixels term (the mounting)")
    if all(t[0] != "pixels" for t in asked):
        pixels_cli.refuse_pixel_options(args)  # --camera, --target: for a pixels term
    pixels_cli.refuse_paper(args)
    chains = contact_chains_cli.term_chains(args, asked)
    res = analyze(Problem(contact_chains_cli.read_terms(args, asked, chains)))
    if args.json:
        print_json(res.to_dict())
    else:
        print(res.summary())
        step = _terms_next_step(args)
        if step is not None:
            print(step)
    return 0


def _terms_next_step(args: argparse.Namespace) -> str | None:
    """The closing line of ``analyze --term``: calibrate these terms (the same words).

    One term is calibrate's ``--base``, ``--tool`` and ``--data`` (a pixels term: its camera's
    ``--measure pixels``); one loop term: None (a loop is a term beside others).
    """
    words = ["calibrate", args.robot]
    if len(args.term) > 1:
        words += [w for term in args.term for w in ("--term", *term)]
    elif args.term[0][0] == "pixels":
        words += ["--measure", "pixels", "--tool", args.term[0][2], "--data", args.term[0][3]]
    elif args.term[0][0] != "loop":
        kind, base, tool, data = args.term[0][:4]
        words += ["--measure", kind, "--base", base, "--tool", tool, "--data", data]
    else:
        return None
    if any(t[0] == "pixels" for t in args.term):
        words += [w for camera in args.camera or () for w in ("--camera", *camera)]
        words += ["--target", args.target] if args.target else []
        words += ["--params", args.params] if args.params else []
    words += ["--out", "calibrated.urdf"]
    return f"next: calib {shlex.join(map(str, words))} fits what the data determine"


def _analyze_markers(args: argparse.Namespace) -> int:
    """What a calibration with K measured points (and free frame and markers) identifies."""
    from ..calibration.chain_registration import held_note
    from ..outputs.sweep import marker_count

    _refuse_with_markers(args)
    chain = load_robot(args.robot, args.base, tool_arg(args))
    if chain.is_tree:
        raise InvalidArgumentError("--markers counts for one chain: give one --tool")
    count = marker_count(chain, args.markers, args.measure, args.configs, args.seed)
    names, held, theory = count.names, count.held, count.theory
    notes = [held_note(held, None)] if held else []
    entries = _marker_entries(chain, names)
    if args.json:
        print_json(
            {
                "robot": chain.name,
                "markers": args.markers,
                "measure": args.measure,
                "n_identifiable": len(names),
                "n_theory": theory,
                "parameters": list(names),
                "identifiable": entries,
                "n_held": len(held),
                "notes": notes,
            }
        )
    else:
        print(
            f"{chain.name}: {chain.base_frame} -> {chain.tool_frame}, "
            f"{counted(args.markers, 'markers')}, "
            f"{args.measure}: {counted(len(names), 'identifiable parameters')} (measurement "
            f"frame and markers free{f', {len(held)} held' if held else ''}), theory "
            f"{'n/a' if theory is None else theory}"
        )
        print(_marker_lines(entries))
        for note in notes:
            print(f"  {note}")
    return 0


def _marker_entries(chain, names) -> list[dict]:
    """Each parameter of ``analyze --markers``: its MDH row and URDF joint, or its frame.

    ``frame.*``: the measurement frame (``measurement``); ``markerK.*`` and ``tool.*`` (the
    tool's orientation, pose), the tool frame's; an MDH row without a joint: the base or tool
    frame (as ``analyze``'s ``parameters``).
    """
    from ..identification.parameters import ROW_NAME, joint_of

    joint_names = from_chain(chain).joint_names
    out = []
    for name in names:
        row = ROW_NAME.fullmatch(name)
        k = None if row is None else int(row.group(2))
        joint = None if k is None else joint_of(name, joint_names)
        frame = None
        if joint is None:
            measured = name.startswith("frame.")
            frame = "measurement" if measured else chain.base_frame if k == 0 else chain.tool_frame
        out.append({"name": name, "row": k, "joint": joint, "frame": frame})
    return out


def _marker_lines(entries: list[dict]) -> str:
    """The parameters of ``analyze --markers`` by joint, in row order after the frames."""
    groups: dict[str, list[str]] = {}
    rows: dict[str, float] = {}
    for e in entries:
        label = e["joint"] or _marker_frame(e)
        groups.setdefault(label, []).append(e["name"])
        rows.setdefault(label, -1.0 if e["row"] is None else e["row"])
    order = sorted(groups, key=lambda label: rows[label])  # stable: frame, markers, tool
    width = max(len(label) for label in order)
    return "\n".join(f"  {label:<{width}}  {', '.join(groups[label])}" for label in order)


def _marker_frame(entry: dict) -> str:
    """The label of a parameter of no joint: its frame, its markers, the tool's orientation."""
    name = entry["name"]
    if entry["row"] is not None:
        return "(base frame)" if entry["row"] == 0 else "(tool frame)"
    if name.startswith("frame."):
        return "(measurement frame)"
    return "(markers)" if name.startswith("marker") else "(tool orientation)"


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job on embedded defaults: the paper's robot and a UR5."""
    print("== The paper's AID robot (Khalil & Gautier 1991), position measurement ==")
    print(mdh_table(from_chain(load_chain("aid"))))
    print()
    print(analysis_text(analyze("aid", measure="position", params="paper")))
    print()
    print("== UR5, full pose measurement, complete parameter set ==")
    res = analyze("ur5", measure="pose", params="complete")
    print(analysis_text(res))
    ur5 = argparse.Namespace(robot="ur5", base=None, tool=None)
    print(_next_step(ur5, res))
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """Analyse every catalog chain and tree (and extra URDFs) and print one table."""
    from ..outputs.plots import counts_figure, figure_bytes, figure_format
    from ..outputs.sweep import rows_table, rows_to_csv, sweep

    if args.markers is not None:  # the counts of the complete set with K markers unknown
        _refuse_with_markers(args)
    plot_format = figure_format(args.plot, "--plot") if args.plot else None
    check_output_paths(
        {"--csv": args.csv, "--plot": args.plot}, {f"the URDF {u}": u for u in args.urdf}
    )
    rows = sweep(
        robots=args.robots,
        extra=args.urdf,
        measure=args.measure,
        marker=args.marker,
        configs=args.configs,
        seed=args.seed,
        progress=terminal(args.quiet),
        params=args.params,
        markers=args.markers,
    )
    files: dict[Path, str | bytes] = {}
    if args.csv:
        files[Path(args.csv)] = rows_to_csv(rows)
    if plot_format is not None:  # --plot given
        title = f"Base parameters per chain, {args.measure} measurement"
        formula = {}
        if args.markers is not None:
            title += f", {counted(args.markers, 'markers')}"
            formula = {"theory": "4R+2P+3K" + (" +3" if args.measure == "pose" else "")}
        fig = counts_figure(rows, title=title, **formula)
        files[Path(args.plot)] = figure_bytes(fig, plot_format)
    write_outputs(files)
    if args.json:
        print_json(
            {
                "measure": args.measure,
                "params": None if args.markers is not None else args.params,  # not used
                "rows": [dataclasses.asdict(r) for r in rows],
            }
        )
    else:
        print(rows_table(rows))
        bad = sum(r.error is not None for r in rows)
        verdict = f"verdict for the {args.params} set"
        if args.markers is not None:
            verdict = (
                f"{counted(args.markers, 'markers')}, measurement frame and markers free: the "
                f"complete set's count (as analyze --markers {args.markers}), verdict against "
                "the theory"
            )
        print(
            f"\n{counted(len(rows), 'chains and trees', 'chain or tree')}, {len(rows) - bad} "
            f"analysed, {bad} with an error (reason in the last column); {args.measure}, {verdict}"
        )
        for path in files:  # as design, simulate and calibrate say what they wrote
            print(f"wrote {path}")
    return 0


def _refuse_with_markers(args: argparse.Namespace) -> None:
    """``analyze`` and ``sweep --markers K`` count the complete set, the K markers unknown.

    Raises:
        InvalidArgumentError: A measure other than position or pose, ``--marker`` or
            ``--params paper`` given (they would change nothing).
    """
    from ..identification.kinds import kind_of

    if not getattr(kind_of(args.measure), "is_campaign", False):
        raise InvalidArgumentError("--markers takes --measure position or pose")
    paper = (
        ["--params paper"] if given_options(args, ("params",)) and args.params == "paper" else []
    )
    typed = given_options(args, ("marker",)) + paper
    if typed:  # the count is of every joint placement (complete), the markers' places unknown
        raise InvalidArgumentError(
            f"{typed[0]} is not for --markers: it counts every joint placement component with "
            f"the measurement frame and the {args.markers} markers unknown"
        )


def add_analysis_parsers(sub) -> None:
    """``list``, ``show`` and ``analyze``."""
    p = command_parser(sub, "list", "robots of the catalog", ["calib list", "calib list --json"])
    p.add_argument_group("output").add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_list)
    p = command_parser(
        sub,
        "show",
        "modified-DH table of a chain or tree",
        ["calib show ur5", "calib show talos --tool wrist_left_ft_tool_link --json"],
    )
    add_chain_args(p.add_argument_group("robot"), trees=True)
    p.add_argument_group("output").add_argument(
        "--json", action="store_true", help="print JSON (radians, metres)"
    )
    p.set_defaults(func=cmd_show)
    _add_analyze_parser(sub)


def _add_analyze_parser(sub) -> None:
    p = command_parser(
        sub,
        "analyze",
        "identifiable (base) parameters of a chain or tree",
        [
            "calib analyze ur5                      # a point measured (position), complete set",
            "calib analyze ur5 --measure pose       # the tool's pose measured",
            "calib analyze aid --params paper       # the paper's set (Khalil & Gautier 1991)",
            "calib analyze ur5 --markers 3          # what 3 points per configuration identify",
            "calib analyze ur5 --measure plane      # touches of a plane, no instrument",
            "calib analyze talos --tool wrist_left_ft_tool_link --tool wrist_right_ft_tool_link",
            "calib analyze talos_full_v2.urdf --term plane left_sole_link gripper_left_base_link "
            "L.csv --term plane left_sole_link gripper_right_base_link R.csv  # what they "
            "determine together",
        ],
    )
    add_chain_args(p.add_argument_group("robot"), trees=True)
    g = p.add_argument_group("instrument")
    add_measure_args(g)
    _add_markers_arg(g)
    g = p.add_argument_group("parameters and configurations")
    g.add_argument(
        "--params",
        default=None,
        choices=PARAMETER_SETS,
        help=f"parameter set: complete (what calibrate chooses from) or paper (the paper's: "
        f"joint offsets fixed by the model) (default: {DEFAULT_SET}; with --measure pixels, "
        "calibrate's default: the target's mounting known)",
    )
    add_sampling_args(g, "m")
    pixels_cli.add_pixel_arguments(p.add_argument_group("cameras (--measure pixels)"), noise=False)
    p.add_argument_group("several terms").add_argument(
        "--term",
        action="append",
        nargs="+",
        metavar="ARG",
        help="what a calibration of these terms determines together, at their rows: KIND BASE "
        f"TOOL DATA, KIND one of {', '.join(contact_chains_cli.TERM_KINDS)}, once per term "
        "(as calibrate's --term; one is enough), instead of --base, --tool, --measure",
    )
    p.add_argument_group("output").add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_analyze, refine_targets=False, refine_intrinsics=False)


def add_sweep_parser(sub) -> None:
    """``sweep``."""
    p = command_parser(
        sub,
        "sweep",
        "analyse every catalog chain and tree (and extra URDFs): one table",
        [
            "calib sweep                            # every robot, a point measured",
            "calib sweep --measure pose --csv sweep.csv",
            "calib sweep --plot survey.png models/mimic_arm.urdf  # and a URDF of yours",
            "calib sweep --robots ur5 panda talos_left_arm -- my_arm.urdf  # these alone",
            "calib sweep --robots ur5 panda --markers 3  # what 3 points identify, side by side",
        ],
    )
    g = p.add_argument_group("robots")
    g.add_argument("urdf", nargs="*", help="extra URDF files analysed after the catalog")
    g.add_argument(
        "--robots",
        nargs="+",
        metavar="NAME",
        help="catalog names analysed instead of the whole catalog (see `calib list`)",
    )
    g = p.add_argument_group("instrument")
    add_measure_args(g)
    _add_markers_arg(g)
    g = p.add_argument_group("parameters and configurations")
    g.add_argument(
        "--params",
        default=VERDICT_SET,
        choices=PARAMETER_SETS,
        help=f"set the verdict column judges (default: {VERDICT_SET}; the complete set reaches the "
        "rank on every chain, the counts of both sets are in the table)",
    )
    add_sampling_args(g, "per chain")
    g = p.add_argument_group("outputs")
    g.add_argument("--csv", help="also write the table as CSV to this file ('-': stdout)")
    g.add_argument("--plot", help="also save the counts plot to this .png, .svg or .pdf file")
    g.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_sweep)


def _add_markers_arg(g) -> None:
    """The ``--markers K`` option of ``analyze`` and ``sweep``."""
    g.add_argument(
        "--markers",
        type=int,
        help="count what a calibration identifies with K points measured per configuration "
        "(frame and markers free)",
    )


def add_demo_parser(sub) -> None:
    """``demo``."""
    p = command_parser(
        sub, "demo", "analyse the paper's robot and a UR5 (no argument needed)", ["calib demo"]
    )
    p.set_defaults(func=cmd_demo)
