"""Real data (TIAGo motion capture, UR10 tool poses): the checks of the real-data study.

The issue's targets (the registration's 4.88 mm, held out below FIGAROH's 3.22 / 12.2 mm,
the plate's pose, the UR10's 4.03 mm) are in tests/test_calibration.py. Here: the complete
model overfits where the default does not, most validation postures improve (each error
recomputed from the models' residuals on the held-out session), the predicted standard
deviation is recomputed from the covariance and the Jacobian, and compliance stays opt-in.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from calib import Columns, calibrate, load_chain, read_measurements
from calib.calibration.engine_model import ChainsData

pytestmark = [pytest.mark.slow, pytest.mark.filterwarnings("ignore::calib.DataWarning")]

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata"
SESSIONS = ("qualisys_2021-11-30_static_postures.csv", "qualisys_2021-11-26_static_postures.csv")


def first_point(data):
    return dataclasses.replace(data, position=data.position[:, :3])


@pytest.fixture(scope="module")
def tiago():
    tiago = REAL / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    train, test = (first_point(read_measurements(tiago / s, chain)) for s in SESSIONS)
    auto = calibrate(chain, train, validate=test)
    complete = calibrate(chain, train, params="complete", validate=test)
    return chain, train, test, auto, complete


def test_complete_overfits_where_auto_does_not(tiago):
    _, _, _, auto, complete = tiago
    assert complete.validation.calibrated.position_max > 15e-3
    assert auto.validation.calibrated.position_max < complete.validation.calibrated.position_max


def test_most_validation_postures_improve(tiago):
    chain, _, test, auto, _ = tiago
    torque = chain.gravity_torques(test.q)
    before = np.linalg.norm(auto.registration.residuals(test)[:, :3], axis=1)
    after = np.linalg.norm(auto.state.residuals(test, torque)[:, :3], axis=1)
    assert np.isclose(
        np.sqrt(np.mean(after**2)), auto.validation.calibrated.position_rms, rtol=1e-12
    )
    assert np.sum(after < before) > 0.7 * len(before)


def test_predicted_std_is_the_covariance_through_the_jacobian(tiago):
    _, _, test, auto, _ = tiago
    assert 0 < auto.predicted_std < auto.after.position_rms
    assert auto.validation.predicted_std < auto.validation.calibrated.position_rms
    fit = auto.solution.fit  # the joint fit's unknowns x: the term's own, then placements

    def jacobian(rows):  # of the points, by central differences of the fit's residuals
        def points(x):
            return fit.model.apply(fit.start, x).residuals(ChainsData((rows,)))[:, :3]

        h = 1e-7
        steps = h * np.eye(fit.x.size)
        return np.stack([(points(fit.x + e) - points(fit.x - e)) / (2 * h) for e in steps], 2)

    J = jacobian(auto.data).reshape(-1, fit.x.size)  # position rows only: weight 1
    rss = float(np.sum(fit.model.apply(fit.start, fit.x).residuals(ChainsData((auto.data,))) ** 2))
    prior = np.zeros(fit.x.size) if auto.solution.prior is None else auto.solution.prior
    cov = rss / (J.shape[0] - J.shape[1]) * np.linalg.inv(J.T @ J + np.diag(prior**2))
    assert np.allclose(cov, auto.covariance, rtol=1e-5, atol=1e-6 * np.abs(cov).max())
    for rows, std in ((auto.data, auto.predicted_std), (test, auto.validation.predicted_std)):
        Jp = jacobian(rows)
        var = np.einsum("mrp,pq,mrq->m", Jp, cov, Jp)
        assert np.isclose(np.sqrt(np.mean(var)), std, rtol=1e-5)


def test_plate_pose_beats_its_registration_in_orientation(tiago):
    chain = tiago[0]
    plate = [read_measurements(REAL / "tiago" / s, chain, Columns("markers")) for s in SESSIONS]
    pose = calibrate(chain, plate[0], validate=plate[1]).validation
    assert pose.calibrated.position_rms < pose.registration.position_rms
    assert pose.calibrated.position_max < pose.registration.position_max
    assert pose.calibrated.orientation_rms < pose.registration.orientation_rms


def test_ur10_complete_is_worse_than_auto_held_out():
    ur10 = REAL / "ur10"
    chain = load_chain(ur10 / "ur10_robot.urdf", "universe", "wrist_3_link")
    data = read_measurements(
        ur10 / "calibration.csv", chain, Columns("rpy", ("phix1", "phiy1", "phiz1"))
    ).position_only()
    folds = np.array_split(np.arange(data.m), 5)

    def pooled(level):
        errors = []
        for test in folds:
            mask = np.zeros(data.m, dtype=bool)
            mask[test] = True
            r = calibrate(chain, data.subset(~mask), params=level)
            held = data.subset(mask)
            torque = chain.gravity_torques(held.q) if np.any(r.state.compliance) else None
            errors.append(np.linalg.norm(r.state.residuals(held, torque)[:, :3], axis=1))
        return float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))

    auto = pooled("auto")
    assert auto <= 4.03e-3  # issue 10's target, its study's registration (test_calibration.py)
    assert pooled("complete") > auto  # 27 parameters from 54 rows


def test_ur10_readme_says_its_urdf_is_a_ur10e_not_the_catalog_ur10():
    """The data's URDF is a UR10e's: planning on the catalog's ``ur10`` is another robot."""
    text = (REAL / "ur10" / "README.md").read_text()
    data = (REAL / "ur10" / "ur10_robot.urdf").read_text()
    catalog = load_chain("ur10").urdf_path.read_text()
    assert '<robot name="ur10e">' in data and '`<robot name="ur10e">`' in text
    for urdf, lengths in ((data, ("0.1807", "0.6127", "0.57155")), (catalog, ("0.1273", "0.5723"))):
        for length in lengths:
            assert length in urdf and length in text, length
