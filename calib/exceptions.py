"""One exception hierarchy: every error calib raises on bad input derives from CalibError."""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Iterable, Sequence

__all__ = [
    "AmbiguousFrameError",
    "CalibError",
    "CalibrationRefusedError",
    "ChainError",
    "ContactGeometryError",
    "ConvergenceError",
    "DataError",
    "FrameNotFoundError",
    "InvalidArgumentError",
    "OutputError",
    "RobotNotFoundError",
    "URDFError",
    "UnsupportedJointError",
    "warn_user",
]

_PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__)) + os.sep


def warn_user(message: str, category: type[Warning]) -> None:
    """Warn at the first line outside calib: the user's call, not calib's own line.

    What ``warnings.warn``'s ``skip_file_prefixes`` does from Python 3.12, for 3.11: the
    warning's file and line (and the ``once``/``default`` filters' registry) are those of
    the innermost caller that is not a module of this package.

    Args:
        message: The one-line warning.
        category: Its class (``DataWarning``, ``RankWarning``).
    """
    frame = sys._getframe(1)
    level = 2  # warnings.warn's stacklevel of this function's caller
    while frame.f_back is not None and frame.f_code.co_filename.startswith(_PACKAGE_DIR):
        frame = frame.f_back
        level += 1
    warnings.warn(message, category, stacklevel=level)


class CalibError(Exception):
    """Base class of every error calib raises on bad input.

    The message is a single line meant for a user; the CLI prints it and exits non-zero.
    """


class RobotNotFoundError(CalibError):
    """A robot name is neither in the catalog nor a path to a URDF file.

    The message suggests catalog names close to it (whatever the case) and ``urdf``, a URDF
    calib finds by its bare file name (``talos_full_v2.urdf`` for ``talos_full_v2``).
    """

    def __init__(self, name: str, known: Sequence[str], urdf: str | None = None):
        self.name = name
        self.known = tuple(known)
        import difflib  # here: every start of calib imports this module

        by_case = {k.lower(): k for k in self.known}  # UR5 is ur5
        close = difflib.get_close_matches(name.lower(), by_case, n=3, cutoff=0.5)
        close = ([urdf] if urdf else []) + [by_case[c] for c in close]  # a URDF's bare name
        hint = f" (did you mean {', '.join(close)}?)" if close else ""
        super().__init__(
            f"unknown robot '{name}'{hint}: give a URDF path or one of the catalog names "
            f"(`calib list`)"
        )


class URDFError(CalibError):
    """A URDF file is missing, unreadable or malformed (or only its collision geometry is).

    ``message`` replaces the default ``cannot load URDF 'path': reason`` where only a part of
    the file fails (its meshes) and the rest loads.
    """

    def __init__(self, path: str, reason: str, message: str | None = None):
        self.path = path
        self.reason = reason
        super().__init__(message or f"cannot load URDF '{path}': {reason}")


def _closest_first(name: str, candidates: Iterable[str]) -> list[str]:
    """Sort candidate names by similarity to ``name``, most similar first.

    Args:
        name: The name that was asked for.
        candidates: Names that exist.

    Returns:
        The distinct candidates, most similar first (ties in alphabetical order).
    """
    import difflib

    unique = sorted(set(candidates))
    return sorted(
        unique, key=lambda c: -difflib.SequenceMatcher(None, name.lower(), c.lower()).ratio()
    )


class FrameNotFoundError(CalibError):
    """A frame name does not exist in the robot model."""

    def __init__(
        self, name: str, available: Iterable[str], limit: int = 8, ranked_as: str | None = None
    ):
        self.name = name
        self.available = tuple(_closest_first(ranked_as or name, available))
        shown = ", ".join(self.available[:limit])
        more = f", ... ({len(self.available)} in all)" if len(self.available) > limit else ""
        super().__init__(
            f"no frame named '{name}'; frames that exist, closest first: {shown}{more}"
        )


class AmbiguousFrameError(CalibError):
    """A frame name matches several frames at different places (e.g. a link and a joint)."""

    def __init__(self, name: str, kinds: Sequence[str]):
        self.name = name
        self.kinds = tuple(kinds)
        options = " or ".join(f"'{k}:{name}'" for k in self.kinds)
        super().__init__(
            f"frame name '{name}' is ambiguous ({', '.join(self.kinds)} frames at different "
            f"places); write {options}"
        )


class ChainError(CalibError):
    """The base and tool frames do not delimit a usable serial chain."""


class UnsupportedJointError(CalibError):
    """A joint in the chain is of a kind calib does not model (planar, floating, mimic, ...)."""

    def __init__(self, joint: str, kind: str):
        self.joint = joint
        self.kind = kind
        super().__init__(
            f"joint '{joint}' in the chain is {kind}: only revolute, continuous and prismatic "
            f"joints are supported"
        )


class InvalidArgumentError(CalibError, ValueError):
    """An argument has a value outside what the function accepts."""


class OutputError(CalibError, OSError):
    """An output file cannot be written (missing or read-only directory, full disk, ...).

    Also an ``OSError``: ``errno`` and ``filename`` (the target as given) are set.
    """

    def __init__(self, code: int | None, reason: str | None, target: str):
        super().__init__(code, reason or "cannot be written", target)

    def __str__(self) -> str:
        return f"cannot write {self.filename}: {self.strerror}"


class DataError(CalibError):
    """A measurement file is malformed; the message names the row and/or column."""

    def __init__(self, path: str, reason: str, row: int | None = None, column: str | None = None):
        self.path = path
        self.row = row
        self.column = column
        where = []
        if row is not None:
            where.append(f"row {row}")
        if column is not None:
            where.append(f"column '{column}'")
        at = f" ({', '.join(where)})" if where else ""
        super().__init__(f"{path}{at}: {reason}")


class ConvergenceError(CalibError):
    """An iterative fit did not converge.

    Kept for scripts that catch it: since issue 28 no calibration raises it (a fit that does
    not converge is refused: ``result.refusal`` names the solver's message, and ``check()``
    raises :class:`CalibrationRefusedError`).
    """


class ContactGeometryError(CalibError):
    """Contact touches cannot fix a plane, point or pose (too few, or a degenerate geometry)."""


class CalibrationRefusedError(CalibError):
    """A calibration failed a check (worse than its start, not identified by the data, ...)."""
