"""Progress bars: on a terminal (a pseudo-terminal here), never on a pipe or with --quiet."""

from __future__ import annotations

import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios

import pytest

from calib.core.progress import phase, steps

RUN = (
    "import sys; import calib.core.progress as p; p.PHASE_DELAY = 0.0; "  # bars at once
    "from calib.cli.commands import main; sys.exit(main(sys.argv[1:]))"
)
DESIGN = ["design", "ur5", "--configs", "12", "--candidates", "200", "--no-collision"]


def _stderr(args: list[str], terminal: bool) -> tuple[int, str]:
    """Exit status and stderr of a calib command run with stderr on a pty or a pipe."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "COLUMNS": "100"}
    command = [sys.executable, "-c", RUN, *args]
    if not terminal:
        done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=120)
        return done.returncode, done.stderr
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 24 x 100
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=slave, env=env)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:  # EIO: the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    os.close(master)
    return proc.wait(timeout=120), b"".join(chunks).decode(errors="replace")


def test_design_shows_progress_on_a_terminal_only():
    code, err = _stderr(DESIGN, terminal=True)
    assert code == 0 and "design: greedy start" in err and "design: exchange" in err
    code, err = _stderr(DESIGN, terminal=False)
    assert code == 0 and err == ""
    code, err = _stderr([*DESIGN, "--quiet"], terminal=True)
    assert code == 0 and "design:" not in err


def test_calibration_phases_show_on_a_terminal(tmp_path):
    data = tmp_path / "d.csv"
    simulate = ["simulate", "ur5", "--configs", "60", "--noise-mm", "0.05", "--out", str(data)]
    assert _stderr(simulate, terminal=False)[0] == 0
    argv = ["calibrate", "ur5", "--data", str(data), "--out", str(tmp_path / "c.urdf")]
    code, err = _stderr(argv, terminal=True)
    assert code == 0
    assert all(f"calibrate: {s}" in err for s in ("registration", "selection", "fit"))
    code, err = _stderr([*argv, "--quiet"], terminal=True)
    assert code == 0 and "calibrate:" not in err


def test_api_progress_gets_every_phase():
    """Any callable of tqdm's form sees the loops' and the phases' names."""
    seen: list[str] = []

    def progress(iterable=None, desc=None, total=None):
        seen.append(desc)
        return iterable

    assert list(steps(progress, range(3), "loop", 3)) == [0, 1, 2]
    with phase(progress, "phase"):
        pass
    assert seen == ["loop", "phase"]
    assert list(steps(None, range(2), "silent")) == [0, 1]


@pytest.mark.parametrize("quiet", [False, True])
def test_quiet_is_accepted_before_and_after_the_command(quiet, capsys):
    from calib.cli.commands import main

    argv = ["--quiet", "list"] if quiet else ["list", "--quiet"]
    assert main(argv) == 0


def test_contact_calibration_tells_its_phases():
    from calib import load_chain
    from calib.calibration.entry import calibrate_contacts
    from calib.measurements.contact_campaign import simulate_contacts

    chain = load_chain("ur5")
    data = simulate_contacts(chain, 30, "plane", contacts=2, seed=0).data
    seen: list[str] = []

    def progress(iterable=None, desc=None, total=None):
        seen.append(desc)
        return iterable

    calibrate_contacts(chain, data, progress=progress)
    assert [d.split(" (")[0] for d in seen] == [
        "calibrate: registration",
        "calibrate: selection",
        "calibrate: fit",
    ]
