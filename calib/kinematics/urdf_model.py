"""A URDF file to a Pinocchio model: size-limited reading, calib's checks, a quiet build.

Pinocchio's C++ URDF parser (urdfdom) prints to the process's stdout and stderr itself; the
build runs with both file descriptors redirected to a temporary file, and what it printed is
logged (logger ``calib``, level INFO), which ``calib --verbose`` shows.
"""

from __future__ import annotations

import contextlib
import ctypes
import logging
import os
import sys
import tempfile
from pathlib import Path

import pinocchio as pin

from ..core.fileio import read_bytes_limited
from ..exceptions import URDFError
from .urdf_xml import MAX_URDF_BYTES, URDFInfo, read_urdf_info

__all__ = [
    "MAX_CAPTURED_BYTES",
    "build_model",
    "console_captured",
    "read_urdf_file",
]

_LOG = logging.getLogger("calib")


def _pinocchio_failure(exc: Exception | None, messages: str) -> str:
    """The cause of a failed build: urdfdom's first error line, else the exception's."""
    for line in messages.splitlines():
        text = line.strip()
        if text.lower().startswith("error:"):
            return text.split(":", 1)[1].strip() or text
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


@contextlib.contextmanager
def console_captured():
    """Send the process's stdout and stderr (file descriptors 1 and 2) to a temporary file.

    Pinocchio's C++ parser prints to them directly. Yields a list that receives the captured
    text when the block ends.
    """
    captured: list[str] = []
    with contextlib.suppress(OSError, ValueError, AttributeError):
        sys.stdout.flush()
        sys.stderr.flush()
    try:
        saved = [os.dup(1), os.dup(2)]
    except OSError:  # no console at all: nothing to keep quiet
        yield captured
        return
    try:
        with tempfile.TemporaryFile() as tmp:
            os.dup2(tmp.fileno(), 1)
            os.dup2(tmp.fileno(), 2)
            try:
                yield captured
            finally:
                _flush_c_stdio()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                tmp.seek(0)
                captured.append(tmp.read(MAX_CAPTURED_BYTES).decode("utf-8", "replace"))
    finally:
        for fd in saved:
            os.close(fd)


def _flush_c_stdio() -> None:
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None).fflush(None)


MAX_CAPTURED_BYTES = 1 << 20
"""Most bytes of Pinocchio's console messages kept per load (for ``--verbose``)."""


def build_model(xml: str, src: str) -> pin.Model:
    """Build a fixed-base Pinocchio model from URDF text, its console messages captured.

    The messages are logged (logger ``calib``, level INFO: ``calib --verbose`` shows them).

    Raises:
        URDFError: Pinocchio refuses the text (the reason is urdfdom's first error line).
    """
    error: Exception | None = None
    model = None
    with console_captured() as captured:
        try:
            model = pin.buildModelFromXML(xml)
        except (RuntimeError, ValueError) as exc:
            error = exc
    messages = captured[0] if captured else ""
    if messages.strip():
        _LOG.info("Pinocchio on %s:\n%s", src, messages.rstrip())
    if model is None:
        raise URDFError(src, f"Pinocchio refuses it: {_pinocchio_failure(error, messages)}")
    return model


def read_urdf_file(path: str | Path) -> URDFInfo:
    """Read and check a URDF file (see :func:`~.urdf_xml.read_urdf_info`).

    Raises:
        URDFError: The file is missing, a directory, too large, malformed, or has a bad
            number.
    """
    try:
        raw = read_bytes_limited(path, MAX_URDF_BYTES)
    except FileNotFoundError:
        raise URDFError(str(path), "no such file") from None
    except OSError as exc:
        raise URDFError(str(path), exc.strerror or str(exc)) from None
    return read_urdf_info(raw, str(path))
