"""The joint engine's words: one chain is "1 chain", a camera's data (not touches) determine
the parameters, a pixel term's rows are observations and its outliers are pixels."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pixel_setups import INTRINSICS, setup

from calib import Problem, Term, calibrate, load_chain, simulate_contacts
from calib.calibration.pixel_chain import PixelData
from calib.calibration.pixel_term import PixelCamera
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
