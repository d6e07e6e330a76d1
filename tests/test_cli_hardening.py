"""The command line, second round (issue 19, behaviours 5-8): inputs stay inputs for every
command, sizes and interrupts, options that mean what they say, honest warnings.

Every expectation comes from outside calib: a file's bytes (sha256) before and after, the exit
status and the lines on stderr, counts made here from the files themselves, Pinocchio.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import calib.measurements.csvfile
from calib.cli.commands import main
from calib.design.collision import find_srdf
from calib.kinematics.catalog import catalog_entry

ROOT = Path(__file__).resolve().parents[1]
UR5_SRDF = find_srdf(catalog_entry("ur5").path)
PANDA_SRDF = find_srdf(catalog_entry("panda").path)
CALIB_DIR = Path(calib.measurements.csvfile.__file__).resolve().parents[1]


def digest(path: Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def run(capsys, argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


def one_error(capsys, argv) -> str:
    """Exit 2 and exactly one ``calib: error:`` line (warnings aside); the line."""
    code, out, err = run(capsys, argv)
    errors = [line for line in err.splitlines() if not line.startswith("calib: warning:")]
    assert code == 2, (argv, out, err)
    assert len(errors) == 1 and errors[0].startswith("calib: error: "), err
    return errors[0]


def warning_lines(err: str) -> list[str]:
    return [
        line.removeprefix("calib: warning: ")
        for line in err.splitlines()
        if line.startswith("calib: warning: ")
    ]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    """30 configurations of a UR5 measured by position, 0.05 mm noise."""
    path = tmp_path_factory.mktemp("campaign") / "m.csv"
    argv = ["simulate", "ur5", "--configs", "30", "--measure", "position", "--noise-mm", "0.05"]
    assert main([*argv, "--seed", "3", "--out", str(path)]) == 0
    return path


@pytest.fixture(scope="module")
def tree_campaign(tmp_path_factory) -> Path:
    """3 configurations of TALOS, every tool measured at each (a ``tool`` column)."""
    path = tmp_path_factory.mktemp("tree") / "t.csv"
    argv = ["simulate", "talos", "--configs", "3", "--measure", "position", "--out", str(path)]
    assert main(argv) == 0
    return path


def rows_of(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# --------------------------------------------------------------------------------------
# 5. Inputs are inputs, for every command
# --------------------------------------------------------------------------------------


def test_no_command_writes_onto_what_it_reads(tmp_path, capsys, campaign, tree_campaign):
    """Each output aimed at each input of the command: refused, the input's bytes unchanged."""
    data, val = tmp_path / "d.csv", tmp_path / "v.csv"
    data.write_bytes(campaign.read_bytes())
    val.write_bytes(campaign.read_bytes().replace(b"\n", b"\r\n"))  # another file, same rows
    tree = tmp_path / "t.csv"
    tree.write_bytes(tree_campaign.read_bytes())
    srdf = tmp_path / "ur5.srdf"
    srdf.write_bytes(UR5_SRDF.read_bytes())
    design = ["design", "ur5", "--configs", "10"]
    cases = [
        (["calibrate", "ur5", "--data", data, "--out", data], data),
        (["calibrate", "ur5", "--data", data, "--validate", val, "--out", val], val),
        (
            [
                "calibrate",
                "ur5",
                "--data",
                data,
                "--validate",
                val,
                "--out",
                tmp_path / "c",
                "--report",
                val,
            ],
            val,
        ),
        (["simulate", "ur5", "--configs-file", data, "--out", data], data),
        (
            [
                "simulate",
                "talos",
                "--measure",
                "position",
                "--configs-file",
                tree,
                "--out",
                tmp_path / "s",
                "--truth",
                tree,
            ],
            tree,
        ),
        ([*design, "--candidates-file", data, "--out", data], data),
        ([*design, "--srdf", srdf, "--out", srdf], srdf),
        ([*design, "--out", UR5_SRDF], UR5_SRDF),  # example-robot-data's own SRDF
        ([*design, "--out", UR5_SRDF.parent / "new.csv"], None),  # inside the package
        ([*design, "--out", CALIB_DIR / "new.csv"], None),  # inside calib itself
    ]
    for argv, target in cases:
        before = {p: digest(p) for p in (data, val, tree, srdf, UR5_SRDF)}
        line = one_error(capsys, argv)
        assert "--out" in line or "--report" in line or "--truth" in line, line
        assert {p: digest(p) for p in before} == before, argv
        assert target is None or target.exists()
    assert not (UR5_SRDF.parent / "new.csv").exists() and not (CALIB_DIR / "new.csv").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.csv", "t.csv", "ur5.srdf", "v.csv"]


def test_measurement_and_validation_files_are_read_with_a_size_limit(
    tmp_path, capsys, monkeypatch, campaign
):
    size = campaign.stat().st_size
    monkeypatch.setattr(calib.measurements.csvfile, "MAX_MEASUREMENTS_BYTES", size - 1)
    out = tmp_path / "c.urdf"
    line = one_error(capsys, ["calibrate", "ur5", "--data", campaign, "--out", out])
    assert str(campaign) in line and "larger than" in line
    small = tmp_path / "small.csv"
    small.write_text("".join(campaign.read_text().splitlines(keepends=True)[:20]))
    argv = ["calibrate", "ur5", "--data", small, "--validate", campaign, "--out", out]
    line = one_error(capsys, argv)
    assert str(campaign) in line and "larger than" in line
    assert not out.exists()


def test_a_device_as_measurement_file_is_refused_quickly(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(calib.measurements.csvfile, "MAX_MEASUREMENTS_BYTES", 1 << 20)
    start = time.perf_counter()
    line = one_error(capsys, ["calibrate", "ur5", "--data", "/dev/zero", "--out", tmp_path / "c"])
    assert "/dev/zero" in line and time.perf_counter() - start < 30


BAD_SRDF = {
    "empty": b"",
    "blank": b"  \n",
    "malformed": b"<robot name='ur5'><disable_collisions link1='a'",
    "not xml": b"shoulder_link,upper_arm_link\n",
    "wrong root": b"<srdf/>",
    "a URDF": (ROOT / "models" / "aid.urdf").read_bytes(),
    "no link2": b"<robot><disable_collisions link1='base_link' reason='x'/></robot>",
    "another robot": PANDA_SRDF.read_bytes(),
    "not utf-8": b"<robot>\xff</robot>",
}


@pytest.mark.parametrize("kind", list(BAD_SRDF))
def test_a_bad_srdf_is_one_line_naming_the_file(tmp_path, capsys, kind):
    srdf = tmp_path / "bad.srdf"
    srdf.write_bytes(BAD_SRDF[kind])
    line = one_error(
        capsys, ["design", "ur5", "--configs", "10", "--candidates", "60", "--srdf", srdf]
    )
    assert str(srdf) in line and "SRDF" in line
    assert srdf.read_bytes() == BAD_SRDF[kind]


def test_a_missing_or_misnamed_srdf_path_is_named(tmp_path, capsys, campaign):
    for path in (tmp_path / "none.srdf", tmp_path, campaign):
        line = one_error(capsys, ["design", "ur5", "--configs", "10", "--srdf", path])
        assert str(path) in line and "SRDF" in line


def test_the_right_srdf_is_accepted_and_its_pairs_counted(tmp_path, capsys):
    """The note counts pairs the SRDF disables: some, at most its <disable_collisions>."""
    import xml.etree.ElementTree as ET

    pairs = len(ET.parse(UR5_SRDF).getroot().findall("disable_collisions"))
    argv = ["design", "ur5", "--configs", "10", "--candidates", "60", "--json"]
    code, out, _ = run(capsys, [*argv, "--srdf", UR5_SRDF])
    (note,) = [n for n in json.loads(out)["filters"]["notes"] if "disabled by ur5.srdf" in n]
    assert code == 0 and 0 < int(note.split()[0]) <= pairs


# --------------------------------------------------------------------------------------
# 6. Sizes and time
# --------------------------------------------------------------------------------------


def test_markers_beyond_memory_are_refused_naming_the_count(capsys):
    line = one_error(capsys, ["analyze", "ur5", "--markers", "100000000", "--measure", "position"])
    assert "100000000 markers" in line and "use at most" in line
    line = one_error(capsys, ["analyze", "ur5", "--markers", "3", "--configs", "10000000000"])
    assert "10000000000 configurations" in line


@pytest.mark.parametrize("command", ["analyze", "simulate", "design"])
def test_a_tree_count_beyond_memory_names_the_users_count(tmp_path, capsys, command):
    """The user's own count, and a maximum that is a count of configurations of this tree."""
    from calib.kinematics.tree import load_robot

    argv = [command, "talos", "--configs", "100000000"]
    if command == "simulate":
        argv += ["--measure", "position", "--out", tmp_path / "m.csv"]
    if command == "design":
        argv = [command, "talos", "--configs", "10", "--candidates", "100000000"]
    line = one_error(capsys, argv)
    assert "100000000 " in line and "500000000" not in line  # not the count times 5 tools
    most = int(line.rsplit("use at most ", 1)[1].split()[0])
    tree = load_robot("talos")
    if command == "design":  # the design's own estimate (calib.core.checks)
        from calib.design.design import candidate_configurations as draw
    else:
        draw = tree.random_configurations
    draw(tree, most, 0) if command == "design" else draw(most, 0)  # the maximum is accepted
    with pytest.raises(Exception, match=f"{most + 1} (configurations|candidates)"):
        draw(tree, most + 1, 0) if command == "design" else draw(most + 1, 0)  # ... the maximum
    assert not (tmp_path / "m.csv").exists()


def _loaded(pid: int, library: str, timeout: float = 60.0) -> None:
    """Wait until the process has mapped a shared library (its import has begun)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with open(f"/proc/{pid}/maps") as f:
            if library in f.read():
                return
        time.sleep(0.002)
    raise AssertionError(f"{library} never loaded")


@pytest.fixture(scope="module")
def large_campaign(tmp_path_factory) -> Path:
    """30,000 configurations of a UR5 measured by position, 0.05 mm noise."""
    path = tmp_path_factory.mktemp("large") / "m.csv"
    argv = ["simulate", "ur5", "--configs", "30000", "--noise-mm", "0.05", "--quiet"]
    assert main([*argv, "--out", str(path)]) == 0
    return path


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="needs /proc (Linux)")
@pytest.mark.parametrize(
    ("library", "delay"),
    [("numpy", 0.0), ("pinocchio", 0.0), ("pinocchio", 1.0), ("pinocchio", 3.0)],
    ids=["importing numpy", "importing pinocchio", "early work", "work"],
)
def test_ctrl_c_at_any_time_is_one_line_and_130(tmp_path, large_campaign, library, delay):
    """From the imports to the work: "calib: interrupted", exit 130, no traceback, no file.

    The command is a calibration of 30,000 rows (about 10 s of CPU here; a simulation of
    the most configurations ended before the last delay on an idle machine)."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)}
    argv = ["calibrate", "ur5", "--data", str(large_campaign), "--out", str(tmp_path / "c")]
    proc = subprocess.Popen(
        [sys.executable, "-m", "calib.cli.launcher", *argv],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    _loaded(proc.pid, library)
    time.sleep(delay)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    # (the command takes far longer than the delays); a shell reports 130 for both: exit
    # 130, or the end by SIGINT itself (seen once under load, after the one line)
    assert proc.returncode in (130, -signal.SIGINT), err
    assert err.decode() == "calib: interrupted\n", err
    assert [p.name for p in tmp_path.iterdir()] == []


# --------------------------------------------------------------------------------------
# 7. Options mean what they say
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("argv", "fact"),
    [
        (
            ["calibrate", "ur5", "--data", "d.csv", "--out", "c", "--elastic", "--no-elastic"],
            "--no-elastic: contradicts --elastic",
        ),
        (
            ["calibrate", "ur5", "--data", "d.csv", "--out", "c", "--no-elastic", "--no-elastic"],
            "given more than once",
        ),
        (["design", "ur5", "--configs", "9", "--collision", "--no-collision"], "contradicts"),
        (["show", "ur5", "--json", "--json"], "given more than once"),
        (["design", "ur5", "--configs", "9", "--noise-mm", "0"], "positive number"),
        (["design", "ur5", "--configs", "9", "--noise-mm", "-0.1"], "positive number"),
        (["design", "ur5", "--configs", "9", "--noise-mm", "nan"], "positive number"),
        (["design", "ur5", "--configs", "9", "--noise-mm", "inf"], "positive number"),
        (
            ["calibrate", "ur5", "--data", "d.csv", "--out", "c", "--noise-mm", "0"],
            "argument --noise-mm: expected a positive number",
        ),
        (
            ["simulate", "ur5", "--out", "s.csv", "--noise-mm", "-1"],
            "argument --noise-mm: expected a number >= 0",
        ),
        (
            ["simulate", "ur5", "--out", "s.csv", "--error-mm", "nan"],
            "argument --error-mm: expected a number >= 0",
        ),
        (
            ["simulate", "ur5", "--out", "s.csv", "--noise-mrad", "2000"],
            "argument --noise-mrad: expected a number >= 0",
        ),
    ],
)
def test_contradictory_repeated_or_impossible_flags_are_usage_errors(capsys, argv, fact):
    line = one_error(capsys, argv)
    assert fact in line and "--help)" in line


# Not --noise-mm: --evaluate prints the error predicted at that noise; not the candidates and
# their limits: --evaluate averages its prediction over the postures they keep.
CHOICE_OPTIONS = [["--configs", "9"], ["--criterion", "A"], ["--out", "x.csv"]]


@pytest.mark.parametrize("option", CHOICE_OPTIONS, ids=[o[0] for o in CHOICE_OPTIONS])
def test_evaluate_refuses_the_options_of_a_choice(tmp_path, capsys, campaign, option):
    line = one_error(capsys, ["design", "ur5", "--evaluate", campaign, *option])
    assert option[0] in line and "--evaluate" in line
    assert not (Path.cwd() / "x.csv").exists()


def test_candidates_and_a_candidates_file_are_exclusive(capsys, campaign):
    argv = ["design", "ur5", "--configs", "9", "--candidates", "40", "--candidates-file", campaign]
    line = one_error(capsys, argv)
    assert "--candidates" in line and "--candidates-file" in line


def test_no_collision_with_obstacles_checks_the_obstacles_only(capsys):
    """A box far away touches nothing; a box around the whole robot touches every candidate."""
    argv = ["design", "ur5", "--configs", "10", "--candidates", "80", "--no-collision", "--json"]
    code, out, _ = run(capsys, [*argv, "--obstacle", "5", "5", "5", "6", "6", "6"])
    filters = json.loads(out)["filters"]
    assert code == 0 and filters["rejected"]["collision"] == 0 and filters["kept"] == 80
    with_self = json.loads(run(capsys, [*argv[:-2], "--json"])[1])["filters"]
    assert with_self["rejected"]["collision"] > 0  # the self-collisions it did not reject
    line = one_error(capsys, [*argv, "--obstacle", "-3", "-3", "-3", "3", "3", "3"])
    assert "collision rejects 80" in line


def test_free_of_a_parameter_the_frame_carries_says_so(tmp_path, capsys, campaign):
    """d1 and theta1 move every point the way a base frame does (a translation, a rotation
    about the first axis): the fitted measurement frame carries them."""
    for name in ("d1", "theta1"):
        argv = ["calibrate", "ur5", "--data", campaign, "--out", tmp_path / "c", "--free", name]
        line = one_error(capsys, argv)
        assert f"free {name} cannot be fitted" in line and "measurement frame" in line
    assert not (tmp_path / "c").exists()


def test_a_holdout_that_holds_out_no_row_says_so(tmp_path, capsys, campaign):
    m = len(rows_of(campaign))
    fraction = 0.4 / m  # round(fraction * m) == 0: not one row
    argv = ["calibrate", "ur5", "--data", campaign, "--out", tmp_path / "c"]
    line = one_error(capsys, [*argv, "--holdout", f"{fraction:.6f}"])
    assert "holds out no row" in line and f"of {m} rows" in line


def test_a_tree_measurement_file_counts_configurations_not_rows(tmp_path, capsys, tree_campaign):
    rows = rows_of(tree_campaign)
    tools = len({r["tool"] for r in rows})
    configs = len(rows) // tools
    assert (configs, tools) == (3, 5)
    code, out, _ = run(capsys, ["design", "talos", "--evaluate", tree_campaign])
    assert code == 0 and out.startswith(f"talos: {configs} configurations from")
    out_csv = tmp_path / "again.csv"
    argv = ["simulate", "talos", "--configs-file", tree_campaign, "--measure", "position"]
    code, out, _ = run(capsys, [*argv, "--out", out_csv])
    again = rows_of(out_csv)
    assert code == 0 and len(again) == len(rows)
    joints = [k for k in rows[0] if k.endswith("_joint")]
    assert [[r[j] for j in joints] for r in again] == [[r[j] for j in joints] for r in rows]


# --------------------------------------------------------------------------------------
# 8. Honest messages
# --------------------------------------------------------------------------------------


def _report(capsys, data: Path, tmp_path: Path, *extra) -> tuple[dict, list[str], str]:
    report = tmp_path / "r.json"
    argv = ["calibrate", "ur5", "--data", data, "--out", tmp_path / "c.urdf", "--report", report]
    code, out, err = run(capsys, [*argv, *extra])
    assert code == 0, err
    return json.loads(report.read_text()), warning_lines(err), out


def test_every_printed_warning_is_in_the_report(tmp_path, capsys, campaign):
    rows = rows_of(campaign)
    data = tmp_path / "extra.csv"
    with open(data, "w", newline="") as f:
        writer = csv.DictWriter(f, [*rows[0], "comment"])
        writer.writeheader()
        writer.writerows({**r, "comment": "ok"} for r in rows)
    report, printed, _ = _report(capsys, data, tmp_path)
    assert any("comment" in w and "ignored" in w for w in printed)
    assert set(printed) <= set(report["warnings"])


def test_repeated_configurations_are_warned_and_reported(tmp_path, capsys, campaign):
    lines = campaign.read_text().splitlines(keepends=True)
    data = tmp_path / "dup.csv"
    data.write_text("".join([*lines, *lines[1:4]]))  # three rows measured twice
    report, printed, _ = _report(capsys, data, tmp_path)
    repeated = [w for w in printed if "repeat" in w]
    assert len(repeated) == 1 and f"3 of {len(lines) + 2} rows" in repeated[0]
    assert "overconfident" in repeated[0] and repeated[0] in report["warnings"]


def test_a_constant_joint_column_is_named_as_such(tmp_path, capsys, campaign):
    rows = rows_of(campaign)
    for r in rows:
        r["wrist_1_joint"] = "0.3"
        r["comment"] = "x"
    data = tmp_path / "const.csv"
    with open(data, "w", newline="") as f:
        writer = csv.DictWriter(f, list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    code, _, err = run(capsys, ["calibrate", "ur5", "--data", data, "--out", tmp_path / "c"])
    (line,) = [e for e in err.splitlines() if e.startswith("calib: error:")]
    assert code == 2 and "wrist_1_joint" in line and "one value in every row" in line
    assert "millimetres" not in line
    # the warning raised before the error is printed too
    assert any("comment" in w and "ignored" in w for w in warning_lines(err)), err


def test_a_normal_campaign_with_its_noise_gets_no_check_the_data_warning(
    tmp_path, capsys, campaign
):
    report, printed, out = _report(capsys, campaign, tmp_path, "--noise-mm", "0.05")
    everything = [*printed, *report["warnings"], out]
    assert not any("check the data" in text for text in everything)


def test_a_selection_too_long_to_wait_for_is_refused_up_front(tmp_path, capsys, monkeypatch):
    """50 markers at 200 configurations (points from Pinocchio's tool placements): --params
    auto is refused before the selection starts, naming the levels to give instead."""
    import numpy as np

    import calib.calibration.choice as choice
    from calib.kinematics.robot import load_chain

    chain = load_chain("ur5")
    q = chain.random_configurations(200, 1)
    F = chain.tool_placements(q)
    markers = np.random.default_rng(2).uniform(-0.1, 0.1, (50, 3))
    points = F[:, None, :3, 3] + np.einsum("mij,kj->mki", F[:, :3, :3], markers)
    data = tmp_path / "k50.csv"
    header = [*chain.joint_names, *(f"{a}{k + 1}" for k in range(50) for a in "xyz")]
    np.savetxt(
        data, np.c_[q, points.reshape(200, -1)], delimiter=",", header=",".join(header), comments=""
    )

    def forbidden(*args, **kwargs):
        raise AssertionError("the selection started")

    monkeypatch.setattr(choice, "select", forbidden)
    line = one_error(capsys, ["calibrate", "ur5", "--data", data, "--out", tmp_path / "c"])
    assert "params 'auto'" in line and "params complete" in line and "200 configurations" in line
    assert not (tmp_path / "c").exists()
