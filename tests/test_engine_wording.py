"""The joint engine's words: one chain is "1 chain", a camera's data (not touches) determine
the parameters, a pixel term's rows are observations and its outliers are pixels."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pixel_setups import INTRINSICS, setup

from calib import Problem, Term, calibrate, load_chain, simulate, simulate_contacts
from calib.calibration.pixel_chain import PixelCamera, PixelData
from calib.exceptions import DataError
from calib.measurements.pixel_simulation import simulate_pixels


def _pixels(tmp_path, obs=None):
    s = setup("ur5", tmp_path, postures=120)
    if obs is None:
        obs = simulate_pixels(s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q)
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    return s, obs, lambda o: Problem((Term(s.nominal, PixelData(camera, s.target, o)),))


def test_one_term_is_one_chain():
    touches = simulate_contacts(load_chain("ur5"), 40, "plane", contacts=2, seed=0).data
    first = calibrate(load_chain("ur5"), touches, params="complete").summary().splitlines()[0]
    assert ": 1 chain, " in first and "chains" not in first


def test_the_first_line_says_a_count_of_one_in_the_singular(tmp_path):
    """One chain with one plane, one measured term or one camera: each count in one style
    (``1 chain, 1 plane``; before, ``1 chain, 1 plane(s)``)."""
    chain = load_chain("ur5")
    marker = (0.05, 0.02, 0.1)
    touches = simulate_contacts(chain, 40, "plane", seed=0).data
    rows = simulate(chain, 30, "position", marker=marker, noise_mm=0.05, seed=1).measurements
    _, obs, problem = _pixels(tmp_path)
    results = {
        "1 plane": calibrate(chain, touches),
        "1 measured term": calibrate(chain, rows, marker=marker),
        "1 camera": calibrate(problem(obs)),
    }
    for objects, result in results.items():
        first = result.summary().splitlines()[0]
        assert f": 1 chain, {objects}, " in first and "(s)" not in first, first


def test_a_camera_only_problem_says_the_data_determine(tmp_path):
    _, obs, problem = _pixels(tmp_path)
    r = calibrate(problem(obs))
    assert "the data determine 20 of the 28 parameters offered" in r.notes
    assert not any("touches" in n for n in r.notes)


def test_a_pixel_outlier_is_labelled_pixels_in_the_report(tmp_path):
    _, obs, problem = _pixels(tmp_path)
    pixels = np.array(obs.pixels, dtype=float)
    pixels[7] += 80.0  # one observation 80 px off
    r = calibrate(problem(dataclasses.replace(obs, pixels=pixels)))
    found = r.to_dict()["outliers"]
    assert [o["kind"] for o in found] == ["pixels"]


def test_too_few_pixel_observations_say_observations(tmp_path):
    _, obs, problem = _pixels(tmp_path)
    few = dataclasses.replace(
        obs, q=obs.q[:2], camera=obs.camera[:2], point=obs.point[:2], pixels=obs.pixels[:2]
    )
    with pytest.raises(DataError, match="observations") as err:
        calibrate(problem(few))
    assert "configurations" not in str(err.value)


@pytest.mark.parametrize("configs", [4, 8])
def test_too_few_configurations_are_told_how_many_determine_every_parameter(configs):
    """auto on too few postures says how many generic ones determine every parameter: a point
    gives 3 equations a configuration, and generic configurations reach the identifiable count
    (Everett's 4R + 3 for a point) as soon as they give that many equations: 9 on a UR5 (theory,
    not calib's own count)."""
    chain = load_chain("ur5")
    data = simulate(chain, configs, "position", marker=(0.01, 0.02, 0.05), seed=3, noise_mm=0.05)
    identifiable = 4 * chain.n_revolute + 3
    res = calibrate(chain, data.measurements)
    note = (
        f"the {configs} configurations determine {3 * configs} of the {identifiable} parameters "
        "generic configurations would: params 'auto' chooses among those only; "
        f"{-(-identifiable // 3)} configurations at generic postures determine them all (calib "
        "design plans them)"
    )
    assert note in res.notes, res.notes
