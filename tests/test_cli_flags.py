"""The library names a way out by its Python keyword, the command line by its flag (texts47).

One table (:data:`calib.cli.flags.FLAGS`) and one translation serve every command: its error
line, its printed warnings, its summary and its report. The expectations come from outside
the texts: the keywords from the Python functions' signatures and dataclasses, the flags from
the command line's parser, the sweep's defaults from both definitions.
"""

from __future__ import annotations

import argparse
import inspect
import json
import re
from types import SimpleNamespace

import pytest

import calib
from calib.calibration.pixel_chain import Unknowns
from calib.calibration.pixel_chain_result import EXPECTED_PX, PixelChain
from calib.cli.commands import build_parser, main
from calib.cli.flags import FLAGS, OPTIONS, in_flags
from calib.outputs.sweep import sweep

FLAG = re.compile(r"--[a-z][a-z-]*")


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


@pytest.fixture(scope="module")
def stalled(tmp_path_factory):
    """A UR5 campaign (30 positions, 1 mm / 1 mrad errors) and an evaluation cap it stops at."""
    data = calib.simulate(calib.load_chain("ur5"), 30, measure="position", seed=1).measurements
    path = tmp_path_factory.mktemp("stalled") / "m.csv"
    calib.write_measurements(path, data)
    return data, path, 3


def test_a_stalled_fit_names_max_iterations_in_python(stalled):
    """The refusal said ``max_iterations (--max-iterations)``: a flag in a Python result."""
    data, _, cap = stalled
    assert "max_iterations" in inspect.signature(calib.calibrate).parameters  # the keyword
    result = calib.calibrate(calib.load_chain("ur5"), data, max_iterations=cap)
    assert result.refusal is not None and "a larger max_iterations may" in result.refusal
    assert FLAG.search(result.refusal) is None
    assert "a larger max_iterations may" in result.summary()
    assert FLAG.search(result.summary()) is None, result.summary()


def test_a_stalled_fit_names_the_flag_from_calib_calibrate(stalled, tmp_path, capsys):
    """Printed summary, error line and written report: the flag, never the keyword."""
    _, path, cap = stalled
    report = tmp_path / "r.json"
    argv = ["calibrate", "ur5", "--data", str(path), "--out", str(tmp_path / "c.urdf")]
    code = main([*argv, "--report", str(report), "--max-iterations", str(cap)])
    out, err = capsys.readouterr()
    assert code == 2 and not (tmp_path / "c.urdf").exists()
    assert "--max-iterations" in _commands()["calibrate"]._option_string_actions
    refusal = json.loads(report.read_text())["refusal"]
    for text in (out, err, refusal):
        assert "a larger --max-iterations may let it finish" in text, text
        assert "max_iterations" not in text, text


def test_a_wrong_camera_warning_names_the_python_way_out():
    """A calibrated reprojection error far above a detector's: the warning said
    ``(--refine-intrinsics)`` to a Python user; it names the pixel term's unknowns now."""
    assert Unknowns(intrinsics=True).intrinsics  # the way out, as the API takes it
    part = SimpleNamespace(
        pixels={"train": {"reprojection_rms_px": 10 * EXPECTED_PX}},
        state=SimpleNamespace(what=Unknowns()),
        name="cam",
    )
    (text,) = PixelChain.warnings(part)
    assert "Unknowns(intrinsics=True)" in text and FLAG.search(text) is None
    part.state.what = Unknowns(intrinsics=True)  # fitted already: no way out named
    assert "Unknowns" not in PixelChain.warnings(part)[0]


def test_every_flag_of_the_table_is_an_option_of_a_command():
    """A table's flag names an option that exists; a command without it keeps the keyword."""
    commands = {name: set(p._option_string_actions) for name, p in _commands().items()}
    for keyword, said in FLAGS.items():
        flag = FLAG.search(said)
        assert flag is not None and keyword not in said, said
        having = [c for c, options in commands.items() if flag.group() in options]
        assert having, flag.group()
        assert in_flags(f"x {keyword} y") == f"x {said} y"
        lacking = next(c for c in commands if c not in having)
        args = argparse.Namespace(command=lacking, **{OPTIONS: commands[lacking]})
        assert in_flags(f"x {keyword} y", args) == f"x {keyword} y", (keyword, lacking)


def _with_angles(tmp_path, path):
    """The campaign with 3 columns the reader ignores, named alike but for x, y, z."""
    lines = path.read_text().splitlines()
    rows = [f"{lines[0]},phix,phiy,phiz", *(f"{row},0,0,0" for row in lines[1:])]
    out = tmp_path / "angles.csv"
    out.write_text("\n".join(rows) + "\n")
    return out


def test_the_columns_hint_under_term_says_what_term_reads(stalled, tmp_path, capsys):
    """``--term`` refuses ``--orientation`` (checked here): its hint said ``--orientation
    rpy --orientation-columns ...``; it says to rename them as their format reads them."""
    data_file = _with_angles(tmp_path, stalled[1])
    term = ["--term", "position", "base_link", "tool0", str(data_file)]
    out = ["--out", str(tmp_path / "c.urdf")]
    assert main(["calibrate", "ur5", *term, *term, *out, "--orientation", "rpy"]) == 2
    assert "--orientation is for one chain" in capsys.readouterr().err
    main(["calibrate", "ur5", *term, *term, *out])  # the file read, the same chain twice
    (line,) = [w for w in capsys.readouterr().err.splitlines() if "columns ignored" in w]
    assert "rename them as its format reads them" in line and "rpy: roll pitch yaw" in line
    assert "--orientation" not in line and "Columns(" not in line, line
    main(["calibrate", "ur5", "--data", str(data_file), *out])  # one chain: both ways
    (line,) = [w for w in capsys.readouterr().err.splitlines() if "columns ignored" in w]
    assert "rename them" in line and "--orientation rpy --orientation-columns phix" in line


def test_python_sweep_defaults_are_the_command_lines():
    """``calib.sweep`` measured a pose by default, ``calib sweep`` a point: read both."""
    parser = _commands()["sweep"]
    cli = {a.dest: a.default for a in parser._actions if a.dest in ("measure", "params")}
    python = inspect.signature(sweep).parameters
    assert {k: python[k].default for k in cli} == cli
    assert cli["measure"] == inspect.signature(calib.analyze).parameters["measure"].default


def test_the_table_says_the_library_texts_as_the_library_writes_them():
    """The table holds three library texts as literals (every command starts without the CSV
    reader and the collision checker): they are the library's, word for word."""
    from calib.cli import flags
    from calib.design.collision import NO_COLLISION
    from calib.design.folds import NOT_WITH
    from calib.measurements.csvfile import NAMED_ORIENTATION

    assert NO_COLLISION in FLAGS and NOT_WITH in FLAGS
    assert flags.NAMED_ORIENTATION == NAMED_ORIENTATION
