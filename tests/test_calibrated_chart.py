"""The report's calibrated MDH rows are in the nominal's chart: comparable row by row.

A URDF's pitch joint after a yaw one has a nominal offset of exactly 90 degrees, where the MDH
conversion's choice of x axis (theta in (-90, 90]) turns: a calibrated robot a milliradian past
it came out with theta 180 degrees away and alpha, d of the other sign from there on. The
independent routes: Pinocchio's forward kinematics of the URDF, against the documented MDH
product of the rows computed here with NumPy; the nominal rows are the reference.
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest

from calib import calibrate, from_chain, load_chain, simulate_contacts
from calib.cli import main
from calib.kinematics.mdh import in_chart_of

ORIGINS = (  # name, xyz, axis, lower, upper: a 6-axis arm, its pitch joints about y
    ("yaw", "0 0 0.4", "0 0 1", -2.9, 2.9),
    ("pitch", "0.15 0 0.2", "0 1 0", -1.7, 1.9),
    ("elbow", "0 0 0.6", "0 1 0", -2.4, 1.3),
    ("roll", "0.25 0 0.12", "1 0 0", -3.1, 3.1),
    ("bend", "0.35 0 0", "0 1 0", -2.0, 2.0),
    ("twist", "0.09 0 0", "1 0 0", -6.0, 6.0),
)


MOVED = {"elbow": ("0.0006 0 0.6", "0.004 0 0")}
"""The real robot's elbow origin: 0.6 mm forward turns the pitch joint's offset 1 mrad past
90 degrees (and a roll of 4 mrad)."""


def arm_urdf(path, moved: dict | None = None):
    """The arm, the origins of ``moved`` (joint -> xyz, rpy) edited."""
    links = ["<link name='l0'/>"]
    for k, (name, nominal_xyz, axis, lo, hi) in enumerate(ORIGINS, start=1):
        xyz, rpy = (moved or {}).get(name, (nominal_xyz, "0 0 0"))
        links.append(
            f"<link name='l{k}'/><joint name='{name}' type='revolute'><parent link='l{k - 1}'/>"
            f"<child link='l{k}'/><origin xyz='{xyz}' rpy='{rpy}'/>"
            f"<axis xyz='{axis}'/><limit lower='{lo}' upper='{hi}' effort='1' velocity='1'/>"
            "</joint>"
        )
    links.append(
        "<link name='tcp'/><joint name='tcp_joint' type='fixed'><parent link='l6'/>"
        "<child link='tcp'/><origin xyz='0.05 0.03 0.12' rpy='0 1.5707963267948966 0'/></joint>"
    )
    path.write_text(f"<robot name='arm'>{''.join(links)}</robot>")
    return path


def mdh_tool(rows: list[dict], q: np.ndarray) -> np.ndarray:
    """The tool frame of the MDH rows at ``q`` (module docstring of calib.kinematics.mdh)."""

    def rot(axis, a):
        c, s = np.cos(a), np.sin(a)
        i, j = [(1, 2), (2, 0), (0, 1)][axis]
        R = np.eye(4)
        R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
        return R

    def move(axis, v):
        T = np.eye(4)
        T[axis, 3] = v
        return T

    T, joint = np.eye(4), 0
    for row in rows:
        angle = row["theta"]
        if row["sigma"] == 0:
            angle, joint = angle + row["sign"] * q[joint], joint + 1
        T = T @ move(1, row["y"]) @ rot(1, row["beta"]) @ rot(0, row["alpha"])
        T = T @ move(0, row["d"]) @ rot(2, angle) @ move(2, row["r"])
    return T


def pin_tool(urdf, frame: str, q: np.ndarray) -> np.ndarray:
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    return data.oMf[model.getFrameId(frame)].homogeneous


def test_a_robot_past_the_nominal_90_degrees_is_charted_as_the_nominal(tmp_path):
    nominal = from_chain(load_chain(arm_urdf(tmp_path / "a.urdf"), "l0", "tcp"))
    path = arm_urdf(tmp_path / "b.urdf", MOVED)
    moved = from_chain(load_chain(path, "l0", "tcp"))
    assert nominal.theta[2] == pytest.approx(np.pi / 2)  # the boundary
    assert moved.theta[2] == pytest.approx(-np.pi / 2 + 1e-3, abs=1e-6)  # turned: x_2 the other way
    charted = in_chart_of(moved, nominal)
    rows, reference = charted.rows(), nominal.rows()
    for row, ref in zip(rows, reference, strict=True):
        for key in ("beta", "alpha", "d", "theta", "r", "y"):
            assert abs(row[key] - ref[key]) < 5e-3, (row["name"], key)
    assert charted.theta[2] == pytest.approx(np.pi / 2 + 1e-3, abs=1e-6)
    rng = np.random.default_rng(51)
    for q in rng.uniform(-1.5, 1.5, (20, 6)):  # the same robot: Pinocchio's kinematics
        assert np.allclose(mdh_tool(rows, q), pin_tool(path, "tcp", q), atol=1e-12)
    assert in_chart_of(nominal, nominal) is nominal


def test_parallel_axes_tilted_past_the_tolerance_keep_the_nominal_beta_row(tmp_path):
    """The elbow's axis tilted 15 mrad from the pitch joint's (PARALLEL_TOL 10 mrad): converted
    afresh, along a common normal some 40 m away; in the nominal's chart, with its beta row."""
    nominal = from_chain(load_chain(arm_urdf(tmp_path / "a.urdf"), "l0", "tcp"))
    path = arm_urdf(tmp_path / "b.urdf", {"elbow": ("0.0006 0 0.6", "0.015 0 0")})
    moved = from_chain(load_chain(path, "l0", "tcp"))
    assert nominal.parallel[3] and not moved.parallel[3]
    assert max(abs(moved.r[2]), abs(moved.r[3])) > 10.0  # metres: the far common normal
    charted = in_chart_of(moved, nominal)
    assert charted.parallel[3] and charted.beta[3] == pytest.approx(-0.015, abs=1e-6)
    rows = charted.rows()
    for row, ref in zip(rows, nominal.rows(), strict=True):
        for key in ("beta", "alpha", "d", "theta", "r", "y"):
            assert abs(row[key] - ref[key]) < 0.02, (row["name"], key)
    rng = np.random.default_rng(52)
    for q in rng.uniform(-1.5, 1.5, (20, 6)):
        assert np.allclose(mdh_tool(rows, q), pin_tool(path, "tcp", q), atol=1e-12)


def test_the_report_rows_compare_with_the_nominal_and_place_the_written_tool(tmp_path):
    """Calibrated from the moved arm's exact points (Pinocchio): the report's mdh_calibrated
    row by row within 5 mrad / 5 mm of mdh_nominal, and the written URDF's tool frame."""
    nominal, real = arm_urdf(tmp_path / "a.urdf"), tmp_path / "real.urdf"
    arm_urdf(real, MOVED)
    rng = np.random.default_rng(7)
    q = rng.uniform([o[3] for o in ORIGINS], [o[4] for o in ORIGINS], (40, 6))
    names = [o[0] for o in ORIGINS]
    lines = [",".join([*names, "x", "y", "z"])]
    for qi in q:
        p = pin_tool(real, "tcp", qi)[:3, 3]
        lines.append(",".join(repr(float(v)) for v in [*qi, *p]))
    data, out, report = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    data.write_text("\n".join(lines) + "\n")
    argv = ["calibrate", str(nominal), "--base", "l0", "--tool", "tcp", "--data", str(data)]
    assert main([*argv, "--params", "complete", "--out", str(out), "--report", str(report)]) == 0
    model = json.loads(report.read_text())["model"]
    for row, ref in zip(model["mdh_calibrated"], model["mdh_nominal"], strict=True):
        for key in ("beta", "alpha", "d", "theta", "r", "y"):
            assert abs(row[key] - ref[key]) < 5e-3, (row["name"], key)
    for qi in q[:10]:
        assert np.allclose(mdh_tool(model["mdh_calibrated"], qi), pin_tool(out, "tcp", qi))


def test_a_touching_chain_report_rows_compare_with_the_nominal(tmp_path):
    """Touches of three planes by the moved arm (simulated on its URDF, no error added): the
    contact report's mdh_calibrated row by row within 5 mrad / 5 mm of mdh_nominal, and the
    rows place the written URDF's tool frame (Pinocchio)."""
    nominal, real = arm_urdf(tmp_path / "a.urdf"), arm_urdf(tmp_path / "real.urdf", MOVED)
    touches = simulate_contacts(
        load_chain(real, "l0", "tcp"), 60, "plane", contacts=3, error_mm=0, error_mrad=0, seed=1
    )
    result = calibrate(load_chain(nominal, "l0", "tcp"), touches.data, params="complete")
    model = result.to_dict()["model"]
    for row, ref in zip(model["mdh_calibrated"], model["mdh_nominal"], strict=True):
        for key in ("beta", "alpha", "d", "theta", "r", "y"):
            assert abs(row[key] - ref[key]) < 5e-3, (row["name"], key)
    out = tmp_path / "cal.urdf"
    result.write(out)
    for qi in touches.data.q[:10]:
        assert np.allclose(mdh_tool(model["mdh_calibrated"], qi), pin_tool(out, "tcp", qi))
