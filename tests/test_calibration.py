"""Calibration: the error model, registration, selection, checks, and the real data sets.

Every expected value comes from an independent route: the simulated truth's forward
kinematics, finite differences, brute-force refits, scipy's rotations, or real held-out
measurements.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import chain_of
from scipy.spatial.transform import Rotation

from calib import (
    CalibrationRefusedError,
    Columns,
    DataError,
    DataWarning,
    Measurements,
    calibrate,
    load_chain,
    read_measurements,
    simulate,
)
from calib.calibration.model import ErrorModel, selection_lift
from calib.calibration.registration import register, rigid_fit
from calib.calibration.selection import block_loo
from calib.calibration.solve import Problem
from calib.cli import main
from calib.measurements import measurements_csv
from calib.parameters import complete_parameters

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata"
MARKER = (0.05, 0.02, 0.1)


def moved(data: Measurements, T: np.ndarray) -> Measurements:
    """The same measurements seen from another instrument frame (points and orientations)."""
    pts = data.points @ T[:3, :3].T + T[:3, 3]
    quat = None
    if data.quaternion is not None:
        quat = Rotation.from_matrix(T[:3, :3] @ data.rotations).as_quat()
    return dataclasses.replace(data, position=pts.reshape(data.m, -1), quaternion=quat)


def transform(yaw: float, xyz) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("zyx", [yaw, 0.2, -0.1]).as_matrix()
    T[:3, 3] = xyz
    return T


def true_points(campaign, q, marker=MARKER) -> np.ndarray:
    T = campaign.truth.true_mdh.forward(q)
    return T[:, :3, :3] @ np.asarray(marker) + T[:, :3, 3]


# --- the error model ------------------------------------------------------------------------


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_jacobian_matches_finite_differences(measure):
    chain = chain_of("panda")
    nominal = calibrate.__globals__["from_chain"](chain)
    data = simulate(chain, configs=15, measure=measure, seed=3, marker=MARKER).measurements
    start = register(nominal, data.q, data.points, data.rotations)
    pset = complete_parameters(nominal)
    model = ErrorModel(
        pset, pset.names, selection_lift(pset, pset.names), (0, 3, 6), pose=measure == "pose"
    )
    torque = np.random.default_rng(0).normal(size=data.q.shape)
    problem = Problem(model, start, data, torque, 0.7)
    x = 1e-2 * np.random.default_rng(1).normal(size=model.size())
    J = problem.data_jac(x)
    h = 1e-7
    fd = np.column_stack(
        [
            (problem.data_rows(x + h * e) - problem.data_rows(x - h * e)) / (2 * h)
            for e in np.eye(model.size())
        ]
    )
    assert np.abs(J - fd).max() < 1e-6 * max(1.0, np.abs(J).max())


def test_rigid_fit_recovers_a_known_motion():
    rng = np.random.default_rng(5)
    A = rng.normal(size=(30, 3))
    R = Rotation.random(random_state=2).as_matrix()
    t = np.array([3.0, -1.0, 0.5])
    R_hat, t_hat = rigid_fit(A, A @ R.T + t)
    assert np.allclose(R_hat, R, atol=1e-12) and np.allclose(t_hat, t, atol=1e-12)


def test_block_loo_equals_refits_without_each_configuration():
    rng = np.random.default_rng(0)
    m, rows, p = 12, 3, 4
    A, e = rng.normal(size=(m * rows, p)), rng.normal(size=m * rows)
    sse = 0.0
    for i in range(m):
        keep = np.ones(m * rows, dtype=bool)
        keep[i * rows : (i + 1) * rows] = False
        x = np.linalg.lstsq(A[keep], e[keep], rcond=None)[0]
        sse += float(np.sum((e[~keep] - A[~keep] @ x) ** 2))
    assert np.isclose(block_loo(A, e, rows), np.sqrt(sse / (m * rows / 3)), rtol=1e-10)
    lam = np.array([0.0, 0.5, 0.5, 2.0])
    sse = 0.0
    for i in range(m):
        keep = np.ones(m * rows, dtype=bool)
        keep[i * rows : (i + 1) * rows] = False
        x = np.linalg.solve(A[keep].T @ A[keep] + np.diag(lam), A[keep].T @ e[keep])
        sse += float(np.sum((e[~keep] - A[~keep] @ x) ** 2))
    assert np.isclose(block_loo(A, e, rows, lam), np.sqrt(sse / (m * rows / 3)), rtol=1e-10)


def overfitting_campaign(chain):
    """No geometric error and 2 mm noise: any model beyond the registration overfits."""
    return simulate(
        chain,
        configs=30,
        measure="position",
        marker=MARKER,
        seed=5,
        noise_mm=2.0,
        error_mm=0.0,
        error_mrad=0.0,
    )


# --- simulated campaigns --------------------------------------------------------------------


@pytest.mark.parametrize("robot", ["ur5", "panda"])
@pytest.mark.parametrize("measure", ["position", "pose"])
def test_noise_free_complete_fit_reproduces_the_true_robot(robot, measure):
    chain = chain_of(robot)
    campaign = simulate(chain, configs=60, measure=measure, marker=MARKER, seed=4)
    res = calibrate(chain, campaign.measurements, MARKER, "complete").check()
    q = chain.random_configurations(100, 99)
    assert np.abs(res.points(q)[:, 0] - true_points(campaign, q)).max() < 1e-9
    if measure == "pose":
        truth = campaign.truth.true_mdh.forward(q)[:, :3, :3]
        _, rot = res.state.predict(q)
        assert np.abs(rot - truth).max() < 1e-9


@pytest.mark.parametrize("yaw_deg", [0, 45, 90, 135, 180])
def test_any_frame_rotation_and_distance_converges_with_default_options(yaw_deg):
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=60, measure="position", marker=MARKER, seed=1, noise_mm=0.05)
    T = transform(np.deg2rad(yaw_deg), [3.0, 0.5, -0.4])
    res = calibrate(chain, moved(campaign.measurements, T)).check()
    assert res.iterations < 20
    q = chain.random_configurations(50, 8)
    err = res.points(q)[:, 0] - (true_points(campaign, q) @ T[:3, :3].T + T[:3, 3])
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.5e-3


def test_paper_level_with_a_far_frame_gives_the_right_model():
    """The paper set has no beta1/y1: the registration carries the frame instead."""
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=80, measure="pose", seed=2)
    T = transform(0.3, [0.8, 0.0, 0.1])
    res = calibrate(chain, moved(campaign.measurements, T), params="paper").check()
    q = chain.random_configurations(50, 8)
    truth = campaign.truth.true_mdh.forward(q)[:, :3, 3] @ T[:3, :3].T + T[:3, 3]
    assert np.abs(res.points(q)[:, 0] - truth).max() < 1e-6


def test_several_markers_are_each_identified():
    chain = chain_of("panda")
    markers = np.array([[0.05, 0.02, 0.1], [-0.04, 0.06, 0.12]])
    a = simulate(chain, configs=40, measure="position", marker=markers[0], seed=6, error_mm=0)
    b = simulate(chain, configs=40, measure="position", marker=markers[1], seed=6, error_mm=0)
    assert np.array_equal(a.measurements.q, b.measurements.q)
    data = dataclasses.replace(
        a.measurements, position=np.hstack([a.measurements.position, b.measurements.position])
    )
    res = calibrate(chain, data, params="frames").check()
    # error_mm = 0 but 1 mrad angle errors: the fitted markers are close, the points exact.
    assert res.state.n_markers == 2
    assert np.abs(res.state.markers - markers).max() < 5e-3
    assert res.after.position_rms < 5e-3


def test_an_outlier_row_is_listed_and_set_aside():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=60, measure="position", marker=MARKER, seed=3, noise_mm=0.1)
    pos = campaign.measurements.position.copy()
    pos[17, 0] += 0.05  # 50 mm
    data = dataclasses.replace(campaign.measurements, position=pos)
    res = calibrate(chain, data, params="complete").check()
    assert [o.row for o in res.outliers] == [18]
    assert res.data.m == 59
    q = chain.random_configurations(50, 8)
    err = res.points(q)[:, 0] - true_points(campaign, q)
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.3e-3


def test_swapped_joint_columns_are_named():
    chain = chain_of("ur5")
    data = simulate(chain, configs=50, measure="position", marker=MARKER, seed=3).measurements
    q = data.q.copy()
    q[:, [3, 4]] = q[:, [4, 3]]  # both within +-2 pi: the limits cannot tell
    with pytest.raises(DataError, match="wrist_1_joint and wrist_2_joint swapped"):
        calibrate(chain, dataclasses.replace(data, q=q))


def test_scalar_first_quaternions_are_named():
    chain = chain_of("ur5")
    data = simulate(chain, configs=50, measure="pose", seed=3).measurements
    wxyz = data.quaternion[:, [3, 0, 1, 2]]  # written scalar first in scalar-last columns
    with pytest.raises(DataError, match="quaternions written w, x, y, z"):
        calibrate(chain, dataclasses.replace(data, quaternion=wxyz))


def test_millimetres_are_named_and_units_mm_reads_them(tmp_path):
    chain = chain_of("ur5")
    data = simulate(chain, configs=40, measure="position", marker=MARKER, seed=3).measurements
    mm = dataclasses.replace(data, position=data.position * 1e3)
    with pytest.raises(DataError, match="millimetres"):
        calibrate(chain, mm)
    path = tmp_path / "mm.csv"
    path.write_text(measurements_csv(mm))
    back = read_measurements(path, chain, Columns(units="mm"))
    assert np.allclose(back.position, data.position, rtol=1e-15, atol=1e-15)


def test_holdout_reports_validation_and_refuses_a_worse_model():
    chain = chain_of("ur5")
    campaign = overfitting_campaign(chain)
    res = calibrate(chain, campaign.measurements, params="complete", holdout=0.3, seed=1)
    assert res.validation is not None and res.validation.registration.configs == 9
    # Nothing to calibrate (no geometric error) and 2 mm noise: the complete model overfits.
    assert res.validation.calibrated.position_rms > res.validation.registration.position_rms
    assert not res.accepted and "held-out" in res.refusal
    with pytest.raises(CalibrationRefusedError):
        res.check()


# --- measurement files ----------------------------------------------------------------------


def test_orientation_formats_read_the_same_rotation(tmp_path):
    chain = chain_of("ur5")
    data = simulate(chain, configs=5, measure="pose", seed=1).measurements
    rot = Rotation.from_quat(data.quaternion)
    joints = ",".join(chain.joint_names)
    cases = {
        "rotvec": ("rx,ry,rz", rot.as_rotvec()),
        "rpy": ("roll,pitch,yaw", rot.as_euler("xyz")),  # extrinsic xyz = Rz Ry Rx
        "quat-wxyz": ("a,b,c,d", rot.as_quat(scalar_first=True)),
    }
    for fmt, (names, values) in cases.items():
        lines = [f"{joints},x,y,z,{names}"]
        lines += [
            ",".join(repr(float(v_)) for v_ in [*q, *p, *v])
            for q, p, v in zip(data.q, data.position, values, strict=True)
        ]
        path = tmp_path / f"{fmt}.csv"
        path.write_text("\n".join(lines) + "\n")
        cols = Columns(fmt, tuple(names.split(",")) if fmt == "quat-wxyz" else None)
        back = read_measurements(path, chain, cols)
        assert np.allclose(back.rotations, rot.as_matrix(), atol=1e-12), fmt


def test_limits_margin_warns_and_far_outside_names_row_and_column(tmp_path):
    chain = chain_of("panda")  # finite limits on every joint
    data = simulate(chain, configs=4, measure="position", seed=1).measurements
    q = data.q.copy()
    q[1, 3] = chain.upper[3] + 0.05
    path = tmp_path / "m.csv"
    path.write_text(measurements_csv(dataclasses.replace(data, q=q)))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrate_data = read_measurements(path, chain)
        from calib.measurements import check_against_chain

        check_against_chain(calibrate_data, chain)
    assert any(
        issubclass(w.category, DataWarning) and "past the URDF joint limits" in str(w.message)
        for w in caught
    )
    q[2, 4] = chain.lower[4] - 1.0
    path.write_text(measurements_csv(dataclasses.replace(data, q=q)))
    with pytest.raises(DataError) as info:
        read_measurements(path, chain)
    assert info.value.row == 4 and info.value.column == chain.joint_names[4]


def test_joint_named_like_a_measured_column_round_trips(tmp_path):
    data = Measurements(("x", "j2"), np.zeros((2, 2)), np.ones((2, 3)))
    assert data.columns == ("x", "j2", "x1", "y1", "z1")


# --- the CLI --------------------------------------------------------------------------------


def test_cli_refusal_writes_the_report_and_no_urdf(tmp_path, capsys):
    chain = chain_of("ur5")
    campaign = overfitting_campaign(chain)
    data = tmp_path / "m.csv"
    data.write_text(measurements_csv(campaign.measurements))
    out, report = tmp_path / "c.urdf", tmp_path / "r.json"
    code = main(
        [
            "calibrate",
            "ur5",
            "--data",
            str(data),
            "--out",
            str(out),
            "--report",
            str(report),
            "--params",
            "complete",
            "--holdout",
            "0.3",
            "--seed",
            "1",
        ]
    )
    err = capsys.readouterr().err
    assert code != 0 and not out.exists()
    assert "calibration refused" in err and "Traceback" not in err
    assert json.loads(report.read_text())["accepted"] is False


# --- real data ------------------------------------------------------------------------------

FILE_26 = "qualisys_2021-11-26_static_postures.csv"


def test_tiago_default_beats_the_issue_targets_on_the_other_session():
    tiago = REAL / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        train = read_measurements(tiago / "qualisys_2021-11-30_static_postures.csv", chain)
        test = read_measurements(tiago / FILE_26, chain)
        first = [dataclasses.replace(d, position=d.position[:, :3]) for d in (train, test)]
        res = calibrate(chain, first[0], validate=first[1], elastic=True)
    # The URDF alone (compliance left out) is worse than the registration: refused.
    assert res.validation.urdf.position_rms > res.validation.registration.position_rms
    assert "URDF alone" in res.refusal
    held = res.validation
    # The registration alone reproduces the issue's baseline: 4.88 mm RMS / 12.2 mm max.
    assert abs(held.registration.position_rms - 4.88e-3) < 0.02e-3
    assert held.calibrated.position_rms < 3.0e-3
    assert held.calibrated.position_max <= 12.2e-3
    # The four markers, read as the plate's pose: better still at point 1, on both counts,
    # and the plate's orientation is predicted better than by the registration.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        plate = [
            read_measurements(tiago / name, chain, Columns("markers"))
            for name in ("qualisys_2021-11-30_static_postures.csv", FILE_26)
        ]
        four = calibrate(chain, plate[0], validate=plate[1], elastic=True).validation
    assert np.allclose(plate[1].position, first[1].position)  # point 1 is the position
    assert four.calibrated.position_rms < held.calibrated.position_rms
    assert four.calibrated.position_max < held.calibrated.position_max
    assert four.calibrated.orientation_rms < 0.7 * four.registration.orientation_rms


def test_ur10_cross_validation_with_default_options():
    ur10 = REAL / "ur10"
    chain = load_chain(ur10 / "ur10_robot.urdf", "universe", "wrist_3_link")
    data = read_measurements(
        ur10 / "calibration.csv", chain, Columns("rpy", ("phix1", "phiy1", "phiz1"))
    )
    errors = []
    for test in np.array_split(np.arange(data.m), 5):  # 5 contiguous folds
        mask = np.zeros(data.m, dtype=bool)
        mask[test] = True
        res = calibrate(chain, data.subset(~mask))
        held = data.subset(mask)
        torque = chain.gravity_torques(held.q) if np.any(res.state.compliance) else None
        errors.append(np.linalg.norm(res.state.residuals(held, torque)[:, :3], axis=1))
    pooled = np.sqrt(np.mean(np.concatenate(errors) ** 2))
    assert pooled <= 4.03e-3


@pytest.mark.parametrize("robot", ["ur5", "panda", "stanford"])
@pytest.mark.parametrize("k", [1, 2, 4])
def test_identifiable_count_with_k_markers_matches_theory(robot, k):
    """Each marker adds its 3 offsets to 4R + 2P (+ 3 for the tool orientation of a pose)."""
    from calib.calibration.counting import identifiable_parameters

    chain = chain_of(robot)
    base = 4 * chain.n_revolute + 2 * chain.n_prismatic
    assert len(identifiable_parameters(chain, k, "position")) == base + 3 * k
    assert len(identifiable_parameters(chain, k, "pose")) == base + 3 + 3 * k


def test_cli_analyze_markers(capsys):
    assert main(["analyze", "ur5", "--markers", "2", "--measure", "position", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n_identifiable"] == 4 * 6 + 6


def test_robust_loss_fits_and_bad_options_are_one_line_errors():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=60, measure="position", marker=MARKER, seed=3, noise_mm=0.1)
    res = calibrate(chain, campaign.measurements, params="complete", loss="soft_l1", noise_mm=0.1)
    q = chain.random_configurations(50, 8)
    err = res.check().points(q)[:, 0] - true_points(campaign, q)
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.3e-3
    from calib import InvalidArgumentError

    for bad in (
        {"loss": "cauchy"},
        {"params": "all"},
        {"fix": ("nope",)},
        {"holdout": 1.5},
        {"fix": ("theta3",), "free": ("theta3",)},
        {"noise_mm": -1.0},
        {"speed": 2},
    ):
        with pytest.raises(InvalidArgumentError) as info:
            calibrate(chain, campaign.measurements, **bad)
        assert "\n" not in str(info.value)


def test_gravity_torques_match_pinocchio_on_the_original_file():
    """calib builds its model from a kinematic copy with the masses: same gravity torques."""
    import pinocchio as pin

    chain = chain_of("panda")
    model = pin.buildModelFromUrdf(str(chain.urdf_path))
    data = model.createData()
    q = chain.random_configurations(5, 2)
    ids = [model.getJointId(n) for n in chain.joint_names]
    expected = []
    for row in q:
        qp = pin.neutral(model)
        for k, jid in enumerate(ids):
            qp[model.joints[jid].idx_q] = row[k]
        expected.append(
            pin.computeGeneralizedGravity(model, data, qp)[[model.joints[j].idx_v for j in ids]]
        )
    assert np.any(np.abs(expected) > 1.0)
    assert np.allclose(chain.gravity_torques(q), expected, rtol=1e-9, atol=1e-9)
