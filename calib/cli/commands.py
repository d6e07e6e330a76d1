"""The ``calib`` command line."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import logging
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

from .. import __version__
from ..calibration.options import (
    DEFAULT_LEVEL,
    DEFAULT_MAX_ITERATIONS,
    LEVELS,
    LOSSES,
)
from ..choices import (
    CAMPAIGN_MEASURES,
    CONTACT_MEASURES,
    DEFAULT_CONFIGS,
    MARKERS,
    ORIENTATION_FORMATS,
    PARAMETER_SETS,
    UNITS,
)
from ..exceptions import CalibError, CalibrationRefusedError, DataError, InvalidArgumentError
from ..fileio import check_outputs, json_text, write_files_atomic, written_in_place
from ..identification.identifiability import analyze
from ..identification.measures import CONTACT_NAMES
from ..identification.report import analysis_text, coupling_lines, mdh_table, tree_table
from ..kinematics.catalog import catalog_files, installed_dirs
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain, load_chain
from ..kinematics.tree import Tree, load_robot
from ..kinematics.tree_model import from_tree
from ..launcher import catalog_listing
from . import contact_cli

__all__ = [
    "CHAIN_ONLY",
    "THREADS_ENV",
    "BooleanOnce",
    "add_chain_args",
    "blas_threads",
    "build_parser",
    "check_output_paths",
    "cmd_analyze",
    "cmd_calibrate",
    "cmd_demo",
    "cmd_list",
    "cmd_show",
    "cmd_simulate",
    "cmd_sweep",
    "compliance_path",
    "given_options",
    "main",
    "positive_number",
    "print_json",
    "tool_arg",
    "warning_lines",
    "write_outputs",
]

if TYPE_CHECKING:
    import numpy as np

_GIVEN = "_calib_given"
"""Namespace attribute where the actions note the options given (dest: option string);
:func:`main` moves it to ``args.given``, where a command checks which options were given."""


def _note_given(parser, namespace, dest: str, option_string: str | None) -> None:
    """Record an option as given; the same option (or its opposite) given again is an error."""
    given = vars(namespace).setdefault(_GIVEN, {})
    if option_string is not None and dest in given:
        first = given[dest]
        what = "given more than once" if first == option_string else f"contradicts {first}"
        parser.error(f"argument {option_string}: {what} (give it once)")
    given[dest] = option_string


class _StoreOnce(argparse._StoreAction):
    """A value option given twice is an error (argparse would silently keep the last)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        _note_given(parser, namespace, self.dest, option_string)
        super().__call__(parser, namespace, values, option_string)


class _StoreTrueOnce(argparse._StoreTrueAction):
    """A flag given twice is an error, like a value option."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        _note_given(parser, namespace, self.dest, option_string)
        super().__call__(parser, namespace, values, option_string)


class BooleanOnce(argparse.BooleanOptionalAction):
    """``--x`` / ``--no-x`` given once: both, or one twice, is a usage error."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        """Note the option, then set it."""
        _note_given(parser, namespace, self.dest, option_string)
        super().__call__(parser, namespace, values, option_string)


class _AppendNoted(argparse._AppendAction):
    """A repeatable option (``--tool``, ``--obstacle``): repeats allowed, noted as given."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        vars(namespace).setdefault(_GIVEN, {})[self.dest] = option_string
        super().__call__(parser, namespace, values, option_string)


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (like every other calib error), no repeated value."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.register("action", None, _StoreOnce)
        self.register("action", "store", _StoreOnce)
        self.register("action", "store_true", _StoreTrueOnce)
        self.register("action", "append", _AppendNoted)

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"calib: error: {self.prog}: {message} (see --help)\n")


def given_options(args: argparse.Namespace, dests) -> list[str]:
    """The options among ``dests`` (argparse dests) the user gave, as typed (``--no-x``)."""
    given = getattr(args, "given", {})
    return [given[d] for d in dests if given.get(d)]


def positive_number(text: str) -> float:
    """The type of a positive option: a finite number > 0 (else a usage error)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0.0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a positive number, got '{text}'")
    return value


def print_json(obj: dict) -> None:
    """Print a JSON document (indented)."""
    print(json.dumps(obj, indent=2))


def cmd_list(args: argparse.Namespace) -> int:
    """Print the catalog."""
    print(catalog_listing(args.json))
    return 0


def tool_arg(args: argparse.Namespace) -> str | tuple[str, ...] | None:
    """``--tool`` of a command that takes several: None, one name, or several (a tree)."""
    if args.tool is None or isinstance(args.tool, str):
        return args.tool
    return args.tool[0] if len(args.tool) == 1 else tuple(args.tool)


def cmd_show(args: argparse.Namespace) -> int:
    """Print the MDH table of a chain or tree."""
    chain = load_robot(args.robot, args.base, tool_arg(args))
    if chain.is_tree:
        return _show_tree(chain, args.json)
    mdh = from_chain(chain)
    mimic = () if chain.coupling is None else chain.coupling.mimic
    if args.json:
        print_json(
            {
                "robot": chain.name,
                "base": chain.base_frame,
                "tool": chain.tool_frame,
                "urdf": str(chain.urdf_path),
                "frames": mdh.rows(),
                "variables": list(chain.variable_names),
                "mimic": [dataclasses.asdict(mj) | {"row": mj.joint + 1} for mj in mimic],
            }
        )
    else:
        print(f"{chain.name}: {chain.base_frame} -> {chain.tool_frame} ({chain.urdf_path})")
        print(mdh_table(mdh))
        for line in coupling_lines(mimic):
            print(line)
    return 0


def _show_tree(tree: Tree, as_json: bool) -> int:
    model = from_tree(tree)
    mimic = () if tree.coupling is None else tree.coupling.mimic
    if as_json:
        print_json(
            {
                "robot": tree.name,
                "base": tree.base_frame,
                "tools": list(tree.tool_frames),
                "urdf": str(tree.urdf_path),
                "frames": model.rows(),
                "variables": list(tree.variable_names),
                "mimic": [dataclasses.asdict(mj) | {"row": mj.joint + 1} for mj in mimic],
            }
        )
    else:
        print(f"{tree.name}: {tree.base_frame} -> {model.tool_frame} ({tree.urdf_path})")
        print(tree_table(model))
        for line in coupling_lines(mimic):
            print(line)
    return 0


def _analyze(args: argparse.Namespace):
    return analyze(
        args.robot,
        args.base,
        tool_arg(args),
        args.measure,
        args.marker,
        args.params,
        args.configs,
        args.seed,
    )


def cmd_analyze(args: argparse.Namespace) -> int:
    """Identifiable parameters of one chain."""
    if args.markers is not None:
        return _analyze_markers(args)
    res = _analyze(args)
    if args.json:
        print_json(res.to_dict())
    else:
        print(analysis_text(res))
    return 0


def _analyze_markers(args: argparse.Namespace) -> int:
    """What a calibration with K measured points (and free frame and markers) identifies."""
    from ..calibration.counting import identifiable_parameters
    from ..identification.kinds import kind_of

    kind = kind_of(args.measure)
    if not getattr(kind, "is_campaign", False):
        raise InvalidArgumentError("--markers takes --measure position or pose")
    chain = load_robot(args.robot, args.base, tool_arg(args))
    if chain.is_tree:
        raise InvalidArgumentError("--markers counts for one chain: give one --tool")
    names = identifiable_parameters(chain, args.markers, args.measure, args.configs, args.seed)
    if args.json:
        print_json(
            {
                "robot": chain.name,
                "markers": args.markers,
                "measure": args.measure,
                "n_identifiable": len(names),
                "parameters": list(names),
            }
        )
    else:
        print(
            f"{chain.name}: {chain.base_frame} -> {chain.tool_frame}, {args.markers} marker(s), "
            f"{args.measure}: {len(names)} identifiable parameters (measurement frame and "
            f"markers free)"
        )
        print("  " + ", ".join(names))
    return 0


def _data_kind(args: argparse.Namespace):
    """The kind ``--measure`` asks a calibration to use, or None for ``auto`` (the data's)."""
    from ..identification.kinds import campaign_kind

    return None if args.measure == "auto" else campaign_kind(args.measure)


def _simulate_contacts(args: argparse.Namespace) -> int:
    """``calib simulate --measure plane|...``: touches of the true robot, joints only."""
    from ..measurements.contact_campaign import contacts_csv, simulate_contacts

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
    )
    truth = campaign.truth
    write_outputs({out: contacts_csv(campaign.data), truth_path: json_text(truth.to_dict())})
    print(
        f"{chain.name}: {campaign.data.m} touches, measure {args.measure}, "
        f"{len(campaign.data.contacts)} {campaign.data.id_column}(s), {len(truth.params)} "
        f"{truth.params.label} parameters perturbed ({truth.error_mm:g} mm, "
        f"{truth.error_mrad:g} mrad), joint noise {truth.noise_mrad:g} mrad, seed {truth.seed}"
    )
    print(f"wrote {out} and {truth_path} (true errors and {campaign.data.id_column}s)")
    return 0


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job on embedded defaults: the paper's robot and a UR5."""
    print("== The paper's AID robot (Khalil & Gautier 1991), position measurement ==")
    print(mdh_table(from_chain(load_chain("aid"))))
    print()
    print(analysis_text(analyze("aid", measure="position", params="paper")))
    print()
    print("== UR5, full pose measurement, complete parameter set ==")
    print(analysis_text(analyze("ur5", measure="pose", params="complete")))
    return 0


def write_outputs(files: dict[Path, str | bytes]) -> None:
    """Write output files (atomically for regular files; one-line OutputError on failure)."""
    write_files_atomic(files)


def check_output_paths(
    outputs: Mapping[str, Path | str | None], inputs: Mapping[str, Path | str | None]
) -> None:
    """Refuse now, in one line, outputs that cannot be written or would overwrite a file.

    The files protected: the command's inputs, the installed catalog's files, every file of
    the installed packages calib reads (:func:`~calib.kinematics.catalog.installed_dirs`), the other
    outputs.
    """
    check_outputs(outputs, {**inputs, **catalog_files()}, installed_dirs())


def _configs(args: argparse.Namespace, robot: Chain | Tree) -> int | np.ndarray:
    """``simulate``'s configurations: ``--configs`` random ones, or ``--configs-file``'s."""
    if not args.configs_file:
        return args.configs
    from ..design.configurations import read_configurations

    return read_configurations(args.configs_file, robot)


def cmd_simulate(args: argparse.Namespace) -> int:
    """Simulate a measurement campaign; write the CSV and the true errors (JSON)."""
    from ..identification.kinds import campaign_kind
    from ..measurements.csvfile import measurements_csv
    from ..measurements.simulation import simulate

    if args.measure in CONTACT_MEASURES:
        return _simulate_contacts(args)
    kind = campaign_kind(args.measure, args.marker)
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
    campaign = simulate(
        chain,
        configs,
        kind,
        None,
        args.error_mm,
        args.error_mrad,
        args.noise_mm,
        args.noise_mrad,
        args.seed,
        args.params,
    )
    truth = campaign.truth
    write_outputs(
        {out: measurements_csv(campaign.measurements), truth_path: json_text(truth.to_dict())}
    )
    print(
        f"{chain.name}: {campaign.measurements.m} configurations, measure {args.measure}, "
        f"{len(truth.params)} {truth.params.label} parameters perturbed "
        f"({truth.error_mm:g} mm, {truth.error_mrad:g} mrad), noise {truth.noise_mm:g} mm"
        + (f", {truth.noise_mrad:g} mrad" if kind.is_pose else "")
        + f", seed {truth.seed}"
    )
    print(f"wrote {out} and {truth_path} (true errors, {truth.analysis.n_base} base values)")
    return 0


def _simulate_tree(args: argparse.Namespace, tree: Tree, configs, paths) -> int:
    """`simulate` with several tools: every tool at each configuration, a ``tool`` column.

    ``configs``: a count or joint positions; ``paths``: ``(--out, --truth)``, checked.
    """
    from ..measurements.csvfile import measurements_csv
    from ..measurements.tree_campaign import simulate_tree

    out, truth_path = paths
    camp = simulate_tree(
        tree,
        configs,
        args.marker,
        args.error_mm,
        args.error_mrad,
        args.noise_mm,
        args.seed,
        args.params,
    )
    truth = {
        "robot": tree.name,
        "base_frame": tree.base_frame,
        "tools": list(tree.tool_frames),
        "params": camp.params.label,
        "errors": dict(zip(camp.params.names, camp.errors.tolist(), strict=True)),
        "markers": camp.markers.tolist(),
        "seed": args.seed,
    }
    write_outputs({out: measurements_csv(camp.measurements), truth_path: json_text(truth)})
    print(
        f"{tree.name}: {camp.measurements.m // tree.n_tools} configurations x {tree.n_tools} tools "
        f"({', '.join(tree.tool_frames)}), {len(camp.params)} {camp.params.label} parameters "
        f"perturbed ({args.error_mm:g} mm, {args.error_mrad:g} mrad), noise {args.noise_mm:g} mm"
    )
    print(f"wrote {out} and {truth_path}")
    return 0


def _weight(text: str) -> float | None:
    """``--orientation-weight``: a number [m/rad] or ``auto`` (None)."""
    if text == "auto":
        return None
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or auto, got '{text}'") from None


def _columns(args: argparse.Namespace):
    from ..measurements.csvfile import Columns

    cols = tuple(args.orientation_columns) if args.orientation_columns else None
    return Columns(args.orientation, cols, args.units)


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Calibrate from a CSV; write the calibrated URDF (if it passes every check) and a report.

    Every warning raised on the way (the data's, the fit's) is printed as usual and goes into
    the report's ``warnings`` too.
    """
    with _recorded_warnings() as recorded:
        chain = load_robot(args.robot, args.base, tool_arg(args))
        if contact_cli.is_contact_run(args):
            return contact_cli.calibrate_contacts_command(args, chain)
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


def _with_warnings(report: dict, recorded: Sequence[warnings.WarningMessage]) -> dict:
    """The report with the recorded warnings added to its ``warnings`` (each once, in order)."""
    lines = list(report.get("warnings", []))
    for w in recorded:
        text = _one_line(w.message)
        if issubclass(w.category, UserWarning) and text not in lines:
            lines.append(text)
    return {**report, "warnings": lines}


def _calibrate_chain(args: argparse.Namespace, chain: Chain, recorded) -> int:
    """`calibrate` with one tool."""
    from ..calibration import calibrate  # only this command loads the calibration
    from ..calibration.text import calibration_text
    from ..kinematics.elastic import compliance_document
    from ..measurements.csvfile import read_measurements

    out, report = _calibration_outputs(args, chain.urdf_path)
    comp = None if written_in_place(out) else compliance_path(out)
    if comp is None and args.elastic:
        raise InvalidArgumentError(
            f"--out {out} is no regular file: --elastic writes the compliance file next to it"
        )
    check_output_paths(
        {"--out": out, "--report": report, "the compliance file": comp},
        {"the nominal URDF": chain.urdf_path, "--data": args.data, "--validate": args.validate},
    )
    columns = _columns(args)
    data = read_measurements(args.data, chain, columns)
    _check_links(chain, data.n_markers, args.world_link)  # before the fit
    check = read_measurements(args.validate, chain, columns) if args.validate else None
    kind = _data_kind(args)
    if kind is not None and kind.is_position:
        data = data.position_only()
        check = check.position_only() if check is not None else None
    elif kind is not None and kind.is_pose and data.quaternion is None:
        raise DataError(args.data, "--measure pose needs orientation columns (qx, qy, qz, qw, ...)")
    result = calibrate(
        chain,
        data,
        params=args.params or DEFAULT_LEVEL,
        marker=args.marker,
        validate=check,
        fix=tuple(args.fix),
        free=tuple(args.free),
        elastic=args.elastic,
        loss=args.loss,
        noise_mm=args.noise_mm,
        orientation_weight=args.orientation_weight,
        max_iterations=args.max_iterations,
        holdout=args.holdout,
        seed=args.seed,
    )

    def files() -> dict[Path, str | bytes]:
        try:
            urdf: dict[Path, str | bytes] = {out: result.urdf(args.world_link)}
        except InvalidArgumentError as exc:  # the library names the keyword: say the flag
            text = str(exc)
            if not text.startswith("world_link:"):
                raise
            raise InvalidArgumentError(f"--world-link{text.removeprefix('world_link')}") from None
        if result.elastic:
            if comp is None:
                raise InvalidArgumentError(
                    f"--out {out} is no regular file: the fitted compliance cannot be written "
                    f"next to it (give a file, or --no-elastic)"
                )
            urdf[comp] = json_text(compliance_document(result, str(out)))
        return urdf

    return _write_calibration(
        args,
        _with_warnings(result.to_dict(args.world_link), recorded),
        lambda: calibration_text(result),
        result.refusal,
        files,
        (out, report),
    )


def compliance_path(out: Path) -> Path:
    """The compliance file written next to the URDF ``out``: ``<stem>.compliance.json``."""
    return out.with_name((out.stem if out.suffix == ".urdf" else out.name) + ".compliance.json")


def _check_links(chain: Chain, n_markers: int, world_link: str | None) -> None:
    """Refuse now a URDF the calibration cannot be written to, or new links with taken names."""
    from ..kinematics.urdf_export import (
        check_base_fixed,
        check_exportable,
        child_link,
        edited_joints,
        read_urdf_source,
    )
    from ..kinematics.urdf_links import check_new_names, marker_joints, marker_link_names

    check_exportable(chain)
    root = read_urdf_source(chain)[1]
    tool_link = child_link(edited_joints(root, chain)[1])
    kept = marker_joints(root, chain.tool_frame, tool_link, n_markers)
    names = marker_link_names(chain.tool_frame, n_markers)
    check_new_names(root, tuple(n for n in names if n not in kept), "marker links")
    if world_link is not None:
        check_new_names(root, (world_link,), "--world-link")
        try:
            check_base_fixed(chain)
        except CalibError as exc:  # the library names the keyword: say the flag
            raise CalibError(f"--world-link{str(exc).removeprefix('world_link')}") from None


def _calibration_outputs(args: argparse.Namespace, urdf: Path) -> tuple[Path, Path | None]:
    """``--out`` and ``--report``, refused now if they cannot be written or are inputs."""
    out, report = Path(args.out), Path(args.report) if args.report else None
    inputs = {"the nominal URDF": urdf, "the data (--data)": args.data}
    if args.validate:
        inputs["the validation data (--validate)"] = args.validate
    check_output_paths({"--out": out, "--report": report}, inputs)
    return out, report


def _write_calibration(args, report_dict, text, refusal, urdf, paths) -> int:
    """Print the result; write the URDF and report, or only the report of a refused model.

    Args:
        args: The command's arguments (``--json``).
        report_dict: The JSON report.
        text: Returns the text printed without ``--json``.
        refusal: Why the model must not be written, or None.
        urdf: Returns the files of an accepted model: the calibrated URDF (and the
            compliance file) by path (called only for an accepted model).
        paths: ``(--out, --report or None)``.

    Raises:
        CalibrationRefusedError: The model was refused (no URDF is written).
    """
    report = paths[1]
    doc = json_text(report_dict)
    print(doc if args.json else text(), end="" if args.json else "\n")
    files: dict[Path, str | bytes] = {} if report is None else {report: doc}
    if refusal is not None:
        write_outputs(files)
        kept = f"; report written to {report}" if report is not None else ""
        raise CalibrationRefusedError(f"calibration refused: {refusal}: no URDF written{kept}")
    written = {**urdf(), **files}
    write_outputs(written)
    if not args.json:
        print(f"wrote {', '.join(str(p) for p in written)}")
    return 0


CHAIN_ONLY: dict[str, object] = {
    "fix": [],
    "free": [],
    "elastic": None,
    "loss": "linear",
    "noise_mm": None,
    "orientation_weight": None,
    "marker": None,
    "units": "m",
    "orientation": "auto",
    "orientation_columns": None,
    "world_link": None,
}
"""Options of `calibrate` a tree calibration does not take, at their defaults."""


def _calibrate_tree(args: argparse.Namespace, tree: Tree, recorded) -> int:
    """`calibrate` with several tools: the tree's calibration, URDF of every branch."""
    from ..calibration.options import TREE_LEVELS
    from ..calibration.tree_pipeline import calibrate_tree
    from ..kinematics.tree_export import calibrated_tree_urdf
    from ..kinematics.urdf_export import check_exportable
    from ..measurements.csvfile import read_measurements

    given = [k for k, v in CHAIN_ONLY.items() if getattr(args, k) != v]
    if given:
        raise InvalidArgumentError(
            f"--{given[0].replace('_', '-')} is for one chain; a tree is calibrated with "
            f"--params {'|'.join(TREE_LEVELS)}, --validate, --holdout, --seed, --max-iterations"
        )
    if args.params not in (None, *TREE_LEVELS):
        raise InvalidArgumentError(
            f"--params {args.params} is for one chain: a tree is calibrated with --params "
            f"{' or '.join(TREE_LEVELS)} (default: complete)"
        )
    kind = _data_kind(args)
    if kind is not None and kind.is_pose:
        raise InvalidArgumentError(
            "--measure pose is for one chain: a tree is calibrated from one point per row "
            "(x, y, z and a tool)"
        )
    level = args.params or "complete"
    out, report = _calibration_outputs(args, tree.urdf_path)
    for chain in tree.chains:  # before the fit: a URDF it cannot be written to is known now
        check_exportable(chain)
    data = read_measurements(args.data, tree)
    check = read_measurements(args.validate, tree) if args.validate else None
    if kind is not None and kind.is_position:
        data = data.position_only()
        check = check.position_only() if check is not None else None
    result = calibrate_tree(
        tree,
        data,
        params=level,
        validate=check,
        holdout=args.holdout,
        seed=args.seed,
        max_iterations=args.max_iterations,
    )
    return _write_calibration(
        args,
        _with_warnings(result.to_dict(), recorded),
        result.text,
        result.refusal,
        lambda: {
            out: calibrated_tree_urdf(tree, result.nominal, result.state.mdh, result.state.markers)
        },
        (out, report),
    )


def cmd_sweep(args: argparse.Namespace) -> int:
    """Analyse every catalog chain and tree (and extra URDFs) and print one table."""
    from tqdm import tqdm

    from ..outputs.plots import counts_figure, figure_bytes, figure_format
    from ..outputs.sweep import rows_table, rows_to_csv, sweep

    def bar(jobs):
        return tqdm(
            jobs,
            desc="calib sweep",
            unit="chain",
            file=sys.stderr,
            leave=False,
            disable=not sys.stderr.isatty(),
        )

    plot_format = figure_format(args.plot, "--plot") if args.plot else None
    check_output_paths(
        {"--csv": args.csv, "--plot": args.plot}, {f"the URDF {u}": u for u in args.urdf}
    )
    rows = sweep(
        extra=args.urdf,
        measure=args.measure,
        marker=args.marker,
        configs=args.configs,
        seed=args.seed,
        progress=bar,
        params=args.params,
    )
    files: dict[Path, str | bytes] = {}
    if args.csv:
        files[Path(args.csv)] = rows_to_csv(rows)
    if plot_format is not None:  # --plot given
        title = f"Base parameters per chain, {args.measure} measurement"
        files[Path(args.plot)] = figure_bytes(counts_figure(rows, title=title), plot_format)
    write_outputs(files)
    if args.json:
        print_json(
            {
                "measure": args.measure,
                "params": args.params,
                "rows": [dataclasses.asdict(r) for r in rows],
            }
        )
    else:
        print(rows_table(rows))
        bad = sum(r.error is not None for r in rows)
        print(
            f"\n{len(rows)} chains and trees, {len(rows) - bad} analysed, {bad} with an error "
            f"(reason in the last column); {args.measure}, verdict for the {args.params} set"
        )
    return 0


def add_chain_args(p: argparse.ArgumentParser, trees: bool = False) -> None:
    """The robot, ``--base`` and ``--tool`` options (``--tool`` repeatable with ``trees``)."""
    p.add_argument("robot", help="catalog name (see `calib list`) or path to a URDF file")
    p.add_argument("--base", help="base frame (default: the catalog's, or the URDF root link)")
    if trees:
        p.add_argument(
            "--tool",
            action="append",
            help="tool frame; give it several times for a tree: the chains to each tool, "
            "shared joints once (default: the catalog's tool or tools, or the deepest tip)",
        )
    else:
        p.add_argument("--tool", help="tool frame (default: the catalog's, or the deepest tip)")


def _add_marker_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--marker",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help="measured point in the tool frame [m] (default: the tool origin)",
    )


def _add_sampling_args(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument(
        "--configs",
        type=int,
        default=DEFAULT_CONFIGS,
        help=f"random configurations {what} (default: {DEFAULT_CONFIGS})",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the configurations (default: 0)")


def _add_measure_args(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--measure",
        default="pose",
        help="pose, position, comma-separated rows among x,y,z,rx,ry,rz, or a contact: plane, "
        "plane-point, fixed-point, fixed-pose (default: pose)",
    )
    _add_marker_arg(p)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``calib``."""
    parser = _Parser(
        prog="calib",
        description="Identifiable geometric parameters and calibration of serial robots (URDF).",
    )
    parser.add_argument("--version", action="version", version=f"calib {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("list", help="robots of the catalog")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_list)

    p = sub.add_parser("show", help="modified-DH table of a chain or tree")
    add_chain_args(p, trees=True)
    p.add_argument("--json", action="store_true", help="print JSON (radians, metres)")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("analyze", help="identifiable (base) parameters of a chain or tree")
    add_chain_args(p, trees=True)
    _add_measure_args(p)
    p.add_argument(
        "--params", default="paper", choices=PARAMETER_SETS, help="parameter set (default: paper)"
    )
    _add_sampling_args(p, "m")
    p.add_argument(
        "--markers",
        type=int,
        help="count what a calibration identifies with K points measured per configuration "
        "(frame and markers free)",
    )
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_analyze)

    p = sub.add_parser("simulate", help="simulate a measurement campaign (CSV + true errors)")
    add_chain_args(p, trees=True)
    p.add_argument("--out", required=True, help="measurement CSV to write ('-': stdout)")
    p.add_argument(
        "--truth",
        help="JSON of the true errors (default: OUT with .truth.json; needed if OUT is '-')",
    )
    p.add_argument(
        "--configs",
        type=int,
        default=DEFAULT_CONFIGS,
        help=f"random configurations m (default: {DEFAULT_CONFIGS})",
    )
    p.add_argument(
        "--configs-file",
        help="CSV of the configurations to simulate (joint columns, e.g. from calib design)",
    )
    p.add_argument(
        "--measure",
        choices=(*CAMPAIGN_MEASURES, *CONTACT_MEASURES),
        default="pose",
        help="pose (point + orientation), position, or a contact: touches recorded by the "
        "joints alone, on the true robot (default: pose)",
    )
    _add_marker_arg(p)
    p.add_argument(
        "--contacts",
        type=int,
        default=1,
        help="planes or points the touches share, with --measure plane|... (default: 1)",
    )
    p.add_argument(
        "--params",
        choices=PARAMETER_SETS,
        default="complete",
        help="parameter set perturbed (default: complete)",
    )
    p.add_argument(
        "--error-mm", type=float, default=1.0, help="std of every length error [mm] (default: 1)"
    )
    p.add_argument(
        "--error-mrad", type=float, default=1.0, help="std of every angle error [mrad] (default: 1)"
    )
    p.add_argument(
        "--noise-mm",
        type=float,
        default=0.0,
        help="std of the position noise per axis [mm] (default: 0)",
    )
    p.add_argument(
        "--noise-mrad",
        type=float,
        default=None,
        help="std of the orientation noise per axis [mrad] (default: NOISE_MM)",
    )
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="seed of the configurations, errors and noise (default: 0)",
    )
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("calibrate", help="calibrate from measurements, write a calibrated URDF")
    add_chain_args(p, trees=True)
    p.add_argument("--data", required=True, help="measurement CSV (joints, x y z or x1..zK, ...)")
    p.add_argument("--out", required=True, help="calibrated URDF to write")
    p.add_argument("--report", help="JSON report to write (also when the model is refused)")
    p.add_argument(
        "--marker",
        nargs="+",
        type=float,
        metavar="X",
        help="guess of the marker(s) in the tool frame [m]: X Y Z, or 3 K numbers (default: 0)",
    )
    p.add_argument(
        "--measure",
        choices=("auto", *CAMPAIGN_MEASURES, *CONTACT_NAMES),
        default="auto",
        help="auto: pose when the CSV has orientation columns, else position; or a contact "
        "(no coordinates in the CSV) (default: auto)",
    )
    contact_cli.add_contact_arguments(p)
    p.add_argument(
        "--params",
        choices=LEVELS,
        default=None,
        help="parameter level: auto keeps what the data support (cross-validated); frames = "
        "measurement frame + markers; offsets adds joint offsets; paper, complete (default: "
        "auto; a tree takes frames or complete, default complete)",
    )
    p.add_argument(
        "--fix",
        nargs="+",
        default=[],
        metavar="NAME",
        help="parameters (or frame, markers, tool) held at their start",
    )
    p.add_argument("--free", nargs="+", default=[], metavar="NAME", help="parameters always fitted")
    p.add_argument(
        "--elastic",
        action=BooleanOnce,
        default=None,
        help="fit joint compliance under gravity, which the URDF cannot hold (default: no; "
        "needs the URDF's masses)",
    )
    p.add_argument(
        "--validate", help="measurement CSV of other configurations: score the result on it"
    )
    p.add_argument(
        "--holdout",
        type=float,
        default=0.0,
        help="fraction of the rows set aside for validation (default: 0)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the holdout split (default: 0)")
    p.add_argument(
        "--loss",
        choices=LOSSES,
        default="linear",
        help="linear, or a robust loss (default: linear)",
    )
    p.add_argument(
        "--noise-mm",
        type=float,
        help="instrument noise [mm]: scale of the robust loss and of the outlier test",
    )
    p.add_argument(
        "--units",
        choices=tuple(UNITS),
        default="m",
        help="unit of the position columns (default: m)",
    )
    p.add_argument(
        "--orientation",
        choices=("auto", MARKERS, *ORIENTATION_FORMATS),
        default="auto",
        help="orientation columns: quaternion (xyzw or wxyz), rotation vector or rpy; "
        "markers: the x1..zK points (K >= 3) of one rigid set read as marker 1's position "
        "and the set's orientation (default: from the column names)",
    )
    p.add_argument(
        "--orientation-columns",
        nargs="+",
        metavar="COL",
        help="names of the orientation columns, in the format's order",
    )
    p.add_argument(
        "--orientation-weight",
        type=_weight,
        default=None,
        metavar="W|auto",
        help="weight of the orientation rows [m/rad] (default: auto, the ratio of the "
        "position and orientation errors of the registration, estimated until it settles)",
    )
    p.add_argument(
        "--max-iterations",
        type=int,
        default=DEFAULT_MAX_ITERATIONS,
        help=f"most residual evaluations of each fit (default: {DEFAULT_MAX_ITERATIONS})",
    )
    p.add_argument(
        "--world-link",
        metavar="NAME",
        help="also write the measurement frame as link NAME, the new root of the URDF: forward "
        "kinematics from NAME gives measured coordinates",
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser(
        "sweep", help="analyse every catalog chain and tree (and extra URDFs): one table"
    )
    p.add_argument("urdf", nargs="*", help="extra URDF files analysed after the catalog")
    _add_measure_args(p)
    p.add_argument(
        "--params",
        default="paper",
        choices=PARAMETER_SETS,
        help="set the verdict is about (default: paper)",
    )
    _add_sampling_args(p, "per chain")
    p.add_argument("--csv", help="also write the table as CSV to this file ('-': stdout)")
    p.add_argument("--plot", help="also save the counts plot to this .png, .svg or .pdf file")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_sweep)

    from .design_cli import add_design_parser

    add_design_parser(sub)

    from .predict_cli import add_predict_parser

    add_predict_parser(sub)

    p = sub.add_parser("demo", help="analyse the paper's robot and a UR5 (no argument needed)")
    p.set_defaults(func=cmd_demo)
    _add_verbose(parser, sub)
    return parser


THREADS_ENV = "CALIB_THREADS"
"""Environment variable: BLAS threads of the CLI (default 1)."""

_BLAS_ENVS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""BLAS's own variables: when the user set one, the CLI leaves the thread count to it."""


def blas_threads() -> int | None:
    """BLAS threads the CLI runs with (None: leave BLAS's own setting).

    ``CALIB_THREADS`` if set; else None when the user set ``OPENBLAS_NUM_THREADS``,
    ``OMP_NUM_THREADS`` or ``MKL_NUM_THREADS``; else 1 (calib's matrices are small: more
    threads only spin and contend for the cores).

    Raises:
        InvalidArgumentError: ``CALIB_THREADS`` is not a positive integer.
    """
    text = os.environ.get(THREADS_ENV, "").strip()
    if text:
        if not text.isdigit() or int(text) < 1:
            raise InvalidArgumentError(f"{THREADS_ENV}={text!r}: expected a positive integer")
        return int(text)
    return None if any(os.environ.get(v, "").strip() for v in _BLAS_ENVS) else 1


def _blas_limit(threads: int | None) -> contextlib.AbstractContextManager:
    if threads is None:
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=threads, user_api="blas")


class _Terminated(BaseException):
    """Raised by the SIGTERM handler: ``finally`` clean-ups (temporary files) then run."""


def _raise_terminated(signum, frame) -> NoReturn:
    raise _Terminated


@contextlib.contextmanager
def _sigterm_raises() -> Iterator[None]:
    """SIGTERM raises _Terminated inside (main thread only); the old handler is back after."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def _one_line(message: object) -> str:
    """A message on one line: control characters (line breaks included) shown escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(message))


def _run(args: argparse.Namespace) -> int:
    """Run a command; every error becomes one line on stderr and an exit code."""
    try:
        with _sigterm_raises(), _blas_limit(blas_threads()):
            return args.func(args)
    except CalibError as exc:
        print(f"calib: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("calib: interrupted", file=sys.stderr)
        return 130
    except _Terminated:
        print("calib: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    except BrokenPipeError:  # `calib ... | head`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except OSError as exc:  # an OS error not raised as a CalibError
        message = f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": ")
        print(f"calib: error: {_one_line(message)}", file=sys.stderr)
        return 2


def _add_verbose(parser: argparse.ArgumentParser, sub) -> None:
    """``--verbose`` before or after the command: show Pinocchio's own messages."""
    text = "show the messages of Pinocchio's URDF parser (hidden by default)"
    parser.add_argument("--verbose", action="store_true", help=text)
    for p in sub.choices.values():
        p.add_argument("--verbose", action="store_true", default=argparse.SUPPRESS, help=text)


@contextlib.contextmanager
def _verbose_logging(verbose: bool):
    """Print calib's log (Pinocchio's messages, level INFO) on stderr while the command runs."""
    if not verbose:
        yield
        return
    logger = logging.getLogger("calib")
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("calib: %(message)s"))
    level = logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.INFO)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return the exit code.

    Errors are one line on stderr and exit code 2; SIGINT gives 130 and SIGTERM 143, after
    any temporary file is removed.
    """
    try:
        with _interrupts_raise():
            return _main(argv)
    except KeyboardInterrupt:  # outside a command (parsing, printing the warnings)
        print("calib: interrupted", file=sys.stderr)
        return 130


@contextlib.contextmanager
def _interrupts_raise() -> Iterator[None]:
    """SIGINT raises KeyboardInterrupt inside (main thread only); the old handler is back after.

    The entry point (:mod:`calib.launcher`) installs a handler that exits at once, for the
    imports; a command needs the exception instead, so that its temporary files go.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, signal.default_int_handler if previous is None else previous)


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # usage error (one line already printed), --help, --version
        return exc.code if isinstance(exc.code, int) else 2
    args.given = dict(vars(args).pop(_GIVEN, {}))
    with warnings.catch_warnings(record=True) as caught, _verbose_logging(args.verbose):
        warnings.simplefilter("always")
        code = _run(args)
    sys.stdout.flush()  # the warnings come after the output
    for line in warning_lines(caught):
        print(line, file=sys.stderr)
    return code


def warning_lines(caught: Sequence[warnings.WarningMessage]) -> list[str]:
    """The warnings a user sees, one line each, each distinct message once.

    calib's own warnings and other ``UserWarning`` subclasses, and the ``RuntimeWarning``
    subclasses of numpy and scipy (overflow, invalid value, an ill-conditioned matrix), which
    say something about the numbers printed: those name their source. Warnings about the code
    itself (deprecations, imports, resources) are left out.
    """
    seen: dict[str, int] = {}
    for w in caught:
        if not issubclass(w.category, UserWarning | RuntimeWarning):
            continue
        text = _one_line(w.message)
        path = os.path.normpath(w.filename or "").split(os.sep)
        source = next((s for s in ("numpy", "scipy") if s in path), None)
        if source or not issubclass(w.category, UserWarning):
            text = f"{w.category.__name__}{f' from {source}' if source else ''}: {text}"
        seen[text] = seen.get(text, 0) + 1
    return [
        f"calib: warning: {text}" + (f" ({count} times)" if count > 1 else "")
        for text, count in seen.items()
    ]


if __name__ == "__main__":
    sys.exit(main())
