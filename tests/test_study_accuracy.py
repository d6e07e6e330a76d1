"""Calibration accuracy on simulated UR5 and Panda campaigns: the checks of the accuracy study.

Held-out errors are measured against the simulation's hidden truth (``campaign.truth``) at
200 seeded configurations no campaign measured, by forward kinematics of the true MDH model
computed here, and compared with what linear least squares predicts for a fit of b
parameters from r noisy equations (a residual sum of squares of sigma^2 (r - b), a
prediction error near sigma sqrt(b / m), proportional to sigma) and with Everett's
completeness formula (4R + 3 for a point off the last axis, 4R + 6 for the pose).
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from pinref import instrument_points

import calib
from calib.calibration.engine import NOTHING_HELD

pytestmark = pytest.mark.slow

MARKER = (0.05, 0.02, 0.1)  # measured point in the tool frame [m], off the last joint axis
NOISE_MM = 0.05
SIGMA = 1e-3 * NOISE_MM  # [m]
HELD_OUT, HELD_OUT_SEED = 200, 1000
SEEDS = range(5)
ROBOTS = ("ur5", "panda")
MEASURES = ("position", "pose")
M = (30, 50, 100, 200, 400)
NOISES = (0.0, 0.01, 0.05, 0.1, 0.2)


def rms(e) -> float:
    return float(np.sqrt(np.mean(np.square(e))))


@cache
def chain_of(robot: str):
    return calib.load_chain(robot)


def point(mdh, q):
    """The marker in frame -1 of an MDH model at configurations q: p + R @ marker [m]."""
    kin = mdh.kinematics(q)
    return kin.p[:, -1] + kin.R[:, -1] @ np.asarray(MARKER)


def held_out_errors(chain, result, truth):
    """|error| of the marker [m] at the held-out configurations: nominal, calibrated."""
    q = chain.random_configurations(HELD_OUT, HELD_OUT_SEED)
    true = point(truth.true_mdh, q)
    nominal = np.linalg.norm(point(result.nominal, q) - true, axis=1)
    calibrated = np.linalg.norm(result.points(q)[:, 0] - true, axis=1)
    return nominal, calibrated


@cache
def run(robot: str, measure: str, m: int, noise_mm: float, seed: int):
    """Simulate, calibrate and score one campaign: result, held-out RMS error [m]."""
    chain = chain_of(robot)
    campaign = calib.simulate(
        chain, configs=m, measure=measure, marker=MARKER, noise_mm=noise_mm, seed=seed
    )
    result = calib.calibrate(chain, campaign.measurements, marker=MARKER, params="complete")
    result = result.check()
    said = (robot, measure, m, noise_mm, seed, result.warnings)
    assert len(result.warnings) == 1 and result.warnings[0].startswith(NOTHING_HELD), said
    return result, rms(held_out_errors(chain, result, campaign.truth)[1])


def pooled_error(robot: str, measure: str, m: int, noise_mm: float) -> float:
    """Held-out RMS error [m] pooled over the repeats (root of the mean square)."""
    return math.sqrt(np.mean([run(robot, measure, m, noise_mm, s)[1] ** 2 for s in SEEDS]))


def test_one_ur5_campaign_residuals_and_held_out_errors(tmp_path):
    ur5 = chain_of("ur5")
    campaign = calib.simulate(
        ur5, configs=100, measure="position", marker=MARKER, noise_mm=NOISE_MM, seed=0
    )
    data, truth = campaign.measurements, campaign.truth
    result = calib.calibrate(ur5, data, marker=MARKER, params="complete").check()
    r, b = 3 * data.m, len(result.names)
    assert (r, b) == (3 * 100, 4 * ur5.n_revolute + 3)  # Everett: 4R + 3, marker off the axis
    errors = result.to_dict()["errors"]["train"]  # [mm]
    assert errors["registration"]["position_rms_mm"] > 0.3  # 1 mm / 1 mrad: a millimetre
    assert math.isclose(result.sigma, SIGMA, rel_tol=0.15)
    assert math.isclose(
        errors["calibrated"]["position_rms_mm"],
        1e3 * SIGMA * math.sqrt((r - b) / data.m),
        rel_tol=0.15,
    )
    q_test = ur5.random_configurations(HELD_OUT, HELD_OUT_SEED)
    assert q_test.shape == (HELD_OUT, ur5.n)
    assert np.all((q_test >= ur5.lower) & (q_test <= ur5.upper))  # inside the joint limits
    assert not np.isin(q_test, data.q).any()  # none of them was measured
    # Pinocchio on the written URDF: its marker link in the report's measurement frame.
    urdf = tmp_path / "ur5.urdf"
    urdf.write_bytes(result.urdf())
    points = instrument_points(
        urdf, result.to_dict(), ur5.base_frame, ur5.tool_frame, ur5.joint_names, q_test
    )
    assert np.allclose(result.points(q_test)[:, 0], points, rtol=0, atol=1e-9)
    nominal_err, calibrated_err = held_out_errors(ur5, result, truth)
    assert rms(nominal_err) > 1e-3
    assert rms(calibrated_err) < rms(nominal_err) / 50
    assert 0.5 < rms(calibrated_err) / (SIGMA * math.sqrt(b / data.m)) < 2
    assert rms(calibrated_err) < SIGMA  # below the measurement noise


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("measure", MEASURES)
def test_error_falls_like_one_over_root_m(robot, measure):
    errs = np.array([pooled_error(robot, measure, m, NOISE_MM) for m in M])
    b = len(run(robot, measure, M[0], NOISE_MM, 0)[0].names)
    assert errs[0] > 2 * errs[-1]  # theory: sqrt(400 / 30) = 3.7
    assert np.all(errs[M.index(50) :] < SIGMA)  # below the noise from m = 50 on
    slope = np.polyfit(np.log(M), np.log(errs), 1)[0]
    assert -0.75 < slope < -0.3, slope
    ratio = errs / (SIGMA * np.sqrt(b / np.array(M, dtype=float)))
    if measure == "position":
        assert np.all((ratio > 0.7) & (ratio < 1.4)), ratio
    else:
        assert np.all(ratio < 1.0), ratio


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("measure", MEASURES)
def test_error_is_proportional_to_the_noise(robot, measure):
    errs = np.array([pooled_error(robot, measure, 100, s) for s in NOISES])
    assert errs[0] < 1e-9  # noise-free: the true robot is recovered
    assert errs[-1] > errs[1]
    assert math.isclose(errs[-1] / errs[1], NOISES[-1] / NOISES[1], rel_tol=0.02)
    per_sigma = errs[1:] / np.array(NOISES[1:])
    assert np.allclose(per_sigma, per_sigma[-1], rtol=0.02), per_sigma


@pytest.mark.parametrize("robot", ROBOTS)
def test_pose_against_position(robot):
    chain = chain_of(robot)
    c = {}
    for measure in MEASURES:
        results = [run(robot, measure, 100, NOISE_MM, s)[0] for s in SEEDS]
        analysis = calib.analyze(chain, measure=measure, marker=MARKER, params="complete")
        c[measure] = {
            "b": {len(res.names) for res in results},
            "rows": results[0].stats["train"].m * len(results[0].one_chain().kind.row_names),
            "theory": analysis.n_theory,
            "on last axis": analysis.on_last_axis,
            "error": pooled_error(robot, measure, 100, NOISE_MM),
            "condition": np.array([res.condition for res in results]),
            "sigma": np.array([res.sigma for res in results]),
        }
    pose, pos = c["pose"], c["position"]
    assert chain.n_prismatic == 0
    assert pose["b"] == {pose["theory"]} == {4 * chain.n_revolute + 6}
    assert not pos["on last axis"]
    assert pos["b"] == {pos["theory"]} == {4 * chain.n_revolute + 3}
    assert (pose["rows"], pos["rows"]) == (600, 300)
    for v in (pose, pos):
        assert np.allclose(v["sigma"], SIGMA, rtol=0.15)  # sigma_hat ~ sigma
    # twice the equations for 3 more unknowns: better conditioned and more accurate
    assert pose["condition"].max() < pos["condition"].min()
    assert pose["error"] < pos["error"]
