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
from test_nothing_held import MARKER, _measured, _pixels, _touches

from calib import calibrate, cross_validate, simulate
from calib.calibration.contact_checks import FEW_POSTURES


def _few(result) -> list[str]:
    return [n for n in result.notes if f"under {FEW_POSTURES}: an RMS over n postures" in n]


def _said(n: int) -> str:
    return f"{n} postures, under 8: an RMS over n postures is known to about 1/sqrt(2n) of " + (
        f"itself (+-{100 / math.sqrt(2 * n):.0f}% here)"
    )


@pytest.mark.parametrize(
    ("kind", "postures", "few", "enough"),
    [("measured", 30, 0.2, 0.3), ("touches", 40, 0.15, 0.25), ("pixels", 30, 0.2, 0.3)],
)
def test_a_holdout_of_few_postures_is_noted_for_every_kind(kind, postures, few, enough, tmp_path):
    """30 postures (40 touches of one plane): ``few`` holds 6 out, noted (+-29%); ``enough``
    holds 9 (10), not."""
    fit = {"measured": _measured, "touches": _touches}.get(kind) or (
        lambda **o: _pixels(tmp_path, **o)
    )
    assert round(few * postures) == 6 < FEW_POSTURES <= round(enough * postures)
    noted, plenty = fit(holdout=few), fit(holdout=enough)
    (note,) = _few(noted)
    assert note.endswith(f"the held-out verdict rests on {_said(6)}"), note
    assert f"note: {note}" in noted.summary() and note in noted.to_dict()["warnings"]
    assert _few(plenty) == [], plenty.notes


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
