"""Atomic file output: a file calib writes is either complete or absent, never half-written."""

from __future__ import annotations

import contextlib
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
        OSError: A directory is missing or not writable, or the disk is full.
    """
    staged: list[tuple[str, Path]] = []
    try:
        for path, content in files.items():
            target = Path(path)
            fd, tmp = tempfile.mkstemp(
                prefix=f".{target.name}.", suffix=".tmp", dir=target.parent or Path(".")
            )
            staged.append((tmp, target))
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode
            with os.fdopen(fd, "wb") as f:
                f.write(_to_bytes(content))
                f.flush()
                os.fsync(f.fileno())
        for tmp, target in staged:
            os.replace(tmp, target)
    finally:
        for tmp, _ in staged:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(path: str | Path, content: str | bytes) -> None:
    """Write one file atomically (see :func:`write_files_atomic`)."""
    write_files_atomic({path: content})


def json_text(obj: object) -> str:
    """Indented, strictly valid JSON text with a final newline.

    Raises:
        ValueError: ``obj`` holds NaN or infinity (write None for "undefined" instead).
    """
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"
