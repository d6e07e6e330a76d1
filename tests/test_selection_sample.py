"""params 'auto' beyond the selection's work bound: the choice on a sample of postures."""

from __future__ import annotations

import numpy as np
import pytest

import calib.calibration.determined as determined
from calib import InvalidArgumentError, load_chain, simulate
from calib.calibration import calibrate
from calib.measurements.postures import posture_groups, sample_postures

MARKER = (0.01, 0.02, 0.05)
NOISE_MM = 0.05


def rms(e: np.ndarray) -> float:
    """RMS of the points' errors ``(m, 3)`` [m]."""
    return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))


def _campaign(m: int, configs=None, noise_mm: float = NOISE_MM):
    chain = load_chain("ur5")
    given = m if configs is None else configs
    camp = simulate(chain, given, "position", MARKER, noise_mm=noise_mm, seed=3)
    return chain, camp.measurements


def test_sample_postures_draws_whole_postures_in_proportion():
    groups = np.repeat(np.arange(300), 2)  # every posture measured twice
    tool = np.where(np.arange(600) < 150, "a", "b")  # a quarter of the rows on tool a
    keep = sample_postures(groups, 200, seed=4, strata=tool)
    assert np.array_equal(keep, sample_postures(groups, 200, seed=4, strata=tool))
    assert not np.array_equal(keep, sample_postures(groups, 200, seed=5, strata=tool))
    assert np.array_equal(keep[0::2], keep[1::2])  # a posture's repeats together
    assert keep[:150].sum() == 50 and keep[150:].sum() == 150  # each tool a third
    assert sample_postures(groups, 0, seed=4).sum() == 2  # at least one posture


def test_auto_beyond_the_work_bound_chooses_on_a_sample(monkeypatch):
    """Just above a lowered bound, the sample's choice is the full selection's; the fit on
    every row is as close to the truth as the full one's (noise-free held-out postures)."""
    chain, data = _campaign(4000)
    seen = []
    sized = determined.selection_configurations

    def spy(m, rows, fixed, candidates):
        seen.append((m, rows, fixed, candidates))
        return sized(m, rows, fixed, candidates)

    monkeypatch.setattr(determined, "selection_configurations", spy)
    full = calibrate(chain, data)
    m, rows, fixed, cand = seen[-1]
    assert m == 4000 and not any("chose the parameters on" in w for w in full.warnings)
    per_configuration = rows * (fixed + cand) ** 2 * cand
    monkeypatch.setattr(determined, "SELECTION_WORK", 3999 * per_configuration)
    monkeypatch.setattr(determined, "SAMPLE_WORK", 2500 * per_configuration + 1)
    sampled = calibrate(chain, data)
    assert sampled.selection.kept == full.selection.kept
    assert sampled.selection.winner == full.selection.winner
    assert sampled.names == full.names and sampled.stats["train"].m == 4000  # the fit: every row
    note = [w for w in sampled.warnings if "chose the parameters on" in w]
    drawn = sample_postures(posture_groups(data.q), 2500, 0)
    assert len(note) == 1 and f"on {drawn.sum()} of the 4000 configurations" in note[0]
    assert f"note: {note[0]}" in sampled.summary()  # the summary says it
    assert note[0] in sampled.to_dict()["warnings"]
    q = chain.random_configurations(500, 11)
    _, truth = _campaign(500, q, noise_mm=0.0)
    errors = [rms(r.points(q)[:, 0] - truth.points[:, 0]) for r in (full, sampled)]
    assert errors[1] < errors[0] + 0.1 * NOISE_MM * 1e-3  # [m]
    assert errors[0] < NOISE_MM * 1e-3  # the full fit itself is close to the truth


def test_a_sample_too_small_to_choose_on_is_refused(monkeypatch):
    chain, data = _campaign(200)
    monkeypatch.setattr(determined, "SELECTION_WORK", 1e6)
    with pytest.raises(InvalidArgumentError, match="a sample within it too small") as error:
        calibrate(chain, data)
    assert "\n" not in str(error.value)
    calibrate(chain, data, params="complete")  # a level is the way out
