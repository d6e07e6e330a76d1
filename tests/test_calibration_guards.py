"""The guards of a calibration, for chains and trees alike (issue 19, behaviours 1-4).

Trees get every guard chains have; no level the rows cannot determine is fitted; validation
data are data; orientation rows count. Expectations come from outside calib: the mistake a
test plants (and so the row, columns or unit it must name), theoretical parameter counts,
the chain's own error text for the same flag, scipy's rotations, Pinocchio's rpy, and the
process's exit status, stderr and files.
"""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest
from conftest import chain_of
from pinref import PinTree
from scipy.spatial.transform import Rotation

from calib import (
    DataError,
    InvalidArgumentError,
    Measurements,
    calibrate,
    load_chain,
    read_measurements,
    simulate,
)
from calib.calibration.entry import calibrate as calibrate_tree
from calib.cli.commands import main
from calib.kinematics.tree import load_robot
from calib.measurements.tree_campaign import simulate_tree, true_points

MARKER = (0.05, 0.02, 0.1)


def run(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def one_error(code: int, err: str) -> str:
    """The one error line of a refused run (exit 2, no traceback), without its prefix."""
    errors = [e for e in err.splitlines() if not e.startswith("calib: warning: ")]
    assert code == 2 and "Traceback" not in err and len(errors) == 1, err
    assert errors[0].startswith("calib: error: ")
    return errors[0].removeprefix("calib: error: ")


def csv_table(path: Path) -> tuple[list[str], list[list[str]]]:
    rows = list(csv.reader(path.open()))
    return rows[0], rows[1:]


def write_table(path: Path, header: list[str], rows: list[list[str]]) -> Path:
    with path.open("w", newline="") as f:
        csv.writer(f).writerows([header, *rows])
    return path


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Position campaigns of ur5 (chain: training and validation rows) and bolt (a tree)."""
    d = tmp_path_factory.mktemp("guards")
    for name, robot, configs in (("ur5_all", "ur5", 60), ("bolt", "bolt", 20)):
        argv = ["simulate", robot, "--measure", "position", "--configs", configs, "--seed", 2]
        code, _, err = run([*argv, "--noise-mm", "0.05", "--out", d / f"{name}.csv"])
        assert code == 0, err
    header, rows = csv_table(d / "ur5_all.csv")  # one robot: 40 rows fitted, 20 held out
    write_table(d / "ur5.csv", header, rows[:40])
    write_table(d / "ur5_val.csv", header, rows[40:])
    return d


# --- behaviour 1: trees get every guard chains have ----------------------------------------


@pytest.mark.parametrize(
    "flags",
    [["--max-iterations", "0"], ["--seed", "-1", "--holdout", "0.2"], ["--holdout", "1.5"]],
)
def test_tree_options_get_the_chains_one_line_errors(files, tmp_path, flags):
    chain = run(["calibrate", "ur5", "--data", files / "ur5.csv", "--out", tmp_path / "c.urdf"])
    assert chain[0] == 0  # the data are fine: only the flags differ
    lines = []
    for robot in ("ur5", "bolt"):
        argv = ["calibrate", robot, "--data", files / f"{robot}.csv", "--out", tmp_path / "o.urdf"]
        lines.append(one_error(*run([*argv, *flags])[::2]))
    assert lines[0] == lines[1]  # the chain's own message, for the same flag
    assert not (tmp_path / "o.urdf").exists()


@pytest.mark.parametrize(
    ("flags", "says"),
    [
        (["--params", "auto"], "--params auto is for one chain"),
        (["--measure", "pose"], "--measure pose is for one chain"),
        (["--validate", "VAL", "--holdout", "0.2"], "not both"),
    ],
)
def test_tree_options_it_cannot_honour_are_refused(files, tmp_path, flags, says):
    val = write_table(tmp_path / "v.csv", *csv_table(files / "bolt.csv"))
    flags = [str(val) if f == "VAL" else f for f in flags]
    out = tmp_path / "o.urdf"
    code, stdout, err = run(
        ["calibrate", "bolt", "--data", files / "bolt.csv", "--out", out, *flags]
    )
    assert says in one_error(code, err) and stdout == ""
    assert not out.exists()


def test_tree_api_refuses_validation_with_a_holdout_fraction(files):
    tree = load_robot("bolt")
    camp = simulate_tree(tree, 20, markers=MARKER, seed=3)
    other = simulate_tree(tree, 10, markers=MARKER, seed=4)
    with pytest.raises(InvalidArgumentError, match="not both"):
        calibrate_tree(tree, camp.measurements, validate=other.measurements, holdout=0.2)
    for bad in ({"max_iterations": 0}, {"seed": -1}, {"holdout": 1.0}, {"seed": True}):
        with pytest.raises(InvalidArgumentError) as info:
            calibrate_tree(tree, camp.measurements, **bad)
        (name, value) = bad.popitem()
        assert f"got {value!r}" in str(info.value) and name.split("_")[0] in str(info.value)


def test_tree_report_has_the_documented_schema(files, tmp_path):
    report = tmp_path / "r.json"
    argv = ["calibrate", "bolt", "--data", files / "bolt.csv", "--out", tmp_path / "o.urdf"]
    code, _, err = run([*argv, "--report", report])
    assert code == 0, err
    rep = json.loads(report.read_text())
    for key in ("data", "measure", "warnings", "message", "iterations", "timings_ms", "outliers"):
        assert key in rep, key
    assert rep["data"] == str(files / "bolt.csv") and rep["measure"] == "position"
    T = np.array(rep["measurement_to_base"]["matrix"])
    assert np.allclose(T[:3, 3], rep["measurement_to_base"]["xyz"])
    R = pin.rpy.rpyToMatrix(np.array(rep["measurement_to_base"]["rpy"]))
    assert np.allclose(R, T[:3, :3], atol=1e-12)
    assert set(rep["timings_ms"]) == {"registration", "selection", "fit", "validation"}
    assert rep["iterations"] >= 1 and isinstance(rep["message"], str)


def test_a_trees_tool_carried_by_its_last_joint_is_written(tmp_path):
    """A tool carried by its chain's last (revolute) joint, ``FR_LOWER_LEG``: refused before
    the fit ("not by a fixed joint"), a rule of the tree's old writer (the tool's placement
    in its fixed joint); the joint engine hangs each tool's markers from the tool's link, as
    a chain's calibration does. Written now, the marker link on the tool's link
    (``tests/test_tree_calibration.py`` checks the written URDF with Pinocchio)."""
    import xml.etree.ElementTree as ET

    tools = ["--tool", "FL_FOOT", "--tool", "FR_LOWER_LEG"]
    data = tmp_path / "m.csv"
    sim = ["simulate", "bolt", *tools, "--measure", "position", "--configs", "20"]
    assert run([*sim, "--out", data])[0] == 0
    out, report = tmp_path / "o.urdf", tmp_path / "r.json"
    code, _, err = run(
        ["calibrate", "bolt", *tools, "--data", data, "--out", out, "--report", report]
    )
    assert code == 0, err
    joints = {j.get("name"): j for j in ET.parse(out).getroot().iter("joint")}
    assert joints["FR_LOWER_LEG_marker1_joint"].find("parent").get("link") == "FR_LOWER_LEG"


def test_tree_outlier_row_is_set_aside(tmp_path):
    tree = load_robot("bolt")
    camp = simulate_tree(tree, 30, markers=MARKER, noise_mm=0.05, seed=5)
    pos = camp.measurements.position.copy()
    pos[13] += [0.03, -0.02, 0.01]  # one reading 37 mm off
    res = calibrate_tree(tree, dataclasses.replace(camp.measurements, position=pos)).check()
    rep = res.to_dict()
    assert [o["row"] for o in rep["outliers"]] == [14]  # no file: rows are numbered from 1
    assert sum(t["configs"] for t in rep["terms"]) == camp.measurements.m - 1
    assert any("row 14" in w for w in rep["warnings"])


def test_tree_usual_mistakes_are_named(files, tmp_path):
    header, rows = csv_table(files / "bolt.csv")
    xyz = [header.index(c) for c in ("x", "y", "z")]
    mm = [[f"{1e3 * float(c)!r}" if j in xyz else c for j, c in enumerate(r)] for r in rows]
    write_table(tmp_path / "mm.csv", header, mm)
    argv = ["calibrate", "bolt", "--data", tmp_path / "mm.csv", "--out", tmp_path / "o.urdf"]
    assert "millimetres" in one_error(*run(argv)[::2])
    # two knee columns swapped (both within the continuous joints' range)
    i, j = header.index("FL_KFE"), header.index("FR_KFE")
    swapped = [[r[j] if k == i else r[i] if k == j else c for k, c in enumerate(r)] for r in rows]
    write_table(tmp_path / "sw.csv", header, swapped)
    argv[3] = tmp_path / "sw.csv"
    assert "FL_KFE and FR_KFE swapped" in one_error(*run(argv)[::2])
    assert not (tmp_path / "o.urdf").exists()


# --- behaviour 2: no silent overfit ---------------------------------------------------------


@pytest.mark.parametrize("keep", [1, 2])
def test_one_or_two_rows_get_one_line(files, tmp_path, keep):
    header, rows = csv_table(files / "ur5.csv")
    data = write_table(tmp_path / "few.csv", header, rows[:keep])
    code, _, err = run(["calibrate", "ur5", "--data", data, "--out", tmp_path / "o.urdf"])
    # 6 frame + 3 marker unknowns, 3 equations per configuration: 4 configurations needed
    assert "it needs at least 4 configurations" in one_error(code, err)
    tree = run(["calibrate", "bolt", "--data", data, "--out", tmp_path / "o.urdf"])
    one_error(tree[0], tree[2])  # rows of another robot: refused in one line too


def test_holdout_099_gets_the_same_line(files, tmp_path):
    for robot, need in (("ur5", "4 configurations"), ("bolt", "5 rows")):  # bolt: 6 + 2 x 3
        argv = ["calibrate", robot, "--data", files / f"{robot}.csv", "--out", tmp_path / "o.urdf"]
        line = one_error(*run([*argv, "--holdout", "0.99"])[::2])
        assert f"it needs at least {need}" in line and "held out" in line


def test_a_level_the_rows_cannot_determine_is_refused_not_cut(files, tmp_path):
    """UR5, position: 4 x 6 + 6 - 3 = 27 identifiable parameters (Everett, minus rotation)."""
    header, rows = csv_table(files / "ur5.csv")
    data = write_table(tmp_path / "five.csv", header, rows[:5])
    argv = ["calibrate", "ur5", "--data", data, "--out", tmp_path / "o.urdf", "--params"]
    line = one_error(*run([*argv, "complete"])[::2])
    assert "15 equations for the 27 parameters" in line and "at least 10 configurations" in line
    # a joint that never moves: enough rows, but the level is not determined at them
    chain = chain_of("ur5")
    camp = simulate(chain, configs=40, measure="position", marker=MARKER, seed=2)
    q = camp.measurements.q.copy()
    q[:, 5] = 0.3
    pts = camp.truth.true_mdh.forward(q)
    pts = pts[:, :3, :3] @ np.array(MARKER) + pts[:, :3, 3]
    still = dataclasses.replace(camp.measurements, q=q, position=pts)
    with pytest.raises(DataError, match="determine only"):
        calibrate(chain, still, params="complete")
    assert calibrate(chain, still, params="frames").accepted  # frames need no joint motion


def test_tree_level_the_rows_cannot_determine_is_refused(tmp_path):
    tree = load_robot("bolt")
    camp = simulate_tree(tree, 30, markers=MARKER, seed=6)
    data = camp.measurements
    with pytest.raises(DataError, match="parameters of params 'complete'"):
        calibrate_tree(tree, data.subset(np.arange(8)))  # 4 rows a tool: its frame and marker
    q = data.q.copy()
    q[:, 2] = 0.4  # FL_KFE never moves (the rows measured so)
    tool = np.array([tree.tool_frames.index(t) for t in data.tool])
    pts = true_points(camp.true_mdh, q, camp.markers)[np.arange(data.m), tool]
    still = dataclasses.replace(data, q=q, position=pts)
    with pytest.raises(DataError, match="determine only"):
        calibrate_tree(tree, still)


def test_tree_generic_count_is_pinocchios_rank(tmp_path):
    """The count a tree's rows must reach (the refusal's 'of the N parameters') is the
    finite-difference rank of Pinocchio's own model at random configurations: every joint
    placement, the base (the instrument's frame) and each tool (its marker) moved, x y z rows."""
    tree = load_robot("bolt")
    camp = simulate_tree(tree, 30, markers=MARKER, seed=6)
    q = camp.measurements.q.copy()
    q[:, 2] = 0.4  # FL_KFE never moves: refused, the message names the generic count
    tool = np.array([tree.tool_frames.index(t) for t in camp.measurements.tool])
    pts = true_points(camp.true_mdh, q, camp.markers)[np.arange(len(q)), tool]
    still = dataclasses.replace(camp.measurements, q=q, position=pts)
    with pytest.raises(DataError, match="determine only") as err:
        calibrate_tree(tree, still)
    generic = int(str(err.value).split(" of the ")[1].split()[0])
    ref = PinTree.of_file(tree.urdf_path, tree.base_frame, list(tree.tool_frames))
    rng = np.random.default_rng(3)
    qr = rng.uniform(-1.0, 1.0, (12, tree.n))
    W = ref.placement_jacobian(tree.joint_names, qr, MARKER)
    keep = np.concatenate([6 * k + np.arange(3) for k in range(len(W) // 6)])
    s = np.linalg.svd(W[keep], compute_uv=False)
    rank = int(np.sum(s > 1e-7 * s[0]))
    assert s[rank] < 1e-9 * s[0]  # a clear gap
    assert generic == rank


# --- behaviour 3: validation data are data --------------------------------------------------


def test_validation_file_that_is_the_data_file_or_holds_its_rows_is_refused(files, tmp_path):
    header, rows = csv_table(files / "ur5.csv")
    _, val = csv_table(files / "ur5_val.csv")
    mixed = write_table(tmp_path / "mixed.csv", header, [*val[:8], rows[3], rows[11]])
    out = tmp_path / "o.urdf"
    for robot in ("ur5", "bolt"):
        data = files / f"{robot}.csv"
        argv = ["calibrate", robot, "--data", data, "--out", out, "--validate", data]
        assert "the validation file is the data file" in one_error(*run(argv)[::2])
    argv = ["calibrate", "ur5", "--data", files / "ur5.csv", "--out", out, "--validate", mixed]
    line = one_error(*run(argv)[::2])
    assert "2 of the 10 validation rows are rows of the data" in line
    assert "row 10 is row 5" in line  # file rows: the header is row 1
    assert not out.exists()


def test_a_rounded_copy_of_the_data_is_refused_as_validation_but_a_remeasurement_is_not():
    """The data written again with 6 decimals is the data (before, rows were compared
    exactly and the copy was scored as held out); the same postures measured again (10 um
    noise) are held-out rows, with a warning that they are no unseen postures."""
    import dataclasses

    from calib import DataError, DataWarning, calibrate, load_robot, simulate

    chain = load_robot("ur5")
    data = simulate(chain, 30, noise_mm=0.01, seed=4).measurements
    rounded = dataclasses.replace(
        data, q=np.round(data.q, 6), position=np.round(data.position, 6), source="copy.csv"
    )
    with pytest.raises(DataError, match="30 of the 30 validation rows are rows of the data"):
        calibrate(chain, data, validate=rounded)
    noise = np.random.default_rng(5).normal(scale=1e-5, size=data.position.shape)
    again = dataclasses.replace(data, position=data.position + noise, source="again.csv")
    with pytest.warns(DataWarning, match="30 of the 30 validation rows are at postures of"):
        assert calibrate(chain, data, validate=again).accepted


def test_validation_data_get_the_diagnosis(files, tmp_path):
    header, rows = csv_table(files / "ur5_val.csv")
    xyz = [header.index(c) for c in ("x", "y", "z")]
    mm = [[f"{1e3 * float(c)!r}" if j in xyz else c for j, c in enumerate(r)] for r in rows]
    val = write_table(tmp_path / "val_mm.csv", header, mm)
    argv = ["calibrate", "ur5", "--data", files / "ur5.csv", "--out", tmp_path / "o.urdf"]
    line = one_error(*run([*argv, "--validate", val])[::2])
    assert line.startswith(str(val)) and "millimetres" in line
    i, j = header.index("wrist_1_joint"), header.index("wrist_2_joint")
    swapped = [[r[j] if k == i else r[i] if k == j else c for k, c in enumerate(r)] for r in rows]
    val = write_table(tmp_path / "val_sw.csv", header, swapped)
    line = one_error(*run([*argv, "--validate", val])[::2])
    assert line.startswith(str(val)) and "wrist_1_joint and wrist_2_joint swapped" in line
    good = run([*argv, "--validate", files / "ur5_val.csv"])
    assert good[0] == 0, good[2]  # the same robot's other configurations: scored, accepted


def test_tree_validation_data_get_the_diagnosis(files, tmp_path):
    tree = load_robot("bolt")
    camp = simulate_tree(tree, 40, markers=MARKER, noise_mm=0.05, seed=7)
    train, held = (
        camp.measurements.subset(np.arange(60)),
        camp.measurements.subset(np.arange(60, 80)),
    )
    res = calibrate_tree(tree, train, validate=held).check()
    assert res.to_dict()["errors"]["held_out"]["registration"]["configs"] == 20
    with pytest.raises(DataError, match="millimetres"):
        calibrate_tree(
            tree, train, validate=dataclasses.replace(held, position=held.position * 1e3)
        )
    with pytest.raises(DataError, match="rows of the data"):
        calibrate_tree(tree, train, validate=train.subset(np.arange(5)))


# --- behaviour 4: orientation rows count ----------------------------------------------------


@pytest.fixture(scope="module")
def pose_campaign():
    chain = chain_of("ur5")
    camp = simulate(chain, configs=40, measure="pose", seed=4, noise_mm=0.05, noise_mrad=0.1)
    return chain, camp


def _pose_csv(path: Path, camp, names: str, values: np.ndarray) -> Path:
    data = camp.measurements
    lines = [f"{','.join(data.joint_names)},x,y,z,{names}"]
    for q, p, v in zip(data.q, data.position, values, strict=True):
        lines.append(",".join(repr(float(x)) for x in (*q, *p, *v)))
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.mark.parametrize(
    ("names", "values", "cause"),
    [
        ("roll,pitch,yaw", lambda r: np.degrees(r.as_euler("xyz")), "rpy angles in degrees"),
        ("rx,ry,rz", lambda r: np.degrees(r.as_rotvec()), "rotation vectors in degrees"),
        ("roll,pitch,yaw", lambda r: r.as_euler("xyz")[:, ::-1], "yaw, pitch, roll"),
        ("roll,pitch,yaw", lambda r: r.as_euler("XYZ"), "composed x, y, z"),
    ],
)
def test_orientation_mistakes_are_named(pose_campaign, tmp_path, names, values, cause):
    """scipy writes the mistakes: degrees, yaw-pitch-roll columns, intrinsic x-y-z angles."""
    _, camp = pose_campaign
    rot = Rotation.from_quat(camp.measurements.quaternion)
    data = _pose_csv(tmp_path / "m.csv", camp, names, values(rot))
    code, _, err = run(["calibrate", "ur5", "--data", data, "--out", tmp_path / "o.urdf"])
    assert cause in one_error(code, err)
    right = _pose_csv(tmp_path / "ok.csv", camp, "roll,pitch,yaw", rot.as_euler("xyz"))
    code, _, err = run(["calibrate", "ur5", "--data", right, "--out", tmp_path / "o.urdf"])
    assert code == 0, err  # the same rotations written right: accepted


@pytest.fixture(scope="module")
def near_pose(tmp_path_factory):
    """Pose rows of UR5 near one posture, rotated so that their rpy angles stay under 0.8 rad.

    Small angles: a wrong rpy convention or noisy orientations barely move the points'
    registration, so only the orientation error (chain_registration's second diagnosis)
    shows them. Returns a writer of the rows with given orientations, and the rotations.
    """
    chain = chain_of("ur5")
    rng = np.random.default_rng(5)
    q = np.array([0.3, -1.2, 1.4, -1.5, -1.4, 0.2]) + rng.uniform(-0.3, 0.3, (40, 6))
    data = simulate(chain, q, measure="pose", seed=4, noise_mm=0.05, noise_mrad=0.1).measurements
    turn = Rotation.from_quat(data.quaternion[0]).inv()  # the measurement frame's rotation
    rot = turn * Rotation.from_quat(data.quaternion)
    folder = tmp_path_factory.mktemp("near_pose")
    moved = SimpleNamespace(
        measurements=dataclasses.replace(data, position=turn.apply(np.array(data.position)))
    )

    def write(name: str, rpy: np.ndarray):
        path = _pose_csv(folder / f"{name}.csv", moved, "roll,pitch,yaw", rpy)
        return read_measurements(path, chain)

    return chain, write, rot, rng


def test_orientation_mistakes_the_points_do_not_show_are_named(near_pose):
    """Angles composed x, y, z: named from the orientation error (the points fit), at the
    default weight whatever the weight given; validation rows too; noisy orientations that
    no mistake explains: a note on the orientation columns."""
    chain, write, rot, rng = near_pose
    right, wrong = write("right", rot.as_euler("xyz")), write("xyz", rot.as_euler("XYZ"))
    assert calibrate(chain, right).accepted
    cause = "rpy angles composed x, y, z"
    said = []
    for weight in (None, 1e-3):  # the diagnosis reads the rows at the default weight
        with pytest.raises(DataError, match=f"{cause}.*orientation error drops") as err:
            calibrate(chain, wrong, orientation_weight=weight)
        said.append(str(err.value))
    assert said[0] == said[1]
    train, held = right.subset(np.arange(30)), wrong.subset(np.arange(30, 40))
    with pytest.raises(DataError, match=cause) as err:
        calibrate(chain, train, validate=held)
    assert str(err.value).startswith(held.source)
    noisy = rot * Rotation.from_rotvec(rng.normal(0.0, 0.08, (40, 3)))
    res = calibrate(chain, write("noisy", noisy.as_euler("xyz")))
    note = "deg RMS of orientation error, far above geometric errors, and no usual mistake"
    assert any(note in w and "check the orientation columns" in w for w in res.warnings)


def test_one_bad_orientation_is_set_aside_like_one_bad_point(pose_campaign):
    chain, camp = pose_campaign
    quat = camp.measurements.quaternion.copy()
    quat[21] = Rotation.from_rotvec([0.0, 2.0, 0.0]).as_quat()  # one wrong reading
    res = calibrate(chain, dataclasses.replace(camp.measurements, quaternion=quat)).check()
    assert [(o.row, o.kind) for o in res.outliers] == [(22, "orientation")]
    assert res.data.m == camp.measurements.m - 1
    assert not any("far above" in w for w in res.warnings)  # the outlier explained it
    q = chain.random_configurations(30, 9)
    T = camp.truth.true_mdh.forward(q)
    err = res.points(q)[:, 0] - T[:, :3, 3]  # the measured point: the tool origin
    assert math.sqrt(np.mean(np.sum(err**2, axis=1))) < 1e-3


@pytest.mark.parametrize(
    ("cols", "taken"),
    [
        (["rotvec", "x", "y", "z"], "'x' is also a position column"),
        (["rpy", "roll", "pitch", "z"], "'z' is also a position column"),
        (["rotvec", "rx", "ry", "wrist_1_joint"], "'wrist_1_joint' is also a joint column"),
    ],
)
def test_orientation_columns_overlapping_others_are_a_usage_error(
    pose_campaign, tmp_path, cols, taken
):
    _, camp = pose_campaign
    rot = Rotation.from_quat(camp.measurements.quaternion)
    data = _pose_csv(tmp_path / "m.csv", camp, "rx,ry,rz", rot.as_rotvec())
    out = tmp_path / "o.urdf"
    argv = ["calibrate", "ur5", "--data", data, "--out", out, "--orientation", cols[0]]
    line = one_error(*run([*argv, "--orientation-columns", *cols[1:]])[::2])
    assert taken in line and "name other columns (--orientation-columns)" in line  # the option
    assert not out.exists()


def test_tree_rows_must_measure_every_tool_and_small_validation_sets_are_scored():
    tree = load_robot("bolt")
    data = simulate_tree(tree, 10, markers=MARKER, noise_mm=0.05, seed=1).measurements
    left = data.subset(np.array([t == "FL_FOOT" for t in data.tool]))
    with pytest.raises(DataError, match="no row measures the tool FR_FOOT"):
        calibrate_tree(tree, left)
    # held-out rows too few to register on their own (one row, one tool): scored, no error
    other = simulate_tree(tree, 3, markers=MARKER, noise_mm=0.05, seed=9).measurements
    res = calibrate_tree(tree, data, validate=other.subset(np.arange(1)))
    assert res.to_dict()["errors"]["held_out"]["registration"]["configs"] == 1


def test_validation_rows_measured_in_another_frame_stop_with_their_cause():
    """Rows shifted by 0.4 m (the tracker moved): each file registers well on its own."""
    chain = chain_of("ur5")
    camp = simulate(chain, configs=60, measure="position", marker=MARKER, seed=8, noise_mm=0.05)
    train, held = (
        camp.measurements.subset(np.arange(40)),
        camp.measurements.subset(np.arange(40, 60)),
    )
    assert calibrate(chain, train, validate=held).accepted
    shifted = dataclasses.replace(held, position=held.position + np.array([0.4, 0.0, 0.0]))
    with pytest.raises(DataError, match="another measurement frame"):
        calibrate(chain, train, validate=shifted)
    tree = load_robot("bolt")
    data = simulate_tree(tree, 30, markers=MARKER, noise_mm=0.05, seed=8).measurements
    train, held = data.subset(np.arange(40)), data.subset(np.arange(40, 60))
    shifted = dataclasses.replace(held, position=held.position + np.array([0.0, 0.4, 0.0]))
    with pytest.raises(DataError, match="another measurement frame"):
        calibrate_tree(tree, train, validate=shifted)


def test_tree_model_worse_on_held_out_rows_is_refused_with_its_report(tmp_path):
    """No geometric error and 2 mm of noise: the complete model can only overfit."""
    from calib.measurements.csvfile import measurements_csv

    tree = load_robot("bolt")
    camp = simulate_tree(tree, 20, markers=MARKER, error_mm=0, error_mrad=0, noise_mm=2, seed=0)
    data = tmp_path / "m.csv"
    data.write_text(measurements_csv(camp.measurements))
    out, report = tmp_path / "o.urdf", tmp_path / "r.json"
    argv = ["calibrate", "bolt", "--data", data, "--out", out, "--report", report]
    line = one_error(*run([*argv, "--holdout", "0.3", "--seed", "1"])[::2])
    assert line.startswith("calibration refused: the calibrated model's held-out errors")
    assert "worse than the registration's" in line
    rep = json.loads(report.read_text())
    assert not out.exists() and rep["accepted"] is False
    held = rep["validation"]
    assert held["calibrated"]["position_rms"] > held["registration"]["position_rms"]


def test_a_joint_column_holding_one_value_is_named_first():
    """A joint not logged (its column one value in every row) is named before any unit or
    order mistake is looked for: the registration's absurd error and the column."""
    chain = chain_of("ur5")
    data = simulate(chain, configs=30, measure="position", marker=MARKER, seed=2).measurements
    q = data.q.copy()
    q[:, 1] = 0.3  # shoulder_lift_joint not logged
    with pytest.raises(DataError, match=r"joint column shoulder_lift_joint holds one value"):
        calibrate(chain, dataclasses.replace(data, q=q))


GANTRY = """<robot name="gantry">
  <link name="base"/><link name="a"/><link name="b"/><link name="tool"/>
  <joint name="px" type="prismatic"><parent link="base"/><child link="a"/><axis xyz="1 0 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="py" type="prismatic"><parent link="a"/><child link="b"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="pz" type="prismatic"><parent link="b"/><child link="tool"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.5" effort="1" velocity="1"/></joint>
</robot>
"""


HELD = "held at its given value"
"""The note of a marker no posture separates from the instrument frame's translation."""


def gantry_rows(chain, m: int, markers, noise_mm: float = 0.0, pose: bool = False, seed=0):
    """Rows of ``markers`` ``(K, 3)`` [m] on the true robot of ``simulate`` (seeded), seen
    from a tracker placed by scipy's rotation, and the true points at any joints ``(m, K, 3)``."""
    campaign = simulate(chain, m, "pose" if pose else "position", seed=seed)
    q, forward = campaign.measurements.q, campaign.truth.true_mdh.forward
    R, t = Rotation.from_rotvec([0.1, -0.2, 0.3]).as_matrix(), np.array([1.0, 2.0, 0.5])

    def truth(q: np.ndarray) -> np.ndarray:
        T = forward(q)
        return (np.einsum("mij,kj->mki", T[:, :3, :3], markers) + T[:, None, :3, 3]) @ R.T + t

    noise = np.random.default_rng([seed, 7]).normal(size=(m, len(markers), 3))
    points = truth(q) + 1e-3 * noise_mm * noise
    turn = None if not pose else Rotation.from_matrix(R @ forward(q)[:, :3, :3]).as_quat()
    return Measurements(chain.joint_names, q, points.reshape(m, -1), turn), truth


@pytest.fixture(scope="module")
def gantry(tmp_path_factory):
    """The gantry's nominal chain (a URDF written to a temporary folder)."""
    urdf = tmp_path_factory.mktemp("gantry") / "gantry.urdf"
    urdf.write_text(GANTRY)
    return load_chain(urdf)


def test_a_gantry_is_calibrated_its_marker_held(gantry, tmp_path):
    """A gantry's tool never turns: its marker and the instrument frame's translation are one
    unknown at every posture. It was refused ("no posture separates them"); the marker is held
    at its given value, the frame absorbs it, the rest is fitted: the held-out rows are
    predicted exactly, by the result and by its URDF read by Pinocchio (the marker link)."""
    data, truth = gantry_rows(gantry, 40, [MARKER])
    result = calibrate(gantry, data, holdout=0.25)
    assert result.accepted, result.refusal
    assert any(HELD in w and "marker1 " in w for w in result.warnings)
    report = result.to_dict()
    assert any(HELD in w for w in report["warnings"])
    assert report["validation"]["calibrated"]["position_rms"] < 1e-9  # [m]
    names = {p["name"] for p in report["parameters"]}
    assert "frame.x" in names and not any(n.startswith("marker1") for n in names)
    result.write_urdf(tmp_path / "cal.urdf")
    model = pin.buildModelFromUrdf(str(tmp_path / "cal.urdf"))
    pdata, q = model.createData(), gantry.random_configurations(20, 5)
    tool = model.getFrameId(report["marker_links"][0])
    frame = np.array(report["measurement_to_base"]["matrix"])
    seen = []
    for row in q:
        pin.framesForwardKinematics(model, pdata, row)
        seen.append(frame[:3, :3] @ pdata.oMf[tool].translation + frame[:3, 3])
    assert np.max(np.abs(np.array(seen) - truth(q)[:, 0])) < 1e-9
    assert np.max(np.abs(result.points(q)[:, 0] - truth(q)[:, 0])) < 1e-9


def test_a_noisy_gantry_is_calibrated_no_worse_than_its_registration(gantry):
    """Noise 0.05 mm: accepted, held-out rows predicted as well as the registration or better."""
    data, _ = gantry_rows(gantry, 40, [MARKER], noise_mm=0.05, seed=3)
    result = calibrate(gantry, data, holdout=0.25, marker=(0.01, 0.0, 0.05))
    assert result.accepted, result.refusal
    assert any(HELD in w and "(0.01, 0, 0.05 m" in w for w in result.warnings)
    held = result.to_dict()["validation"]
    assert held["calibrated"]["position_rms"] <= held["registration"]["position_rms"]


def test_a_gantry_validation_file_of_three_rows_is_diagnosed(gantry):
    """Three validation rows give 9 equations, more than the 6 unknowns of their own
    registration once the marker is held: they are registered alone and their mistake (here
    positions in metres divided by 1000) is named, as four rows' is. The held coordinates
    were counted as unknowns (9 against 9): the rows were judged too few and only said to be
    far from the model."""
    data, _ = gantry_rows(gantry, 43, [MARKER])
    train, rows = data.subset(np.arange(40)), data.subset(np.arange(40, 43))
    wrong = Measurements(rows.joint_names, rows.q, rows.points.reshape(3, -1) / 1000.0)
    with pytest.raises(DataError, match="metres read as millimetres"):
        calibrate(gantry, train, validate=wrong)


def test_a_gantry_with_two_markers_holds_the_first_and_fits_the_other(gantry):
    """Two markers: the first is held (the frame absorbs it), the second's offset from it is
    determined and fitted: every point of every held-out row predicted exactly."""
    markers = np.array([MARKER, (-0.03, 0.04, 0.12)])
    data, truth = gantry_rows(gantry, 40, markers)
    result = calibrate(gantry, data, holdout=0.25)
    assert result.accepted, result.refusal
    assert any("marker1 held" in w for w in result.warnings)
    names = {p["name"] for p in result.to_dict()["parameters"]}
    assert {"marker2.x", "marker2.y", "marker2.z"} <= names and "marker1.x" not in names
    q = gantry.random_configurations(20, 5)
    assert np.max(np.abs(result.points(q) - truth(q))) < 1e-9


def test_a_gantry_measured_by_poses_is_calibrated(gantry):
    """Pose rows: the marker is held as with positions; the orientations are fitted."""
    data, truth = gantry_rows(gantry, 40, [MARKER], pose=True)
    result = calibrate(gantry, data, holdout=0.25)
    assert result.accepted, result.refusal
    assert any(HELD in w for w in result.warnings)
    q = gantry.random_configurations(20, 5)
    assert np.max(np.abs(result.points(q)[:, 0] - truth(q)[:, 0])) < 1e-9


SCARA = """<robot name="scara">
  <link name="base"/><link name="a"/><link name="b"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/>
    <origin xyz="0 0 0.4"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="b"/>
    <origin xyz="0.4 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
  <joint name="j3" type="prismatic"><parent link="b"/><child link="tool"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-0.3" upper="0" effort="1" velocity="1"/></joint>
</robot>
"""


def test_a_tool_turning_about_one_axis_holds_the_marker_along_it(tmp_path):
    """A SCARA's tool turns about its vertical axis only: the marker's height on it and the
    frame's are one unknown at every posture (it was refused); marker1.z alone is held."""
    urdf = tmp_path / "scara.urdf"
    urdf.write_text(SCARA)
    chain = load_chain(urdf)
    data, truth = gantry_rows(chain, 40, [MARKER])
    result = calibrate(chain, data, holdout=0.25, marker=(0.0, 0.0, 0.08))
    assert result.accepted, result.refusal
    assert any("marker1.z held at its given value (0.08 m" in w for w in result.warnings)
    names = {p["name"] for p in result.to_dict()["parameters"]}
    assert {"marker1.x", "marker1.y"} <= names and "marker1.z" not in names
    q = chain.random_configurations(20, 5)
    assert np.max(np.abs(result.points(q)[:, 0] - truth(q)[:, 0])) < 1e-9


def test_a_gantry_is_calibrated_on_the_command_line(tmp_path):
    """``calib simulate`` then ``calib calibrate`` on the gantry's URDF: exit 0, the URDF
    written, the note in its summary."""
    urdf, data, out = tmp_path / "gantry.urdf", tmp_path / "g.csv", tmp_path / "cal.urdf"
    urdf.write_text(GANTRY)
    code, _, err = run(["simulate", urdf, "--configs", 30, "--noise-mm", 0.02, "--out", data])
    assert code == 0, err
    code, text, err = run(["calibrate", urdf, "--data", data, "--holdout", 0.25, "--out", out])
    assert code == 0, err
    assert HELD in text + err and out.exists()


def test_analyze_markers_holds_what_calibrate_holds(tmp_path):
    """``calib analyze --markers``: the first marker's coordinates a calibration holds (all
    three on a gantry, its z on a SCARA) are counted as held, with calibrate's reason, not
    listed as identifiable; the second marker's offset from it is (it listed marker1's)."""
    for name, text, held in (("gantry", GANTRY, "marker1 "), ("scara", SCARA, "marker1.z ")):
        urdf = tmp_path / f"{name}.urdf"
        urdf.write_text(text)
        argv = ["analyze", urdf, "--markers", 2, "--measure", "pose", "--json"]
        code, out, err = run(argv)
        assert code == 0, err
        report = json.loads(out)
        assert report["n_held"] == (3 if name == "gantry" else 1)
        assert any(HELD in n and n.startswith(held) for n in report["notes"])
        assert "marker1.z" not in report["parameters"]
        assert {"marker2.x", "marker2.y", "marker2.z"} <= set(report["parameters"])
        code, out, err = run(argv[:-1])
        assert code == 0 and f"{held}{HELD}" in out, err


def test_a_tool_turning_a_few_microradians_is_refused_not_held(tmp_path):
    """A wrist joint limited to +-1e-6 rad turns the tool, a little: nothing is held (the
    robot's structure is not a still tool), and with noise the marker's height and the
    frame's are refused as no posture within the joint limits separates them (as the docs,
    docs/reference/errors.md and docs/howto/validate.md, say)."""
    wrist = """  <link name="w"/>
  <joint name="rx" type="revolute"><parent link="tool"/><child link="w"/><axis xyz="1 0 0"/>
    <origin xyz="0 0 -0.2"/><limit lower="-1e-6" upper="1e-6" effort="1" velocity="1"/></joint>
</robot>
"""
    turn = """<joint name="pz" type="revolute"><parent link="b"/><child link="tool"/>
    <axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>"""
    urdf = tmp_path / "tiny.urdf"
    text = GANTRY.replace(GANTRY[GANTRY.index('<joint name="pz"') :], turn + "\n" + wrist)
    urdf.write_text(text)
    chain = load_chain(urdf)
    assert chain.tool_frame == "w" and list(chain.sigma) == [1, 1, 0, 0]
    data, _ = gantry_rows(chain, 40, [MARKER], noise_mm=0.02)
    result = calibrate(chain, data)
    assert not result.accepted and not any(HELD in w for w in result.warnings)
    assert "frame.z and marker1.z" in result.refusal
    assert "no posture separates them" in result.refusal
    assert "cannot tell them apart" in result.refusal


GANTRY_TREE = GANTRY.replace(
    "</robot>",
    """  <link name="b2"/><link name="t2"/><link name="f1"/><link name="f2"/>
  <joint name="py2" type="prismatic"><parent link="a"/><child link="b2"/><axis xyz="0 1 0"/>
    <origin xyz="0 0.3 0"/><limit lower="0" upper="1" effort="1" velocity="1"/></joint>
  <joint name="pz2" type="prismatic"><parent link="b2"/><child link="t2"/><axis xyz="0 0 1"/>
    <limit lower="0" upper="0.5" effort="1" velocity="1"/></joint>
  <joint name="f1" type="fixed"><parent link="tool"/><child link="f1"/></joint>
  <joint name="f2" type="fixed"><parent link="t2"/><child link="f2"/></joint>
</robot>""",
)


def test_a_tree_of_tools_that_never_turn_holds_the_first_marker(tmp_path):
    """Two gantry heads measured by one tracker: no tool turns, so the shared frame's
    translation and both markers move together at every posture. The first tool's marker is
    held at its given value (a note says so), the second's offset is fitted; the held-out
    rows are predicted exactly. Both markers were fitted along that direction: delivered
    some 0.5 m from the tools (the truth: 0), 19 unknowns said determined."""
    urdf = tmp_path / "gantry_tree.urdf"
    urdf.write_text(GANTRY_TREE)
    tree = load_robot(urdf, tool=["f1", "f2"])
    data = simulate_tree(tree, 30, noise_mm=0.02, seed=0).measurements
    report = calibrate_tree(tree, data).to_dict()
    assert report["accepted"], report["refusal"]
    assert any(HELD in w and "f1: marker1 held" in w for w in report["warnings"])
    assert report["markers"]["f1"] == [0.0, 0.0, 0.0]
    assert np.max(np.abs(report["markers"]["f2"])) < 0.02  # [m] the truth 0, placements 1 mm
    exact = calibrate_tree(tree, simulate_tree(tree, 40, seed=1).measurements, holdout=0.25)
    assert exact.to_dict()["validation"]["calibrated"]["position_rms"] < 1e-9  # [m]
