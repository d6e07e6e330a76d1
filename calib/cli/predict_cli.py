"""The ``calib predict`` command: apply a calibrated URDF with its compliance file.

Kept beside :mod:`calib.cli.commands` (which registers it), as ``calib design``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ..core.words import counted
from .common import check_output_paths, command_parser, write_outputs

__all__ = ["add_predict_parser", "cmd_predict"]


def cmd_predict(args: argparse.Namespace) -> int:
    """Predict the measured points and the deflected joints at given configurations."""
    from ..design.configurations import read_configurations, read_readings
    from ..kinematics.elastic import load_calibrated, predictions_csv

    out = Path(args.out)
    check_output_paths(
        {"--out": out},
        {"the URDF": args.urdf, "--compliance": args.compliance, "--configs": args.configs},
    )
    model = load_calibrated(args.urdf, args.compliance, args.tool, args.term)
    q = read_configurations(args.configs, model.chain)
    readings = read_readings(args.configs, model.readings) if model.readings else None
    write_outputs({out: predictions_csv(model, q, readings)})
    where = (
        "the contact's origin in the base frame"
        if model.contact is not None
        else f"{counted(len(model.markers), 'points')} in the measurement frame"
    )
    if readings is not None:
        off = counted(len(readings.names), "joints")
        where += f", the load with {off} off the chain as read"
    configs = counted(len(q), "configurations")
    print(f"{model.chain.name}: {configs}, {where} and the deflected joints; wrote {out}")
    return 0


def add_predict_parser(sub) -> None:
    """The ``predict`` subcommand's options."""
    p = command_parser(
        sub,
        "predict",
        "predict measured points and deflected joints with a calibrated URDF + compliance",
        [
            "calib calibrate ur5 --data meas.csv --elastic --out cal.urdf --report cal.json",
            "calib predict cal.urdf --compliance cal.json --configs configs.csv --out pred.csv",
        ],
    )
    g = p.add_argument_group("inputs")
    g.add_argument("urdf", metavar="URDF", help="calibrated URDF written by calib calibrate")
    g.add_argument(
        "--compliance",
        required=True,
        metavar="FILE",
        help="its compliance file (OUT.compliance.json) or its calibration report (--report)",
    )
    g.add_argument(
        "--tool",
        metavar="FRAME",
        help="the tool frame of the term to predict, in a report of several (a tree's tools)",
    )
    g.add_argument(
        "--term-index",
        dest="term",
        type=int,
        metavar="K",
        help="the index (from 0) of the term to predict in the report's terms: two terms of "
        "one tool (a hand measured by a camera and touching a table)",
    )
    g.add_argument(
        "--configs",
        required=True,
        metavar="CONFIGS.csv",
        help="commanded configurations (joint columns, named as in the URDF)",
    )
    p.add_argument_group("output").add_argument(
        "--out",
        required=True,
        help="CSV to write: joints, x1,y1,z1,... [m, measurement frame], deflected_<joint>",
    )
    p.set_defaults(func=cmd_predict)
