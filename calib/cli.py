"""The ``calib`` command line."""

from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections.abc import Sequence

from . import __version__
from .catalog import catalog
from .exceptions import CalibError
from .identifiability import DEFAULT_CONFIGS, analyze
from .mdh import from_chain
from .report import analysis_text, format_table, mdh_table
from .robot import load_chain


def _print_json(obj: dict) -> None:
    print(json.dumps(obj, indent=2))


def cmd_list(args: argparse.Namespace) -> int:
    """Print the catalog."""
    rows = [[e.name, f"{e.base} -> {e.tool}", e.description + (f" [{e.expect_error}]" if e.expect_error else "")]
            for e in catalog()]
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
        _print_json({"robot": chain.name, "base": chain.base_frame, "tool": chain.tool_frame,
                     "urdf": str(chain.urdf_path), "frames": mdh.rows()})
    else:
        print(f"{chain.name}: {chain.base_frame} -> {chain.tool_frame} ({chain.urdf_path})")
        print(mdh_table(mdh))
    return 0


def _analyze(args: argparse.Namespace):
    return analyze(args.robot, args.base, args.tool, args.measure, args.marker, args.params,
                   args.configs, args.seed)


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


def _add_chain_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("robot", help="catalog name (see `calib list`) or path to a URDF file")
    p.add_argument("--base", help="base frame (default: the catalog's, or the URDF root link)")
    p.add_argument("--tool", help="tool frame (default: the catalog's, or the deepest tip)")


def _add_measure_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--measure", default="pose",
                   help="pose, position, or comma-separated rows among x,y,z,rx,ry,rz (default: pose)")
    p.add_argument("--marker", nargs="+", type=float, metavar=("X", "Y"),
                   help="measured point in the tool frame: X Y Z [m] (default: the tool origin)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``calib``."""
    parser = argparse.ArgumentParser(
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
    p.add_argument("--params", default="paper", help="paper or complete (default: paper)")
    p.add_argument("--configs", type=int, default=DEFAULT_CONFIGS,
                   help=f"random configurations m (default: {DEFAULT_CONFIGS})")
    p.add_argument("--seed", type=int, default=0, help="seed of the configurations (default: 0)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_analyze)

    p = sub.add_parser("demo", help="analyse the paper's robot and a UR5 (no argument needed)")
    p.set_defaults(func=cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit code (errors: one line on stderr, code 2)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            code = args.func(args)
        except CalibError as exc:
            print(f"calib: error: {exc}", file=sys.stderr)
            code = 2
        except KeyboardInterrupt:
            print("calib: interrupted", file=sys.stderr)
            code = 130
    for w in caught:
        if issubclass(w.category, UserWarning):
            print(f"calib: warning: {w.message}", file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
