"""The command line (list, show, analyze): output contract and error handling."""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from calib.cli.commands import main

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).parent / "data"
CALIB = Path(sys.executable).parent / "calib"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def catalog_names() -> list[str]:
    """The catalog read straight from the TOML file (not through calib)."""
    with open(ROOT / "models" / "catalog.toml", "rb") as f:
        return [row["name"] for row in tomllib.load(f)["robot"]]


# --------------------------------------------------------------------------------------
# list / show
# --------------------------------------------------------------------------------------


def test_list(capsys):
    code, out, err = run(capsys, "list")
    assert code == 0
    assert err == ""
    for name in catalog_names():
        assert name in out


def test_list_json(capsys):
    code, out, _ = run(capsys, "list", "--json")
    assert code == 0
    robots = json.loads(out)["robots"]
    assert [r["name"] for r in robots] == catalog_names()
    for r in robots:
        assert {"name", "urdf", "base", "tool", "description", "path"} <= set(r)


def test_show_aid_text(capsys):
    code, out, err = run(capsys, "show", "aid")
    assert code == 0 and err == ""
    lines = out.splitlines()
    assert "aid" in lines[0] and "base_link" in lines[0] and "tool" in lines[0]
    header = lines[1].split()
    assert header == [
        "j",
        "joint",
        "sigma",
        "beta[deg]",
        "alpha[deg]",
        "d[m]",
        "theta[deg]",
        "r[m]",
    ]
    body = [line.split() for line in lines[3:]]
    assert len(body) == 8
    assert [row[0] for row in body] == [str(k) for k in range(8)]
    assert body[0][2] == "fixed" and body[-1][2] == "fixed"
    # Table 1 (docs/method.md): alpha of frames 1..6 and the three lengths
    assert [float(row[4]) for row in body[1:7]] == [0.0, 90.0, 0.0, -90.0, 90.0, -90.0]
    assert float(body[3][5]) == 0.3
    assert float(body[4][7]) == 0.4
    assert float(body[7][7]) == 0.21
    assert [row[6] for row in body[1:7]] == [f"q{k}" for k in range(1, 7)]


def test_show_panda_json(capsys):
    code, out, err = run(capsys, "show", "panda", "--json")
    assert code == 0 and err == ""
    doc = json.loads(out)
    assert doc["robot"] == "panda"
    frames = doc["frames"]
    assert len(frames) == 7 + 2
    for row in frames:
        assert set(row) >= {"name", "joint", "sigma", "beta", "alpha", "d", "theta", "r"}
        for key in ("beta", "alpha", "d", "theta", "r"):
            assert isinstance(row[key], float) and math.isfinite(row[key])
    assert frames[0]["joint"] is None and frames[0]["sigma"] is None
    assert frames[-1]["joint"] is None and frames[-1]["sigma"] is None
    assert [f["joint"] for f in frames[1:-1]] == [f"panda_joint{k}" for k in range(1, 8)]
    assert all(f["sigma"] == 0 for f in frames[1:-1])
    assert frames[-1]["r"] == pytest.approx(0.107, abs=1e-12)
    assert frames[-1]["theta"] == pytest.approx(-math.pi / 4, abs=1e-12)


def test_show_with_frames_and_a_urdf_path(capsys):
    code, out, _ = run(
        capsys, "show", str(DATA / "same_name_diff_place.urdf"), "--tool", "link:j", "--json"
    )
    assert code == 0
    doc = json.loads(out)
    assert doc["tool"] == "j"
    assert [f["joint"] for f in doc["frames"][1:-1]] == ["a0", "a"]


# --------------------------------------------------------------------------------------
# analyze
# --------------------------------------------------------------------------------------


def test_analyze_aid_json(capsys):
    code, out, err = run(
        capsys, "analyze", "aid", "--measure", "position", "--params", "paper", "--json"
    )
    assert code == 0
    assert "error" not in err
    doc = json.loads(out)
    for key in (
        "robot",
        "measure",
        "params",
        "joints",
        "n_standard",
        "n_base",
        "n_complete",
        "base_parameters",
        "nonidentifiable",
        "regrouping",
        "tolerance",
        "timings_ms",
    ):
        assert key in doc, key
    assert doc["robot"] == "aid"
    assert doc["measure"] == "position"
    assert doc["params"] == "paper"
    assert doc["joints"] == {"revolute": 6, "prismatic": 0}
    assert doc["n_standard"] == 30
    assert doc["n_base"] == 23  # Khalil & Gautier 1991, eq. 29
    assert doc["n_complete"] == 4 * 6 + 3 - 2
    assert len(doc["base_parameters"]) == 23
    assert set(doc["regrouping"]) == set(doc["base_parameters"])
    assert set(doc["nonidentifiable"]) == {"theta6", "theta7"}  # point on z6 and z7
    assert doc["tolerance"] > 0
    assert {"load", "convert", "jacobian", "qr"} <= set(doc["timings_ms"])
    assert all(v >= 0 for v in doc["timings_ms"].values())


def test_analyze_aid_text(capsys):
    code, out, _ = run(capsys, "analyze", "aid", "--measure", "position", "--params", "paper")
    assert code == 0
    lines = out.splitlines()
    # Table-2 style status table: one row per frame 0..7, parameter kinds as columns.
    i = next(k for k, line in enumerate(lines) if line.split()[:1] == ["j"])
    assert lines[i].split() == ["j", "joint", "beta", "alpha", "d", "theta", "r"]
    rows = [re.split(r"\s{2,}", line.strip()) for line in lines[i + 2 : i + 10]]
    assert [r[0] for r in rows] == [str(k) for k in range(8)]
    joints = [f"joint{k}" for k in range(1, 7)]  # the joints of models/aid.urdf
    assert [r[1] for r in rows] == ["(base frame)", *joints, "(tool frame)"]
    cells = [c for r in rows for c in r[2:]]
    assert set(cells) <= {"id", "reg", "0", "-"}
    assert sum(c == "id" for c in cells) == 23
    assert sum(c in ("id", "reg", "0") for c in cells) == 30
    # Regrouping lines "name = expression", one per base parameter, some with a regrouped term.
    regroup = [line.split("=", 1) for line in lines if line.startswith("  ") and " = " in line]
    assert len(regroup) == 23
    assert any(("+" in rhs or " - " in rhs) for _, rhs in regroup)
    assert "23" in out and "30" in out


def test_analyze_few_configs_warns_on_stderr(capsys):
    code, _, err = run(capsys, "analyze", "aid", "--configs", "1")
    assert code == 0
    assert "calib: warning:" in err
    assert "Traceback" not in err


def test_version(capsys):
    assert main(["--version"]) == 0  # main returns the exit code, also for --version
    assert "calib" in capsys.readouterr().out


# --------------------------------------------------------------------------------------
# Errors: exit code != 0, exactly one line on stderr "calib: error: ...", no traceback
# --------------------------------------------------------------------------------------


def _error_cases(tmp: Path):
    broken = tmp / "broken.urdf"
    broken.write_text('<?xml version="1.0"?>\n<robot name="x">\n  <link name="a">\n</robot>\n')
    return [
        (["analyze", "nosuchrobot"], "nosuchrobot"),
        (["show", str(tmp / "missing.urdf")], "missing.urdf"),
        (["show", str(broken)], "broken.urdf"),
        (["show", "ur5", "--tool", "tool1"], "tool1"),
        (["show", "solo", "--base", "FL_FOOT", "--tool", "FR_FOOT", "--tool", "HL_FOOT"], "below"),
        (["show", "ur5", "--base", "tool0", "--tool", "tool0"], "tool0"),
        (["show", str(DATA / "planar_joint.urdf"), "--tool", "tool"], "planar"),
        (["show", str(DATA / "floating_joint.urdf"), "--tool", "tool"], "floating"),
        (["show", str(DATA / "mimic_broken.urdf"), "--tool", "tool"], "mimic"),
        (["show", "so100", "--tool", "gripper"], "gripper"),
        (["analyze", "aid", "--measure", "orientation"], "orientation"),
        (["analyze", "aid", "--marker", "0.1", "0.2"], "marker"),
        (["analyze", "aid", "--configs", "0"], "0"),
        (["analyze", "aid", "--params", "full"], "full"),
    ]


def test_errors_are_one_line(capsys, tmp_path):
    for argv, fact in _error_cases(tmp_path):
        code, out, err = run(capsys, *argv)
        assert code != 0, argv
        lines = err.splitlines()
        assert len(lines) == 1, (argv, err)
        assert lines[0].startswith("calib: error:"), (argv, err)
        assert fact in lines[0], (argv, err)
        assert "Traceback" not in err
        assert out == "", (argv, out)


@pytest.mark.parametrize(
    ("fixture", "fact"), [("missing_link.urdf", "missing_link.urdf"), ("zero_axis.urdf", "j2")]
)
def test_invalid_urdf_gives_one_line_also_at_the_file_descriptor_level(capfd, fixture, fact):
    """Pinocchio's C++ URDF parser can write to the process's stderr itself: the user must
    still see exactly one line."""
    code = main(["show", str(DATA / fixture), "--tool", "tool"])
    out, err = capfd.readouterr()
    assert code != 0
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("calib: error:")
    assert fact in lines[0]
    assert out == ""


def test_console_script_reports_an_unknown_robot_without_traceback():
    exe = CALIB if CALIB.exists() else ROOT / ".venv" / "bin" / "calib"
    proc = subprocess.run(
        [str(exe), "analyze", "nosuchrobot"], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("calib: error:")
    assert "nosuchrobot" in lines[0]
    assert proc.stdout == ""


# --------------------------------------------------------------------------------------
# robot names against files and folders of the working directory; warnings
# --------------------------------------------------------------------------------------


def test_folder_named_like_a_catalog_robot_does_not_shadow_it(capsys, tmp_path, monkeypatch):
    """A folder ``ur5/`` in the working directory: ``calib show ur5`` is the catalog's UR5."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ur5").mkdir()
    code, out, err = run(capsys, "show", "ur5", "--json")
    assert code == 0, err
    shown = json.loads(out)
    assert shown["urdf"].endswith("ur5_robot.urdf")  # the catalog's file (models/catalog.toml)
    assert len(shown["variables"]) == 6


def test_file_named_like_a_catalog_robot_wins(capsys, tmp_path, monkeypatch):
    """A URDF file named ``ur5`` (no extension) in the working directory is loaded, not the
    catalog's UR5: its one joint is what ``show`` prints."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "ur5").write_bytes((DATA / "single_joint.urdf").read_bytes())
    code, out, err = run(capsys, "show", "ur5", "--json")
    assert code == 0, err
    shown = json.loads(out)
    assert Path(shown["urdf"]).resolve() == (tmp_path / "ur5").resolve()
    assert shown["variables"] == ["j1"]  # single_joint.urdf's one joint


def test_numpy_warnings_reach_the_user_after_the_output(tmp_path):
    """A command whose numbers meet a numpy floating-point warning prints it on stderr after
    its output; a DeprecationWarning (about code, not results) is not printed."""
    script = (
        "import sys, warnings\n"
        "import numpy as np\n"
        "import calib.cli.commands as cli\n"
        "def run(args):\n"
        "    print('OUTPUT', flush=True)\n"
        "    np.log(np.zeros(2))\n"
        "    warnings.warn('old api', DeprecationWarning)\n"
        "    return 0\n"
        "cli._run = run\n"
        "sys.exit(cli.main(['list']))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, cwd=tmp_path, check=False
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout == "OUTPUT\n"
    assert proc.stderr == "calib: warning: RuntimeWarning: divide by zero encountered in log\n"
    merged = subprocess.run(
        [sys.executable, "-c", script],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        cwd=tmp_path,
        check=False,
    ).stdout
    assert merged.index("OUTPUT") < merged.index("divide by zero")


@pytest.mark.parametrize("argv", [["--version"], ["list"], ["list", "--json"]])
def test_the_calib_script_answers_version_and_list_without_numpy(argv):
    """The installed ``calib`` script (calib.cli.launcher) prints what ``calib.cli`` prints, and
    does it without importing numpy, pinocchio or scipy."""
    script = (
        "import sys\n"
        "from calib.cli.launcher import main\n"
        "code = main(sys.argv[1:])\n"
        "heavy = sorted(m for m in ('numpy', 'pinocchio', 'scipy') if m in sys.modules)\n"
        "print('HEAVY', heavy, file=sys.stderr)\n"
        "sys.exit(code)\n"
    )
    fast = subprocess.run(
        [sys.executable, "-c", script, *argv], capture_output=True, text=True, check=False
    )
    full = subprocess.run(
        [sys.executable, "-c", "import sys; from calib.cli import main; sys.exit(main())", *argv],
        capture_output=True,
        text=True,
        check=False,
    )
    assert fast.returncode == full.returncode == 0
    assert fast.stdout == full.stdout
    assert fast.stderr == "HEAVY []\n"
