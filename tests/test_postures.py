"""Repeated postures buy nothing (issue 29, item 2) and the default selection converges to
the complete fit (issue 30): simulated campaigns with a known truth.

Every expected value comes from the file without its repeats, from brute-force refits, or
from the true robot (Pinocchio on the written URDF).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from test_calibration import refit_loo

from calib import DataError, load_chain, simulate
from calib.calibration import calibrate
from calib.calibration.contact_checks import split_contacts
from calib.calibration.entry import calibrate_contacts
from calib.calibration.selection import OUTER_FOLDS, RICH, STRENGTHS, select
from calib.calibration.validation import split
from calib.measurements.contact_campaign import simulate_contacts
from calib.measurements.postures import posture_groups

MARKER = (0.01, 0.02, 0.05)


def test_posture_groups_numbers_repeats_in_order_of_first_appearance():
    q = np.array([[0.1, 0.2], [0.3, 0.4], [0.1, 0.2 + 1e-9], [0.3, 0.4], [0.1, 0.2]])
    assert posture_groups(q).tolist() == [0, 1, 0, 1, 0]
    assert posture_groups(q, ["a", "b", "b", "b", "a"]).tolist() == [0, 1, 2, 1, 0]
    assert posture_groups(q + [[0.0, 1e-3]] * 5 * np.arange(5)[:, None]).tolist() == [0, 1, 2, 3, 4]


def campaign(m=40, seed=3, noise_mm=0.05):
    chain = load_chain("ur5")
    data = simulate(chain, m, "position", MARKER, noise_mm=noise_mm, seed=seed).measurements
    return chain, data


def test_every_row_twice_gives_the_selection_of_the_file_once():
    chain, data = campaign()
    once = calibrate(chain, data).selection
    twice = calibrate(chain, data.subset(np.repeat(np.arange(data.m), 2))).selection
    assert twice.kept == once.kept
    assert twice.strength == once.strength
    assert np.isclose(twice.selection_cv, once.selection_cv, rtol=1e-9)
    assert np.allclose([s.loo for s in twice.steps], [s.loo for s in once.steps], rtol=1e-9)


def test_select_of_repeats_is_select_of_their_means():
    """Unequal repeats with their own noise: select() on the rows with their postures is
    select() on each posture's mean (weighted by its count), its errors raised by the spread
    the repeats leave about their mean (brute force: the pooled held-out error of the
    registration's refits without each fold's postures)."""
    rng = np.random.default_rng(4)
    g, rows, fixed, cand = 30, 3, 3, 5
    Jg = rng.normal(size=(g, rows, fixed + cand))
    x = np.r_[rng.normal(size=fixed), 0.5, 0.0, -0.3, 0.0, 0.1]
    count = rng.integers(1, 4, size=g)
    groups = np.repeat(np.arange(g), count)
    J = Jg[groups]
    e = J @ x + 0.2 * rng.normal(size=(len(groups), rows))
    names = tuple(f"p{i}" for i in range(cand))
    sel, _ = select(J, e, fixed, names, groups=groups)
    A = J.reshape(-1, fixed + cand) / np.linalg.norm(J.reshape(-1, fixed + cand), axis=0)
    sse = 0.0
    for f in range(OUTER_FOLDS):
        held = np.repeat(groups % OUTER_FOLDS == f, rows)
        x0 = np.linalg.lstsq(A[~held, :fixed], e.ravel()[~held], rcond=None)[0]
        sse += np.sum((e.ravel()[held] - A[held, :fixed] @ x0) ** 2)
    assert np.isclose(sel.registration_cv, np.sqrt(sse / len(groups)), rtol=1e-9)
    alone, _ = select(J, e, fixed, names)  # each row a posture: its repeats train its folds
    assert alone.registration_cv != pytest.approx(sel.registration_cv, rel=1e-3)


def test_holdout_leaves_out_whole_postures():
    _, data = campaign(m=30)
    twice = data.subset(np.repeat(np.arange(data.m), 2))
    train, held = split(twice, 0.3, 5)
    assert held.m == 2 * 9
    seen = {tuple(q) for q in train.q}
    assert not any(tuple(q) in seen for q in held.q)


def test_equations_count_postures():
    """Three postures recorded ten times give 9 equations for the frame and marker's 9."""
    chain, data = campaign(m=3)
    with pytest.raises(DataError, match="3 configurations to fit give 9 equations"):
        calibrate(chain, data.subset(np.tile(np.arange(3), 10)), params="frames")


def test_touches_twice_give_the_selection_of_the_touches_once():
    chain = load_chain("ur5")
    data = simulate_contacts(chain, 60, "plane", noise_mrad=0.05, seed=3).data
    once = calibrate_contacts(chain, data).selection
    twice = calibrate_contacts(chain, data.subset(np.repeat(np.arange(data.m), 2))).selection
    assert twice.kept == once.kept and twice.strength == once.strength
    train, held = split_contacts(data.subset(np.repeat(np.arange(data.m), 2)), 0.3, 1)
    seen = {tuple(q) for q in train.q}
    assert held.m % 2 == 0 and not any(tuple(q) in seen for q in held.q)


def test_complete_candidate_error_is_each_folds_ridge_refit():
    """select()'s cross-validated error of the complete fit: each fold's prior strength is
    its own brute-force best, and its ridge fit predicts the held-out configurations (31
    configurations: over RICH equations per parameter, the complete fit is a candidate)."""
    rng = np.random.default_rng(9)
    m, rows, fixed, cand = 31, 3, 3, 6
    assert m * rows >= RICH * (fixed + cand)
    J = rng.normal(size=(m, rows, fixed + cand)) * rng.uniform(0.5, 3.0, size=fixed + cand)
    e = J @ np.r_[rng.normal(size=fixed), 0.2 * rng.normal(size=cand)]
    e += 0.3 * rng.normal(size=(m, rows))
    selection, _ = select(J, e, fixed, tuple(f"p{i}" for i in range(cand)))
    A = J.reshape(m * rows, -1)
    A = A / np.linalg.norm(A, axis=0)
    ev, sse = e.ravel(), 0.0
    for f in range(OUTER_FOLDS):
        held = np.repeat(np.arange(m) % OUTER_FOLDS == f, rows)
        At, et = A[~held], ev[~held]
        brute = {
            t: refit_loo(At, et, rows, np.r_[np.zeros(fixed), np.full(cand, t)]).sum()
            for t in (0.0, *STRENGTHS)
        }
        lam = np.r_[np.zeros(fixed), np.full(cand, min(brute, key=brute.get))]
        aug = np.vstack([At, np.diag(np.sqrt(lam))])
        xs = np.linalg.lstsq(aug, np.r_[et, np.zeros(fixed + cand)], rcond=None)[0]
        sse += np.sum((ev[held] - A[held] @ xs) ** 2)
    assert np.isclose(selection.complete_cv, np.sqrt(sse / m), rtol=1e-9)


def test_abundant_data_deliver_the_complete_fit():
    """300 postures, every parameter off: the default keeps every candidate (the complete
    fit won the cross-validation) and predicts unseen postures as well as params complete."""
    chain, data = campaign(m=300, seed=1)
    auto = calibrate(chain, data)
    complete = calibrate(chain, data, params="complete")
    assert auto.selection.winner == "complete"
    assert set(auto.names) == set(complete.names)
    q = chain.random_configurations(200, 9)
    truth = simulate(chain, q, "position", MARKER, seed=1).measurements
    err = [np.linalg.norm(r.points(q)[:, 0] - truth.points[:, 0], axis=1) for r in (auto, complete)]
    assert np.sqrt(np.mean(err[0] ** 2)) <= 1.03 * np.sqrt(np.mean(err[1] ** 2))


def test_noise_free_round_trip_with_default_options(tmp_path):
    """Simulate without noise, calibrate with the defaults, write the URDF: Pinocchio on the
    written file reproduces the measured points to 1e-9 m (no marker: the tool origin)."""
    chain = load_chain("ur5")
    camp = simulate(chain, 100, "position", seed=0)
    res = calibrate(chain, camp.measurements).check()
    path = tmp_path / "ur5_cal.urdf"
    res.write_urdf(path)  # the result's URDF: its base frame in the instrument's is
    model = pin.buildModelFromUrdf(str(path))  # measurement_to_base
    dmodel = model.createData()
    frame = model.getFrameId(chain.tool_frame)
    base = model.getFrameId(chain.base_frame)
    got = []
    for q in camp.measurements.q:
        full = pin.neutral(model)
        for name, value in zip(chain.joint_names, q, strict=True):
            full[model.joints[model.getJointId(name)].idx_q] = value
        pin.framesForwardKinematics(model, dmodel, full)
        T = (dmodel.oMf[base].inverse() * dmodel.oMf[frame]).homogeneous
        point = T[:3, :3] @ res.state.markers[0] + T[:3, 3]
        got.append(res.measurement_to_base[:3, :3] @ point + res.measurement_to_base[:3, 3])
    assert np.abs(np.array(got) - camp.measurements.points[:, 0]).max() < 1e-9


def test_count_is_the_number_of_posture_groups():
    """``count`` (rows sorted) counts what ``posture_groups`` numbers: repeats, keys, -0.0."""
    from calib.measurements.postures import count, posture_groups

    rng = np.random.default_rng(1)
    for _ in range(300):
        m, n = int(rng.integers(1, 30)), int(rng.integers(0, 5))
        base = rng.normal(size=(max(m // 2, 1), n)) * rng.choice([1.0, 1e-6, 1e-7])
        q = base[rng.integers(0, len(base), m)] + rng.choice([0, 1e-8]) * rng.normal(size=(m, n))
        q = -0.0 * q if rng.random() < 0.2 else q
        key = None if rng.random() < 0.5 else rng.choice(["a", "b", "c"], m)
        assert count(q, key) == int(posture_groups(q, key).max()) + 1
