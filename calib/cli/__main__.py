"""``python -m calib.cli``: the full command line (as :func:`calib.cli.commands.main`)."""

import sys

from .commands import main

__all__: list[str] = []

sys.exit(main())
