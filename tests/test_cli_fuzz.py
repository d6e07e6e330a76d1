"""Fuzz the command line with mutated URDF and CSV files, in-process.

The contract, whatever the bytes: exit 0 with valid output, or a non-zero exit with exactly
one ``calib: error:`` line on stderr and no traceback; the input file is unchanged; the output
directory holds nothing but complete outputs (no temporary or half-written file). The files
mutated: URDFs, measurement CSVs, and the inputs of ``calib design`` (configurations files for
``--evaluate`` and ``--candidates-file``, SRDFs).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import re
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from calib.cli.commands import main

ROOT = Path(__file__).resolve().parents[1]
AID = ROOT / "models" / "aid.urdf"


def _ur5_srdf() -> bytes:
    from calib.design.collision import find_srdf
    from calib.kinematics.catalog import catalog_entry

    return find_srdf(catalog_entry("ur5").path).read_bytes()


UR5_SRDF_BYTES = _ur5_srdf()

FUZZ = settings(
    max_examples=int(os.environ.get("CALIB_FUZZ_EXAMPLES", "80")),
    deadline=None,
    derandomize=os.environ.get("CALIB_FUZZ_EXAMPLES") is None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

NUMBER = re.compile(rb"(?<![\w.])[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?(?![\w.])")
"""A number on its own (not the digit of a name such as ``joint1``)."""
ODD_NUMBERS = [
    b"nan",
    b"-nan",
    b"inf",
    b"-inf",
    b"1e300",
    b"-1e300",
    b"1e-300",
    b"",
    b" ",
    b"0",
    b"-0",
    b"1_0",
    b"0x10",
    b"1e",
    b"--1",
    b"1,5",
    b"\xff",
]


def _flip_byte(draw, text: bytes) -> bytes:
    if not text:
        return text
    i = draw(st.integers(0, len(text) - 1))
    return text[:i] + bytes([draw(st.integers(0, 255))]) + text[i + 1 :]


def _truncate(draw, text: bytes) -> bytes:
    return text[: draw(st.integers(0, len(text)))]


def _lines_edit(draw, text: bytes) -> bytes:
    lines = text.splitlines(keepends=True)
    if not lines:
        return text
    i = draw(st.integers(0, len(lines) - 1))
    if draw(st.booleans()):
        return b"".join(lines[:i] + lines[i + 1 :])  # a line deleted
    return b"".join(lines[: i + 1] + lines[i:])  # a line duplicated


def _odd_number(draw, text: bytes) -> bytes:
    found = list(NUMBER.finditer(text))
    if not found:
        return text
    m = draw(st.sampled_from(found))
    return text[: m.start()] + draw(st.sampled_from(ODD_NUMBERS)) + text[m.end() :]


def _insert_junk(draw, text: bytes) -> bytes:
    i = draw(st.integers(0, len(text)))
    junk = draw(st.sampled_from([b"<", b">", b"&", b'"', b",", b"\n", b"\x00", b"\r\n", b";"]))
    return text[:i] + junk + text[i:]


MUTATIONS: tuple[Callable, ...] = (
    _flip_byte,
    _truncate,
    _lines_edit,
    _odd_number,
    _odd_number,  # numbers are what most of a URDF or a measurement file is made of
    _insert_junk,
)


@st.composite
def mutated(draw, base: bytes) -> bytes:
    """``base`` after one to three random mutations."""
    text = base
    for _ in range(draw(st.integers(1, 3))):
        text = draw(st.sampled_from(MUTATIONS))(draw, text)
    return text


@contextlib.contextmanager
def workspace(name: str, content: bytes) -> Iterator[tuple[Path, Path]]:
    """A fresh input file ``in/name`` holding ``content`` and an empty ``out/`` folder."""
    with tempfile.TemporaryDirectory() as tmp:
        src, out_dir = Path(tmp) / "in", Path(tmp) / "out"
        src.mkdir()
        out_dir.mkdir()
        (src / name).write_bytes(content)
        yield src / name, out_dir


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def check_contract(code: int, out: str, err: str, valid_output: Callable[[str], object]) -> None:
    """Exit 0 and valid output, or one error line; warnings may precede, nothing else."""
    assert "Traceback" not in err
    lines = err.splitlines()
    errors = [line for line in lines if line.startswith("calib: error: ")]
    assert all(line.startswith(("calib: error: ", "calib: warning: ")) for line in lines), err
    if code == 0:
        assert errors == [], err
        valid_output(out)
    else:
        assert len(errors) == 1, err
    event("exit 0" if code == 0 else f"refused: {_gist(errors[0])}")


def _gist(line: str) -> str:
    """The kind of an error line, without paths and numbers (hypothesis statistics)."""
    return re.sub(r"\S*/\S*|\d+|'[^']*'", "_", line.removeprefix("calib: error: "))[:60]


class NonFiniteJSONError(AssertionError):
    """JSON output with NaN or Infinity (not JSON)."""


def strict_json(text: str) -> object:
    def refuse(name: str):
        raise NonFiniteJSONError(f"invalid JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def csv_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# --------------------------------------------------------------------------------------
# URDF text: show, analyze and simulate
# --------------------------------------------------------------------------------------


@FUZZ
@given(mutated(AID.read_bytes()))
def test_mutated_urdf(urdf: bytes):
    with workspace("r.urdf", urdf) as (robot, out_dir):
        check_contract(*run_cli(["show", str(robot), "--json"]), strict_json)
        check_contract(*run_cli(["analyze", str(robot), "--configs", "15", "--json"]), strict_json)
        meas = out_dir / "m.csv"
        code, out, err = run_cli(
            ["simulate", str(robot), "--configs", "8", "--measure", "position", "--out", str(meas)]
        )
        check_contract(code, out, err, lambda _: None)
        assert robot.read_bytes() == urdf  # the input is never touched
        left = sorted(p.name for p in out_dir.iterdir())
        if code == 0:
            assert left == ["m.csv", "m.truth.json"]
            assert len(csv_rows(meas)) == 8
            strict_json((out_dir / "m.truth.json").read_text())
        else:
            assert left == []


@pytest.mark.parametrize("axis", ["1e300 0 1", "0 0 1e-300"])
def test_a_huge_or_denormal_axis_is_refused_not_nan(tmp_path, axis):
    """The minimal reproducer the fuzz test found: now one error line, never NaN in JSON."""
    robot = tmp_path / "r.urdf"
    robot.write_text(AID.read_text().replace('<axis xyz="0 0 1"/>', f'<axis xyz="{axis}"/>', 4))
    code, out, err = run_cli(["show", str(robot), "--json"])
    if code == 0:  # a huge axis is a direction: normalised, then valid (strict) JSON
        strict_json(out)
    else:
        assert code == 2 and out == "" and len(err.splitlines()) == 1
        assert err.startswith("calib: error:") and "axis" in err


# --------------------------------------------------------------------------------------
# Measurement CSV: calibrate (the file comes from `calib simulate`, whatever its format)
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def clean_csv(tmp_path_factory) -> bytes:
    path = tmp_path_factory.mktemp("clean") / "m.csv"
    code, _, err = run_cli(
        ["simulate", "ur5", "--configs", "20", "--measure", "position", "--out", str(path)]
    )
    assert code == 0, err
    return path.read_bytes()


def _valid_urdf(path: Path) -> None:
    assert ET.parse(path).getroot().tag == "robot"


@FUZZ
@given(data=st.data())
def test_mutated_measurements(clean_csv, data):
    csv_bytes = data.draw(mutated(clean_csv), label="csv")
    with workspace("m.csv", csv_bytes) as (meas, out_dir):
        urdf, report = out_dir / "cal.urdf", out_dir / "report.json"
        argv = ["calibrate", "ur5", "--data", str(meas), "--out", str(urdf)]
        code, out, err = run_cli([*argv, "--report", str(report)])
        check_contract(code, out, err, lambda text: None)
        assert meas.read_bytes() == csv_bytes
        left = sorted(p.name for p in out_dir.iterdir())
        if code == 0:
            assert left == ["cal.urdf", "report.json"]
            _valid_urdf(urdf)
        else:
            # only a fit that did not converge keeps its (complete) report, and no URDF
            assert left in ([], ["report.json"]), left
        if report.exists():
            strict_json(report.read_text())


# --------------------------------------------------------------------------------------
# Trees, validation files, orientation formats and hostile options: calibrate
# --------------------------------------------------------------------------------------

FEWER = settings(FUZZ, max_examples=max(1, FUZZ.max_examples // 3))
"""The calibrations below fit a model per example: a third of the examples."""


def _calibrate_contract(argv: list[str], inputs: dict[Path, bytes], out_dir: Path) -> None:
    """Run ``calibrate``; check the contract, the inputs untouched and only complete outputs."""
    urdf, report = out_dir / "cal.urdf", out_dir / "report.json"
    code, out, err = run_cli([*argv, "--out", str(urdf), "--report", str(report)])
    check_contract(code, out, err, lambda text: None)
    for path, content in inputs.items():
        assert path.read_bytes() == content
    left = sorted(p.name for p in out_dir.iterdir())
    if code == 0:
        assert left == ["cal.urdf", "report.json"]
        _valid_urdf(urdf)
    else:  # a refused model keeps its complete report, never a URDF
        assert left in ([], ["report.json"]), left
    if report.exists():
        strict_json(report.read_text())


@pytest.fixture(scope="module")
def campaigns(tmp_path_factory) -> dict[str, bytes]:
    """Clean files: a bolt (tree) campaign, ur5 data and validation rows, ur5 poses as rpy."""
    d = tmp_path_factory.mktemp("campaigns")
    for name, robot, measure, configs in (
        ("bolt", "bolt", "position", 12),
        ("ur5", "ur5", "position", 30),
        ("pose", "ur5", "pose", 20),
    ):
        argv = ["simulate", robot, "--configs", str(configs), "--measure", measure]
        code, _, err = run_cli([*argv, "--noise-mm", "0.05", "--out", str(d / f"{name}.csv")])
        assert code == 0, err
    lines = (d / "ur5.csv").read_bytes().splitlines(keepends=True)
    files = {"bolt": (d / "bolt.csv").read_bytes()}
    files["ur5"], files["ur5_val"] = b"".join(lines[:21]), b"".join(lines[:1] + lines[21:])
    files |= _angle_files(d / "pose.csv")
    return files


def _angle_files(path: Path) -> dict[str, bytes]:
    """The pose campaign with its quaternions, and as rpy and rotation-vector columns."""
    from scipy.spatial.transform import Rotation

    rows = csv_rows(path)
    names = list(rows[0])
    quat = [[float(r[c]) for c in ("qx", "qy", "qz", "qw")] for r in rows]
    rot = Rotation.from_quat(quat)
    files = {"quat": path.read_bytes()}
    for fmt, cols, values in (
        ("rpy", "roll,pitch,yaw", rot.as_euler("xyz")),
        ("rotvec", "rx,ry,rz", rot.as_rotvec()),
    ):
        keep = [n for n in names if n not in ("qx", "qy", "qz", "qw")]
        lines = [",".join(keep) + "," + cols]
        for r, v in zip(rows, values, strict=True):
            lines.append(",".join([*(r[n] for n in keep), *(repr(float(x)) for x in v)]))
        files[fmt] = ("\n".join(lines) + "\n").encode()
    return files


@FEWER
@given(data=st.data())
def test_mutated_tree_measurements(campaigns, data):
    csv_bytes = data.draw(mutated(campaigns["bolt"]), label="csv")
    with workspace("m.csv", csv_bytes) as (meas, out_dir):
        _calibrate_contract(["calibrate", "bolt", "--data", str(meas)], {meas: csv_bytes}, out_dir)


@FEWER
@given(data=st.data())
def test_mutated_validation_file(campaigns, data):
    val = data.draw(mutated(campaigns["ur5_val"]), label="validation csv")
    with workspace("v.csv", val) as (val_path, out_dir):
        train = val_path.parent / "m.csv"
        train.write_bytes(campaigns["ur5"])
        argv = ["calibrate", "ur5", "--data", str(train), "--validate", str(val_path)]
        inputs = {train: campaigns["ur5"], val_path: val}
        _calibrate_contract([*argv, "--params", "frames"], inputs, out_dir)


@FEWER
@given(data=st.data())
def test_mutated_orientation_formats(campaigns, data):
    fmt = data.draw(st.sampled_from(["quat", "rpy", "rotvec"]), label="format")
    clean = campaigns[fmt]  # clean or mutated: the options alone must not break the contract
    csv_bytes = data.draw(st.one_of(st.just(clean), mutated(clean)), label="csv")
    option = data.draw(
        st.sampled_from(
            [
                [],
                ["--orientation", "auto"],
                ["--orientation", "rpy"],
                ["--orientation", "rotvec"],
                ["--orientation", "quat-wxyz"],
                ["--orientation", "rotvec", "--orientation-columns", "x", "y", "z"],
                ["--orientation", "rpy", "--orientation-columns", "yaw", "pitch", "roll"],
                ["--measure", "pose"],
                ["--measure", "position"],
            ]
        ),
        label="options",
    )
    with workspace("m.csv", csv_bytes) as (meas, out_dir):
        argv = ["calibrate", "ur5", "--data", str(meas), "--params", "frames", *option]
        _calibrate_contract(argv, {meas: csv_bytes}, out_dir)


HOSTILE_OPTIONS = st.lists(
    st.sampled_from(
        [
            ["--max-iterations", "0"],
            ["--max-iterations", "-3"],
            ["--max-iterations", "3"],
            ["--seed", "-1"],
            ["--seed", "5"],
            ["--holdout", "0.2"],
            ["--holdout", "0.99"],
            ["--holdout", "1"],
            ["--holdout", "-0.1"],
            ["--holdout", "nan"],
            ["--params", "auto"],
            ["--params", "frames"],
            ["--params", "complete"],
            ["--params", "paper"],
            ["--measure", "pose"],
            ["--measure", "position"],
            ["--validate", "SELF"],
            ["--validate", "OTHER"],
        ]
    ),
    max_size=3,
    unique_by=lambda option: option[0],
)


@FEWER
@given(robot=st.sampled_from(["bolt", "ur5"]), options=HOSTILE_OPTIONS)
def test_hostile_options_on_chains_and_trees(campaigns, robot, options):
    """Every option combination: exit 0 or one error line; --validate SELF is always refused."""
    with workspace("m.csv", campaigns[robot]) as (meas, out_dir):
        other = meas.parent / "v.csv"
        other.write_bytes(campaigns["ur5_val"] if robot == "ur5" else campaigns["bolt"][:0])
        names = {"SELF": str(meas), "OTHER": str(other)}
        argv = ["calibrate", robot, "--data", str(meas)]
        argv += [names.get(a, a) for opt in options for a in opt]
        _calibrate_contract(argv, {meas: campaigns[robot]}, out_dir)
        if ["--validate", "SELF"] in options:
            assert not (out_dir / "cal.urdf").exists()


# Design inputs: configurations files (--evaluate, --candidates-file) and SRDFs
# --------------------------------------------------------------------------------------

DESIGN_FUZZ = settings(FUZZ, max_examples=max(10, FUZZ.max_examples // 4))
"""Fewer examples: each design filters candidates through the collision model."""


@pytest.fixture(scope="module")
def clean_configs(tmp_path_factory) -> bytes:
    path = tmp_path_factory.mktemp("configs") / "q.csv"
    code, _, err = run_cli(
        ["design", "ur5", "--configs", "12", "--candidates", "60", "--out", str(path)]
    )
    assert code == 0, err
    return path.read_bytes()


def _design_outputs(out_dir: Path, code: int, rows: int | None) -> None:
    left = sorted(p.name for p in out_dir.iterdir())
    if code == 0:
        assert left == ["q.csv"]
        assert rows is None or len(csv_rows(out_dir / "q.csv")) == rows
    else:
        assert left == []


@FUZZ
@given(data=st.data())
def test_mutated_configurations_for_design(clean_configs, data):
    """--evaluate and --candidates-file read a mutated configurations file."""
    text = data.draw(mutated(clean_configs), label="configs")
    with workspace("q.csv", text) as (configs, out_dir):
        code, out, err = run_cli(["design", "ur5", "--evaluate", str(configs), "--json"])
        check_contract(code, out, err, strict_json)
        argv = ["design", "ur5", "--configs", "6", "--candidates-file", str(configs)]
        code, out, err = run_cli([*argv, "--no-collision", "--out", str(out_dir / "q.csv")])
        check_contract(code, out, err, lambda _: None)
        assert configs.read_bytes() == text
        _design_outputs(out_dir, code, 6)


@DESIGN_FUZZ
@given(srdf=mutated(UR5_SRDF_BYTES))
def test_mutated_srdf(srdf):
    with workspace("ur5.srdf", srdf) as (path, out_dir):
        argv = ["design", "ur5", "--configs", "9", "--candidates", "40", "--srdf", str(path)]
        code, out, err = run_cli([*argv, "--out", str(out_dir / "q.csv")])
        check_contract(code, out, err, lambda _: None)
        assert path.read_bytes() == srdf
        _design_outputs(out_dir, code, 9)
        if code != 0 and "SRDF" in err:
            assert str(path) in err  # an SRDF error names the file
