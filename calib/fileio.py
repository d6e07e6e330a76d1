"""File input and output: size-limited reading and atomic writing.

Inputs are read with a size limit; a file calib writes is either complete or absent, never
half-written.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

READ_CHUNK = 1 << 20
"""Bytes read at a time by :func:`read_bytes_limited` [B]."""


def read_bytes_limited(path: str | Path, limit: int) -> bytes:
    """Read a whole file, refusing one larger than ``limit`` bytes before reading it all.

    The size is checked while reading, so a device (``/dev/zero``), a FIFO or a file that
    grows is refused after at most ``limit + 1`` bytes, in well under a second.

    Args:
        path: File to read.
        limit: Largest accepted size [B].

    Returns:
        The content.

    Raises:
        OSError: The file is missing (``FileNotFoundError``), a directory
            (``IsADirectoryError``), unreadable, or larger than ``limit`` (``errno.EFBIG``);
            the error names the file and its ``strerror`` is a one-line reason.
    """
    target = Path(path)
    if target.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a directory, not a file", str(target))
    chunks: list[bytes] = []
    size = 0
    with open(target, "rb") as f:
        while size <= limit:
            chunk = f.read(min(READ_CHUNK, limit + 1 - size))
            if not chunk:
                return b"".join(chunks)
            chunks.append(chunk)
            size += len(chunk)
    raise OSError(errno.EFBIG, f"file larger than {_human_size(limit)}", str(target))


def read_text_limited(path: str | Path, limit: int) -> str:
    """Read a UTF-8 text file (a BOM is dropped) of at most ``limit`` bytes.

    Args:
        path: File to read.
        limit: Largest accepted size [B].

    Returns:
        The text; line ends are kept as they are in the file.

    Raises:
        OSError: As :func:`read_bytes_limited`, or ``errno.EILSEQ`` when the bytes are not
            UTF-8 (the message gives the byte offset).
    """
    raw = read_bytes_limited(path, limit)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise OSError(
            errno.EILSEQ, f"not UTF-8 text (byte {exc.start})", str(Path(path))
        ) from None


def _human_size(n: int) -> str:
    for unit, size in (("GB", 1 << 30), ("MB", 1 << 20), ("kB", 1 << 10)):
        if n >= size:
            return f"{n / size:g} {unit}"
    return f"{n} bytes"


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
