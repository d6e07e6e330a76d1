"""The ``calib`` command's entry point: Ctrl-C is one line and exit 130 from the first instant.

A top-level module, so that its SIGINT handler is in place before ``calib`` (and Pinocchio)
are imported: an interrupt during those imports would otherwise print a traceback.
:func:`calib.cli.main` raises KeyboardInterrupt again while a command runs (temporary files
are then removed) and says "calib: interrupted" itself.
"""

from __future__ import annotations

import os
import signal
import sys

INTERRUPTED = 130
"""Exit status after Ctrl-C (128 + SIGINT)."""


def _interrupted(signum, frame) -> None:
    os.write(2, b"calib: interrupted\n")
    os._exit(INTERRUPTED)


def main() -> int:
    """Run ``calib`` with a quiet Ctrl-C outside the command's own handling."""
    signal.signal(signal.SIGINT, _interrupted)
    from calib.cli import main as cli_main

    return cli_main()


if __name__ == "__main__":
    sys.exit(main())
