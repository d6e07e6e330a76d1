"""File input and output: size-limited reads, and outputs that are never half-written.

Inputs are read with a size limit (:func:`read_text_limited`, :func:`read_bytes_limited`).
Outputs are checked before any work, never onto an input, complete or not written at all.

Every command that writes files goes through :func:`check_outputs` (before its work) and
:func:`write_files_atomic` (after it):

* an output that is the same file as an input, or as another output (same resolved path,
  or ``os.path.samefile``: symbolic and hard links included), is refused;
* a regular file (or a new one) is written to a temporary file in its directory and renamed
  onto its path, so it is complete or left as it was; a symbolic link is written through to
  its target and stays a link;
* a character device (``/dev/null``), a FIFO and any path under ``/dev`` or ``/proc`` are
  written directly: renaming onto them would replace the device node; ``-`` (and a path
  under ``/dev`` that is standard output, such as ``/dev/stdout``) is written to standard
  output after what was printed there;
* every OS error becomes one :class:`~calib.exceptions.OutputError` line naming the target.
"""

from __future__ import annotations

import contextlib
import csv
import enum
import errno
import io
import itertools
import json
import os
import stat
import sys
import sysconfig
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TextIO, TypeVar

from ..exceptions import InvalidArgumentError, OutputError

__all__ = [
    "READ_CHUNK",
    "STDOUT",
    "PathLike",
    "check_outputs",
    "csv_text",
    "inputs_recorded",
    "json_text",
    "path_text",
    "read_bytes_limited",
    "read_failure",
    "read_text_limited",
    "same_file",
    "text_to_stderr",
    "write_all",
    "write_atomic",
    "write_files_atomic",
    "writes_stdout",
    "written_in_place",
]

STDOUT = "-"
"""The output name that means standard output."""

_DIRECT_TREES = ("/dev/", "/proc/")
"""Paths under these folders are written directly (``/dev/stdout`` is a link into /proc)."""

PathLike = str | os.PathLike[str]
_AnyPath = TypeVar("_AnyPath", bound=PathLike)  # a mapping of Path keys is no mapping of PathLike


class _Kind(enum.Enum):
    """How an output is written."""

    RENAME = "temporary file renamed onto the target"
    DIRECT = "opened and written in place"
    STDOUT = "standard output"


@dataclass(frozen=True)
class _Target:
    """An output path, what it really names and how it is written.

    Attributes:
        path: The path as given (errors name it).
        real: Where the bytes go: ``path`` with every symbolic link resolved.
        kind: How it is written.
    """

    path: str
    real: str
    kind: _Kind


def _target(path: PathLike) -> _Target:
    """Classify an output path.

    Raises:
        OutputError: A directory, a socket or block device, or a missing parent directory.
    """
    text = path_text(path)
    if writes_stdout(text):  # -, /dev/stdout, /dev/fd/1: after what was printed
        return _Target(text, text, _Kind.STDOUT)
    if os.path.abspath(text).startswith(_DIRECT_TREES):
        return _Target(text, text, _Kind.DIRECT)
    real = os.path.realpath(text)
    try:
        mode = os.stat(real).st_mode
    except FileNotFoundError:
        if not os.path.isdir(os.path.dirname(real)):
            raise OutputError(errno.ENOENT, "no such directory", text) from None
        return _Target(text, real, _Kind.RENAME)
    except OSError as exc:
        raise OutputError(exc.errno, exc.strerror, text) from None
    if stat.S_ISREG(mode):
        return _Target(text, real, _Kind.RENAME)
    if stat.S_ISCHR(mode) or stat.S_ISFIFO(mode):
        return _Target(text, text, _Kind.DIRECT)
    if stat.S_ISDIR(mode):
        raise OutputError(errno.EISDIR, "is a directory", text)
    raise OutputError(errno.EINVAL, "not a regular file, character device or FIFO", text)


def _check_writable(target: _Target) -> None:
    """Raise OutputError (naming the target) if it cannot be written."""
    if target.kind is _Kind.STDOUT:
        return
    if target.kind is _Kind.RENAME:
        folder = os.path.dirname(target.real)
        if _read_only(folder):
            raise OutputError(errno.EROFS, "read-only file system", target.path)
        if not os.access(folder, os.W_OK | os.X_OK):
            raise OutputError(errno.EACCES, "directory not writable", target.path)
    if os.path.exists(target.real) and not os.access(target.real, os.W_OK):
        raise OutputError(errno.EACCES, "file not writable", target.path)


def _read_only(folder: str) -> bool:
    try:
        return bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def _file_key(path: PathLike) -> tuple[int, int] | None:
    """(device, inode) of the file a path names (standard output for ``-``), if it exists."""
    try:
        st = os.fstat(_stdout().fileno()) if os.fspath(path) == STDOUT else os.stat(path)
    except (OSError, ValueError, AttributeError):  # no such file; stdout without a descriptor
        return None
    return st.st_dev, st.st_ino


def same_file(a: PathLike, b: PathLike) -> bool:
    """Whether two paths name one file: same resolved path, or same device and inode.

    ``-`` (standard output) is the same file as ``-`` and as the file standard output is.
    """
    a, b = os.fspath(a), os.fspath(b)
    if a == b:
        return True
    if STDOUT not in (a, b) and os.path.realpath(a) == os.path.realpath(b):
        return True
    key_a = _file_key(a)
    return key_a is not None and key_a == _file_key(b)


def check_outputs(
    outputs: Mapping[str, PathLike | None],
    inputs: Mapping[str, PathLike | None] | None = None,
    protected: Mapping[str, PathLike] | None = None,
) -> None:
    """Refuse, before any work, outputs that would overwrite an input or each other.

    Args:
        outputs: Output path by the option that names it (``{"--out": "cal.urdf"}``);
            None for an output not asked for.
        inputs: Input path by what it is (``{"the nominal URDF": path}``); None entries
            are ignored.
        protected: Folders by what they are (installed packages): no output may resolve
            to a path inside one.

    Raises:
        InvalidArgumentError: An output is the same file as an input, as a file read so far
            within :func:`inputs_recorded`, or as another output, or lies in a protected
            folder.
        OutputError: An output cannot be written: a directory, a missing or read-only
            directory, a socket.
    """
    given = {option: path for option, path in outputs.items() if path is not None}
    for option, path in given.items():
        for what, source in (inputs or {}).items():
            if source is not None and same_file(path, source):
                raise InvalidArgumentError(f"{option} {os.fspath(path)} would overwrite {what}")
        if os.fspath(path) != STDOUT:
            _refuse_read(path)
        _check_not_inside(option, path, protected or {})
    for (opt_a, a), (opt_b, b) in itertools.combinations(given.items(), 2):
        if same_file(a, b):
            raise InvalidArgumentError(
                f"{opt_a} and {opt_b} name the same file ({os.fspath(a)}, {os.fspath(b)})"
            )
    for path in given.values():
        _check_writable(_target(path))


def _check_not_inside(option: str, path: PathLike, protected: Mapping[str, PathLike]) -> None:
    """Refuse an output whose resolved path lies inside a protected folder."""
    text = os.fspath(path)
    if text == STDOUT or os.path.abspath(text).startswith(_DIRECT_TREES):
        return
    real = Path(os.path.realpath(text))
    for what, folder in protected.items():
        if real.is_relative_to(os.path.realpath(folder)):
            raise InvalidArgumentError(
                f"{option} {text} is inside the installed files of {what}: write elsewhere"
            )


_READ: list[list[str]] = []
"""The files read within each :func:`inputs_recorded` block, innermost last."""


@contextlib.contextmanager
def inputs_recorded() -> Iterator[None]:
    """Within the block, no output may be a file read in it (every command runs in one).

    Every file :func:`read_bytes_limited` reads is noted, the ones found rather than given
    included (the SRDF beside a URDF); :func:`check_outputs` and :func:`write_files_atomic`
    then refuse an output that is one of them. Outside a block (the Python API) a program
    may rewrite what it read.
    """
    _READ.append([])
    try:
        yield
    finally:
        _READ.pop()


def _refuse_read(path: PathLike) -> None:
    """InvalidArgumentError if ``path`` is a file read in the current block."""
    for read in _READ[-1] if _READ else ():
        if same_file(path, read):
            raise InvalidArgumentError(
                f"{os.fspath(path)} is {read}, which this command read: calib never "
                f"overwrites its inputs (write elsewhere)"
            )


_DATA: list[TextIO] = []
"""Standard output as it was when each :func:`text_to_stderr` block began, innermost last."""


@contextlib.contextmanager
def text_to_stderr() -> Iterator[None]:
    """Within the block, printed text goes to standard error, files written to ``-`` to stdout.

    A command whose output is ``-`` (``calib simulate --out - > meas.csv``) leaves the data
    alone on standard output.
    """
    _DATA.append(sys.stdout)
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        _DATA.pop()


def writes_stdout(path: object) -> bool:
    """Whether an output path is standard output (``-``, ``/dev/stdout``, ``/dev/fd/1``)."""
    text = os.fspath(path) if isinstance(path, str | os.PathLike) else None
    if text == STDOUT:
        return True
    if not isinstance(text, str) or not os.path.abspath(text).startswith(_DIRECT_TREES):
        return False
    key = _file_key(text)
    return key is not None and key == _file_key(STDOUT)


def _stdout() -> TextIO:
    """Where a file written to ``-`` goes (standard output, outside :func:`text_to_stderr`)."""
    return _DATA[-1] if _DATA else sys.stdout


READ_CHUNK = 1 << 20
"""Bytes read at a time by :func:`read_bytes_limited` [B]."""


def read_bytes_limited(path: str | Path, limit: int) -> bytes:
    """Read a whole regular file, refusing one larger than ``limit`` bytes before reading it all.

    Anything else is refused before a byte is read: a FIFO (whose ``open`` would wait for a
    writer forever), a device (``/dev/zero`` never ends), a directory, a socket. The size is
    checked while reading, so a file that grows is refused after at most ``limit + 1`` bytes.

    Args:
        path: File to read.
        limit: Largest accepted size [B].

    Returns:
        The content.

    Raises:
        OSError: The file is missing (``FileNotFoundError``), a directory
            (``IsADirectoryError``), no regular file (``errno.EINVAL``), unreadable, or larger
            than ``limit`` (``errno.EFBIG``); the error names the file and its ``strerror``
            is a one-line reason.
        InvalidArgumentError: ``path`` is not a path (None, a number, empty).
    """
    target = Path(path_text(path))
    fd = _open_regular(target)
    if _READ:
        _READ[-1].append(str(target))
    chunks: list[bytes] = []
    size = 0
    with open(fd, "rb") as f:
        while size <= limit:
            chunk = f.read(min(READ_CHUNK, limit + 1 - size))
            if not chunk:
                return b"".join(chunks)
            chunks.append(chunk)
            size += len(chunk)
    raise OSError(errno.EFBIG, f"file larger than {_human_size(limit)}", str(target))


_NOT_REGULAR = (
    (stat.S_ISDIR, errno.EISDIR, "is a directory, not a file"),
    (stat.S_ISFIFO, errno.EINVAL, "a FIFO (named pipe), not a regular file: it may never end"),
    (stat.S_ISCHR, errno.EINVAL, "a character device, not a regular file: it may never end"),
    (stat.S_ISBLK, errno.EINVAL, "a block device, not a regular file"),
    (stat.S_ISSOCK, errno.EINVAL, "a socket, not a regular file"),
)
"""What an input that is no regular file is, and the reason its refusal gives."""


def path_text(path: object) -> str:
    """The text of a file path (an input or an output): a ``str`` or ``os.PathLike``.

    Raises:
        InvalidArgumentError: None, a number, bytes or an empty path.
    """
    text = os.fspath(path) if isinstance(path, str | os.PathLike) else None
    if not isinstance(text, str) or not text:
        raise InvalidArgumentError(f"a file path must be a non-empty str or Path, got {path!r:.60}")
    return text


def _open_regular(target: Path) -> int:
    """A read descriptor of a regular file; never waits on a FIFO or reads a device.

    The file is checked before it is opened (a FIFO's ``open`` waits for a writer) and
    again once open without blocking (it may have been replaced in between).

    Raises:
        OSError: Missing, unreadable, or not a regular file (a directory, a FIFO, a
            device, a socket); the error names the file.
    """
    _refuse_irregular(target, os.stat(target).st_mode)
    fd = os.open(target, os.O_RDONLY | os.O_NONBLOCK)
    try:
        _refuse_irregular(target, os.fstat(fd).st_mode)
        os.set_blocking(fd, True)
    except BaseException:
        os.close(fd)
        raise
    return fd


def _refuse_irregular(target: Path, mode: int) -> None:
    """Raise OSError naming ``target`` unless ``mode`` is a regular file's."""
    for test, code, reason in _NOT_REGULAR:
        if test(mode):
            raise OSError(code, reason, str(target))


def read_failure(exc: OSError) -> str:
    """Why a file could not be read, as an error's reason: "no such file" or the OS's words."""
    if isinstance(exc, FileNotFoundError):
        return "no such file"
    return f"cannot read the file: {exc.strerror or exc}"


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
        raise OSError(errno.EILSEQ, f"not UTF-8 text (byte {exc.start})", str(Path(path))) from None


def _human_size(n: int) -> str:
    for unit, size in (("GB", 1 << 30), ("MB", 1 << 20), ("kB", 1 << 10)):
        if n >= size:
            return f"{n / size:g} {unit}"
    return f"{n} bytes"


def _to_bytes(content: str | bytes) -> bytes:
    if isinstance(content, str):
        return content.encode("utf-8")
    if isinstance(content, bytes | bytearray | memoryview):
        return bytes(content)
    raise TypeError(f"file content must be str or bytes, not {type(content).__name__}")


def written_in_place(path: PathLike) -> bool:
    """Whether ``path`` is written directly (``-``, a device, a FIFO, a /dev or /proc path).

    Such an output is no file of its own: no name can be derived from it.

    Raises:
        OutputError: ``path`` cannot be an output (a directory, a socket, no such folder).
    """
    return _target(path).kind is not _Kind.RENAME


def write_files_atomic(files: Mapping[_AnyPath, str | bytes]) -> None:
    """Write several files so that no regular file is ever left half-written.

    Regular (and new) files are first written in full to temporary files in their target
    directories; devices, FIFOs and ``-`` are then written directly; only when all of that
    succeeded are the temporary files renamed (``os.replace``) onto their paths. On any
    failure, a signal that raises included, the temporary files are removed and the regular
    targets are left as they were.

    Args:
        files: Content (text is written as UTF-8) by target path; ``-`` is standard output.

    Raises:
        OutputError: A target is a directory, a directory is missing or not writable, or the
            disk is full; the error names the target, never the temporary file.
        TypeError: A content is neither text nor bytes.
    """
    jobs = [(_target(path), _to_bytes(content)) for path, content in files.items()]
    for target, _ in jobs:
        if target.kind is not _Kind.STDOUT:
            _refuse_read(target.path)
            _refuse_installed(target)
        _check_writable(target)
    staged: list[str] = []
    try:
        renames = [
            (_stage(target, data, staged), target)
            for target, data in jobs
            if target.kind is _Kind.RENAME
        ]
        for target, data in jobs:
            if target.kind is _Kind.DIRECT:
                _write_direct(target, data)
            elif target.kind is _Kind.STDOUT:
                _write_stdout(data)
        for tmp, target in renames:
            _guarded(target, os.replace, tmp, target.real)
    finally:
        for tmp in staged:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)


_SITE = ("purelib", "platlib")
"""The ``sysconfig`` paths of installed packages, which no output may go inside."""


def _refuse_installed(target: _Target) -> None:
    """Refuse a file inside installed packages, whatever writes it (the Python API too).

    Python's ``site-packages`` (example-robot-data's URDFs, SRDFs and meshes among them)
    and calib's own folder: ``calib.write_measurements(chain.urdf_path, data)`` replaced the
    installed robot for every later use.

    Raises:
        InvalidArgumentError: ``target`` resolves inside one of them.
    """
    roots = [("calib", Path(__file__).resolve().parent.parent)]
    roots += [("the installed Python packages", Path(sysconfig.get_path(k))) for k in _SITE]
    for what, root in roots:
        if Path(target.real).is_relative_to(os.path.realpath(root)):
            raise InvalidArgumentError(
                f"{target.path} is inside the installed files of {what}: write elsewhere"
            )


def _guarded(target: _Target, func, *args):
    """Call ``func(*args)``; an OSError becomes an OutputError naming the target."""
    try:
        return func(*args)
    except OutputError:
        raise
    except OSError as exc:
        raise OutputError(exc.errno, exc.strerror or str(exc), target.path) from None


def _stage(target: _Target, data: bytes, staged: list[str]) -> str:
    """Write ``data`` to a new temporary file beside the target; record it in ``staged``."""
    folder = os.path.dirname(target.real)
    name = os.path.basename(target.real)
    fd, tmp = _guarded(target, tempfile.mkstemp, ".tmp", f".{name}.", folder)
    staged.append(tmp)
    try:
        _guarded(target, os.fchmod, fd, _mode_for(target.real))
        _guarded(target, write_all, fd, data)
        _guarded(target, os.fsync, fd)
    finally:
        os.close(fd)
    return tmp


def _mode_for(path: str) -> int:
    """The permission bits of the file being replaced, else the usual ones (umask applied)."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~_UMASK


def write_all(fd: int, data: bytes) -> None:
    """Write every byte of ``data`` to a file descriptor (``os.write`` may write fewer).

    Raises:
        OSError: The write failed (disk full, device error, ...).
    """
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _write_direct(target: _Target, data: bytes) -> None:
    """Open a device, FIFO or /dev, /proc path and write to it in place."""
    fd = _guarded(target, os.open, target.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
    try:
        _guarded(target, write_all, fd, data)
    finally:
        os.close(fd)


def _write_stdout(data: bytes) -> None:
    """Write to standard output after what was printed there before."""
    out = _stdout()
    out.flush()
    buffer = getattr(out, "buffer", None)
    if buffer is None:
        out.write(data.decode("utf-8", errors="replace"))
    else:
        buffer.write(data)
        buffer.flush()


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


_UMASK = _read_umask()
"""The process umask, read once at import."""


def write_atomic(path: PathLike, content: str | bytes) -> None:
    """Write one file (see :func:`write_files_atomic`)."""
    write_files_atomic({path: content})


def json_text(obj: object) -> str:
    """Indented, strictly valid JSON text with a final newline.

    Raises:
        ValueError: ``obj`` holds NaN or infinity (write None for "undefined" instead).
    """
    return json.dumps(obj, indent=2, allow_nan=False) + "\n"


def csv_text(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    """CSV text of a header and rows of cells (Unix line ends), as calib writes its files."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return out.getvalue()
