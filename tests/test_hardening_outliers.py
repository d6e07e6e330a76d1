"""Issue 29, items 1, 3 and 4: diagnoses that explain what they can, outliers held out and
several outliers, on simulated data whose truth is known (each test failed before the fix)."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from conftest import chain_of

from calib import DataError, calibrate, load_robot, simulate
from calib.calibration.contact_checks import split_contacts
from calib.calibration.entry import calibrate_contacts
from calib.calibration.validation import split
from calib.measurements.contact_campaign import simulate_contacts

MARKER = (0.05, 0.02, 0.1)


def _true_points(campaign, q) -> np.ndarray:
    T = campaign.truth.true_mdh.forward(q)
    return T[:, :3, :3] @ np.asarray(MARKER) + T[:, :3, 3]


@pytest.mark.parametrize("seed", [0, 5])
def test_five_20_mm_outliers_among_35_postures_are_all_found(seed):
    """Item 4: before, 3 of 5 (seed 0) and none (seed 5) were found: beside the registration's
    geometric errors (3.6 mm median) a 20 mm outlier is not five times the median."""
    chain = chain_of("ur5")
    campaign = simulate(chain, 35, "position", marker=MARKER, seed=seed, noise_mm=0.05)
    rng = np.random.default_rng(seed)
    bad = rng.choice(35, 5, replace=False)
    step = rng.normal(size=(5, 3))
    pos = campaign.measurements.position.copy()
    pos[bad] += 0.02 * step / np.linalg.norm(step, axis=1, keepdims=True)
    res = calibrate(chain, dataclasses.replace(campaign.measurements, position=pos))
    assert sorted(o.row for o in res.outliers) == sorted(bad + 1)
    q = chain.random_configurations(50, 8)  # the truth, at postures never measured
    err = res.check().points(q)[:, 0] - _true_points(campaign, q)
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.3e-3


def test_no_outlier_is_found_in_clean_data():
    chain = chain_of("ur5")
    for seed in range(3):
        campaign = simulate(chain, 35, "position", marker=MARKER, seed=seed, noise_mm=0.05)
        assert calibrate(chain, campaign.measurements).outliers == ()


def _panda_touches(m: int, contacts: int = 1):
    chain = load_robot("panda")
    return chain, simulate_contacts(chain, m, "plane", contacts=contacts, seed=3, noise_mrad=0.1)


def test_a_glitched_touch_is_set_aside_not_called_degrees():
    """Item 1: one 1-rad encoder glitch among 160 touches was reported as degrees."""
    chain, camp = _panda_touches(160)
    q = camp.data.q.copy()
    q[40, 1] += 1.0
    rows = tuple(range(2, camp.data.m + 2))
    res = calibrate_contacts(
        chain, dataclasses.replace(camp.data, q=q, rows=rows), params="offsets"
    )
    assert [o.row for o in res.chains[0].outliers] == [42]
    assert res.stats["train"].m == 159


def test_two_tables_under_one_id_are_not_called_degrees():
    """Item 1: dividing the joints by 57.3 brings every touch near one posture, where one
    plane fits two tables: that was named degrees; now no mistake is named. The calibrated
    model still misses the one table by 158 mm: the touches do not match the chain (it was
    only noted, and accepted)."""
    chain, camp = _panda_touches(160, contacts=2)
    one = dataclasses.replace(camp.data, ids=tuple("t" for _ in camp.data.ids))
    with pytest.raises(DataError, match="do not match panda_link0 -> panda_hand") as caught:
        calibrate_contacts(chain, one, params="offsets")
    assert "degrees" not in str(caught.value)


def test_true_degrees_and_swaps_are_still_named():
    chain, camp = _panda_touches(60)
    with pytest.raises(DataError, match="degrees"):
        calibrate_contacts(chain, dataclasses.replace(camp.data, q=np.degrees(camp.data.q)))
    ur5 = chain_of("ur5")
    data = simulate(ur5, 50, "position", marker=MARKER, seed=3).measurements
    with pytest.raises(DataError, match="degrees"):
        calibrate(ur5, dataclasses.replace(data, q=np.degrees(data.q)))


def test_a_bad_held_out_row_is_set_aside_not_refusing_the_run():
    """Item 3: one wild row among the held-out ones refused the whole run ('another frame')."""
    chain = chain_of("ur5")
    campaign = simulate(chain, 60, "position", marker=MARKER, seed=3, noise_mm=0.05)
    data = dataclasses.replace(campaign.measurements, rows=tuple(range(2, 62)))
    _, held = split(data, 0.3, 1)
    wild = held.rows[2]
    pos = data.position.copy()
    pos[wild - 2, 1] += 0.5
    res = calibrate(
        chain, dataclasses.replace(data, position=pos), params="complete", holdout=0.3, seed=1
    )
    assert res.validation.calibrated.configs == held.m - 1
    assert any(f"row {wild} (" in w and "held-out statistics" in w for w in res.warnings)
    clean = held.subset(np.array(held.rows) != wild)
    err = res.points(clean.q)[:, 0] - _true_points(campaign, clean.q)
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.3e-3  # against the truth
    measured = np.linalg.norm(res.points(clean.q)[:, 0] - clean.points[:, 0], axis=1)
    assert np.isclose(np.sqrt(np.mean(measured**2)), res.validation.calibrated.position_rms)


def test_a_bad_held_out_touch_is_set_aside():
    chain, camp = _panda_touches(80)
    data = dataclasses.replace(camp.data, rows=tuple(range(2, camp.data.m + 2)))
    clean = calibrate_contacts(chain, data, params="offsets", holdout=0.3, seed=1)
    held_m = clean.stats["held_out"].m
    trained = {tuple(q) for q in split_contacts(data, 0.3, 1)[0].q}
    wild = next(i for i in range(data.m) if tuple(data.q[i]) not in trained)
    q = data.q.copy()
    q[wild, 1] += 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = calibrate_contacts(
            chain, dataclasses.replace(data, q=q), params="offsets", holdout=0.3, seed=1
        )
    assert res.stats["held_out"].m == held_m - 1
    assert any(f"row {wild + 2} (" in n and "held-out statistics" in n for n in res.notes)


def test_a_bad_held_out_tree_row_is_set_aside():
    """Item 3 for trees: one wild held-out row refused the run ('another frame')."""
    from calib.calibration.entry import calibrate_tree
    from calib.measurements.tree_campaign import simulate_tree

    tree = load_robot("bolt")
    camp = simulate_tree(tree, 30, markers=(0.0, 0.0, 0.02), noise_mm=0.05, seed=5)
    data = dataclasses.replace(camp.measurements, rows=tuple(range(2, camp.measurements.m + 2)))
    _, held = split(data, 0.3, 1)
    wild = held.rows[1]
    pos = data.position.copy()
    pos[wild - 2] += [0.5, 0.0, 0.0]
    res = calibrate_tree(tree, dataclasses.replace(data, position=pos), holdout=0.3, seed=1)
    assert res.to_dict()["errors"]["held_out"]["calibrated"]["configs"] == held.m - 1
    assert any(f"row {wild} (" in w and "held-out statistics" in w for w in res.notes)


def _hidden_touch_error(dq: float = 0.005):
    """80 panda touches of a point, the robot 3 mm / 3 mrad off, one's shoulder 5 mrad off."""
    chain = load_robot("panda")
    camp = simulate_contacts(
        chain, 80, "fixed-point", seed=3, noise_mrad=0.05, error_mm=3.0, error_mrad=3.0
    )
    data = dataclasses.replace(camp.data, rows=tuple(range(2, camp.data.m + 2)))
    q = data.q.copy()
    q[40, 1] += dq
    return chain, data, dataclasses.replace(data, q=q)


def test_a_touch_error_hidden_by_the_geometric_errors_is_set_aside_after_the_fit():
    """Issue 28: the registration's gaps (7.7 mm RMS of geometric errors) hide a 3-4 mm touch
    error; the fitted model's (0.06 mm) show it: set aside after the fit, refitted without."""
    chain, clean, data = _hidden_touch_error()
    res = calibrate(chain, data, params="paper")
    assert [o.row for o in res.chains[0].outliers] == [42]
    assert 3e-3 < res.chains[0].outliers[0].error < 5e-3  # under the fit
    assert any("set aside" in n and "row 42" in n for n in res.notes)
    assert res.stats["train"].m == clean.m - 1
    assert res.stats["train"].length_rms_mm < 0.1  # as the clean touches' fit
    assert calibrate(chain, clean, params="paper").chains[0].outliers == ()


def test_a_tree_row_hidden_by_the_geometric_errors_is_set_aside_after_the_fit():
    """Issue 28 for trees: an 8 mm error on one tool's row, hidden among the registration's
    geometric errors (3 mm / 3 mrad), is set aside after the joint fit (per tool's rows)."""
    from calib.calibration.entry import calibrate_tree
    from calib.measurements.tree_campaign import simulate_tree

    tree = load_robot("bolt")
    camp = simulate_tree(
        tree, 40, markers=(0.0, 0.0, 0.02), noise_mm=0.05, seed=5, error_mm=3.0, error_mrad=3.0
    )
    data = dataclasses.replace(camp.measurements, rows=tuple(range(2, camp.measurements.m + 2)))
    pos = data.position.copy()
    pos[17] += [0.0, 0.008, 0.0]
    res = calibrate_tree(tree, dataclasses.replace(data, position=pos))
    assert [[o.row for o in c.outliers] for c in res.chains] == [[], [19]]
    error = res.chains[1].outliers[0].error
    assert 7e-3 < error < 9e-3  # the 8 mm given, under the fit
    assert any(f"row 19 ({1e3 * error:.2f} mm)" in n for n in res.notes)


def test_ten_20_mm_tree_outliers_hidden_by_the_geometric_errors_are_all_found():
    """Issue 28: a tree's measured terms are tested as one chain's are (every row again, from
    the robust proposals). Ten 20 mm outliers among a Bolt's 70 rows (5 mm / 5 mrad errors):
    before, its FR_FOOT term's six were kept (none found) and its fit was 4.7 mm RMS."""
    from calib.calibration.entry import calibrate_tree
    from calib.measurements.tree_campaign import simulate_tree

    tree = load_robot("bolt")
    camp = simulate_tree(
        tree, 35, markers=(0.0, 0.0, 0.02), noise_mm=0.05, seed=5, error_mm=5.0, error_mrad=5.0
    )
    data = camp.measurements
    rng = np.random.default_rng(5)
    bad = rng.choice(data.m, 10, replace=False)
    step = rng.normal(size=(10, 3))
    pos = data.position.copy()
    pos[bad] += 0.02 * step / np.linalg.norm(step, axis=1, keepdims=True)
    res = calibrate_tree(tree, dataclasses.replace(data, position=pos))
    found = sorted(o.row for c in res.chains for o in c.outliers)
    assert found == sorted(bad + 1)
    for c in res.chains:  # each tool's rows (odd: FL_FOOT, even: FR_FOOT)
        assert max(c.stats["train"].rms) < 0.1  # [mm] per axis, as clean rows


def test_the_loop_keeps_the_rows_its_holdout_drew():
    """With ``holdout``, the fit made again after the loop's outlier is scored on the rows the
    first draw held out: the same as the training rows less the outlier fitted with those
    rows given as validation touches."""
    from calib.calibration.contact_checks import split_contacts

    chain, _, data = _hidden_touch_error()
    train, held = split_contacts(data, 0.25, 0)
    assert 42 in train.rows
    res = calibrate(chain, data, params="paper", holdout=0.25, seed=0)
    assert [o.row for o in res.chains[0].outliers] == [42]
    keep = np.array([r != 42 for r in train.rows])
    same = calibrate(chain, train, params="paper", validate=held)
    again = calibrate(chain, train.subset(keep), params="paper", validate=held)
    assert same.chains[0].outliers[0].row == 42  # the loop finds it from the given rows too
    for r in (same, again):
        got, want = res.stats["held_out"], r.stats["held_out"]
        assert got.m == want.m == held.m
        assert abs(got.length_rms_mm - want.length_rms_mm) < 1e-9


def test_an_outlier_round_whose_refit_stalls_ends_on_the_round_before():
    """A round's refit that did not converge (the rule proposes None) is not kept: the loop
    ends on the round before, whose fit converged, as on a refit refused; a first fit that
    stalled is returned as it is (the engine refuses or refits it)."""
    from calib.calibration.outliers import stable_set

    start = np.zeros(4, dtype=bool)
    fits = {0: "first", 1: "second (stalled)"}  # by the number of units set aside
    rule = {"first": np.array([0, 1, 0, 0], bool), "second (stalled)": None}.get
    found = stable_set(lambda keep: fits[int((~keep).sum())], rule, start)
    assert found[0] == "first" and not found[1].any()
    alone = stable_set(lambda keep: "second (stalled)", rule, start)
    assert alone[0] == "second (stalled)"


def test_a_registration_stopped_by_its_cap_sets_no_row_aside():
    """A UR5 measured in pose without noise, one row moved 5 mm (seed 1, its fourth). At
    ``max_iterations=4`` the registration of every row stops at the cap; before, the outlier
    loop read that registration's errors, set the row aside and the calibration went on
    from the refit without it. After, a stalled registration sets no row aside (as the fit's
    loop): the registration of every row is the last one, refused for its cap with the option
    to raise. At the default cap it converges and the moved row is set aside."""
    chain = chain_of("ur5")
    data = simulate(chain, 30, "pose", noise_mm=0.0, seed=1).measurements
    position = data.position.copy()
    position[3] += 0.005
    data = dataclasses.replace(data, position=position)
    with pytest.raises(DataError, match="the registration did not converge") as info:
        calibrate(chain, data, params="complete", max_iterations=4)
    assert "stopped after 4 residual evaluations, a larger max_iterations" in str(info.value)
    converged = calibrate(chain, data, params="complete")
    assert [o.row for o in converged.chains[0].outliers] == [4]  # rows count from 1


def test_a_pixel_terms_own_fit_stopped_by_its_cap_sets_no_row_aside(tmp_path, monkeypatch):
    """The pixels' rule of the registration's above: a UR5 seen by a camera in the cell
    (tests/pixel_setups.py), 0.3 px of noise (seed 1), one pixel moved by 40 px (its tenth
    row). Its own fit (the camera and the chain's placements, whose errors the outlier rule
    reads) stopped at 2 evaluations (not the registration, of the camera's 6: it raises):
    before, its errors set that row aside; after, none, and a note says why. At the default
    cap it converges and sets the moved row aside."""

    from pixel_setups import INTRINSICS, setup

    from calib.calibration import pixel_fit
    from calib.calibration.pixel_chain import PixelCamera, PixelData, pixel_part
    from calib.measurements.pixel_simulation import simulate_pixels

    s = setup("ur5", tmp_path, postures=30)
    truth = (s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q)
    obs = simulate_pixels(*truth, noise_px=0.3, seed=1)
    pixels = np.array(obs.pixels)
    pixels[9, 0] += 40.0
    obs = dataclasses.replace(obs, pixels=pixels)
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    part = pixel_part(s.nominal, PixelData(camera, s.target, obs))
    _, kept, found, notes, _ = pixel_fit.checked_pixels(s.nominal, part, None)
    assert [o.row for o in found] == [part.rows.lines[9]] and kept.m == part.m - 1
    real = pixel_fit.fit

    def capped(model, *args, max_iterations, **kwargs):  # the own fit's, not the camera's 6
        cap = 2 if model.size() > 6 else max_iterations
        return real(model, *args, max_iterations=cap, **kwargs)

    monkeypatch.setattr(pixel_fit, "fit", capped)
    _, kept, found, notes, _ = pixel_fit.checked_pixels(s.nominal, part, None)
    assert found == [] and kept is part, found
    assert any("own fit did not converge" in n and "no outliers" in n for n in notes), notes


def test_a_pixel_cameras_registration_stopped_by_its_cap_is_an_error(tmp_path, monkeypatch):
    """A measured chain's rule (above) for a camera's: its placement refined on its 6 from
    the given one stopped by the cap (2 evaluations; it takes 4 to converge here) was used as
    it stood; it is an error naming the camera, without the max_iterations hint (the cap is
    the module's). The UR5 camera of tests/pixel_setups.py, 30 postures, 0.3 px (seed 1)."""

    from pixel_setups import INTRINSICS, setup

    from calib.calibration import pixel_fit
    from calib.calibration.pixel_chain import PixelCamera, PixelData, pixel_part
    from calib.measurements.pixel_simulation import simulate_pixels

    s = setup("ur5", tmp_path, postures=30)
    truth = (s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q)
    obs = simulate_pixels(*truth, noise_px=0.3, seed=1)
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    part = pixel_part(s.nominal, PixelData(camera, s.target, obs))
    real, six = pixel_fit.fit, []

    def recorded(model, *args, **kwargs):
        out = real(model, *args, **kwargs)
        six.extend([out] if model.size() == 6 else [])
        return out

    monkeypatch.setattr(pixel_fit, "fit", recorded)
    pixel_fit.checked_pixels(s.nominal, part, None)
    assert six and all(f.converged for f in six)  # at the default cap
    monkeypatch.setattr(pixel_fit, "MAX_EVALUATIONS", 2)
    six.clear()
    with pytest.raises(DataError, match=f"camera {s.camera}'s registration did not") as info:
        pixel_fit.checked_pixels(s.nominal, part, None)
    assert not six[-1].converged and six[-1].evaluations == 2
    assert "stopped after 2 residual evaluations" in str(info.value)
    assert "max_iterations" not in str(info.value)
