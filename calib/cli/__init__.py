"""The command line: ``calib`` and its subcommands.

:mod:`.commands` holds the parser and ``main`` (re-exported here so that ``calib.cli:main``
keeps working); one module per command group adds its commands to it: :mod:`.analysis_cli`
(``list``, ``show``, ``analyze``, ``sweep``, ``demo``), :mod:`.simulate_cli`,
:mod:`.calibrate_cli`, :mod:`.design_cli` (``design``, ``evaluate``) and :mod:`.predict_cli`.
What they share is in :mod:`.common` (and :mod:`.listing`, light: the catalog table); the
command modules do not import each other. The entry point is :func:`.launcher.main`, which
starts light (``--version`` and ``list`` without numpy) and calls ``main``.

May import: every wing below (:mod:`calib.outputs`, :mod:`calib.design`,
:mod:`calib.calibration`, :mod:`calib.measurements`, :mod:`calib.identification`,
:mod:`calib.kinematics`) and the bottom modules.
"""

from ..core.lazy import attributes

_LAZY = {"main": "commands"}

__getattr__ = attributes(__name__, _LAZY)

TYPE_CHECKING = False  # True for type checkers; importing typing would cost start-up
if TYPE_CHECKING:  # what the lazy names are, for type checkers (tests/test_public.py)
    from .commands import main

__all__ = ["main"]
