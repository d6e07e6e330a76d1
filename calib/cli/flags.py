"""The command line's words for the library's: a way out named by its keyword, said as a flag.

The library's messages name the keyword of a way out (``give its noise (noise_mm)``), for a
Python user; the command line says the flag instead (``give its noise (--noise-mm)``).
:data:`FLAGS` is the one table of those texts, :func:`in_flags` the one translation: of an
error's line (:func:`calib.cli.commands.main`), of the warnings printed, and of a result's
summary and report (:func:`~.common.write_calibration`).
"""

from __future__ import annotations

import argparse
import re
from collections.abc import Collection

__all__ = ["FLAGS", "OPTIONS", "in_flags", "report_in_flags"]


FLAGS = {
    "(Columns' orientation_columns)": "(--orientation-columns)",
    "(Columns' points)": "(--points)",
    "(the data's position_only())": "(--measure position)",
    "Unknowns(intrinsics=True)": "--refine-intrinsics",
    "give its noise (noise_mm)": "give its noise (--noise-mm)",
    "a larger max_iterations": "a larger --max-iterations",
    "constraints=calib.design.constraints.Constraints(collision=False)": "--no-collision",
    "(term=)": "(--term-index)",
    "the number of folds must be": "--folds must be",
    "robot_seed must be": "--robot-seed must be",
    "params='complete' fits": "--params complete fits",
    "compare params='offsets'": "compare --params offsets",
    "did not see: folds)": "did not see: --folds K)",
    "folds hold every posture out in turn: not with holdout or validate (a term's too)": (
        "--folds holds every posture out in turn: not with --holdout, --validate or a term's "
        "validation file"
    ),
    "with fix left none": "with --fix left none",
    "fewer parameters in fix": "fewer parameters in --fix",
    "the measurement frame with world_link": "the measurement frame with --world-link",
    "world_link: ": "--world-link: ",
    "on_robot: ": "--on-robot: ",
    "with Columns(units='mm')": "with --units mm",
    "takes one marker for all or one per tool": (
        "takes --marker once for all its tools or once per tool (in --tool order)"
    ),
    "out: holdout, validate or folds)": "out: --holdout, --validate or --folds)",
    "out: holdout or validate)": "out: --holdout or --validate)",
    "out: a term's validate, as the other terms)": (
        "out: a --term's VALIDATION file, as the other terms)"
    ),
}
"""A library text naming a keyword -> the command line's text naming its flag (the first
``--`` word of the value is the flag: a command without it keeps the keyword)."""

OPTIONS = "_calib_options"
"""The attribute of a command's arguments holding its option strings (set by ``main``)."""


def in_flags(text: str, args: argparse.Namespace | None = None) -> str:
    """``text`` with the keywords of :data:`FLAGS` said as the command's flags.

    Args:
        text: A library text: an error's line, a warning, a summary, a report's JSON.
        args: The command's arguments: a keyword whose flag the command does not have stays
            as it is; with ``--term`` (each term's file read by its default column names, as
            ``--term`` refuses ``--orientation``), the columns-ignored warning's way out
            through other names (:data:`~calib.measurements.csvfile.NAMED_ORIENTATION`) is
            cut. None: every keyword said as its flag.
    """
    options: Collection[str] | None = None if args is None else getattr(args, OPTIONS, None)
    for keyword, flag in FLAGS.items():
        name = _FLAG.search(flag)
        if keyword in text and (options is None or (name and name.group() in options)):
            text = text.replace(keyword, flag)
    if isinstance(getattr(args, "term", None), list) and NAMED_ORIENTATION in text:
        text = text.partition(NAMED_ORIENTATION)[0]  # the hint's last clause: cut to the end
    return text


NAMED_ORIENTATION = ", or name its format and columns"
""":data:`calib.measurements.csvfile.NAMED_ORIENTATION`, the columns-ignored warning's last clause
(written again here: every command starts without the CSV reader; a test checks they agree)."""

_FLAG = re.compile(r"--[a-z][a-z-]*")
"""A flag in a value of :data:`FLAGS`."""


def report_in_flags(doc, args: argparse.Namespace | None = None):
    """A report (JSON-like: dicts, lists, strings) with each string :func:`in_flags`'s."""
    if isinstance(doc, str):
        return in_flags(doc, args)
    if isinstance(doc, dict):
        return {k: report_in_flags(v, args) for k, v in doc.items()}
    if isinstance(doc, list | tuple):
        return [report_in_flags(v, args) for v in doc]
    return doc
