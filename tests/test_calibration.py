"""Identification: noise-free campaigns are reproduced exactly (also at held-out
configurations), noisy ones give residuals of the noise level and standard deviations that
cover the truth; the analytic Jacobian of the fit; bad input; the command line.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import chain_of

from calib import (
    ConvergenceError,
    DataError,
    InvalidArgumentError,
    Measurements,
    calibrate,
    measurement_to_base,
    model_residuals,
    read_measurements,
    simulate,
)
from calib.calibration import ResidualStats, _Problem, calibration_text
from calib.cli import main
from calib.jacobian import measured_point
from calib.measurements import measurements_csv

MARKER = (0.05, 0.02, 0.1)
"""Measured point for position campaigns: off the last joint axis."""


def held_out_error(chain, result, truth, seed: int = 1000) -> tuple[float, float]:
    """Largest point [m] and orientation [rad] error at 100 configurations not measured."""
    q = chain.random_configurations(100, seed)
    marker = result.measurement.marker_array
    true_kin = truth.true_mdh.kinematics(q)
    cal_kin = result.calibrated.kinematics(q)
    dp = np.abs(measured_point(cal_kin, marker) - measured_point(true_kin, marker)).max()
    dR = np.abs(cal_kin.R[:, -1] - true_kin.R[:, -1]).max()
    return float(dp), float(dR)


# --- noise-free campaigns ---------------------------------------------------------------------


@pytest.mark.parametrize("robot", ["ur5", "panda"])
@pytest.mark.parametrize("measure", ["pose", "position"])
@pytest.mark.parametrize("seed", [0, 7])
def test_noise_free_campaign_is_reproduced_exactly(robot, measure, seed):
    chain = chain_of(robot)
    marker = MARKER if measure == "position" else None
    campaign = simulate(
        chain, configs=60, measure=measure, marker=marker, seed=seed, error_mm=1.0, error_mrad=1.0
    )
    res = calibrate(chain, campaign.measurements, marker=marker)
    assert res.converged and res.check() is res
    assert res.before.position_rms > 1e-3  # 1 mm / 1 mrad errors are visible
    assert res.after.position_max < 1e-9
    dp, dR = held_out_error(chain, res, campaign.truth)
    assert dp < 1e-9
    if measure == "pose":
        assert dR < 1e-9 and res.after.orientation_max < 1e-9
        # Where regroupings are exact or small, the base values are the regrouped errors to
        # second order.
        assert np.allclose(res.estimate, campaign.truth.base_values, atol=2e-5, rtol=0)
    assert res.analysis.base == campaign.truth.analysis.base
    assert 1 <= res.iterations <= 20 and res.condition < 1e4 and res.warnings == ()


@pytest.mark.parametrize("robot", ["stanford", "aid"])
def test_other_chains_prismatic_and_continuous_joints(robot):
    chain = chain_of(robot)
    for measure, marker in (("pose", None), ("position", MARKER)):
        campaign = simulate(chain, configs=50, measure=measure, marker=marker, seed=3)
        res = calibrate(chain, campaign.measurements, marker=marker)
        assert res.converged and res.after.position_max < 1e-9
        assert held_out_error(chain, res, campaign.truth)[0] < 1e-9


def test_paper_set_is_exact_only_to_first_order():
    # Errors of the paper set only. Its regroupings theta0 + theta1 and r0 + r1 hold while
    # z0 // z1; an alpha1 error tilts z1, and the set has no beta1 to follow: the paper set
    # misses its own errors at second order (mm * mrad). The complete set fits them exactly.
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=40, measure="pose", params="paper", seed=2)
    paper = calibrate(chain, campaign.measurements, params="paper")
    assert paper.analysis.params.label == "paper" and paper.n_base == 27
    assert 1e-8 < paper.after.position_max < 1e-5
    complete = calibrate(chain, campaign.measurements)
    assert complete.after.position_max < 1e-9
    assert held_out_error(chain, complete, campaign.truth)[0] < 1e-9


def test_nominal_model_is_a_fixed_point():
    chain = chain_of("panda")
    campaign = simulate(chain, configs=30, measure="pose", error_mm=0, error_mrad=0, seed=1)
    res = calibrate(chain, campaign.measurements)
    assert np.abs(res.estimate).max() < 1e-12 and res.after.position_max < 1e-12
    assert np.allclose(res.measurement_to_base, np.eye(4), atol=1e-12)


# --- a point on the last joint axis ---------------------------------------------------------


@pytest.mark.parametrize(("robot", "b_nominal"), [("ur5", 25), ("panda", 29)])
@pytest.mark.parametrize("error", [1.0, 10.0])
def test_point_on_the_last_axis_is_refitted(robot, b_nominal, error):
    # The tool origin lies on the last axis of the nominal model, where its offset from the
    # axis and the axis direction cannot be identified; the true robot's point is off the
    # axis. The base set of the first fit's geometry has 2 more parameters and reproduces it.
    chain = chain_of(robot)
    campaign = simulate(
        chain, configs=100, measure="position", seed=0, error_mm=error, error_mrad=error
    )
    res = calibrate(chain, campaign.measurements)
    assert res.converged and res.refitted and res.n_base == b_nominal + 2
    assert res.after.position_max < 1e-9
    assert held_out_error(chain, res, campaign.truth)[0] < 1e-9
    assert any("lies on the last joint axis of the nominal model" in w for w in res.warnings)
    assert any("--marker" in w for w in res.warnings)
    report = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert report["refitted"] is True and report["n_base"] == b_nominal + 2
    assert "last joint axis" in calibration_text(res)
    # The corrections are the lift of the base values, as without a refit.
    assert np.allclose(res.corrections, res.lift @ res.estimate, rtol=0, atol=1e-15)


def test_point_really_on_the_last_axis_keeps_the_first_fit():
    # No error: the true point is on the axis too, and noise alone does not justify the two
    # extra parameters (F test): the first fit stays, with the warning.
    chain = chain_of("ur5")
    campaign = simulate(
        chain, configs=100, measure="position", seed=0, error_mm=0, error_mrad=0, noise_mm=0.01
    )
    res = calibrate(chain, campaign.measurements)
    assert res.converged and not res.refitted and res.n_base == 25
    assert any("cannot follow it exactly" in w for w in res.warnings)
    assert 0.7 < res.sigma / 1e-5 < 1.3


def test_marker_off_the_axis_and_pose_do_not_refit():
    chain = chain_of("ur5")
    for measure, marker in (("pose", None), ("position", MARKER)):
        campaign = simulate(chain, configs=40, measure=measure, marker=marker, seed=1)
        res = calibrate(chain, campaign.measurements, marker=marker)
        assert not res.refitted and res.warnings == () and res.timings_ms["refit"] < 1


# --- poorly varied configurations -------------------------------------------------------------


@pytest.mark.parametrize(
    ("measure", "marker", "expected"),
    [("position", MARKER, "only 3 of the 27"), ("pose", None, "only 6 of the 30")],
    ids=["position", "pose"],
)
def test_identical_configurations_are_flagged(measure, marker, expected):
    chain = chain_of("ur5")
    data = simulate(chain, configs=100, measure=measure, marker=marker, seed=1).measurements
    quat = None if data.quaternion is None else np.repeat(data.quaternion[:1], 100, axis=0)
    same = Measurements(
        data.joint_names,
        np.repeat(data.q[:1], 100, axis=0),
        np.repeat(data.position[:1], 100, axis=0),
        quat,
    )
    res = calibrate(chain, same, marker=marker)
    assert res.n_base == int(expected.split()[1])
    notes = [w for w in res.warnings if "measure more varied configurations" in w]
    assert len(notes) == 1 and expected in notes[0]
    # Varied configurations of the same campaign carry no such warning.
    assert calibrate(chain, data, marker=marker).warnings == ()


def test_few_configurations_that_reach_the_generic_rank_are_not_flagged():
    chain = chain_of("ur5")
    data = simulate(chain, configs=10, measure="pose", seed=2).measurements
    res = calibrate(chain, data)
    assert res.n_base == 30
    assert not any("varied configurations" in w for w in res.warnings)


# --- noisy campaigns --------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("measure", "marker"), [("pose", None), ("position", MARKER)], ids=["pose", "position"]
)
def test_noise_level_and_coverage_of_the_standard_deviations(measure, marker):
    chain = chain_of("ur5")
    sigma, m, seeds = 1e-4, 50, range(25)
    inside = inside_linear = total = 0
    rms, sigma_hat = [], []
    for seed in seeds:
        noisy = simulate(
            chain, configs=m, measure=measure, marker=marker, seed=seed, noise_mm=1e3 * sigma
        )
        clean = simulate(chain, configs=m, measure=measure, marker=marker, seed=seed)
        res = calibrate(chain, noisy.measurements, marker=marker)
        # The exact truth: the base values that reproduce the true robot (noise-free fit at
        # the same configurations).
        exact = calibrate(chain, clean.measurements, marker=marker).estimate
        assert res.converged
        inside += int(np.sum(np.abs(res.estimate - exact) <= 2 * res.std))
        inside_linear += int(np.sum(np.abs(res.estimate - noisy.truth.base_values) <= 2 * res.std))
        total += res.n_base
        rms.append(np.array(res.after.rms) / sigma)
        sigma_hat.append(res.sigma / sigma)
    assert 0.88 <= inside / total <= 1.0
    if measure == "pose":  # small regrouping coefficients: the first-order truth is as good
        assert 0.88 <= inside_linear / total <= 1.0
    # Residual RMS per axis ~ sigma sqrt(1 - b/r); sigma_hat ~ sigma.
    assert np.all((np.mean(rms, axis=0) > 0.8) & (np.mean(rms, axis=0) < 1.1))
    assert 0.93 < np.mean(sigma_hat) < 1.07


def test_orientation_weight_scales_orientation_rows():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=40, measure="pose", seed=5, noise_mm=0.1, noise_mrad=1.0)
    matched = calibrate(chain, campaign.measurements, orientation_weight=0.1)  # 0.1 mm / 1 mrad
    default = calibrate(chain, campaign.measurements)
    assert matched.orientation_weight == 0.1 and default.orientation_weight == 1.0
    assert 0.85 < matched.sigma / 1e-4 < 1.15  # weighted rows have the position noise
    assert not np.allclose(matched.estimate, default.estimate)


# --- the fit's Jacobian and residuals ---------------------------------------------------------


def test_fit_jacobian_against_finite_differences():
    chain = chain_of("panda")
    campaign = simulate(
        chain,
        configs=8,
        measure="pose",
        marker=MARKER,
        seed=4,
        error_mm=3,
        error_mrad=30,
        noise_mm=2.0,
    )
    res = calibrate(chain, campaign.measurements, marker=MARKER, orientation_weight=0.3)
    problem = _Problem(
        res.nominal, res.analysis.params, res.lift, campaign.measurements, res.measurement, 0.3
    )
    x = res.estimate + np.random.default_rng(0).normal(0, 0.02, res.n_base)
    J = problem.jac(x)
    h = 1e-6
    fd = np.empty_like(J)
    for i in range(res.n_base):
        e = np.zeros(res.n_base)
        e[i] = h
        fd[:, i] = (problem.fun(x + e) - problem.fun(x - e)) / (2 * h)
    assert np.abs(problem.fun(x)).max() > 1e-3  # far from zero residual: Jr^-1 matters
    assert np.allclose(J, fd, atol=1e-7, rtol=0)


def test_residuals_and_base_transform():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=20, measure="pose", seed=9)
    res = calibrate(chain, campaign.measurements)
    before = model_residuals(res.nominal, campaign.measurements)
    assert before.shape == (20, 6)
    assert np.isclose(np.sqrt(np.mean(before[:, 0] ** 2)), res.before.rms[0])
    assert np.abs(model_residuals(res.calibrated, campaign.measurements)).max() < 1e-9
    T = res.measurement_to_base
    assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3)) and np.allclose(T[3], [0, 0, 0, 1])
    assert np.allclose(measurement_to_base(res.nominal, res.nominal), np.eye(4))
    # The base transform is the calibrated robot's placement of the nominal joint-1 frame.
    true_T = measurement_to_base(res.nominal, campaign.truth.true_mdh)
    assert np.allclose(T, true_T, atol=1e-9)


def test_report_and_summary():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=30, measure="position", marker=MARKER, seed=1, noise_mm=0.05)
    res = calibrate(chain, campaign.measurements, marker=MARKER)
    report = json.loads(json.dumps(res.to_dict(), allow_nan=False))
    assert report["converged"] is True and report["n_base"] == res.n_base == 27
    assert report["configs"] == 30 and report["rows"] == 90 and report["measure"] == "position"
    assert set(report["residuals"]["before"]["rms"]) == {"x", "y", "z"}
    after = report["residuals"]["after"]
    assert after["position_max"] >= after["position_rms"]
    assert [p["name"] for p in report["base_parameters"]] == list(res.base_names)
    assert set(report["base_parameters"][0]) == {"name", "stands_for", "value", "std"}
    assert len(report["standard_corrections"]) == len(res.analysis.params)
    assert len(report["measurement_to_base"]["matrix"]) == 4
    rpy = report["measurement_to_base"]["rpy"]
    R = pin.rpy.rpyToMatrix(*rpy)
    assert np.allclose(R, res.measurement_to_base[:3, :3], atol=1e-14)
    for key in (
        "iterations",
        "status",
        "message",
        "sigma",
        "condition_number",
        "mdh_calibrated",
        "warnings",
        "timings_ms",
        "orientation_weight",
        "marker",
        "params",
    ):
        assert key in report
    text = calibration_text(res)
    assert "converged in" in text and "theta6" in text and "measurement frame" in text


def test_report_writes_null_for_every_non_finite_number():
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=30, measure="pose", seed=1)
    res = calibrate(chain, campaign.measurements)
    nan, inf = math.nan, math.inf
    residual = np.zeros((30, 6))
    residual[0, 0], residual[1, 4] = inf, nan
    broken = dataclasses.replace(
        res,
        sigma=nan,
        condition=inf,
        estimate=np.full(res.n_base, nan),
        corrections=np.full(len(res.corrections), inf),
        std=np.full(res.n_base, inf),
        before=ResidualStats.of(residual),
        after=ResidualStats.of(residual),
        calibrated=res.nominal.replace(d=np.full(res.nominal.n + 2, nan)),
        measurement_to_base=np.full((4, 4), nan),
    )
    report = broken.to_dict()
    json.dumps(report, allow_nan=False)  # raises ValueError on inf or NaN

    def floats(tree):
        if isinstance(tree, dict):
            return [v for x in tree.values() for v in floats(x)]
        if isinstance(tree, list):
            return [v for x in tree for v in floats(x)]
        return [tree] if isinstance(tree, float) else []

    assert all(math.isfinite(v) for v in floats(report))
    assert report["sigma"] is None and report["condition_number"] is None
    assert report["residuals"]["after"]["rms"]["x"] is None
    assert report["residuals"]["after"]["position_max"] is None
    assert report["residuals"]["after"]["rms"]["y"] == 0.0
    assert all(p["value"] is None and p["std"] is None for p in report["base_parameters"])
    assert set(report["standard_corrections"].values()) == {None}
    assert report["measurement_to_base"]["matrix"][0] == [None] * 4
    assert report["mdh_calibrated"][1]["d"] is None
    assert report["mdh_calibrated"][1]["alpha"] == res.nominal.alpha[1]


# --- bad input and non-convergence ------------------------------------------------------------


def test_too_few_measurements():
    chain = chain_of("ur5")
    pose = simulate(chain, configs=40, measure="pose", seed=1).measurements
    few = Measurements(pose.joint_names, pose.q[:4], pose.position[:4], pose.quaternion[:4])
    with pytest.raises(DataError, match=r"4 measurement rows give 24 equations, fewer than the 30"):
        calibrate(chain, few)
    position = simulate(chain, configs=40, measure="position", marker=MARKER, seed=1).measurements
    few = Measurements(position.joint_names, position.q[:8], position.position[:8])
    with pytest.raises(DataError, match=r"at least 9 rows"):
        calibrate(chain, few, marker=MARKER)


def test_data_must_belong_to_the_chain():
    chain = chain_of("ur5")
    data = simulate(chain, configs=10, measure="pose", seed=1).measurements
    other = Measurements(tuple(f"j{i}" for i in range(6)), data.q, data.position)
    with pytest.raises(DataError, match="do not match the chain"):
        calibrate(chain, other)
    q = data.q.copy()
    q[3, 2] = 4.0  # elbow limited to [-pi, pi]
    outside = Measurements(data.joint_names, q, data.position, data.quaternion)
    with pytest.raises(DataError, match=r"row 4, column 'elbow_joint'.*outside the joint limits"):
        calibrate(chain, outside)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"orientation_weight": 0},
        {"orientation_weight": float("inf")},
        {"max_iterations": 0},
        {"max_iterations": 1.5},
        {"max_iterations": None},
        {"max_iterations": True},
        {"params": "all"},
        {"marker": (1, 2)},
    ],
)
def test_bad_arguments(kwargs):
    chain = chain_of("ur5")
    data = simulate(chain, configs=10, measure="pose", seed=1).measurements
    with pytest.raises(InvalidArgumentError):
        calibrate(chain, data, **kwargs)


def test_a_fit_that_does_not_converge_is_flagged():
    chain = chain_of("ur5")
    data = simulate(
        chain, configs=30, measure="pose", seed=1, error_mm=20, error_mrad=20, noise_mm=0.1
    ).measurements
    res = calibrate(chain, data, max_iterations=2)
    assert not res.converged and res.status == 0
    assert "NOT CONVERGED" in calibration_text(res)
    assert res.to_dict()["converged"] is False
    with pytest.raises(ConvergenceError, match="did not converge after"):
        res.check()


# --- the command line -------------------------------------------------------------------------


def test_cli_simulate_then_calibrate(tmp_path, capsys):
    meas, urdf, report = tmp_path / "meas.csv", tmp_path / "cal.urdf", tmp_path / "report.json"
    marker = [str(v) for v in MARKER]
    assert (
        main(
            [
                "simulate",
                "ur5",
                "--out",
                str(meas),
                "--configs",
                "60",
                "--measure",
                "position",
                "--marker",
                *marker,
                "--noise-mm",
                "0.02",
                "--seed",
                "3",
            ]
        )
        == 0
    )
    truth = json.loads((tmp_path / "meas.truth.json").read_text())
    assert truth["seed"] == 3 and truth["noise_mm"] == 0.02 and truth["measure"] == "position"
    assert (
        main(
            [
                "calibrate",
                "ur5",
                "--data",
                str(meas),
                "--out",
                str(urdf),
                "--report",
                str(report),
                "--marker",
                *marker,
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "converged in" in out and f"wrote {urdf}" in out
    rep = json.loads(report.read_text())
    assert rep["converged"] and rep["data"] == str(meas)
    assert 0.015e-3 < rep["residuals"]["after"]["rms"]["x"] < 0.025e-3
    # The URDF reloaded by Pinocchio, placed by the report's base transform, predicts the
    # measured points.
    chain = chain_of("ur5")
    data = read_measurements(meas, chain)
    model = pin.buildModelFromUrdf(str(urdf))
    pdata = model.createData()
    T = np.array(rep["measurement_to_base"]["matrix"])
    base, tool = model.getFrameId("base_link"), model.getFrameId("tool0")
    worst = 0.0
    for q, p in zip(chain.pin_configurations(data.q), data.position, strict=True):
        pin.framesForwardKinematics(model, pdata, q)
        M = pdata.oMf[base].actInv(pdata.oMf[tool]).homogeneous
        worst = max(
            worst, float(np.linalg.norm(T[:3, :3] @ (M[:3, :3] @ MARKER + M[:3, 3]) + T[:3, 3] - p))
        )
    assert worst < 1e-4  # 0.02 mm noise


def test_cli_position_of_the_tool_origin_warns(tmp_path, capsys):
    meas, urdf = tmp_path / "m.csv", tmp_path / "c.urdf"
    assert main(["simulate", "ur5", "--out", str(meas), "--measure", "position"]) == 0
    capsys.readouterr()
    assert main(["calibrate", "ur5", "--data", str(meas), "--out", str(urdf)]) == 0
    out = capsys.readouterr().out
    assert "warning: the measured point lies on the last joint axis" in out
    assert "27 base parameters" in out and urdf.exists()


def test_cli_json_and_pose_only_on_request(tmp_path, capsys):
    meas = tmp_path / "m.csv"
    main(["simulate", "panda", "--out", str(meas), "--configs", "30", "--seed", "1"])
    capsys.readouterr()
    assert (
        main(
            [
                "calibrate",
                "panda",
                "--data",
                str(meas),
                "--out",
                str(tmp_path / "p.urdf"),
                "--measure",
                "position",
                "--json",
            ]
        )
        == 0
    )
    rep = json.loads(capsys.readouterr().out)
    assert rep["measure"] == "position" and rep["converged"]


def _cli_fails(capsys, argv) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("calib: error: ") and err.count("\n") == 1 + err.count("warning")
    return err


def _with_cell(line: str, j: int, value: str) -> str:
    cells = line.split(",")
    return ",".join([*cells[:j], value, *cells[j + 1 :]])


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda lines: [lines[0].replace("elbow_joint", "elbow"), *lines[1:]], "column 'elbow'"),
        (
            lambda lines: [
                *lines[:3],
                lines[3].replace(lines[3].split(",")[7], "abc", 1),
                *lines[4:],
            ],
            "row 4, column 'y'",
        ),
        (lambda lines: lines[:6], "fewer than the"),
        (
            lambda lines: [*lines[:5], _with_cell(lines[5], 6, "1e300"), *lines[6:]],
            "row 6, column 'x'",
        ),
    ],
    ids=["unknown column", "text cell", "too few rows", "absurd coordinate"],
)
def test_cli_bad_csv_writes_nothing(tmp_path, capsys, edit, message):
    chain = chain_of("ur5")
    campaign = simulate(chain, configs=20, measure="position", marker=MARKER, seed=1)
    lines = measurements_csv(campaign.measurements).splitlines()
    meas = tmp_path / "bad.csv"
    meas.write_text("\n".join(edit(lines)) + "\n")
    urdf, report = tmp_path / "cal.urdf", tmp_path / "report.json"
    err = _cli_fails(
        capsys,
        [
            "calibrate",
            "ur5",
            "--data",
            str(meas),
            "--out",
            str(urdf),
            "--report",
            str(report),
            "--marker",
            *map(str, MARKER),
        ],
    )
    assert message in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv"]


def test_cli_not_converged_writes_report_but_no_urdf(tmp_path, capsys):
    meas, urdf, report = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    main(
        [
            "simulate",
            "ur5",
            "--out",
            str(meas),
            "--configs",
            "30",
            "--error-mm",
            "20",
            "--error-mrad",
            "20",
            "--noise-mm",
            "0.1",
        ]
    )
    capsys.readouterr()
    err = _cli_fails(
        capsys,
        [
            "calibrate",
            "ur5",
            "--data",
            str(meas),
            "--out",
            str(urdf),
            "--report",
            str(report),
            "--max-iterations",
            "2",
        ],
    )
    assert "did not converge" in err and "no URDF written" in err
    assert not urdf.exists() and json.loads(report.read_text())["converged"] is False


def test_cli_refuses_to_overwrite_the_nominal_urdf(tmp_path, capsys):
    meas = tmp_path / "m.csv"
    main(["simulate", "ur5", "--out", str(meas), "--configs", "10"])
    capsys.readouterr()
    nominal = chain_of("ur5").urdf_path
    before = nominal.read_bytes()
    err = _cli_fails(capsys, ["calibrate", "ur5", "--data", str(meas), "--out", str(nominal)])
    assert "overwrite the nominal URDF" in err and nominal.read_bytes() == before


def test_cli_unwritable_output_is_one_line(tmp_path, capsys):
    meas = tmp_path / "m.csv"
    err = _cli_fails(capsys, ["simulate", "ur5", "--out", str(tmp_path / "nodir" / "m.csv")])
    assert "cannot write" in err and not meas.exists()


def test_cli_refuses_a_tool_without_fixed_joint_before_fitting(tmp_path, capsys):
    robot = str(Path(__file__).parent / "data" / "fixed_middle.urdf")
    meas = tmp_path / "m.csv"
    assert main(["simulate", robot, "--out", str(meas), "--configs", "30"]) == 0
    capsys.readouterr()
    err = _cli_fails(
        capsys,
        [
            "calibrate",
            robot,
            "--data",
            str(meas),
            "--out",
            str(tmp_path / "c.urdf"),
            "--report",
            str(tmp_path / "r.json"),
        ],
    )
    assert "not by a fixed joint" in err and capsys.readouterr().out == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv", "m.truth.json"]
