"""The ``calib`` command's entry point.

``calib --version`` and ``calib list [--json]`` are answered here, from the standard library
and the catalog file: they start without numpy, Pinocchio or SciPy. Every other command line
goes to :func:`calib.cli.commands.main`.

Ctrl-C is one line and exit 130 from the first instant: :func:`main` installs a SIGINT
handler that exits at once before numpy, Pinocchio or calib's modules are imported (an
interrupt during those imports would otherwise print a traceback). :func:`calib.cli.commands.main`
raises KeyboardInterrupt again while a command runs (temporary files are then removed) and
says "calib: interrupted" itself. ``import calib`` itself is lazy: only the catalog and the
errors are imported before the handler is in place.
"""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Sequence

from .. import __version__
from ..exceptions import CalibError
from .listing import catalog_listing

__all__ = ["INTERRUPTED", "main"]


INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT)."""


def _interrupted(signum, frame) -> None:
    os.write(2, b"calib: interrupted\n")
    os._exit(INTERRUPTED)


_BLAS_ENVS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""Thread counts BLAS reads when it is loaded (OpenBLAS, MKL)."""


def _one_blas_thread() -> None:
    """The command's BLAS on one thread from its start, as :func:`~.cli.commands.blas_threads` asks.

    Before numpy is imported, with neither ``CALIB_THREADS`` nor a BLAS thread variable set,
    ``OPENBLAS_NUM_THREADS`` and ``MKL_NUM_THREADS`` are set to 1: :mod:`~.cli.commands` then sees
    the count set and leaves it, which spares the command importing threadpoolctl and
    inspecting the loaded libraries (20 ms of every start).
    """
    names = ("CALIB_THREADS", "OMP_NUM_THREADS", *_BLAS_ENVS)
    if "numpy" in sys.modules or any(os.environ.get(v, "").strip() for v in names):
        return
    for name in _BLAS_ENVS:
        os.environ[name] = "1"


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``calib`` with these arguments (default: the command line); the exit code.

    Run as the command (no ``argv``), Ctrl-C exits at once with "calib: interrupted" until a
    command's own handling takes over; a caller that passes ``argv`` keeps its handler.
    """
    if argv is None:
        signal.signal(signal.SIGINT, _interrupted)
        _one_blas_thread()
    args = list(sys.argv[1:] if argv is None else argv)
    if args == ["--version"]:
        print(f"calib {__version__}")
        return 0
    if args in (["list"], ["list", "--json"]):
        try:
            text = catalog_listing(args == ["list", "--json"])
        except (CalibError, OSError):
            pass  # the full command line says it the usual way
        else:
            try:
                print(text, flush=True)
            except BrokenPipeError:  # `calib list | head`: stop quietly
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 0
    from .commands import main as full

    return full(args)


if __name__ == "__main__":
    sys.exit(main())
