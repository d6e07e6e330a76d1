"""Atomic file output: a file calib writes is either complete or absent, never half-written."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path


def _to_bytes(content: str | bytes) -> bytes:
    return content.encode("utf-8") if isinstance(content, str) else content


def write_files_atomic(files: Mapping[str | Path, str | bytes]) -> None:
    """Write several files so that none of them is ever left half-written.

    Every file is first written in full to a temporary file in its target directory; only
    when all of them are written are they renamed (``os.replace``) onto their paths. On any
    failure the temporary files are removed and the targets are left as they were.

    Args:
        files: Content (text is written as UTF-8) by target path.

    Raises:
        OSError: A target is a directory, a directory is missing or not writable, or the
            disk is full; the error names the target, never the temporary file.
    """
    for path in files:
        _check_target(Path(path))
    staged: list[tuple[str, Path]] = []
    try:
        for path, content in files.items():
            target = Path(path)
            try:
                fd, tmp = tempfile.mkstemp(
                    prefix=f".{target.name}.", suffix=".tmp", dir=target.parent or Path(".")
                )
            except OSError as exc:
                raise OSError(exc.errno, exc.strerror, str(target)) from None
            staged.append((tmp, target))
            with os.fdopen(fd, "wb") as f:
                os.fchmod(f.fileno(), 0o666 & ~_UMASK)  # mkstemp makes 0600: use the usual mode
                f.write(_to_bytes(content))
                f.flush()
                os.fsync(f.fileno())
        for tmp, target in staged:
            os.replace(tmp, target)
    finally:
        for tmp, _ in staged:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)


def _check_target(target: Path) -> None:
    """Raise OSError (naming the target) if it cannot be written: before any work is done."""
    parent = target.parent if str(target.parent) else Path(".")
    if target.is_dir():
        raise OSError(errno.EISDIR, "is a directory", str(target))
    if not parent.is_dir():
        raise OSError(errno.ENOENT, "no such directory", str(parent))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OSError(errno.EACCES, "directory not writable", str(parent))


def check_writable(*paths: str | Path | None) -> None:
    """Check, before a long computation, that every output path can be written.

    Raises:
        OSError: A target is a directory, or its directory is missing or not writable.
    """
    for path in paths:
        if path is not None:
            _check_target(Path(path))


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _read_umask()
"""The process umask, read once at import."""


def write_atomic(path: str | Path, content: str | bytes) -> None:
    """Write one file atomically (see :func:`write_files_atomic`)."""
    write_files_atomic({path: content})


def json_text(obj: object) -> str:
    """Indented, strictly valid JSON text with a final newline.

    Raises:
        ValueError: ``obj`` holds NaN or infinity (write None for "undefined" instead).
    """
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"
