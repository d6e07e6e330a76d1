"""Files: no output onto an input or another output, the right way to write each kind of file,
one-line errors for every OS failure, clean-up on SIGTERM, figure formats, BLAS threads."""

from __future__ import annotations

import contextlib
import dataclasses
import errno
import hashlib
import json
import os
import signal
import stat
import subprocess
import sys
import textwrap
import threading
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

import calib.cli.commands
import calib.core.fileio
import calib.measurements.csvfile
import calib.outputs.sweep
from calib.cli.commands import main
from calib.core.fileio import check_outputs, same_file, write_atomic, write_files_atomic
from calib.exceptions import CalibError, InvalidArgumentError, OutputError

ROOT = Path(__file__).resolve().parents[1]
AID = ROOT / "models" / "aid.urdf"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SIMULATE = ["simulate", "ur5", "--configs", "5", "--measure", "position"]
"""A quick command with outputs."""


def digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def listing(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def one_line_error(capsys, argv) -> str:
    """Run the CLI, expect exit 2 and exactly one error line (warnings aside), return it."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    errors = [line for line in err.splitlines() if not line.startswith("calib: warning:")]
    assert code == 2, (argv, out, err)
    assert len(errors) == 1 and errors[0].startswith("calib: error: "), err
    assert "Traceback" not in err
    return errors[0]


@pytest.fixture
def no_work(monkeypatch):
    """Make every long computation of the CLI fail loudly: a refusal must come before it."""

    def forbidden(*args, **kwargs):
        raise AssertionError("the work started before the outputs were checked")

    for name in ("simulate", "calibrate", "read_measurements"):
        monkeypatch.setattr(calib.cli.commands, name, forbidden, raising=False)
    monkeypatch.setattr(calib.outputs.sweep, "sweep", forbidden)


# --------------------------------------------------------------------------------------
# Item 1: an output never overwrites an input or another output, refused before any work
# --------------------------------------------------------------------------------------


def _links(tmp: Path) -> dict[str, Path]:
    robot = tmp / "r.urdf"
    robot.write_bytes(AID.read_bytes())
    data = tmp / "d.csv"
    data.write_text("not read: the refusal comes first\n")
    (tmp / "soft.urdf").symlink_to(robot.name)
    os.link(robot, tmp / "hard.urdf")
    (tmp / "sub").mkdir()
    return {"robot": robot, "data": data}


CASES = [  # (command line, a fact of the error line)
    ("simulate {robot} --out {robot}", "--out"),
    ("simulate {robot} --out {tmp}/m.csv --truth {robot}", "--truth"),
    ("simulate {robot} --out {tmp}/hard.urdf", "--out"),
    ("simulate {robot} --out {tmp}/soft.urdf", "--out"),
    ("simulate {robot} --out {tmp}/sub/../r.urdf", "--out"),
    ("simulate {robot} --out {tmp}/m.csv --truth {tmp}/m.csv", "same file"),
    ("calibrate {robot} --data {data} --out {data}", "--out"),
    ("calibrate {robot} --data {data} --out {tmp}/c.urdf --report {tmp}/soft.urdf", "--report"),
    ("calibrate {robot} --data {data} --out {tmp}/hard.urdf", "nominal"),
    ("calibrate {robot} --data {data} --out {tmp}/c.urdf --report {tmp}/sub/../c.urdf", "same"),
    ("calibrate {robot} --data {data} --out {tmp}/c.json --report {tmp}/c.urdf", "not the JSON"),
    ("sweep {robot} --csv {robot}", "--csv"),
    ("sweep {robot} --csv {tmp}/s.png --plot {tmp}/s.png", "same file"),
    ("sweep {robot} --csv {tmp}/hard.urdf", "--csv"),
]


@pytest.mark.parametrize(("argv", "fact"), CASES, ids=[c[0] for c in CASES])
def test_output_onto_an_input_or_another_output_is_refused_before_any_work(
    tmp_path, capsys, no_work, argv, fact
):
    paths = _links(tmp_path)
    before = {name: digest(tmp_path / name) for name in ("r.urdf", "d.csv")}
    names = listing(tmp_path)
    line = one_line_error(capsys, argv.format(tmp=tmp_path, **paths).split())
    assert fact in line
    assert {name: digest(tmp_path / name) for name in before} == before
    assert listing(tmp_path) == names and listing(tmp_path / "sub") == []
    assert (tmp_path / "soft.urdf").is_symlink()


@contextlib.contextmanager
def must_stay(target: Path):
    """Fail if ``target`` changes inside (and put it back: never leave the install damaged)."""
    original = target.read_bytes()
    try:
        yield
    finally:
        if target.read_bytes() != original:
            target.write_bytes(original)
            pytest.fail(f"{target} was overwritten")


@pytest.mark.parametrize("entry", ["aid.urdf", "catalog.toml"])
def test_a_file_of_the_installed_catalog_is_never_overwritten(tmp_path, capsys, no_work, entry):
    from calib.kinematics.catalog import models_dir

    target = models_dir() / entry
    with must_stay(target):
        # The robot analysed is a copy elsewhere: only the catalog's own protection refuses.
        robot = tmp_path / "r.urdf"
        robot.write_bytes(AID.read_bytes())
        line = one_line_error(capsys, ["simulate", robot, "--out", target])
        assert "catalog" in line and entry in line
        line = one_line_error(capsys, ["sweep", "--csv", target])
        assert "--csv" in line and "catalog" in line


def test_the_catalog_urdf_of_a_robot_name_is_protected(tmp_path, capsys, no_work):
    from calib.kinematics.catalog import catalog_entry

    target = catalog_entry("ur5").path  # example-robot-data's file
    with must_stay(target):
        line = one_line_error(capsys, ["sweep", "--csv", target])
        assert "the catalog URDF of 'ur5'" in line


def test_same_file_against_the_file_system(tmp_path):
    a = tmp_path / "a.txt"
    a.write_text("a")
    (tmp_path / "soft").symlink_to(a)
    os.link(a, tmp_path / "hard")
    (tmp_path / "d").mkdir()
    os.chdir(tmp_path / "d")
    try:
        assert same_file(a, "../a.txt")
        assert same_file(tmp_path / "soft", a) and same_file(tmp_path / "hard", a)
        assert same_file(tmp_path / "new.txt", tmp_path / "d" / ".." / "new.txt")  # not there yet
        assert not same_file(tmp_path / "new.txt", a)
        assert not same_file(tmp_path / "new.txt", tmp_path / "new.csv")
        assert same_file("-", "-") and not same_file("-", a)
        assert same_file("/dev/null", "/dev/null")
    finally:
        os.chdir(ROOT)


def test_check_outputs_messages_name_the_options(tmp_path):
    src = tmp_path / "in.urdf"
    src.write_text("x")
    with pytest.raises(InvalidArgumentError, match=r"^--out .*in\.urdf would overwrite the URDF$"):
        check_outputs({"--out": src}, {"the URDF": src})
    with pytest.raises(InvalidArgumentError, match="--a and --b name the same file"):
        check_outputs({"--a": tmp_path / "x", "--b": tmp_path / "x", "--c": None})
    check_outputs({"--a": tmp_path / "x", "--b": None}, {"nothing": None})  # fine
    with pytest.raises(OutputError, match="is a directory"):
        check_outputs({"--a": tmp_path})
    with pytest.raises(OutputError, match="no such directory") as info:
        check_outputs({"--a": tmp_path / "no" / "x"})
    assert isinstance(info.value, CalibError) and isinstance(info.value, OSError)
    assert info.value.errno == errno.ENOENT and info.value.filename == str(tmp_path / "no" / "x")


def test_api_export_refuses_to_overwrite_the_nominal_urdf(tmp_path):
    from calib import from_chain, load_chain
    from calib.kinematics.urdf_export import write_calibrated_urdf

    robot = tmp_path / "r.urdf"
    robot.write_bytes(AID.read_bytes())
    chain = load_chain(robot)
    mdh = from_chain(chain)
    with pytest.raises(InvalidArgumentError, match="nominal URDF"):
        write_calibrated_urdf(tmp_path / "." / "r.urdf", chain, mdh, mdh)
    assert robot.read_bytes() == AID.read_bytes()


def test_a_results_write_never_overwrites_the_data_it_was_fitted_on(tmp_path):
    """``result.write`` refuses, before writing anything, an output that is a term's data or
    validation file (it checked the nominal URDF only: ``write("meas.csv")`` replaced the
    campaign)."""
    import calib

    chain = calib.load_robot("ur5")
    paths = [tmp_path / "a.csv", tmp_path / "b.csv"]
    every = calib.simulate(chain, 42, seed=1, noise_mm=0.05).measurements
    for keep, path in zip((np.arange(42) < 30, np.arange(42) >= 30), paths, strict=True):
        calib.write_measurements(path, every.subset(keep))
    before = [p.read_bytes() for p in paths]
    data, held = (calib.read_measurements(p, chain) for p in paths)
    result = calib.calibrate(chain, data, validate=held)
    for out, report, what in [
        (paths[0], None, "the data of term 1"),
        (tmp_path / "c.urdf", paths[1], "the validation data of term 1"),
        (tmp_path / "c.urdf", tmp_path / "." / "a.csv", "the data of term 1"),
    ]:
        with pytest.raises(InvalidArgumentError, match=f"would overwrite {what}"):
            result.write(out, report=report)
    assert [p.read_bytes() for p in paths] == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.csv", "b.csv"]


# --------------------------------------------------------------------------------------
# Item 2: regular files by rename; devices, FIFOs, stdout directly; links written through
# --------------------------------------------------------------------------------------


def test_dev_null_stays_a_device_and_the_other_output_is_written(tmp_path, capsys):
    truth = tmp_path / "t.json"
    code = main([*SIMULATE, "--out", "/dev/null", "--truth", str(truth)])
    assert code == 0, capsys.readouterr().err
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)
    assert json.loads(truth.read_text())["robot"] == "ur5"
    assert listing(tmp_path) == ["t.json"]


@pytest.mark.parametrize("out", ["/dev/null", "-"])
def test_simulate_to_a_device_or_stdout_needs_an_explicit_truth_file(
    tmp_path, capsys, no_work, monkeypatch, out
):
    monkeypatch.chdir(tmp_path)
    line = one_line_error(capsys, [*SIMULATE, "--out", out])
    assert "--truth" in line
    assert listing(tmp_path) == [] and not os.path.exists("/dev/null.truth.json")


@pytest.mark.parametrize("out", ["-", "/dev/stdout"])
def test_data_written_to_stdout_is_alone_there_and_the_text_goes_to_stderr(tmp_path, out):
    """``calib simulate --out - > meas.csv``: the file was followed on stdout by the printed
    summary, so the CSV redirected was not one."""
    argv = [*SIMULATE, "--out", out, "--truth", str(tmp_path / "t.json")]
    printed = subprocess.run(
        [sys.executable, "-m", "calib.cli", *argv], capture_output=True, text=True, timeout=120
    )
    assert printed.returncode == 0, printed.stderr
    rows = printed.stdout.splitlines()
    assert rows[0].startswith("shoulder_pan_joint,") and len(rows) == 6, printed.stdout
    assert {row.count(",") for row in rows} == {8}
    assert "5 configurations" in printed.stderr and "wrote" in printed.stderr


def test_json_and_an_output_on_stdout_are_refused_together(capsys):
    """``calib design --out - --json``: the JSON went to standard error with the messages."""
    code = main(["design", "ur5", "--configs", "3", "--out", "-", "--json"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert (
        err
        == "calib: error: --json prints to standard output, where --out - writes: give it a file\n"
    )


def test_a_relative_path_to_dev_stdout_is_standard_output(monkeypatch):
    """``cd /dev; calib ... --out stdout`` writes standard output (the file's path is taken
    absolute), so the printed text must leave it too."""
    assert calib.core.fileio.writes_stdout("/dev/stdout")
    monkeypatch.chdir("/dev")
    assert calib.core.fileio.writes_stdout("stdout")


def test_a_closed_pipe_on_stdout_leaves_the_warnings_on_stderr(tmp_path):
    """``calib calibrate --out - | head -c 0``: the URDF stops quietly; the warnings after it
    still go to standard error (it was standard error that was sent to /dev/null)."""
    chain = calib.load_chain("ur5")
    data = calib.simulate(chain, 30, seed=1, noise_mm=0.05).measurements
    q = data.q.copy()
    q[0, 0] = chain.upper[0] + 0.02  # past the limit by less than the margin: a warning
    path = tmp_path / "m.csv"
    calib.measurements.csvfile.write_measurements(path, dataclasses.replace(data, q=q))
    read, write = os.pipe()
    os.close(read)  # a reader that left at once
    try:
        printed = subprocess.run(
            [
                sys.executable,
                "-m",
                "calib.cli",
                "calibrate",
                "ur5",
                "--data",
                str(path),
                "--out",
                "-",
            ],
            stdout=write,
            stderr=subprocess.PIPE,
            text=True,
            timeout=120,
        )
    finally:
        os.close(write)
    assert printed.returncode == 0, printed.stderr
    assert "read past the URDF joint limits" in printed.stderr


def test_dev_full_is_a_one_line_error_and_nothing_else_is_written(tmp_path, capsys):
    line = one_line_error(
        capsys,
        [*SIMULATE, "--out", "/dev/full", "--truth", tmp_path / "t.json"],
    )
    assert line == "calib: error: cannot write /dev/full: " + os.strerror(errno.ENOSPC)
    assert stat.S_ISCHR(os.stat("/dev/full").st_mode)
    assert listing(tmp_path) == []


def test_a_fifo_is_written_directly(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    received: list[bytes] = []

    def reader():
        with open(fifo, "rb") as f:
            received.append(f.read())

    thread = threading.Thread(target=reader, daemon=True)
    thread.start()
    payload = b"x,y\n" * 50_000  # more than a pipe buffer: the writer must wait for the reader
    write_files_atomic({fifo: payload, tmp_path / "regular.txt": "r"})
    thread.join(timeout=30)
    assert received == [payload]
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert listing(tmp_path) == ["pipe", "regular.txt"]


def test_standard_output_after_what_was_printed(capsys):
    print("first")
    write_files_atomic({"-": "second\n"})
    assert capsys.readouterr().out == "first\nsecond\n"


STD_STREAMS_SCRIPT = textwrap.dedent(
    """
    from calib.core.fileio import write_atomic

    print("before", flush=True)
    write_atomic("/dev/stdout", "written\\n")
    print("after")
    write_atomic("/dev/stderr", "to stderr\\n")
    """
)


def test_dev_stdout_and_stderr_redirected_to_files_are_not_replaced(tmp_path):
    """``> out.txt``: /dev/stdout leads to a regular file, which a rename would replace (and
    what the process prints next would go to the unlinked file)."""
    with open(tmp_path / "out.txt", "w+b") as out, open(tmp_path / "err.txt", "w+b") as err:
        proc = subprocess.run(
            [sys.executable, "-c", STD_STREAMS_SCRIPT], stdout=out, stderr=err, timeout=120
        )
        assert proc.returncode == 0
        out.seek(0)
        err.seek(0)
        assert out.read() == b"before\nwritten\nafter\n"  # read through the inode we opened
        assert err.read() == b"to stderr\n"
    assert listing(tmp_path) == ["err.txt", "out.txt"]


def test_a_symlink_is_written_through_and_stays_a_link(tmp_path):
    real_dir, link_dir = tmp_path / "real", tmp_path / "links"
    real_dir.mkdir()
    link_dir.mkdir()
    target = real_dir / "data.csv"
    target.write_text("old")
    target.chmod(0o640)
    link = link_dir / "data.csv"
    link.symlink_to(target)
    write_atomic(link, "new")
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert target.read_text() == "new"
    assert stat.S_IMODE(target.stat().st_mode) == 0o640  # the replaced file's mode is kept
    assert listing(real_dir) == ["data.csv"] and listing(link_dir) == ["data.csv"]
    dangling = link_dir / "future.csv"
    dangling.symlink_to(real_dir / "future.csv")
    write_atomic(dangling, "born")
    assert dangling.is_symlink() and (real_dir / "future.csv").read_text() == "born"


def test_full_disk_while_writing_keeps_the_old_file_and_leaves_no_temporary(
    tmp_path, monkeypatch, capsys
):
    old = tmp_path / "m.csv"
    old.write_text("old")

    def full(fd, data):
        os.write(fd, bytes(data)[:10])  # a part goes out, then the disk is full
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(calib.core.fileio, "write_all", full)
    with pytest.raises(OutputError) as info:
        write_files_atomic({old: "new content", tmp_path / "t.json": "{}"})
    assert str(info.value) == f"cannot write {old}: {os.strerror(errno.ENOSPC)}"
    assert old.read_text() == "old" and listing(tmp_path) == ["m.csv"]
    line = one_line_error(capsys, [*SIMULATE, "--out", old])
    assert line == f"calib: error: cannot write {old}: {os.strerror(errno.ENOSPC)}"
    assert old.read_text() == "old" and listing(tmp_path) == ["m.csv"]


def test_a_read_only_directory_is_refused_before_work(tmp_path, monkeypatch, capsys, no_work):
    """As root the kernel lets every directory be written: the permission answer is faked at
    the os.access level, so the real check (and not a stub of it) decides."""
    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access
    monkeypatch.setattr(
        os, "access", lambda p, mode: False if Path(p) == locked else real_access(p, mode)
    )
    line = one_line_error(capsys, [*SIMULATE, "--out", locked / "m.csv"])
    assert line == f"calib: error: cannot write {locked / 'm.csv'}: directory not writable"
    assert listing(locked) == []


def test_a_read_only_file_system_is_named(tmp_path, monkeypatch, capsys, no_work):
    real = os.statvfs

    class ReadOnly:
        def __init__(self, res):
            self.f_flag = res.f_flag | os.ST_RDONLY

    monkeypatch.setattr(
        os, "statvfs", lambda p: ReadOnly(real(p)) if Path(p) == tmp_path else real(p)
    )
    line = one_line_error(capsys, [*SIMULATE, "--out", tmp_path / "m.csv"])
    assert line.endswith(f"cannot write {tmp_path / 'm.csv'}: read-only file system")


def test_permission_denied_while_writing_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    """The directory became unwritable after the check: the temporary file cannot be made."""
    import tempfile

    def denied(*args, **kwargs):
        raise PermissionError(errno.EACCES, os.strerror(errno.EACCES))

    monkeypatch.setattr(tempfile, "mkstemp", denied)
    with pytest.raises(OutputError) as info:
        write_files_atomic({tmp_path / "a.csv": "a"})
    assert str(info.value) == f"cannot write {tmp_path / 'a.csv'}: {os.strerror(errno.EACCES)}"
    assert listing(tmp_path) == []


def test_sockets_and_directories_are_refused(tmp_path):
    import socket

    path = tmp_path / "s.sock"
    sock = socket.socket(socket.AF_UNIX)
    try:
        sock.bind(str(path))
        with pytest.raises(OutputError, match="not a regular file"):
            write_atomic(path, "x")
    finally:
        sock.close()
    with pytest.raises(OutputError, match="is a directory"):
        write_atomic(tmp_path, "x")


SIGTERM_SCRIPT = textwrap.dedent(
    """
    import os, signal, sys
    import calib.core.fileio
    from calib.cli.commands import main

    real = calib.core.fileio.write_all

    def write_then_terminated(fd, data):
        real(fd, bytes(data)[: len(data) // 2])
        os.kill(os.getpid(), signal.SIGTERM)  # a real signal, in the middle of the write
        real(fd, bytes(data)[len(data) // 2 :])

    calib.core.fileio.write_all = write_then_terminated
    code = main(sys.argv[1:])
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL, "handler not restored"
    sys.exit(code)
    """
)


def test_sigterm_during_a_write_removes_the_temporary_file(tmp_path):
    out = tmp_path / "m.csv"
    out.write_text("old")
    proc = subprocess.run(
        [sys.executable, "-c", SIGTERM_SCRIPT, *SIMULATE, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert proc.returncode == 128 + signal.SIGTERM, proc.stderr
    errors = [line for line in proc.stderr.splitlines() if "warning" not in line]
    assert errors == ["calib: terminated"]
    assert listing(tmp_path) == ["m.csv"] and out.read_text() == "old"


# --------------------------------------------------------------------------------------
# Item 3: --plot honours the extension
# --------------------------------------------------------------------------------------


def _is_svg(data: bytes) -> bool:
    return ET.fromstring(data).tag == "{http://www.w3.org/2000/svg}svg"


def test_sweep_plot_svg_has_svg_bytes(tmp_path, capsys):
    out = tmp_path / "counts.SVG"
    assert main(["sweep", "--configs", "20", "--plot", str(out)]) == 0
    capsys.readouterr()
    assert _is_svg(out.read_bytes())
    assert listing(tmp_path) == ["counts.SVG"]


@pytest.mark.parametrize(
    ("name", "check"),
    [
        ("f.png", lambda b: b.startswith(PNG_MAGIC)),
        ("f.pdf", lambda b: b.startswith(b"%PDF-") and b.rstrip().endswith(b"%%EOF")),
        ("f.svg", _is_svg),
    ],
)
def test_save_figure_format_follows_the_extension(tmp_path, name, check):
    from calib.outputs.plots import errors_figure, save_figure

    save_figure(errors_figure([1e-3, 2e-3], [1e-6, 2e-6]), tmp_path / name)
    assert check((tmp_path / name).read_bytes())


@pytest.mark.parametrize("plot", ["s.gif", "s", "s.png.bak", "-"])
def test_unknown_plot_extension_is_refused_before_work(tmp_path, capsys, no_work, plot):
    target = plot if plot == "-" else tmp_path / plot
    line = one_line_error(capsys, ["sweep", "--csv", tmp_path / "s.csv", "--plot", target])
    assert "--plot" in line and ".png, .svg, .pdf" in line
    assert listing(tmp_path) == []


# --------------------------------------------------------------------------------------
# Item 13: one BLAS thread by default
# --------------------------------------------------------------------------------------


THREADS_SCRIPT = textwrap.dedent(
    """
    import json, os, sys
    from threadpoolctl import threadpool_info
    import calib.cli.analysis_cli
    import calib.cli.commands

    def blas():
        return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

    seen = []
    real = calib.cli.analysis_cli.analyze

    def spy(*args, **kwargs):
        seen.append(blas())
        return real(*args, **kwargs)

    calib.cli.analysis_cli.analyze = spy
    argv = ["analyze", "aid", "--configs", "20"]
    outside = blas()
    assert calib.cli.commands.main(argv) == 0
    os.environ["CALIB_THREADS"] = "2"
    assert calib.cli.commands.main(argv) == 0
    after = blas()
    print(json.dumps({"outside": outside, "default": seen[0], "two": seen[1], "after": after}),
          file=sys.stderr)
    """
)


def test_the_cli_runs_blas_on_one_thread_unless_told_otherwise():
    env = {
        k: v
        for k, v in os.environ.items()
        if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "CALIB_THREADS")
    }
    proc = subprocess.run(
        [sys.executable, "-c", THREADS_SCRIPT],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    seen = json.loads(proc.stderr.splitlines()[-1])
    assert seen["default"] == [1]
    assert seen["two"] == [2]
    assert seen["after"] == seen["outside"]  # the process's own setting is given back


def test_a_thread_count_the_user_set_is_respected(monkeypatch):
    monkeypatch.delenv("CALIB_THREADS", raising=False)
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "3")
    assert calib.cli.commands.blas_threads() is None
    monkeypatch.setenv("CALIB_THREADS", "2")
    assert calib.cli.commands.blas_threads() == 2
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "CALIB_THREADS"):
        monkeypatch.delenv(var, raising=False)
    assert calib.cli.commands.blas_threads() == 1


@pytest.mark.parametrize("value", ["0", "-1", "two", "1.5"])
def test_a_bad_thread_count_is_one_line(capsys, monkeypatch, value):
    monkeypatch.setenv("CALIB_THREADS", value)
    line = one_line_error(capsys, ["show", "aid"])
    assert "CALIB_THREADS" in line


# --------------------------------------------------------------------------------------
# One line, whatever the message holds
# --------------------------------------------------------------------------------------


def test_control_characters_in_a_message_are_escaped(tmp_path, capsys):
    """The fuzz test found a vertical tab of a CSV header cell breaking the error line."""
    name = "a\x0bb\nc\u2028d.urdf"
    line = one_line_error(capsys, ["show", tmp_path / name])
    assert r"a\x0bb\nc\u2028d.urdf" in line


def test_the_python_writers_never_write_inside_installed_packages(tmp_path, monkeypatch):
    """``calib.write_measurements(chain.urdf_path, data)`` (a notebook's slip) replaced the
    installed UR5 URDF with a CSV, for every later use of ``ur5``; the CLI refused such a
    path, the Python writers did not. Every writer refuses a file in site-packages (here a
    stand-in folder, so that the test harms nothing where the refusal is missing), before
    writing anything."""
    import sysconfig

    import calib

    site = tmp_path / "site-packages"
    (site / "robots").mkdir(parents=True)
    installed = site / "robots" / "robot.urdf"
    installed.write_text("<robot/>\n")
    monkeypatch.setattr(sysconfig, "get_path", lambda name, *a, **k: str(site))
    chain = calib.load_chain("ur5")
    data = calib.simulate(chain, 12, seed=0).measurements
    result = calib.calibrate(chain, data)
    writes = {
        "write_measurements": lambda: calib.write_measurements(installed, data),
        "Result.write": lambda: result.write(site / "robots" / "cal.urdf"),
        "Result.write report": lambda: result.write(tmp_path / "c.urdf", site / "r.json"),
    }
    for what, write in writes.items():
        with pytest.raises(InvalidArgumentError, match="inside the installed files") as info:
            write()
        assert "\n" not in str(info.value), what
    assert installed.read_text() == "<robot/>\n"
    assert sorted(p.name for p in site.rglob("*")) == ["robot.urdf", "robots"]
    assert not (tmp_path / "c.urdf").exists()
