"""What the command modules share.

The parser and its actions (an option given once), the argument builders, output checks and
writing, JSON printing and the warning lines.

Imports none of the command modules.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import NoReturn

from ..calibration import options
from ..calibration.delivery import compliance_path, paired_files, paired_report
from ..core.choices import DEFAULT_CONFIGS, DEFAULT_MEASURE
from ..core.fileio import check_outputs, json_text, write_files_atomic
from ..exceptions import CalibrationRefusedError, InvalidArgumentError
from ..kinematics.catalog import catalog_files, installed_dirs
from .flags import in_flags, report_in_flags

__all__ = [
    "APPLIES",
    "GIVEN",
    "PLANE_METAVAR",
    "SHAPE_LABELS",
    "BooleanOnce",
    "Group",
    "Parser",
    "add_chain_args",
    "add_look_args",
    "add_marker_arg",
    "add_measure_args",
    "add_sampling_args",
    "check_applicable",
    "check_output_paths",
    "command_parser",
    "compliance_path",
    "cross_validated",
    "fold_seed",
    "given_options",
    "look_outputs",
    "named_planes",
    "nonnegative_number",
    "one_line",
    "orientation_wanted",
    "positive_number",
    "print_json",
    "refuse_unused_weight",
    "robot_words",
    "tool_arg",
    "warning_lines",
    "with_warnings",
    "write_calibration",
    "write_outputs",
]


GIVEN = "_calib_given"
"""Namespace attribute where the actions note the options given (dest: option string);
:func:`main` moves it to ``args.given``, where a command checks which options were given."""


def _note_given(parser, namespace, dest: str, option_string: str | None) -> None:
    """Record an option as given; the same option (or its opposite) given again is an error."""
    given = vars(namespace).setdefault(GIVEN, {})
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
        vars(namespace).setdefault(GIVEN, {})[self.dest] = option_string
        super().__call__(parser, namespace, values, option_string)


class Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (like every other calib error), no repeated value."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.register("action", None, _StoreOnce)
        self.register("action", "store", _StoreOnce)
        self.register("action", "store_true", _StoreTrueOnce)
        self.register("action", "append", _AppendNoted)

    def error(self, message: str) -> NoReturn:
        """Exit with one usage line (exit status 2), under the one ``calib: error:`` prefix.

        The command is named in the hint (``see calib calibrate --help``), not in a second
        prefix.
        """
        self.exit(2, f"calib: error: {message} (see {self.prog} --help)\n")


Group = argparse._ActionsContainer
"""Where an option is added: a parser or one of its argument groups (``--help``'s sections)."""


def command_parser(sub, name: str, summary: str, examples: Sequence[str]) -> Parser:
    """A command's parser: its summary, and an ``examples:`` section at the end of ``--help``.

    Args:
        sub: The subparsers of ``calib``.
        name: The command's name.
        summary: One line, lower case, no full stop (``calib --help`` lists it).
        examples: Command lines, each shown on its own line (``calib`` first).
    """
    return sub.add_parser(
        name,
        help=summary,
        description=f"{summary[0].upper()}{summary[1:]}.",
        epilog="examples:\n" + "\n".join(f"  {e}" for e in examples),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )


def given_options(args: argparse.Namespace, dests) -> list[str]:
    """The options among ``dests`` (argparse dests) the user gave, as typed (``--no-x``)."""
    given = getattr(args, "given", {})
    return [given[d] for d in dests if given.get(d)]


PLANE_METAVAR = ("NAME", "X", "Y", "Z", "NX", "NY", "NZ")
"""A plane given on the command line: its name, a point and its normal in the base frame [m]."""


def named_planes(given: list[list[str]] | None, flag: str) -> dict[str, list[float]] | None:
    """``FLAG NAME X Y Z NX NY NZ`` (repeated) as ``{name: [x, y, z, nx, ny, nz]}``, or None.

    Raises:
        InvalidArgumentError: A value that is not a number, or a name given twice.
    """
    if not given:
        return None
    planes: dict[str, list[float]] = {}
    for name, *values in given:
        try:
            numbers = [float(v) for v in values]
        except ValueError:
            raise InvalidArgumentError(
                f"{flag} takes NAME X Y Z NX NY NZ (a point and a normal in the base frame, m), "
                f"got {' '.join([name, *values])}"
            ) from None
        if name in planes:
            raise InvalidArgumentError(f"{flag} names plane '{name}' twice")
        planes[name] = numbers
    return planes


SHAPE_LABELS = {
    **options.SHAPE_LABELS,
    "tree": "a tree (several --tool)",
    "contacts": "contact kinds (--measure plane|plane-point|fixed-point|fixed-pose)",
    "chains": "several terms in one fit (--term, --chain, --loop)",
}
"""What ``calibrate`` builds, by shape, in the words of its messages."""

APPLIES: dict[str, tuple[str, ...]] = {
    **options.APPLIES,
    "marker": ("chain",),
    "units": ("chain", "tree"),
    "points": ("chain", "tree"),
    "orientation": ("chain",),
    "orientation_columns": ("chain",),
    "world_link": ("chain",),
    "on_robot": ("chain",),
    "contact": ("contacts", "chains"),
    "other_foot": ("contacts",),
    "base": ("chain", "tree", "contacts"),
    "tool": ("chain", "tree", "contacts"),
    "data": ("chain", "tree", "contacts"),
    "validate": ("chain", "tree", "contacts"),
}
"""The table of ``calib calibrate``'s options that apply to some shapes only: the library's
(:data:`calib.calibration.options.APPLIES`) and the command line's own flags, argparse dest ->
the shapes it applies to. One given where it does not apply is an error
(:func:`check_applicable`)."""


def cross_validated(args: argparse.Namespace, fit: Callable, data: list, validate: list | None):
    """``fit(data, validate)``, or with ``--folds K`` its K-fold cross-validation.

    ``fit``: a route's calibration of its terms' data, each with its validation data (a
    list, or None: none); with ``--folds``, :func:`calib.design.folds.k_fold` calls it K + 1
    times (``--holdout`` and ``--validate`` refused before: :func:`check_applicable`), the
    folds shuffled by ``--seed`` where it is given (:func:`fold_seed`).
    """
    if getattr(args, "folds", None) is None:
        return fit(data, validate)
    from ..design.folds import k_fold  # numpy: only when calibrating

    return k_fold(fit, data, args.folds, fold_seed(args))


def fold_seed(args: argparse.Namespace) -> int | None:
    """``--seed`` where it is given (``--folds``: random folds), else None (contiguous)."""
    return args.seed if given_options(args, ("seed",)) else None


def check_applicable(args: argparse.Namespace, shape: str) -> None:
    """Refuse an option of :data:`APPLIES` given where it does not apply.

    ``--folds`` with ``--holdout`` or ``--validate`` too: each holds rows out its own way.

    Args:
        args: ``calibrate``'s arguments (with ``given``, the options typed).
        shape: ``chain``, ``tree``, ``contacts`` or ``chains``.

    Raises:
        InvalidArgumentError: The first such option, saying what it is for.
    """
    folds = given_options(args, ("folds",))
    held = given_options(args, ("holdout", "validate"))
    if folds and held:
        from ..design.folds import NOT_WITH  # numpy: only on this error

        raise InvalidArgumentError(NOT_WITH)  # said with the flags: calib.cli.flags.FLAGS
    for dest, shapes in APPLIES.items():
        typed = given_options(args, (dest,))
        if shape in shapes or not typed:
            continue
        flag = typed[0]
        labels = [SHAPE_LABELS[s] for s in shapes]
        where = labels[0] if len(labels) == 1 else f"{', '.join(labels[:-1])} or {labels[-1]}"
        raise InvalidArgumentError(f"{flag} is for {where}, not {SHAPE_LABELS[shape]}")


def refuse_unused_weight(args: argparse.Namespace, angles: bool, data: str) -> None:
    """Refuse ``--orientation-weight`` when the data have no angle rows for it to weigh.

    Args:
        args: ``calibrate``'s arguments.
        angles: Whether the data have orientation (or tilt) rows.
        data: What the data are, for the message (``positions only``).

    Raises:
        InvalidArgumentError: The value is out of range (the options' own message, first),
            or the option was given and would be ignored.
    """
    from ..core.checks import MAX_WEIGHT, check_number  # numpy: only when calibrating

    if isinstance(args.orientation_weight, float):
        check_number(args.orientation_weight, "the orientation weight", 0.0, MAX_WEIGHT, above=True)
    typed = given_options(args, ("orientation_weight",))
    if typed and not angles:
        raise InvalidArgumentError(
            f"{typed[0]} weighs orientation or tilt rows: the data have none ({data})"
        )


def positive_number(text: str) -> float:
    """The type of a noise option [mm]: a finite number > 0, at most 1 m (else a usage error)."""
    return _bounded(text, zero=False)


def nonnegative_number(text: str) -> float:
    """The type of a simulated error or noise [mm or mrad]: a number in [0, 1000]."""
    return _bounded(text, zero=True)


def _bounded(text: str, zero: bool) -> float:
    """``text`` as a number in (0, MAX_ERROR_MM] (``zero``: [0, MAX_ERROR_MM])."""
    from ..core.checks import MAX_ERROR_MM  # numpy: only when the option is given

    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not ((value >= 0.0 if zero else value > 0.0) and value <= MAX_ERROR_MM):
        sign = "a number >= 0" if zero else "a positive number"
        raise argparse.ArgumentTypeError(f"expected {sign} at most {MAX_ERROR_MM:g}, got '{text}'")
    return value


def print_json(obj: dict) -> None:
    """Print a JSON document (indented)."""
    print(json.dumps(obj, indent=2))


def robot_words(args: argparse.Namespace) -> list[str]:
    """The robot, ``--base`` and ``--tool`` as the user gave them (a ``next:`` line's words)."""
    words = [args.robot] + (["--base", args.base] if args.base else [])
    tools = [args.tool] if isinstance(args.tool, str) else args.tool or ()
    for tool in tools:
        words += ["--tool", tool]
    return words


def tool_arg(args: argparse.Namespace) -> str | tuple[str, ...] | None:
    """``--tool`` of a command that takes several: None, one name, or several (a tree)."""
    if args.tool is None or isinstance(args.tool, str):
        return args.tool
    return args.tool[0] if len(args.tool) == 1 else tuple(args.tool)


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


def add_chain_args(p: Group, trees: bool = False) -> None:
    """The robot, ``--base`` and ``--tool`` options (``--tool`` repeatable with ``trees``)."""
    p.add_argument("robot", help="catalog name (see `calib list`) or path to a URDF file")
    p.add_argument("--base", help="base frame (default: the catalog's, or the URDF root link)")
    if trees:
        p.add_argument(
            "--tool",
            action="append",
            help="tool frame; give it several times for a tree: the chains to each tool, "
            "shared joints once (default: the catalog's tool or tools, or the deepest tip, a "
            "mimic gripper's fingers passed over)",
        )
    else:
        p.add_argument(
            "--tool",
            help="tool frame (default: the catalog's, or the deepest tip, a mimic gripper's "
            "fingers passed over)",
        )


def add_marker_arg(p: Group, several: bool = False) -> None:
    """The ``--marker X Y Z`` option (``several``: given once per marker, a list of them)."""
    many = "; repeat for several markers (a tree: one for every tool, or one per tool in --tool "
    many += "order; "
    p.add_argument(
        "--marker",
        nargs=3,
        type=float,
        metavar=("X", "Y", "Z"),
        help=f"measured point in the tool frame [m]{many if several else ' ('}default: the tool "
        "origin)",
        action="append" if several else "store",
    )


def add_sampling_args(p: Group, what: str) -> None:
    """The ``--configs`` and ``--seed`` options of random configurations."""
    p.add_argument(
        "--configs",
        type=int,
        default=DEFAULT_CONFIGS,
        help=f"random configurations {what} (default: {DEFAULT_CONFIGS})",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the configurations (default: 0)")


def add_measure_args(p: Group) -> None:
    """The ``--measure`` and ``--marker`` options."""
    p.add_argument(
        "--measure",
        default=DEFAULT_MEASURE,
        help="position (a point, as a tracker measures it), pose (point and orientation), "
        "comma-separated rows among x,y,z,rx,ry,rz, or a contact: plane, plane-point, "
        f"fixed-point, fixed-pose (default: {DEFAULT_MEASURE}, as simulate and design)",
    )
    add_marker_arg(p)


def orientation_wanted(option: str, renamed: bool) -> str:
    """The error of a pose read from a file without orientation columns.

    Args:
        option: the option that asked for a pose (``--measure pose``, ``--term pose``).
        renamed: whether ``--orientation FORMAT --orientation-columns`` can name other columns.

    Returns:
        One line naming the column names read as an orientation (and the options, if any).
    """
    from ..measurements.csvfile import DEFAULT_ORIENTATION_COLUMNS

    names = "; ".join(
        ", ".join(DEFAULT_ORIENTATION_COLUMNS[f]) for f in ("quat-xyzw", "rotvec", "rpy")
    )
    other = ", or name yours: --orientation FORMAT --orientation-columns A B C [D]"
    return f"{option} needs orientation columns ({names}){other if renamed else ''}"


def _print_out(text: str, end: str = "\n") -> None:
    """Print to standard output; a reader gone (``calib calibrate ... | head``) silences it.

    The command goes on: the files still to write are written (the pipe's end stopped the
    command before them, with exit code 0).

    Args:
        text: What to print.
        end: The end of the line, as ``print``'s.
    """
    try:
        print(text, end=end, flush=True)
    except BrokenPipeError:
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())


def one_line(message: object) -> str:
    """A message on one line: control characters (line breaks included) shown escaped."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(message))


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
        text = one_line(w.message)
        path = os.path.normpath(w.filename or "").split(os.sep)
        source = next((s for s in ("numpy", "scipy") if s in path), None)
        if source or not issubclass(w.category, UserWarning):
            text = f"{w.category.__name__}{f' from {source}' if source else ''}: {text}"
        seen[text] = seen.get(text, 0) + 1
    return [
        f"calib: warning: {text}" + (f" ({count} times)" if count > 1 else "")
        for text, count in seen.items()
    ]


def with_warnings(report: dict, recorded: Sequence[warnings.WarningMessage]) -> dict:
    """The report with the recorded warnings added to its ``warnings`` (each once, in order)."""
    lines = list(report.get("warnings", []))
    for w in recorded:
        text = one_line(w.message)
        if issubclass(w.category, UserWarning) and text not in lines:
            lines.append(text)
    return {**report, "warnings": lines}


def add_look_args(p: Group) -> None:
    """``--plot`` and ``--origins``: a calibration to look at, and to carry into a xacro file."""
    p.add_argument(
        "--plot",
        metavar="FILE",
        help="also write a figure (.png, .svg or .pdf): errors per configuration before "
        "(registration) and after calibration, held-out rows marked, and the parameters "
        "with their uncertainties (written with the report, also for a refused model)",
    )
    p.add_argument(
        "--origins",
        metavar="FILE.yaml",
        help="also write the joint origins the calibration moved or added (markers, world "
        "link), calibrated xyz rpy beside the nominal, as YAML a xacro reads "
        "(xacro.load_yaml; docs/howto/calibrated-urdf.md)",
    )


def look_outputs(args: argparse.Namespace) -> dict[str, Path | None]:
    """``--plot`` and ``--origins`` as outputs to check; a figure's extension checked now.

    Raises:
        InvalidArgumentError: ``--plot`` does not end in .png, .svg or .pdf.
    """
    plot, origins = getattr(args, "plot", None), getattr(args, "origins", None)
    if plot is not None:
        from ..outputs.plots import figure_format  # matplotlib: only when asked

        figure_format(plot, "--plot")
    return {
        "--plot": None if plot is None else Path(plot),
        "--origins": None if origins is None else Path(origins),
    }


def _look_files(args, result, urdf: bytes | None) -> dict[Path, str | bytes]:
    """The ``--plot`` figure and (with a URDF) the ``--origins`` YAML of a result."""
    files: dict[Path, str | bytes] = {}
    if getattr(args, "plot", None) is not None:
        from ..outputs.plots import calibration_figure, figure_bytes, figure_format

        fig = calibration_figure(result)
        files[Path(args.plot)] = figure_bytes(fig, figure_format(args.plot, "--plot"))
    if urdf is not None and getattr(args, "origins", None) is not None:
        from ..kinematics.origins import origins_yaml

        files[Path(args.origins)] = origins_yaml(result.origins(urdf))
    return files


def write_calibration(
    args, report_dict, text, refusal, urdf, paths, recorded=(), result=None
) -> int:
    """Print the result; write the URDF and report, or only the report of a refused model.

    Args:
        args: The command's arguments (``--json``).
        report_dict: The JSON report (the ``recorded`` warnings are added to its
            ``warnings``, the URDF's digest to its ``model``).
        text: Returns the text printed without ``--json``.
        refusal: Why the model must not be written, or None.
        urdf: Returns the files of an accepted model: the calibrated URDF (and the
            compliance file) by path (called only for an accepted model).
        paths: ``(--out, --report or None)``.
        recorded: Warnings raised on the way (the data's, the fit's).
        result: The result (a :class:`~calib.calibration.delivery.Result`): ``--plot`` and
            ``--origins`` are written from it.

    Raises:
        CalibrationRefusedError: The model was refused (no URDF is written).
    """
    report = paths[1]
    out = Path(paths[0])  # the report and the compliance file record the URDF's digest
    model: dict = {} if refusal is not None else paired_files(urdf(), out)
    found = report_in_flags(with_warnings(report_dict, recorded), args)  # the flags, not keywords
    doc = json_text(paired_report(found, model[out]) if model else found)
    _print_out(doc if args.json else in_flags(text(), args), end="" if args.json else "\n")
    files: dict[Path, str | bytes] = {} if report is None else {report: doc}
    if refusal is not None:
        files.update({} if result is None else _look_files(args, result, None))
        write_outputs(files)
        kept = f"; report written to {report}" if report is not None else ""
        raise CalibrationRefusedError(f"calibration refused: {refusal}: no URDF written{kept}")
    written = {**model, **files}
    if result is not None:
        written.update(_look_files(args, result, written[out]))
    write_outputs(written)
    if not args.json:
        _print_out(f"wrote {', '.join(str(p) for p in written)}")
    return 0
