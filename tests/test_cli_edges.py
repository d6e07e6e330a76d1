"""The command line, third round (issue 29, items 6-11): numbers out of range, files that
never end, mimic joints and clashing joint names through every reader, every listed choice,
inputs found rather than given.

Every expectation comes from outside calib: the exit status and the lines on stderr, the
bytes of files before and after, the URDFs the tests write, counts made here.
"""

from __future__ import annotations

import csv
import os
import threading
from pathlib import Path

import numpy as np
import pytest
from test_cli_hardening import digest, one_error, rows_of, run

import calib
from calib.cli.commands import main

ROOT = Path(__file__).resolve().parents[1]
MIMIC_TREE = ROOT / "tests" / "data" / "mimic_tree.urdf"


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    """20 configurations of a UR5 measured by position (through the API)."""
    data = calib.simulate(calib.load_chain("ur5"), 20, measure="position").measurements
    path = tmp_path_factory.mktemp("campaign") / "m.csv"
    calib.write_measurements(path, data)
    return path


# Item 6: numbers out of range ---------------------------------------------------------------

OUT_OF_RANGE = [
    # (command, option, value, words the error line has)
    ("calibrate", "--max-iterations", "3000000000", "1000000"),
    ("calibrate", "--max-iterations", "0", "max_iterations"),
    ("calibrate", "--noise-mm", "nan", "noise"),
    ("calibrate", "--noise-mm", "1e300", "at most 1000"),
    ("calibrate", "--orientation-weight", "inf", "orientation weight"),
    ("calibrate", "--orientation-weight", "1e300", "at most 10000"),
    ("calibrate", "--holdout", "nan", "holdout"),
    ("calibrate", "--seed", "-1", "seed"),
    ("simulate", "--configs", "-3", "configurations"),
    ("simulate", "--configs", "3000000000", "use at most"),
    ("simulate", "--error-mm", "1e300", "at most 1000"),
    ("simulate", "--error-mrad", "1e30", "at most 1000"),
    ("simulate", "--noise-mm", "1e5", "at most 1000"),
    ("simulate", "--noise-mrad", "-2", "argument --noise-mrad: expected a number >= 0"),
    ("simulate", "--contacts", "-1", "--contacts"),
    ("simulate plane", "--contacts", "3000000000", "[1, 20]"),
    ("simulate plane", "--contacts", "0", "contacts"),
    ("simulate plane", "--noise-mrad", "1e9", "at most 1000"),
    ("simulate plane", "--error-mm", "nan", "argument --error-mm: expected a number >= 0"),
    ("design", "--noise-mm", "1e300", "at most 1000"),
    ("design", "--noise-mm", "-1", "--noise-mm"),
    ("design", "--orientation-weight", "1e300", "at most 10000"),
    ("design", "--candidates", "3000000000", "use at most"),
    ("design", "--margin", "nan", "margin"),
    ("analyze", "--configs", "3000000000", "use at most"),
    ("analyze", "--markers", "-1", "markers"),
    ("analyze", "--seed", "-1", "seed"),
    ("sweep", "--configs", "0", "configurations"),
]


@pytest.mark.parametrize(("command", "option", "value", "words"), OUT_OF_RANGE)
def test_numbers_out_of_range_are_one_line(
    tmp_path, capsys, campaign, command, option, value, words
):
    out = tmp_path / "out"
    base = {
        "calibrate": ["calibrate", "ur5", "--data", campaign, "--out", out],
        "simulate": ["simulate", "ur5", "--configs", "20", "--out", out],
        "simulate plane": [
            "simulate",
            "ur5",
            "--measure",
            "plane",
            "--configs",
            "20",
            "--out",
            out,
        ],
        "design": ["design", "ur5", "--configs", "10", "--candidates", "100", "--out", out],
        "analyze": ["analyze", "ur5"],
        "sweep": ["sweep", "--csv", out],
    }[command]
    if option in base:
        base = base[: base.index(option)] + base[base.index(option) + 2 :]
    line = one_error(capsys, [*base, option, value])
    assert words in line, line
    assert not out.exists()


# Item 7: files that never end ------------------------------------------------------------


def _error_within(capsys, argv, fifo: Path, seconds: float = 20.0) -> str:
    """The one error line of ``argv``, which must come within ``seconds``.

    A command that waits on the FIFO is released (a writer opens and closes it) and the test
    fails instead of hanging.
    """
    outcome: list = []
    thread = threading.Thread(target=lambda: outcome.append(main([str(a) for a in argv])))
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))  # EOF for a waiting reader
        thread.join()
        pytest.fail(f"{argv} waited on the FIFO")
    out, err = capsys.readouterr()
    errors = [line for line in err.splitlines() if not line.startswith("calib: warning:")]
    assert outcome == [2] and len(errors) == 1, (out, err)
    assert "Traceback" not in err
    return errors[0]


def _fifo_commands(fifo: Path, data: Path, out: Path) -> dict[str, list]:
    return {
        "--data": ["calibrate", "ur5", "--data", fifo, "--out", out],
        "--validate": ["calibrate", "ur5", "--data", data, "--validate", fifo, "--out", out],
        "contact --data": ["calibrate", "ur5", "--measure", "plane", "--data", fifo, "--out", out],
        "design --evaluate": ["design", "ur5", "--evaluate", fifo],
        "design --candidates-file": ["design", "ur5", "--configs", "5", "--candidates-file", fifo],
        "design --srdf": ["design", "ur5", "--configs", "5", "--candidates", "50", "--srdf", fifo],
        "simulate --configs-file": ["simulate", "ur5", "--configs-file", fifo, "--out", out],
        "predict --compliance": [
            "predict",
            "ur5",
            "--compliance",
            fifo,
            "--configs",
            data,
            "--out",
            out,
        ],
        "the URDF": ["analyze", fifo.with_suffix(".urdf")],
    }


@pytest.mark.parametrize(
    "option",
    [
        "--data",
        "--validate",
        "contact --data",
        "design --evaluate",
        "design --candidates-file",
        "design --srdf",
        "simulate --configs-file",
        "predict --compliance",
        "the URDF",
    ],
)
def test_a_fifo_given_as_an_input_is_one_line_never_a_hang(tmp_path, capsys, campaign, option):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    os.mkfifo(fifo.with_suffix(".urdf"))
    argv = _fifo_commands(fifo, campaign, tmp_path / "out.csv")[option]
    line = _error_within(capsys, argv, fifo.with_suffix(".urdf") if option == "the URDF" else fifo)
    assert "FIFO" in line and "pipe" in line, line
    assert not (tmp_path / "out.csv").exists()


@pytest.mark.parametrize("option", ["--data", "design --evaluate", "simulate --configs-file"])
def test_a_device_given_as_an_input_is_refused_before_reading(tmp_path, capsys, campaign, option):
    zero = Path("/dev/zero")
    argv = _fifo_commands(zero, campaign, tmp_path / "out.csv")[option]
    line = one_error(capsys, argv)
    assert "/dev/zero" in line and "character device" in line, line


# Item 11: inputs found, not given --------------------------------------------------------


@pytest.fixture()
def ur5_with_srdf(tmp_path) -> tuple[Path, Path]:
    """A copy of example-robot-data's UR5 layout: urdf/ur5_robot.urdf and srdf/ur5.srdf."""
    from calib.design.collision import find_srdf
    from calib.kinematics.catalog import catalog_entry

    urdf = catalog_entry("ur5").path
    srdf = find_srdf(urdf)
    assert srdf is not None
    (tmp_path / "urdf").mkdir()
    (tmp_path / "srdf").mkdir()
    copy = tmp_path / "urdf" / urdf.name
    copy.write_bytes(urdf.read_bytes())
    found = tmp_path / "srdf" / srdf.name
    found.write_bytes(srdf.read_bytes())
    return copy, found


def test_design_never_overwrites_the_srdf_it_found(capsys, ur5_with_srdf):
    urdf, srdf = ur5_with_srdf
    before = digest(srdf)
    argv = ["design", urdf, "--configs", "8", "--candidates", "60"]
    line = one_error(capsys, [*argv, "--out", srdf.parent / ".." / "srdf" / srdf.name])
    assert "SRDF found beside the URDF" in line, line
    assert digest(srdf) == before


def test_no_output_is_a_file_the_command_read(tmp_path):
    """The net under every command: a file read within the block is never written."""
    from calib.core.fileio import inputs_recorded, read_text_limited, write_files_atomic
    from calib.exceptions import InvalidArgumentError

    found = tmp_path / "found.txt"
    found.write_text("read\n")
    link = tmp_path / "link.txt"
    link.symlink_to(found)
    with inputs_recorded():
        read_text_limited(found, 100)
        with pytest.raises(InvalidArgumentError, match="which this command read"):
            write_files_atomic({link: "new", tmp_path / "other.txt": "x"})
    assert found.read_text() == "read\n" and not (tmp_path / "other.txt").exists()
    write_files_atomic({found: "rewritten\n"})  # the API outside a command may
    assert found.read_text() == "rewritten\n"


# Item 8: mimic joints round-trip ------------------------------------------------------------


def _mimic_relation(path: Path) -> dict[str, tuple[str, float, float]]:
    """follower: (leader, multiplier, offset), read from the URDF's tags here."""
    import xml.etree.ElementTree as ET

    tags = {}
    for joint in ET.parse(path).getroot().iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None:
            tags[joint.get("name")] = (
                mimic.get("joint"),
                float(mimic.get("multiplier", 1)),
                float(mimic.get("offset", 0)),
            )
    return tags


MIMIC_ROBOTS = {
    "chain": ["mimic_arm"],
    "tree": [MIMIC_TREE, "--tool", "tool_a", "--tool", "tool_b"],
}


@pytest.mark.parametrize("robot", sorted(MIMIC_ROBOTS))
@pytest.mark.parametrize("reader", ["design --evaluate", "simulate --configs-file"])
def test_what_simulate_writes_through_mimic_joints_is_read_everywhere(
    tmp_path, capsys, robot, reader
):
    argv = MIMIC_ROBOTS[robot]
    data = tmp_path / "m.csv"
    code, _, err = run(
        capsys, ["simulate", *argv, "--configs", "12", "--measure", "position", "--out", data]
    )
    assert code == 0, err
    if reader == "design --evaluate":
        code, _, err = run(capsys, ["design", *argv, "--evaluate", data])
    else:
        again = tmp_path / "again.csv"
        code, _, err = run(
            capsys,
            ["simulate", *argv, "--configs-file", data, "--measure", "position", "--out", again],
        )
        if code == 0:  # the same configurations, row for row
            joints = [c for c in rows_of(data)[0] if c not in ("x", "y", "z", "tool")]
            first = [[r[c] for c in joints] for r in rows_of(data)]
            assert [[r[c] for c in joints] for r in rows_of(again)] == first
    assert code == 0, err


def _with_followers(tmp_path: Path, shift: float) -> tuple[Path, Path]:
    """mimic_arm's 12 configurations with the followers' columns (computed here from the
    URDF's tags), one of them moved by ``shift``; and the URDF."""
    from calib.kinematics.catalog import catalog_entry

    urdf = catalog_entry("mimic_arm").path
    rng = np.random.default_rng(4)
    leaders = {n: rng.uniform(-1.0, 1.0, 12) for n in ("joint1", "joint2", "joint4", "joint6")}
    columns = dict(leaders)
    for follower, (leader, k, offset) in _mimic_relation(urdf).items():
        columns[follower] = k * leaders[leader] + offset
    columns["joint3"] = columns["joint3"] + np.r_[0.0, 0.0, shift, np.zeros(9)]
    path = tmp_path / "q.csv"
    names = sorted(columns)
    lines = [",".join(names)] + [
        ",".join(repr(float(columns[n][i])) for n in names) for i in range(12)
    ]
    path.write_text("\n".join(lines) + "\n")
    return path, urdf


@pytest.mark.parametrize("reader", ["design --evaluate", "simulate --configs-file"])
def test_follower_columns_are_checked_against_their_leaders(tmp_path, capsys, reader):
    good, _ = _with_followers(tmp_path, 0.0)
    argv = {
        "design --evaluate": ["design", "mimic_arm", "--evaluate"],
        "simulate --configs-file": [
            "simulate",
            "mimic_arm",
            "--out",
            tmp_path / "o.csv",
            "--configs-file",
        ],
    }[reader]
    code, _, err = run(capsys, [*argv, good])
    assert code == 0, err
    bad, _ = _with_followers(tmp_path, 0.01)
    line = one_error(capsys, [*argv, bad])
    assert "row 4, column 'joint3'" in line and "does not follow joint2" in line, line


def test_a_measurement_file_with_follower_columns_is_checked_too(tmp_path, capsys):
    data = tmp_path / "m.csv"
    run(
        capsys, ["simulate", "mimic_arm", "--configs", "12", "--measure", "position", "--out", data]
    )
    rows = rows_of(data)
    for row in rows:  # the follower from its leader, by the URDF's tag: -joint2 + 0.1
        row["joint3"] = repr(-float(row["joint2"]) + 0.1)
    rows[5]["joint3"] = repr(float(rows[5]["joint3"]) + 1e-3)
    with open(data, "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    line = one_error(capsys, ["calibrate", "mimic_arm", "--data", data, "--out", tmp_path / "c"])
    assert "row 7, column 'joint3'" in line and "does not follow" in line, line


# Item 9: names that clash ---------------------------------------------------------------------


def clash_urdf(tmp_path: Path, names: tuple[str, ...]) -> Path:
    """A 6R arm (axes z, y, y, x, y, z, offsets not parallel) whose joints have ``names``."""
    axes = ["0 0 1", "0 1 0", "0 1 0", "1 0 0", "0 1 0", "0 0 1"]
    origins = ["0 0 0.1", "0 0.1 0.2", "0.3 0 0.05", "0.25 0.05 0", "0.1 0 0.04", "0 0.08 0.1"]
    parts = ['<?xml version="1.0"?>', '<robot name="clash">', '<link name="base"/>']
    for i, name in enumerate(names):
        parent = "base" if i == 0 else f"l{i}"
        parts += [
            f'<link name="l{i + 1}"/>',
            f'<joint name="{name}" type="revolute"><parent link="{parent}"/>'
            f'<child link="l{i + 1}"/><origin xyz="{origins[i]}" rpy="0.1 0 0"/>'
            f'<axis xyz="{axes[i]}"/><limit lower="-3" upper="3" effort="1" velocity="1"/>'
            f"</joint>",
        ]
    parts += [
        '<link name="tool"/>',
        f'<joint name="tool_joint" type="fixed"><parent link="l{len(names)}"/>'
        '<child link="tool"/><origin xyz="0 0 0.1"/></joint>',
        "</robot>",
    ]
    path = tmp_path / "clash.urdf"
    path.write_text("\n".join(parts) + "\n")
    return path


CLASHING = ("plane", "point", "x", "y", "z", "qw")


@pytest.mark.parametrize("kind", ["plane", "plane-point", "fixed-point", "fixed-pose"])
def test_joints_named_plane_or_point_round_trip_through_contacts(tmp_path, capsys, kind):
    from calib.measurements.contact_campaign import read_contacts, simulate_contacts

    urdf = clash_urdf(tmp_path, CLASHING)
    data = tmp_path / "touches.csv"
    code, _, err = run(
        capsys, ["simulate", urdf, "--measure", kind, "--configs", "40", "--out", data]
    )
    assert code == 0, err
    chain = calib.load_chain(urdf)
    truth = simulate_contacts(chain, 40, kind, seed=0).data  # what simulate wrote
    rows = rows_of(data)
    for j, name in enumerate(CLASHING):
        column = f"joint:{name}" if name in ("plane", "point") else name
        assert [float(r[column]) for r in rows] == truth.q[:, j].tolist()
    assert np.array_equal(read_contacts(data, chain, kind).q, truth.q)
    code, _, err = run(
        capsys, ["calibrate", urdf, "--measure", kind, "--data", data, "--out", tmp_path / "c.urdf"]
    )
    assert code == 0, err


@pytest.mark.parametrize("reader", ["design --evaluate", "simulate --configs-file"])
def test_joint_prefix_columns_are_joints_wherever_configurations_are_read(tmp_path, capsys, reader):
    """A pose campaign of joints named x, y, z, qw: ``joint:qw`` is the joint, ``qw`` the
    quaternion; the configurations read are the joint columns (checked here by evaluating
    the same configurations from a file of joint columns only)."""
    urdf = clash_urdf(tmp_path, ("a", "b", "x", "y", "z", "qw"))
    data = tmp_path / "pose.csv"
    argv = ["simulate", urdf, "--measure", "pose", "--configs", "30", "--out", data]
    assert run(capsys, argv)[0] == 0  # pose: the default instrument measures positions
    rows = rows_of(data)
    assert "joint:qw" in rows[0] and "qw" in rows[0]
    plain = tmp_path / "plain.csv"
    names = ("a", "b", "x", "y", "z", "qw")
    keys = ("a", "b", "x", "y", "z", "joint:qw")
    plain.write_text(
        ",".join(names) + "\n" + "".join(",".join(r[k] for k in keys) + "\n" for r in rows)
    )
    if reader == "design --evaluate":
        outs = [run(capsys, ["design", urdf, "--evaluate", f, "--json"]) for f in (data, plain)]
        assert outs[0][0] == outs[1][0] == 0
        assert outs[0][1].replace(str(data), str(plain)) == outs[1][1]
    else:
        a, b = tmp_path / "a.csv", tmp_path / "b.csv"
        for source, out in ((data, a), (plain, b)):
            assert run(capsys, ["simulate", urdf, "--configs-file", source, "--out", out])[0] == 0
        assert a.read_bytes() == b.read_bytes()


# Item 10: every listed choice works --------------------------------------------------------


@pytest.mark.parametrize("kind", ["plane", "plane-point", "fixed-point", "fixed-pose"])
def test_sweep_takes_every_measure_its_help_lists(tmp_path, capsys, monkeypatch, kind):
    """``calib sweep --measure KIND`` (the catalog cut to the UR5 and a tree): the UR5's
    counts are analyze's, the tree is a row with its reason (contacts are one chain's)."""
    import calib.outputs.sweep as sweep_module

    keep = [e for e in sweep_module.catalog() if e.name in ("ur5", "bolt")]
    monkeypatch.setattr(sweep_module, "catalog", lambda: keep)
    table = tmp_path / "sweep.csv"
    code, _, err = run(capsys, ["sweep", "--measure", kind, "--configs", "40", "--csv", table])
    assert code == 0, err
    rows = {r["robot"]: r for r in rows_of(table)}
    assert set(rows) == {"ur5", "bolt"}
    assert rows["bolt"]["verdict"] == "error" and "one chain" in rows["bolt"]["error"]
    for params, column in (("paper", "n_base_paper"), ("complete", "n_base_complete")):
        res = calib.analyze("ur5", measure=kind, params=params, configs=40, seed=0)
        assert int(rows["ur5"][column]) == res.n_base > 0


def test_simulating_many_planes_never_stops_on_a_singular_newton_step(tmp_path, capsys):
    """The Allegro index finger meets a posture where the Newton system is singular (10
    planes, seed 0): the touches are still simulated, each on its true plane."""
    out = tmp_path / "c.csv"
    argv = ["simulate", "allegro_index", "--measure", "plane", "--contacts", "10"]
    code, _, err = run(capsys, [*argv, "--configs", "10", "--out", out])
    assert code == 0, err
    assert len(rows_of(out)) == 10


def test_the_singular_step_is_the_least_norm_least_squares_one():
    from calib.identification.contact_postures import _newton_step

    J = np.array([[[1e8, 2e8, 0.0], [1e8, 2e8, 0.0]]])  # J J^T singular in floating point
    gap = np.array([[1.0, 3.0]])
    expected = np.linalg.lstsq(J[0], -gap[0], rcond=None)[0]  # least norm of the mean
    assert np.allclose(_newton_step(J, gap)[0], expected, rtol=1e-9, atol=0)


def test_a_contact_that_cannot_be_reached_is_named(capsys):
    """The 65th plane of a two-joint arm (seed 0) is out of its reach: the error names it."""
    argv = ["simulate", "twodof", "--measure", "plane", "--contacts", "65", "--configs", "65"]
    line = one_error(capsys, [*argv, "--out", "-", "--truth", "/dev/null"])
    assert "plane table65: only 0 of" in line, line


@pytest.mark.parametrize("weight", ["2", "auto"])
def test_an_orientation_weight_with_no_angle_rows_is_refused(tmp_path, capsys, campaign, weight):
    """Positions only, or lengths-only touches (fixed-point): ``--orientation-weight`` has no
    rows to weigh; it is an error, not ignored (the report recorded the ignored weight)."""
    out = tmp_path / "cal.urdf"
    argv = ["calibrate", "ur5", "--data", campaign, "--out", out, "--orientation-weight", weight]
    assert "the data have none (positions only)" in one_error(capsys, argv)
    touches = tmp_path / "points.csv"
    code, _, _ = run(capsys, ["simulate", "ur5", "--measure", "fixed-point", "--out", touches])
    assert code == 0
    argv = [
        "calibrate",
        "ur5",
        "--measure",
        "fixed-point",
        "--data",
        touches,
        "--out",
        out,
        "--orientation-weight",
        weight,
    ]
    assert "the data have none (--measure fixed-point: lengths)" in one_error(capsys, argv)
    assert not out.exists()


@pytest.mark.parametrize(
    "option", [["--marker", "0", "0", "0.1"], ["--params", "paper"]], ids=["marker", "paper"]
)
def test_analyze_markers_refuses_an_option_it_would_ignore(capsys, option):
    """``analyze --markers K`` counts with the K markers unknown, every joint placement
    offered: a known ``--marker`` or the paper's set changed nothing (the same output)."""
    line = one_error(capsys, ["analyze", "ur5", "--markers", "3", *option])
    assert f"{' '.join(option[:2]) if option[0] == '--params' else option[0]} is not for" in line
    code, out, _ = run(capsys, ["analyze", "ur5", "--markers", "3", "--params", "complete"])
    assert code == 0 and "33 identifiable parameters" in out


def test_a_measure_naming_a_row_twice_is_refused(capsys):
    """``--measure x,y,x`` (a typo for ``x,y,z``?) was analysed as ``x,y``, labelled x,y,x."""
    line = one_error(capsys, ["analyze", "ur5", "--measure", "x,y,x"])
    assert line.endswith("measure 'x,y,x' names the row x twice"), line
    with pytest.raises(calib.InvalidArgumentError, match="names the row rz twice"):
        calib.analyze("ur5", measure="rz,x,rz")


@pytest.mark.parametrize(
    "argv",
    [
        ["design", "ur5", "--configs", "30"],
        ["design", "ur5", "--measure", "plane", "--configs", "30"],
        ["design", "ur5", "--evaluate", "CONFIGS"],
    ],
    ids=["position", "plane", "evaluate"],
)
def test_design_refuses_an_orientation_weight_it_would_ignore(tmp_path, capsys, argv):
    """Only pose data have orientation rows the design weighs (a contact design weighs no
    row): the same design came out with or without ``--orientation-weight 2``."""
    configs = tmp_path / "c.csv"
    assert run(capsys, ["design", "ur5", "--configs", "12", "--out", configs])[0] == 0
    argv = [str(configs) if a == "CONFIGS" else a for a in argv]
    line = one_error(capsys, [*argv, "--orientation-weight", "2"])
    assert "--orientation-weight weighs the orientation rows of --measure pose" in line
    chain = calib.load_chain("ur5")
    with pytest.raises(calib.InvalidArgumentError, match="weighs the orientation rows"):
        calib.design(
            chain,
            30,
            measure=argv[argv.index("--measure") + 1] if "--measure" in argv else "position",
            orientation_weight=2.0,
        )
    assert (
        run(
            capsys,
            ["design", "ur5", "--measure", "pose", "--configs", "30", "--orientation-weight", "2"],
        )[0]
        == 0
    )


HANDS = ["--tool", "wrist_left_ft_tool_link", "--tool", "gripper_left_base_link"]


@pytest.mark.parametrize("robot", [["ur5"], ["talos", *HANDS]], ids=["chain", "tree"])
def test_simulate_refuses_an_orientation_noise_with_no_orientation(tmp_path, capsys, robot):
    """``--noise-mrad`` with positions (a chain's, or a tree's: positions only) changed
    nothing: the campaign said ``noise 0 mm`` and no mrad."""
    argv = ["simulate", *robot, "--noise-mrad", "0.1", "--out", tmp_path / "m.csv"]
    line = one_error(capsys, argv)
    assert line.endswith("--measure position records no orientation"), line
    assert list(tmp_path.iterdir()) == []


def test_design_json_refuses_the_noise_of_a_prediction_it_does_not_print(capsys):
    """``design --json --noise-mm N``: the JSON has no prediction, so N changed nothing."""
    line = one_error(capsys, ["design", "ur5", "--configs", "30", "--json", "--noise-mm", "0.5"])
    assert "--noise-mm scales the printed error prediction" in line, line


def test_a_pose_without_orientation_columns_names_the_names_read_and_the_options(tmp_path, capsys):
    """The UR10's real file names its angles phix1, phiy1, phiz1: ``--measure pose`` said
    "needs orientation columns (qx, qy, qz, qw, ...)", hiding the rotation vector's and rpy's
    names and the options that read other names. Its advice, followed, reads the file."""
    chain = calib.load_chain("ur5")
    data = calib.simulate(chain, 20, measure="pose", seed=0).measurements
    path = tmp_path / "pose.csv"
    calib.write_measurements(path, data)
    text = path.read_text()
    header, rest = text.split("\n", 1)
    renamed = {"qx": "a1", "qy": "a2", "qz": "a3", "qw": "a4"}
    path.write_text(",".join(renamed.get(c, c) for c in header.split(",")) + "\n" + rest)
    argv = ["calibrate", "ur5", "--data", path, "--measure", "pose", "--out", tmp_path / "c.urdf"]
    line = one_error(capsys, argv)
    assert "(qx, qy, qz, qw; rx, ry, rz; roll, pitch, yaw)" in line, line
    assert "--orientation FORMAT --orientation-columns A B C [D]" in line, line
    named = ["--orientation", "quat-xyzw", "--orientation-columns", "a1", "a2", "a3", "a4"]
    code, out, err = run(capsys, [*argv, *named])
    assert code == 0 and "rot rms [mrad]" in out, err


def test_calibrate_writes_its_files_when_its_reader_is_gone(tmp_path):
    """``calib calibrate ... | head -2``: the summary's print met the closed pipe, the command
    stopped quietly with exit code 0 and wrote neither the URDF nor the report."""
    import subprocess
    import sys

    data = calib.simulate(calib.load_chain("ur5"), 40, measure="position", seed=1).measurements
    calib.write_measurements(tmp_path / "m.csv", data)
    argv = ["calibrate", "ur5", "--data", "m.csv", "--out", "c.urdf", "--report", "r.json"]
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OPENBLAS_NUM_THREADS": "1"}
    with subprocess.Popen(
        [sys.executable, "-m", "calib.cli", *argv],
        cwd=tmp_path,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    ) as proc:
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.close()  # the reader is gone before calib prints
        err = proc.stderr.read().decode()
    assert proc.returncode == 0 and "Traceback" not in err, err
    assert (tmp_path / "c.urdf").is_file() and (tmp_path / "r.json").is_file()
