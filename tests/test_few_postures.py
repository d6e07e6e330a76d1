"""A held-out verdict on few postures says so, one rule for every kind (verdict48).

An RMS over n postures is known to about 1/sqrt(2n) of itself: the note names the count and
that figure where it is under ``FEW_POSTURES`` (8: over 25%). The counts expected here come
from the split's arithmetic (``round(fraction * postures)`` held out; K folds of sizes
differing by one at most, the largest ceil(P / K)), not from calib's counting.
"""

from __future__ import annotations

import math

import pytest
from conftest import chain_of
from pixel_setups import INTRINSICS, calibrated, setup

from calib import calibrate, cross_validate, simulate, simulate_contacts
from calib.calibration.contact_checks import FEW_POSTURES
from calib.calibration.pixel_term import PixelCamera
from calib.measurements.pixel_simulation import simulate_pixels

MARKER = (0.05, 0.02, 0.1)


def _measured(postures=30, **options):
    chain = chain_of("ur5")
    data = simulate(chain, postures, "position", marker=MARKER, noise_mm=0.05, seed=1)
    return calibrate(chain, data.measurements, marker=MARKER, **options)


def _touches(**options):
    chain = chain_of("ur5")
    data = simulate_contacts(chain, 30, "plane", seed=1).data
    return calibrate(chain, data, **options)


def _pixels(tmp_path, **options):
    s = setup("ur5", tmp_path, postures=30)
    obs = simulate_pixels(s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q, seed=1)
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    return calibrated(s.nominal, camera, s.target, obs, **options)


def _few(result) -> list[str]:
    return [n for n in result.notes if f"under {FEW_POSTURES}: an RMS over n postures" in n]


def _said(n: int) -> str:
    return f"{n} postures, under 8: an RMS over n postures is known to about 1/sqrt(2n) of " + (
        f"itself (+-{100 / math.sqrt(2 * n):.0f}% here)"
    )


@pytest.mark.parametrize("kind", ["measured", "touches", "pixels"])
def test_a_holdout_of_few_postures_is_noted_for_every_kind(kind, tmp_path):
    """30 postures (touches of one plane): 0.2 holds 6 out, noted (+-29%); 0.3 holds 9, not."""
    fit = {"measured": _measured, "touches": _touches}.get(kind) or (
        lambda **o: _pixels(tmp_path, **o)
    )
    few, enough = fit(holdout=0.2), fit(holdout=0.3)
    assert round(0.2 * 30) == 6 < FEW_POSTURES <= round(0.3 * 30) == 9
    (note,) = _few(few)
    assert note.endswith(f"the held-out verdict rests on {_said(6)}"), note
    assert f"note: {note}" in few.summary() and note in few.to_dict()["warnings"]
    assert _few(enough) == [], enough.notes


def test_validation_data_of_few_postures_are_noted():
    chain = chain_of("ur5")
    data = simulate(chain, 30, "position", marker=MARKER, noise_mm=0.05, seed=1).measurements
    other = simulate(chain, 3, "position", marker=MARKER, noise_mm=0.05, seed=3).measurements
    result = calibrate(chain, data, marker=MARKER, validate=other)
    (note,) = _few(result)
    assert note.endswith(f"the held-out verdict rests on {_said(3)}"), note


@pytest.mark.parametrize(("postures", "folds", "trained"), [(10, 2, 5), (10, 5, 8), (30, 5, 24)])
def test_folds_note_fits_trained_on_few_postures(postures, folds, trained):
    """Each fold's fit trains on P - (its fold); the smallest on P - ceil(P / K)."""
    assert postures - math.ceil(postures / folds) == trained
    chain = chain_of("ur5")
    data = simulate(chain, postures, "position", marker=MARKER, noise_mm=0.05, seed=1)
    result = cross_validate(chain, data.measurements, folds=folds, marker=MARKER)
    notes = _few(result)
    if trained >= FEW_POSTURES:
        assert notes == [], notes
        return
    (note,) = notes
    assert note.endswith(f"the folds' verdict is of fits on as few as {_said(trained)}"), note
