"""Command-line slips of stop 47 (cli48): options silently ignored beside another, and counts
of one printed with a plural noun.

The expectations come from outside the texts: the option strings typed, the rows counted in
the CSV here, the fitted components' names the result lists.
"""

from __future__ import annotations

import csv
import warnings
from pathlib import Path

import pytest

from calib import Columns, cross_validate, load_chain, read_measurements
from calib.cli.commands import main
from calib.core.words import counted

UR10 = Path(__file__).resolve().parents[1] / "data" / "realdata" / "ur10"


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


@pytest.mark.parametrize("order", ["configs first", "configs-file first"])
def test_simulate_refuses_configs_beside_configs_file(tmp_path, capsys, order):
    """--configs N was silently ignored beside --configs-file: one line naming both."""
    plan = tmp_path / "plan.csv"
    code, _, err = run(capsys, "simulate", "ur5", "--configs", 7, "--out", plan)
    assert code == 0, err
    pair = [["--configs", 5], ["--configs-file", plan]]
    pair = pair if order == "configs first" else pair[::-1]
    out = tmp_path / "meas.csv"
    code, _, err = run(capsys, "simulate", "ur5", *pair[0], *pair[1], "--out", out)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("calib: error: "), err
    assert "--configs " in lines[0] and "--configs-file" in lines[0]
    assert not out.exists()


@pytest.mark.parametrize("measure", ["pixels", "plane"])
def test_every_simulate_route_refuses_the_pair(tmp_path, capsys, measure):
    """The pixels and contact routes too (each read --configs-file its own way, or not)."""
    argv = ["simulate", "ur5", "--measure", measure, "--configs", 5]
    code, _, err = run(capsys, *argv, "--configs-file", tmp_path / "p.csv", "--out", tmp_path / "o")
    assert code == 2
    assert "--configs draws random configurations; --configs-file gives them" in err


def test_design_refuses_configs_beside_evaluate(tmp_path, capsys):
    """design's pair (--configs, --evaluate) was already refused; analyze reads no file."""
    plan = tmp_path / "plan.csv"
    assert run(capsys, "simulate", "ur5", "--configs", 7, "--out", plan)[0] == 0
    code, _, err = run(capsys, "design", "ur5", "--configs", 5, "--evaluate", plan)
    assert code == 2 and "--configs is for choosing configurations" in err


def test_a_count_of_one_takes_the_singular():
    assert counted(1, "rows") == "1 row"
    assert counted(2, "rows") == "2 rows"
    assert counted(0, "touches") == "0 touches"
    assert counted(1, "touches") == "1 touch"
    assert counted(1, "joint placement components") == "1 joint placement component"
    assert counted(1, "people", "person") == "1 person"


def test_one_component_and_one_row_per_fold_are_singular():
    """The UR10's 23 real positions, 23 folds: each fold holds one row out; the fit keeps one
    joint placement component (named in the result). Were "1 joint placement components",
    "(1 rows)"."""
    with (UR10 / "calibration.csv").open() as f:
        postures = len({tuple(row.values()) for row in csv.DictReader(f)})
    chain = load_chain(UR10 / "ur10_robot.urdf", "universe", "wrist_3_link")
    columns = Columns("rpy", ("phix1", "phiy1", "phiz1"))
    data = read_measurements(UR10 / "calibration.csv", chain, columns).position_only()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = cross_validate(chain, data, folds=postures)
    text = result.summary()
    joints = [p for p in result.to_dict()["parameters"] if p["joint"] is not None]
    assert len(joints) == 1  # one joint placement component fitted, beside the frame's
    assert "1 chain, " in text.splitlines()[0]
    assert ", 1 joint placement component fitted, " in text.splitlines()[0]
    folds = [line for line in text.splitlines() if line.startswith("  fold ")]
    assert len(folds) == postures
    assert all(line.endswith(" (1 row)") for line in folds), folds


def test_simulate_of_one_configuration_says_configuration(tmp_path, capsys):
    code, out, err = run(capsys, "simulate", "ur5", "--configs", 1, "--out", tmp_path / "m.csv")
    assert code == 0, err
    with (tmp_path / "m.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 1
    assert out.startswith("ur5: 1 configuration, measure position")


def test_predict_of_one_configuration_says_configuration(tmp_path, capsys):
    """``calib predict`` at one posture printed ``1 configurations``: counted from the file
    written here (one row), as ``simulate --configs 1``."""
    data, urdf, report = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    assert run(capsys, "simulate", "ur5", "--configs", 30, "--out", data)[0] == 0
    code, _, err = run(
        capsys, "calibrate", "ur5", "--data", data, "--out", urdf, "--report", report
    )
    assert code == 0, err
    chain = load_chain("ur5")
    plan = tmp_path / "one.csv"
    plan.write_text(",".join(chain.joint_names) + "\n" + ",".join(["0.1"] * chain.n) + "\n")
    argv = ["predict", urdf, "--compliance", report, "--configs", plan, "--out", tmp_path / "p.csv"]
    code, out, err = run(capsys, *argv)
    assert code == 0, err
    with (tmp_path / "p.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 1
    assert out.split(": ", 1)[1].startswith("1 configuration, "), out  # after the robot's name
