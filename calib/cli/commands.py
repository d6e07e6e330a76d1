"""The ``calib`` command line: the parser of every command, and :func:`main`.

:func:`main` runs one command (BLAS threads, signals, one-line errors, the warnings after the
output).

The commands live in one module per group (:mod:`.analysis_cli`, :mod:`.simulate_cli`,
:mod:`.calibrate_cli`, :mod:`.design_cli`, :mod:`.predict_cli`,
:mod:`.detect_cli`); what they share is in
:mod:`.common`.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import signal
import sys
import threading
import warnings
from collections.abc import Iterator, Sequence
from typing import NoReturn

from .. import __version__
from ..core.fileio import inputs_recorded, text_to_stderr, writes_stdout
from ..exceptions import CalibError, InvalidArgumentError
from .analysis_cli import add_analysis_parsers, add_demo_parser, add_sweep_parser
from .calibrate_cli import add_calibrate_parser
from .common import GIVEN, Parser, one_line, warning_lines
from .design_cli import add_design_parser
from .detect_cli import add_detect_parser
from .flags import OPTIONS, in_flags
from .predict_cli import add_predict_parser
from .simulate_cli import add_simulate_parser

__all__ = [
    "THREADS_ENV",
    "blas_threads",
    "build_parser",
    "main",
]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``calib``."""
    parser = Parser(
        prog="calib",
        description="Identifiable geometric parameters and calibration of serial robots (URDF).",
        epilog=_EXAMPLES,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"calib {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    add_analysis_parsers(sub)
    add_simulate_parser(sub)
    add_calibrate_parser(sub)
    add_sweep_parser(sub)
    add_design_parser(sub)
    add_predict_parser(sub)
    add_detect_parser(sub)
    add_demo_parser(sub)
    _add_message_flags(parser, sub)
    return parser


_EXAMPLES = """\
examples:
  calib list                                        # the robots of the catalog
  calib analyze ur5                                 # what a point on a UR5 identifies
  calib design ur5 --configs 30 --out configs.csv   # which configurations to measure
  calib simulate ur5 --configs-file configs.csv --noise-mm 0.05 --out meas.csv
  calib calibrate ur5 --data meas.csv --holdout 0.3 --out ur5_cal.urdf --plot cal.png
  calib COMMAND --help                              # a command's options and examples"""


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


def _run(args: argparse.Namespace) -> int:
    """Run a command; every error becomes one line on stderr and an exit code."""
    try:
        on_stdout = _stdout_output(args) if getattr(args, "json", False) else None
        if on_stdout is not None:
            raise InvalidArgumentError(
                f"--json prints to standard output, where {on_stdout} writes: give it a file"
            )
        with _sigterm_raises(), _blas_limit(blas_threads()):
            return args.func(args)
    except CalibError as exc:  # the library names a way out by its keyword: say the flag
        print(f"calib: error: {in_flags(one_line(exc), args)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("calib: interrupted", file=sys.stderr)
        return 130
    except _Terminated:
        print("calib: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    except BrokenPipeError:  # `calib ... | head`: stop quietly
        os.dup2(os.open(os.devnull, os.O_WRONLY), 1)  # fd 1: sys.stdout may be stderr here
        return 0
    except OSError as exc:  # an OS error not raised as a CalibError
        message = f"{exc.strerror or exc}: {exc.filename or ''}".rstrip(": ")
        print(f"calib: error: {one_line(message)}", file=sys.stderr)
        return 2


def _add_message_flags(parser: argparse.ArgumentParser, sub) -> None:
    """``--verbose`` and ``--quiet``, before or after the command (a command's ``messages``).

    ``--verbose`` shows Pinocchio's own messages; ``--quiet`` no progress bars, even on a
    terminal.
    """
    flags = {
        "--verbose": "show the messages of Pinocchio's URDF parser (hidden by default)",
        "--quiet": "no progress bars (shown on a terminal for phases longer than a second)",
    }
    for flag, text in flags.items():
        parser.add_argument(flag, action="store_true", help=text)
    for p in sub.choices.values():
        group = p.add_argument_group("messages")
        for flag, text in flags.items():
            group.add_argument(flag, action="store_true", default=argparse.SUPPRESS, help=text)


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

    The entry point (:mod:`calib.cli.launcher`) installs a handler that exits at once, for the
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


def _parse(parser: argparse.ArgumentParser, argv: Sequence[str] | None) -> argparse.Namespace:
    """The arguments; one left over is the command's usage error (``see calib CMD --help``)."""
    args, extra = parser.parse_known_args(argv)
    if extra:
        _command(parser, args.command).error(f"unrecognized arguments: {' '.join(extra)}")
    return args


def _command(parser: argparse.ArgumentParser, name: str) -> argparse.ArgumentParser:
    """The parser of the command ``name``."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return sub.choices[name]


def _options(parser: argparse.ArgumentParser, command: str) -> frozenset[str]:
    """The option strings of ``command`` (``--noise-mm``, ...): the flags :func:`in_flags` says."""
    return frozenset(_command(parser, command)._option_string_actions)


_OUTPUTS = ("out", "csv", "report", "truth", "origins", "intrinsics_out")
"""The options (``dest``) of a file a command writes (``detect``'s ``--target`` too)."""


def _stdout_output(args: argparse.Namespace) -> str | None:
    """The option whose file is standard output (``-``, ``/dev/stdout``), or None."""
    dests = (*_OUTPUTS, "target") if args.command == "detect" else _OUTPUTS
    for dest in dests:
        path = getattr(args, dest, None)
        if path is not None and writes_stdout(path):
            return f"--{dest.replace('_', '-')} {path}"
    return None


def _main(argv: Sequence[str] | None) -> int:
    parser = build_parser()
    try:
        args = _parse(parser, argv)
    except SystemExit as exc:  # usage error (one line already printed), --help, --version
        return exc.code if isinstance(exc.code, int) else 2
    args.given = dict(vars(args).pop(GIVEN, {}))
    setattr(args, OPTIONS, _options(parser, args.command))
    with (
        warnings.catch_warnings(record=True) as caught,
        _verbose_logging(args.verbose),
        inputs_recorded(),
    ):
        warnings.simplefilter("always")
        on_stdout = _stdout_output(args)
        with contextlib.nullcontext() if on_stdout is None else text_to_stderr():
            code = _run(args)
    sys.stdout.flush()  # the warnings come after the output
    for line in warning_lines(caught):
        print(in_flags(line, args), file=sys.stderr)
    return code


if __name__ == "__main__":
    sys.exit(main())
