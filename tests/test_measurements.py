"""Measurement campaigns: CSV round trip and validation, simulated campaigns, rotations,
atomic writing.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import chain_of, mdh_of
from scipy.spatial.transform import Rotation

from calib import (
    DataError,
    DataWarning,
    InvalidArgumentError,
    Measurements,
    load_chain,
    read_measurements,
    simulate,
    write_measurements,
)
from calib.core.fileio import json_text, write_files_atomic
from calib.identification.identifiability import analyze_model
from calib.identification.jacobian import measured_point
from calib.kinematics import so3
from calib.measurements.csvfile import measurements_csv, parse_measurements

MARKER = (0.05, 0.02, 0.1)


@pytest.fixture(scope="module")
def ur5_pose():
    return simulate(chain_of("ur5"), configs=12, measure="pose", seed=4, noise_mm=0.1)


def csv_lines(campaign) -> list[str]:
    return measurements_csv(campaign.measurements).splitlines()


# --- CSV round trip -------------------------------------------------------------------------


def test_csv_round_trip_is_exact(ur5_pose, tmp_path):
    path = tmp_path / "meas.csv"
    write_measurements(path, ur5_pose.measurements)
    back = read_measurements(path, chain_of("ur5"))
    data = ur5_pose.measurements
    assert back.measure == "pose" and back.source == str(path)
    assert np.array_equal(back.q, data.q)
    assert np.array_equal(back.position, data.position)
    assert np.allclose(back.quaternion, data.quaternion, atol=1e-15, rtol=0)


def test_csv_header_is_joints_then_xyz_then_quaternion(ur5_pose):
    header = csv_lines(ur5_pose)[0].split(",")
    assert header == [*chain_of("ur5").joint_names, "x", "y", "z", "qx", "qy", "qz", "qw"]
    position = simulate(chain_of("ur5"), configs=12, measure="position", marker=MARKER, seed=1)
    assert csv_lines(position)[0].split(",")[-3:] == ["x", "y", "z"]


def test_columns_in_any_order_blank_lines_and_bom(ur5_pose):
    lines = [line.split(",") for line in csv_lines(ur5_pose)]
    order = np.random.default_rng(0).permutation(len(lines[0]))
    shuffled = [",".join(row[i] for i in order) for row in lines]
    text = "\ufeff" + "\n".join([shuffled[0], "", *shuffled[1:], "", ""])
    back = parse_measurements(text.removeprefix("\ufeff"), chain_of("ur5"))
    assert np.array_equal(back.q, ur5_pose.measurements.q)
    assert np.array_equal(back.position, ur5_pose.measurements.position)


def test_quaternions_are_normalised_and_scalar_last(tmp_path):
    chain = chain_of("ur5")
    names = ",".join(chain.joint_names)
    # 90 degrees about z, scaled by 2: (0, 0, sin 45, cos 45) * 2.
    s = math.sqrt(2.0)
    (tmp_path / "m.csv").write_text(f"{names},x,y,z,qx,qy,qz,qw\n0,0,0,0,0,0,1,2,3,0,0,{s},{s}\n")
    data = read_measurements(tmp_path / "m.csv", chain)
    assert np.allclose(np.linalg.norm(data.quaternion, axis=1), 1.0)
    assert np.allclose(data.rotations[0], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-15)


def test_continuous_joints_are_unbounded():
    chain = chain_of("stanford")  # joint6 is continuous
    q = np.zeros(chain.n)
    q[5] = 10.0
    q[2] = 0.2  # the prismatic joint3 is limited to [0, 0.5]
    text = (
        ",".join([*chain.joint_names, "x", "y", "z"])
        + "\n"
        + ",".join([*(repr(float(v)) for v in q), "0", "0", "0"])
    )
    assert parse_measurements(text, chain).q[0, 5] == 10.0


SCARA = Path(__file__).parent / "data" / "scara.urdf"


def test_joints_without_urdf_limits_read_any_value(tmp_path):
    # a <limit> tag left out: calib samples +-0.1 m (prismatic) or a turn, but a reading
    # outside that range is no mistake; the limits the URDF gives are still checked
    text = SCARA.read_text()
    quill, wrist = '<limit lower="0" upper="0.2"', '<limit lower="-3" upper="3"'
    assert quill in text and wrist in text
    bare = tmp_path / "scara_no_limits.urdf"
    bare.write_text(text.replace(quill, "<limit").replace(wrist, "<limit"))
    row = ["0.5", "-1.0", "0.19", "4.0", "0.5", "0.1", "0.2"]  # j3 0.19 m, j4 4 rad
    header = ["j1", "j2", "j3", "j4", "x", "y", "z"]
    chain = load_chain(bare, "base_link", "tool0")
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)  # not even "past the URDF joint limits"
        q = parse_measurements(_text(chain, [row], header), chain).q
    assert q[0, 2] == 0.19 and q[0, 3] == 4.0
    limited = load_chain(SCARA, "base_link", "tool0")
    row[2] = "0.3"
    with pytest.raises(DataError, match=r"j3.*joint limits \[0, 0.2\] m"):
        parse_measurements(_text(limited, [row], header), limited)


# --- bad input --------------------------------------------------------------------------------


def _text(chain, rows: list[list[str]], header: list[str] | None = None) -> str:
    header = header or [*chain.joint_names, "x", "y", "z"]
    return "\n".join(",".join(r) for r in [header, *rows]) + "\n"


def _good_row(chain) -> list[str]:
    return ["0.1"] * chain.n + ["0.5", "0.1", "0.2"]


BAD_CASES = {
    "missing joint column": (
        lambda c: _text(c, [_good_row(c)[1:]], [*c.joint_names[1:], "x", "y", "z"]),
        1,
        "shoulder_pan_joint",
        "missing joint column",
    ),
    "another robot's file": (  # a Panda's campaign read for the UR5: no joint of it, not one
        lambda c: _text(
            c, [["0.1"] * 10], [f"panda_joint{i}" for i in range(1, 8)] + ["x", "y", "z"]
        ),
        1,
        None,
        "no joint column of ur5 base_link -> tool0 (its 6 joints: shoulder_pan_joint, ...); the "
        "file's columns: panda_joint1, panda_joint2, panda_joint3, panda_joint4, panda_joint5, "
        "panda_joint6, ...: a file of another robot or chain?",
    ),
    "number with an underscore": (
        lambda c: _text(c, [[*_good_row(c)[:6], "1_0", *_good_row(c)[7:]]]),
        2,
        "x",
        "not a number: '1_0'",
    ),
    "duplicate column": (
        lambda c: _text(c, [[*_good_row(c), "1"]], [*c.joint_names, "x", "y", "z", "x"]),
        1,
        "x",
        "duplicate column",
    ),
    "missing position column": (
        lambda c: _text(c, [_good_row(c)[:-1]], [*c.joint_names, "x", "y"]),
        1,
        "z",
        "missing position column",
    ),
    "partial quaternion": (
        lambda c: _text(
            c, [[*_good_row(c), "0", "0", "0"]], [*c.joint_names, "x", "y", "z", "qx", "qy", "qz"]
        ),
        1,
        "qw",
        "missing orientation column",
    ),
    "NaN cell": (  # one coordinate of a point missing, as NumPy writes it
        lambda c: _text(c, [_good_row(c), [*_good_row(c)[:7], "nan", "0.2"]]),
        3,
        "y",
        "empty cell: a marker not seen leaves all of x, y, z empty (or NaN), this row has 1 of "
        "them",
    ),
    "point not seen written NaN": (  # MATLAB's writematrix of a tracker's lost beam
        lambda c: _text(c, [_good_row(c), [*_good_row(c)[:6], "NaN", "NaN", "NaN"]]),
        3,
        None,
        "empty cells: this row measures no point: leave the row out (start it with #)",
    ),
    "joint written NaN": (
        lambda c: _text(c, [[*_good_row(c)[:3], " -NaN", *_good_row(c)[4:]]]),
        2,
        "wrist_1_joint",
        "'-NaN': a value not measured leaves the row out (start it with #)",
    ),
    "infinite cell": (
        lambda c: _text(c, [[*_good_row(c)[:2], "-inf", *_good_row(c)[3:]]]),
        2,
        "elbow_joint",
        "not a number: '-inf'",
    ),
    "empty cell": (
        lambda c: _text(c, [_good_row(c), _good_row(c), ["0.1", "", *_good_row(c)[2:]]]),
        4,
        "shoulder_lift_joint",
        "empty cell",
    ),
    "non-numeric text": (
        lambda c: _text(c, [[*_good_row(c)[:6], "12 mm", *_good_row(c)[7:]]]),
        2,
        "x",
        "not a number: '12 mm'",
    ),
    "short row": (
        lambda c: _text(c, [_good_row(c), _good_row(c)[:-1]]),
        3,
        None,
        "expected 9 cells, found 8",
    ),
    "absurd coordinate": (
        lambda c: _text(c, [_good_row(c), [*_good_row(c)[:6], "1e300", *_good_row(c)[7:]]]),
        3,
        "x",
        "not a plausible measurement",
    ),
    "coordinate beyond a kilometre": (
        lambda c: _text(c, [[*_good_row(c)[:8], "-1000.5"]]),
        2,
        "z",
        "not a plausible measurement",
    ),
    "joint outside its limits": (
        lambda c: _text(c, [_good_row(c), _good_row(c), ["0.1", "0.2", "3.5", *_good_row(c)[3:]]]),
        4,
        "elbow_joint",
        "outside the joint limits",
    ),
    "zero quaternion": (
        lambda c: _text(
            c,
            [[*_good_row(c), "0", "0", "0", "1"], [*_good_row(c), "0", "0", "0", "0"]],
            [*c.joint_names, "x", "y", "z", "qx", "qy", "qz", "qw"],
        ),
        3,
        None,
        "zero norm",
    ),
    "header only": (lambda c: _text(c, []), None, None, "no measurement rows"),
    "empty file": (lambda c: "\n\n", None, None, "empty file"),
}


@pytest.mark.parametrize("case", list(BAD_CASES))
def test_bad_csv_names_row_and_column(case, tmp_path):
    chain = chain_of("ur5")
    make, row, column, reason = BAD_CASES[case]
    path = tmp_path / "bad.csv"
    path.write_text(make(chain))
    with pytest.raises(DataError) as info:
        read_measurements(path, chain)
    err = info.value
    assert err.row == row and err.column == column
    assert reason in str(err) and str(path) in str(err)
    if row is not None:
        assert f"row {row}" in str(err)
    if column is not None:
        assert f"column '{column}'" in str(err)
    assert "\n" not in str(err)


def test_missing_joint_column_names_the_chain_that_needs_it(tmp_path):
    """A file for another chain of the robot: the error says which chain wanted the joint."""
    chain = chain_of("ur5")  # the catalog's base_link -> tool0 (calib list)
    path = tmp_path / "other_chain.csv"
    path.write_text(_text(chain, [_good_row(chain)[1:]], [*chain.joint_names[1:], "x", "y", "z"]))
    with pytest.raises(DataError, match=r"the chain base_link -> tool0 moves that joint"):
        read_measurements(path, chain)


def test_missing_and_unreadable_files(tmp_path):
    with pytest.raises(DataError, match="no such file"):
        read_measurements(tmp_path / "nope.csv", chain_of("ur5"))
    (tmp_path / "bin.csv").write_bytes(b"\xff\xfe\x00bad")
    with pytest.raises(DataError, match="cannot read"):
        read_measurements(tmp_path / "bin.csv", chain_of("ur5"))


def test_measurements_value_checks():
    names = ("a", "b")
    with pytest.raises(InvalidArgumentError, match=r"joint positions .* got \(3, 3\)"):
        Measurements(names, np.zeros((3, 3)), np.zeros((3, 3)))
    with pytest.raises(InvalidArgumentError, match=r"^positions .* got \(2, 3\)"):
        Measurements(names, np.zeros((3, 2)), np.zeros((2, 3)))
    with pytest.raises(InvalidArgumentError, match="NaN or infinity"):
        Measurements(names, np.zeros((1, 2)), [[0, np.nan, 0]])
    with pytest.raises(InvalidArgumentError, match="quaternions must be finite and non-zero"):
        Measurements(names, np.zeros((1, 2)), np.zeros((1, 3)), np.zeros((1, 4)))
    with pytest.raises(InvalidArgumentError, match="not a plausible measurement in metres"):
        Measurements(names, np.zeros((1, 2)), [[0, 1e300, 0]])
    data = Measurements(names, np.zeros((1, 2)), np.zeros((1, 3)), [[0, 0, 0, 2.0]])
    assert data.quaternion.tolist() == [[0, 0, 0, 1.0]] and not data.q.flags.writeable
    assert data.position_only().measure == "position"
    # Within the bound; a huge quaternion is a rotation too (its plain norm would overflow).
    data = Measurements(names, np.zeros((1, 2)), [[1e3, -1e3, 0]], [[0, 0, 1e300, 1e300]])
    assert np.allclose(data.quaternion, [[0, 0, math.sqrt(0.5), math.sqrt(0.5)]], atol=1e-15)


def test_absurd_coordinate_in_a_file_names_row_and_column(tmp_path):
    chain = chain_of("ur5")
    lines = csv_lines(simulate(chain, configs=12, measure="position", marker=MARKER, seed=1))
    cells = lines[3].split(",")
    cells[7] = "1e300"  # y
    path = tmp_path / "m.csv"
    path.write_text("\n".join([*lines[:3], ",".join(cells), *lines[4:]]) + "\n")
    with pytest.raises(DataError, match=r"row 4, column 'y'.*not a plausible measurement") as info:
        read_measurements(path, chain)
    assert info.value.row == 4 and info.value.column == "y"


# --- simulation -------------------------------------------------------------------------------


def test_simulation_is_the_true_robot_plus_noise():
    chain = chain_of("panda")
    clean = simulate(chain, configs=30, measure="pose", marker=MARKER, seed=2)
    noisy = simulate(chain, configs=30, measure="pose", marker=MARKER, seed=2, noise_mm=0.5)
    truth = clean.truth
    kin = truth.true_mdh.kinematics(clean.measurements.q)
    assert np.allclose(
        clean.measurements.position, measured_point(kin, np.array(MARKER)), atol=1e-15, rtol=0
    )
    assert np.allclose(clean.measurements.rotations, kin.R[:, -1], atol=1e-14, rtol=0)
    # Same seed: same configurations and errors, only the noise differs.
    assert np.array_equal(noisy.measurements.q, clean.measurements.q)
    assert np.array_equal(noisy.truth.errors, truth.errors)
    q = noisy.measurements.q
    assert np.all(q >= chain.lower) and np.all(q <= chain.upper)
    assert 0 < np.abs(noisy.measurements.position - clean.measurements.position).max() < 5e-3
    other = simulate(chain, configs=30, measure="pose", seed=3)
    assert not np.array_equal(other.truth.errors, truth.errors)


def test_configurations_are_those_analyze_draws():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=9, seed=11, measure="pose")
    assert np.array_equal(campaign.measurements.q, chain.random_configurations(9, 11))


def test_errors_follow_the_requested_scales():
    chain = chain_of("ur5")
    truth = simulate(chain, configs=6, error_mm=2.0, error_mrad=0.0, seed=5, measure="pose").truth
    rot = np.array([p.kind.is_rotation for p in truth.params.parameters])
    assert np.all(truth.errors[rot] == 0) and np.all(truth.errors[~rot] != 0)
    assert 0.5e-3 < np.std(truth.errors[~rot]) < 4e-3
    none = simulate(chain, configs=6, error_mm=0.0, error_mrad=0.0, seed=5, measure="pose").truth
    assert np.all(none.errors == 0)
    assert truth.params.label == "complete"
    assert (
        simulate(chain, configs=6, params="paper", seed=5, measure="pose").truth.params.label
        == "paper"
    )


def test_noise_statistics():
    chain = chain_of("ur5")
    m = 4000
    clean = simulate(chain, configs=m, error_mm=0, error_mrad=0, seed=8, measure="pose")
    noisy = simulate(
        chain,
        configs=m,
        error_mm=0,
        error_mrad=0,
        seed=8,
        noise_mm=0.2,
        noise_mrad=0.5,
        measure="pose",
    )
    dp = noisy.measurements.position - clean.measurements.position
    assert np.allclose(np.std(dp, axis=0), 0.2e-3, rtol=0.06)
    rel = noisy.measurements.rotations @ np.swapaxes(clean.measurements.rotations, 1, 2)
    dr = so3.rotation_vector(rel)
    assert np.allclose(np.std(dr, axis=0), 0.5e-3, rtol=0.06)
    default = simulate(chain, configs=6, seed=8, noise_mm=0.3, measure="pose").truth
    assert default.noise_mrad == 0.3


def test_truth_base_values_are_the_regrouped_errors():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=40, measure="position", marker=MARKER, seed=6)
    truth = campaign.truth
    res = analyze_model(
        mdh_of("ur5").idealized(), "complete", truth.measurement, campaign.measurements.q
    )
    assert truth.analysis.base == res.base
    idx = {n: i for i, n in enumerate(truth.params.names)}
    dx = truth.errors
    expected = dx[[idx[n] for n in res.base]] + res.B @ dx[[idx[n] for n in res.others]]
    assert np.allclose(truth.base_values, expected, atol=1e-15)
    record = json.loads(json_text(truth.to_dict()))
    assert record["robot"] == "ur5" and record["params"] == "complete"
    assert record["measure"] == "position" and record["marker"] == list(MARKER)
    assert record["seed"] == 6 and record["configs"] == 40
    assert set(record) >= {
        "error_mm",
        "error_mrad",
        "noise_mm",
        "noise_mrad",
        "parameter_names",
        "errors",
        "base_parameters",
        "regrouping",
        "true_mdh",
    }
    assert list(record["errors"]) == list(truth.params.names)
    assert list(record["base_parameters"]) == list(res.base)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"measure": "x,y"},
        {"configs": 0},
        {"configs": 2.5},
        {"seed": -1},
        {"seed": None},
        {"seed": True},
        {"seed": 1.5},
        {"seed": 2.0},
        {"seed": "3"},
        {"configs": None},
        {"configs": "5"},
        {"configs": np.float64(5)},
        {"error_mm": None},
        {"noise_mm": "0.1"},
        {"noise_mrad": True},
        {"error_mm": -1},
        {"noise_mm": float("nan")},
        {"marker": (1, 2)},
        {"params": "all"},
    ],
)
def test_simulate_rejects_bad_arguments(kwargs):
    with pytest.raises(InvalidArgumentError) as info:
        simulate(chain_of("ur5"), **{"configs": 5, **kwargs})
    (bad,) = kwargs.values()
    assert repr(bad) in str(info.value)  # refused for this argument, not for another


def test_simulate_accepts_numpy_integers():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=np.int64(6), seed=np.uint8(3), measure="pose")
    assert campaign.measurements.m == 6 and campaign.truth.seed == 3
    assert type(campaign.truth.seed) is int


# --- rotations --------------------------------------------------------------------------------


def test_rotations_match_scipy():
    R = Rotation.random(500, random_state=1)
    M = R.as_matrix()
    assert np.allclose(so3.quaternion_to_matrix(R.as_quat()), M, atol=1e-15)
    q = so3.matrix_to_quaternion(M)
    ref = R.as_quat()
    assert np.allclose(q, np.where(ref[:, 3:] < 0, -ref, ref), atol=1e-15)
    assert np.allclose(so3.rotation_vector(M), R.as_rotvec(), atol=1e-14)
    assert np.allclose(so3.rotation_matrix(R.as_rotvec()), M, atol=1e-15)
    tiny = np.random.default_rng(0).normal(0, 1e-9, (50, 3))
    assert np.allclose(so3.rotation_vector(so3.rotation_matrix(tiny)), tiny, atol=1e-22, rtol=1e-9)
    half_turn = so3.rotation_vector(so3.rotation_matrix([[math.pi, 0, 0], [0, 0, -math.pi]]))
    assert np.allclose(np.abs(half_turn), [[math.pi, 0, 0], [0, 0, math.pi]])


def test_inverse_right_jacobian_against_finite_differences():
    rng = np.random.default_rng(3)
    for phi in [rng.normal(0, 0.7, 3), rng.normal(0, 1e-6, 3), np.zeros(3)]:
        Jinv = so3.inverse_right_jacobian(phi[None])[0]
        h = 1e-6
        cols = []
        for i in range(3):
            e = np.zeros(3)
            e[i] = h
            plus = so3.rotation_vector(so3.rotation_matrix(phi) @ so3.rotation_matrix(e))
            minus = so3.rotation_vector(so3.rotation_matrix(phi) @ so3.rotation_matrix(-e))
            cols.append((plus - minus) / (2 * h))
        assert np.allclose(np.array(cols).T, Jinv, atol=1e-8)


# --- atomic writing ---------------------------------------------------------------------------


def test_atomic_write_leaves_nothing_behind_on_failure(tmp_path, monkeypatch, ur5_pose):
    import calib.core.fileio

    def broken(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(calib.core.fileio.os, "replace", broken)
    target = tmp_path / "meas.csv"
    with pytest.raises(OSError):
        write_measurements(target, ur5_pose.measurements)
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_keeps_the_old_file_when_a_write_fails(tmp_path):
    old = tmp_path / "a.txt"
    old.write_text("old")

    class Unwritable:  # not str/bytes: fails while staging the second file
        pass

    with pytest.raises(TypeError):
        write_files_atomic({old: "new", tmp_path / "b.txt": Unwritable()})
    assert old.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt"]
    write_files_atomic({old: "new", tmp_path / "b.txt": b"bytes"})
    assert old.read_text() == "new" and (tmp_path / "b.txt").read_bytes() == b"bytes"
    assert not any(Path(p).name.endswith(".tmp") for p in os.listdir(tmp_path))


def test_tool_column_names_each_rows_tool_and_survives_a_round_trip():

    chain = chain_of("ur5")
    data = simulate(chain, configs=6, measure="position", seed=1).measurements
    named = dataclasses.replace(data, tool=(chain.tool_frame,) * data.m)
    text = measurements_csv(named)
    assert text.splitlines()[0].endswith(",tool")
    back = parse_measurements(text, chain)
    assert back.tool == named.tool and np.array_equal(back.position, data.position)
    assert back.subset(np.array([0, 2])).tool == (chain.tool_frame,) * 2
    assert back.tools == (chain.tool_frame,)
    wrong = text.replace(f",{chain.tool_frame}\n", ",left_hand\n", 1)
    with pytest.raises(DataError, match=r"row 2, column 'tool'\): unknown tool 'left_hand'"):
        parse_measurements(wrong, chain)
    empty = text.replace(f",{chain.tool_frame}\n", ",\n", 1)
    with pytest.raises(DataError, match=r"row 2, column 'tool'\): empty cell"):
        parse_measurements(empty, chain)


CLASH_URDF = """<?xml version="1.0"?>
<robot name="clash">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <link name="tip"/>
  <joint name="x" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="y" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0 0.05 0.2"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="z" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="qw" type="revolute"><parent link="l3"/><child link="l4"/>
    <origin xyz="0.25 0 0.02"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="fix" type="fixed"><parent link="l4"/><child link="tip"/>
    <origin xyz="0.1 0.02 0.03"/></joint>
</robot>
"""


def test_joints_named_like_measurement_columns_round_trip(tmp_path):
    """Joints x, y, z, qw: simulate writes a CSV that reads back to the same numbers.

    The file is also read with the csv module (not calib's reader) to check the rule: a joint
    whose name is one of the file's measurement columns is written ``joint:NAME``.
    """
    import csv

    urdf = tmp_path / "clash.urdf"
    urdf.write_text(CLASH_URDF)
    chain = load_chain(urdf)
    assert chain.joint_names == ("x", "y", "z", "qw")
    data = simulate(chain, configs=9, measure="pose", seed=2, noise_mm=0.1).measurements
    path = tmp_path / "m.csv"
    write_measurements(path, data)
    rows = list(csv.reader(path.read_text().splitlines()))
    header = rows[0]
    assert len(set(header)) == len(header)  # no duplicate column
    assert header == ["x", "y", "z", "joint:qw", "x1", "y1", "z1", "qx", "qy", "qz", "qw"]
    table = np.array(rows[1:], dtype=float)
    np.testing.assert_array_equal(table[:, 3], data.q[:, 3])  # joint:qw is the joint
    np.testing.assert_array_equal(table[:, 10], data.quaternion[:, 3])  # qw the quaternion
    back = read_measurements(path, chain)
    np.testing.assert_array_equal(back.q, data.q)
    np.testing.assert_array_equal(back.position, data.position)
    np.testing.assert_allclose(back.quaternion, data.quaternion, rtol=0, atol=1e-15)


def test_joint_prefix_is_optional_and_decides_the_plain_column(tmp_path):
    """Without ``joint:qw`` a plain ``qw`` is the joint; with it, ``qw`` is the quaternion's."""
    urdf = tmp_path / "clash.urdf"
    urdf.write_text(CLASH_URDF)
    chain = load_chain(urdf)
    plain = parse_measurements("x,y,z,qw,x1,y1,z1\n0.1,0.2,0.3,0.4,1,2,3\n", chain)
    np.testing.assert_array_equal(plain.q, [[0.1, 0.2, 0.3, 0.4]])
    assert plain.quaternion is None
    both = parse_measurements(
        "joint:x,joint:y,joint:z,joint:qw,x,y,z,qw,qx,qy,qz\n0.1,0.2,0.3,0.4,1,2,3,1,0,0,0\n",
        chain,
    )
    np.testing.assert_array_equal(both.q, [[0.1, 0.2, 0.3, 0.4]])
    np.testing.assert_array_equal(both.position, [[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(both.quaternion, [[0.0, 0.0, 0.0, 1.0]])


def test_cli_simulate_then_calibrate_with_clashing_joint_names(tmp_path, monkeypatch, capsys):
    """`calib simulate` then `calib calibrate` on joints x, y, z, qw: both exit 0 and the
    calibrated URDF is written (the CSV used to be refused: duplicate column 'qw')."""
    from calib.cli.commands import main

    monkeypatch.chdir(tmp_path)
    Path("clash.urdf").write_text(CLASH_URDF)
    assert main(["simulate", "clash.urdf", "--out", "m.csv", "--measure", "pose"]) == 0
    code = main(["calibrate", "clash.urdf", "--data", "m.csv", "--out", "c.urdf"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "duplicate" not in err
    assert Path("c.urdf").stat().st_size > 0


def test_ignored_columns_that_may_be_an_orientation_say_how_to_read_them(tmp_path):
    """The UR10 data's phix1, phiy1, phiz1 (roll-pitch-yaw) were ignored without a way out; an
    IMU's xsens_rx, xsens_ry, xsens_rz got none (the hint read a name's first x alone)."""
    chain = chain_of("ur5")
    names = ",".join(chain.joint_names)
    (tmp_path / "m.csv").write_text(f"{names},x,y,z,phix,phiy,phiz\n0,0,0,0,0,0,1,2,3,0,0,0\n")
    hint = r"phix, phiy, phiz; .* --orientation rpy --orientation-columns phix phiy phiz"
    with pytest.warns(DataWarning, match=hint):
        read_measurements(tmp_path / "m.csv", chain)
    (tmp_path / "s.csv").write_text(f"{names},x,y,z,stamp\n0,0,0,0,0,0,1,2,3,7\n")
    with pytest.warns(DataWarning, match=r"or tool\): stamp$"):  # one column: no hint
        read_measurements(tmp_path / "s.csv", chain)
    (tmp_path / "i.csv").write_text(f"{names},x,y,z,xsens_rx,xsens_ry,xsens_rz\n{'0,' * 11}0\n")
    imu = r"--orientation-columns xsens_rx xsens_ry xsens_rz \(Python"  # not the brand's x
    with pytest.warns(DataWarning, match=imu):
        read_measurements(tmp_path / "i.csv", chain)


def test_ignored_columns_no_axes_name_get_no_orientation_hint(tmp_path):
    """The TIAGo data's bookkeeping columns (the quickstart's first calibration) were offered
    as an orientation: --orientation-columns shipped_row t_start_robot t_end_robot."""
    chain = chain_of("ur5")
    names = ",".join(chain.joint_names)
    log = "shipped_row,t_start_robot,t_end_robot,marker_std_mm"
    (tmp_path / "m.csv").write_text(f"{names},x,y,z,{log}\n0,0,0,0,0,0,1,2,3,4,5,6,7\n")
    with pytest.warns(DataWarning, match=r"or tool\): shipped_row, .*, marker_std_mm$"):
        read_measurements(tmp_path / "m.csv", chain)
