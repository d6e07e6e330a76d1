"""The command line: ``calib`` and its subcommands.

:mod:`.commands` holds the parser, the shared helpers and most commands (``main``, re-exported
here so that ``calib.cli:main`` keeps working); :mod:`.design_cli` (``calib design``,
``calib evaluate``) and :mod:`.predict_cli` (``calib predict``) add their command groups to it.
The entry point is :func:`calib.launcher.main`, which starts light and calls ``main``.

May import: every wing below (:mod:`calib.outputs`, :mod:`calib.design`,
:mod:`calib.calibration`, :mod:`calib.measurements`, :mod:`calib.identification`,
:mod:`calib.kinematics`) and the bottom modules.
"""

from ..lazy import attributes

_LAZY = {"main": "commands"}

__getattr__ = attributes(__name__, _LAZY)

TYPE_CHECKING = False  # True for type checkers; importing typing would cost start-up
if TYPE_CHECKING:  # what the lazy names are, for type checkers (tests/test_public.py)
    from .commands import main

__all__ = ["main"]
