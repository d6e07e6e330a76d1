"""The ``calib`` command line."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import logging
import os
import sys
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import NoReturn

from . import __version__
from .calibration import (
    DEFAULT_MAX_ITERATIONS,
    DEFAULT_ORIENTATION_WEIGHT,
    DEFAULT_PARAMS,
    calibrate,
    calibration_text,
)
from .catalog import catalog
from .exceptions import CalibError, ConvergenceError, DataError, InvalidArgumentError
from .fileio import check_writable, json_text, write_files_atomic
from .identifiability import DEFAULT_CONFIGS, analyze
from .mdh import from_chain
from .measurements import CAMPAIGN_MEASURES, measurements_csv, read_measurements, simulate
from .parameters import PARAMETER_SETS
from .report import analysis_text, format_table, mdh_table
from .robot import load_chain
from .urdf_export import calibrated_urdf, check_exportable


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors, like every other calib error."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"calib: error: {self.prog}: {message} (see --help)\n")


def _print_json(obj: dict) -> None:
    print(json.dumps(obj, indent=2))


def cmd_list(args: argparse.Namespace) -> int:
    """Print the catalog."""
    rows = [
        [
            e.name,
            f"{e.base} -> {e.tool}",
            e.description + (f" [{e.expect_error}]" if e.expect_error else ""),
        ]
        for e in catalog()
    ]
    if args.json:
        _print_json({"robots": [e.__dict__ | {"path": str(e.path)} for e in catalog()]})
    else:
        print(format_table(["name", "chain", "description"], rows))
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """Print the MDH table of a chain."""
    chain = load_chain(args.robot, args.base, args.tool)
    mdh = from_chain(chain)
    if args.json:
        _print_json(
            {
                "robot": chain.name,
                "base": chain.base_frame,
                "tool": chain.tool_frame,
                "urdf": str(chain.urdf_path),
                "frames": mdh.rows(),
            }
        )
    else:
        print(f"{chain.name}: {chain.base_frame} -> {chain.tool_frame} ({chain.urdf_path})")
        print(mdh_table(mdh))
    return 0


def _analyze(args: argparse.Namespace):
    return analyze(
        args.robot,
        args.base,
        args.tool,
        args.measure,
        args.marker,
        args.params,
        args.configs,
        args.seed,
    )


def cmd_analyze(args: argparse.Namespace) -> int:
    """Identifiable parameters of one chain."""
    res = _analyze(args)
    if args.json:
        _print_json(res.to_dict())
    else:
        print(analysis_text(res))
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


def _write(files: dict[Path, str | bytes]) -> None:
    """Write output files atomically; an OS error becomes a one-line CalibError."""
    try:
        write_files_atomic(files)
    except OSError as exc:
        name = exc.filename or ", ".join(str(p) for p in files)
        raise CalibError(f"cannot write {name}: {exc.strerror or exc}") from None


def _check_outputs(*paths: Path | str | None) -> None:
    """Fail now, in one line, if an output cannot be written (not after the work)."""
    try:
        check_writable(*paths)
    except OSError as exc:
        raise CalibError(f"cannot write {exc.filename}: {exc.strerror}") from None


def cmd_simulate(args: argparse.Namespace) -> int:
    """Simulate a measurement campaign; write the CSV and the true errors (JSON)."""
    out = Path(args.out)
    truth_path = Path(args.truth) if args.truth else out.with_suffix(".truth.json")
    _check_outputs(out, truth_path)
    chain = load_chain(args.robot, args.base, args.tool)
    campaign = simulate(
        chain,
        args.configs,
        args.measure,
        args.marker,
        args.error_mm,
        args.error_mrad,
        args.noise_mm,
        args.noise_mrad,
        args.seed,
        args.params,
    )
    if truth_path.resolve() == out.resolve():
        raise InvalidArgumentError("--truth and --out name the same file")
    truth = campaign.truth
    _write({out: measurements_csv(campaign.measurements), truth_path: json_text(truth.to_dict())})
    print(
        f"{chain.name}: {campaign.measurements.m} configurations, measure {args.measure}, "
        f"{len(truth.params)} {truth.params.label} parameters perturbed "
        f"({truth.error_mm:g} mm, {truth.error_mrad:g} mrad), noise {truth.noise_mm:g} mm"
        + (f", {truth.noise_mrad:g} mrad" if args.measure == "pose" else "")
        + f", seed {truth.seed}"
    )
    print(f"wrote {out} and {truth_path} (true errors, {truth.analysis.n_base} base values)")
    return 0


def cmd_calibrate(args: argparse.Namespace) -> int:
    """Identify the base parameters from a CSV; write the calibrated URDF and a report."""
    chain = load_chain(args.robot, args.base, args.tool)
    out = Path(args.out)
    report = Path(args.report) if args.report else None
    if report is not None and report.resolve() == out.resolve():
        raise InvalidArgumentError("--report and --out name the same file")
    outputs = {"--out": out, "--report": report}
    inputs = {"the nominal URDF": chain.urdf_path, "the data": Path(args.data)}
    for option, target in outputs.items():
        for what, path in inputs.items():
            if target is not None and target.resolve() == path.resolve():
                raise InvalidArgumentError(f"{option} {target} would overwrite {what}")
    check_exportable(chain)  # before the fit: a URDF it cannot be written to is known now
    _check_outputs(out, report)
    data = read_measurements(args.data, chain)
    if args.measure == "position":
        data = data.position_only()
    elif args.measure == "pose" and data.quaternion is None:
        raise DataError(args.data, "--measure pose needs the columns qx, qy, qz, qw")
    result = calibrate(
        chain, data, args.marker, args.params, args.orientation_weight, args.max_iterations
    )
    text = json_text(result.to_dict())
    print(text if args.json else calibration_text(result), end="" if args.json else "\n")
    if not result.converged:
        if report is not None:
            _write({report: text})
        kept = f"; report written to {report}" if report is not None else ""
        raise ConvergenceError(
            f"the fit did not converge after {result.iterations} iterations "
            f"({result.message}): no URDF written{kept}"
        )
    urdf = calibrated_urdf(chain, result.nominal, result.calibrated)
    files: dict[Path, str | bytes] = {out: urdf}
    if report is not None:
        files[report] = text
    _write(files)
    if not args.json:
        print(f"wrote {out}" + (f" and {report}" if report is not None else ""))
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    """Analyse every catalog chain (and extra URDFs) and print one table."""
    from tqdm import tqdm

    from .plots import counts_figure, figure_png
    from .sweep import rows_table, rows_to_csv, sweep

    def bar(jobs):
        return tqdm(
            jobs,
            desc="calib sweep",
            unit="chain",
            file=sys.stderr,
            leave=False,
            disable=not sys.stderr.isatty(),
        )

    _check_outputs(args.csv, args.plot)
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
    if args.plot:
        title = f"Base parameters per chain, {args.measure} measurement"
        files[Path(args.plot)] = figure_png(counts_figure(rows, title=title))
    _write(files)
    if args.json:
        _print_json(
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
            f"\n{len(rows)} chains, {len(rows) - bad} analysed, {bad} with an error "
            f"(reason in the last column); {args.measure}, verdict for the {args.params} set"
        )
    return 0


def _add_chain_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("robot", help="catalog name (see `calib list`) or path to a URDF file")
    p.add_argument("--base", help="base frame (default: the catalog's, or the URDF root link)")
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
        help="pose, position, or comma-separated rows among x,y,z,rx,ry,rz (default: pose)",
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

    p = sub.add_parser("show", help="modified-DH table of a chain")
    _add_chain_args(p)
    p.add_argument("--json", action="store_true", help="print JSON (radians, metres)")
    p.set_defaults(func=cmd_show)

    p = sub.add_parser("analyze", help="identifiable (base) parameters of a chain")
    _add_chain_args(p)
    _add_measure_args(p)
    p.add_argument(
        "--params", default="paper", choices=PARAMETER_SETS, help="parameter set (default: paper)"
    )
    _add_sampling_args(p, "m")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_analyze)

    p = sub.add_parser("simulate", help="simulate a measurement campaign (CSV + true errors)")
    _add_chain_args(p)
    p.add_argument("--out", required=True, help="measurement CSV to write")
    p.add_argument("--truth", help="JSON of the true errors (default: OUT with .truth.json)")
    p.add_argument(
        "--configs",
        type=int,
        default=DEFAULT_CONFIGS,
        help=f"random configurations m (default: {DEFAULT_CONFIGS})",
    )
    p.add_argument(
        "--measure",
        choices=CAMPAIGN_MEASURES,
        default="pose",
        help="pose (point + orientation) or position (default: pose)",
    )
    _add_marker_arg(p)
    p.add_argument(
        "--params",
        choices=PARAMETER_SETS,
        default=DEFAULT_PARAMS,
        help=f"parameter set perturbed (default: {DEFAULT_PARAMS})",
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

    p = sub.add_parser("calibrate", help="identify the base parameters, write a calibrated URDF")
    _add_chain_args(p)
    p.add_argument("--data", required=True, help="measurement CSV (joints, x, y, z[, qx..qw])")
    p.add_argument("--out", required=True, help="calibrated URDF to write")
    p.add_argument("--report", help="JSON report to write")
    _add_marker_arg(p)
    p.add_argument(
        "--measure",
        choices=("auto", *CAMPAIGN_MEASURES),
        default="auto",
        help="auto: pose when the CSV has qx..qw, else position (default: auto)",
    )
    p.add_argument(
        "--params",
        choices=PARAMETER_SETS,
        default=DEFAULT_PARAMS,
        help=f"standard parameter set (default: {DEFAULT_PARAMS})",
    )
    p.add_argument(
        "--orientation-weight",
        type=float,
        default=DEFAULT_ORIENTATION_WEIGHT,
        help="weight of the orientation rows [m/rad] (default: 1, 1 mrad ~ 1 mm)",
    )
    p.add_argument(
        "--max-iterations",
        type=int,
        default=DEFAULT_MAX_ITERATIONS,
        help=f"most residual evaluations of the solver (default: {DEFAULT_MAX_ITERATIONS})",
    )
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("sweep", help="analyse every catalog chain (and extra URDFs): one table")
    p.add_argument("urdf", nargs="*", help="extra URDF files analysed after the catalog")
    _add_measure_args(p)
    p.add_argument(
        "--params",
        default="paper",
        choices=PARAMETER_SETS,
        help="set the verdict is about (default: paper)",
    )
    _add_sampling_args(p, "per chain")
    p.add_argument("--csv", help="also write the table as CSV to this file")
    p.add_argument("--plot", help="also save the counts plot as PNG to this file")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("demo", help="analyse the paper's robot and a UR5 (no argument needed)")
    p.set_defaults(func=cmd_demo)
    _add_verbose(parser, sub)
    return parser


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
    """Run the CLI; return the exit code (errors: one line on stderr, code 2)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # usage error (one line already printed), --help, --version
        return exc.code if isinstance(exc.code, int) else 2
    with warnings.catch_warnings(record=True) as caught, _verbose_logging(args.verbose):
        warnings.simplefilter("always")
        try:
            code = args.func(args)
        except CalibError as exc:
            print(f"calib: error: {exc}", file=sys.stderr)
            code = 2
        except KeyboardInterrupt:
            print("calib: interrupted", file=sys.stderr)
            code = 130
        except BrokenPipeError:  # `calib ... | head`: stop quietly
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            code = 0
        except OSError as exc:  # a file that cannot be written
            print(
                f"calib: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "),
                file=sys.stderr,
            )
            code = 2
    for w in caught:
        if issubclass(w.category, UserWarning):
            print(f"calib: warning: {w.message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
