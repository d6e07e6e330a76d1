"""One ``calib: error:`` prefix on every error line: usage errors, CalibErrors, OS errors."""

from __future__ import annotations

import pytest

from calib.cli.commands import main

CASES = [
    ["calibrate", "ur5", "--data", "d.csv"],  # usage: --out missing
    ["calibrate", "ur5", "--data", "d.csv", "--out", "c.urdf", "--holdout", "x"],  # usage: type
    ["analyze", "ur5", "--no-such-flag"],  # usage: unknown flag
    ["design", "ur5", "--configs", "9", "--noise-mm", "0"],  # usage: a bad number
    ["show", "no_such_robot"],  # CalibError
    ["calibrate", "ur5", "--data", "no_such.csv", "--out", "c.urdf"],  # missing file
]


@pytest.mark.parametrize("argv", CASES, ids=[" ".join(c[:3]) for c in CASES])
def test_every_error_has_one_calib_error_prefix(tmp_path, monkeypatch, capsys, argv):
    monkeypatch.chdir(tmp_path)
    code = main(argv)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if not line.startswith("calib: warning:")]
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("calib: error: "), err
    rest = lines[0].removeprefix("calib: error: ")
    assert not rest.startswith("calib"), err  # not `calib: error: calib calibrate: ...`
    assert "error:" not in rest, err


def test_a_usage_error_names_the_command_in_its_hint(capsys):
    assert main(["calibrate", "ur5", "--data", "d.csv"]) == 2
    line = capsys.readouterr().err.strip()
    assert line.endswith("(see calib calibrate --help)"), line
