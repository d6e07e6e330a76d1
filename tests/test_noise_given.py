"""A calibrated model that misses its rows far above the noise the user gave is said (noise50).

With the noise right and the model right, the calibrated positions' ``RSS / noise^2`` is
chi-square with their share of the fit's ``rows - unknowns`` degrees of freedom: its noise
estimate ``sqrt(RSS / dof)`` over :data:`~calib.calibration.validation.ABOVE_NOISE` (10) times
the noise has a probability under ``P(chi2_1 > 100) = 1.5e-23`` at any row count. Real robots
leave errors beyond their geometry that no noise figure describes, so nothing is said under
:data:`~calib.calibration.validation.UNMODELLED` (5 mm per point) either.
"""

from __future__ import annotations

import numpy as np
import pytest

import calib
from calib import calibrate, load_chain
from calib.calibration import validation
from calib.calibration.validation import far_above_noise
from calib.measurements.data import Measurements

MARKER = (0.05, 0.08, 0.03)  # off wrist_3's axis
SAID = "times the noise given"


def _wrist_3_within(amplitude: float, noise_mm: float) -> Measurements:
    """A marker on the UR5's wrist_3_link, wrist_3_joint within +-``amplitude`` [rad], the
    rows read for the chain to wrist_2_link (built in Python: no file, so no column of
    wrist_3_joint for the diagnosis to read again)."""
    on3 = load_chain("ur5", tool="wrist_3_link")
    q = on3.random_configurations(100, 5)
    q[:, 5] = np.random.default_rng(7).uniform(-amplitude, amplitude, len(q))
    seen = calib.simulate(on3, q, "position", marker=MARKER, noise_mm=noise_mm, seed=2)
    rows = seen.measurements
    return Measurements(rows.joint_names[:5], rows.q[:, :5], rows.position, source="m")


@pytest.mark.parametrize("holdout", [0.0, 0.25])
def test_a_joint_left_out_that_moves_little_is_said_when_the_noise_is_given(holdout):
    """Failed before: 15.7 mm RMS accepted with 0.1 mm of noise given, and nothing said.

    The registration leaves 16 mm (under the 20 mm that starts the diagnosis)."""
    on2 = load_chain("ur5", tool="wrist_2_link")
    data = _wrist_3_within(0.5, 0.1)
    result = calibrate(on2, data, noise_mm=0.1, holdout=holdout, seed=1)
    said = [w for w in result.warnings if SAID in w]
    assert result.accepted and len(said) == 1
    assert "a joint left out of the chain or one too many" in said[0]
    assert "the marker on another link" in said[0] and "other units" in said[0]
    rms = 1e3 * result.after.position_rms  # the rows fitted; the noise alone: 0.17 mm
    assert f"misses the rows fitted by {rms:.4g} mm RMS" in said[0]
    assert rms > 1e3 * validation.UNMODELLED
    unknown = calibrate(on2, data, holdout=holdout, seed=1)  # no noise given: as before
    assert not [w for w in unknown.warnings if SAID in w]


@pytest.mark.parametrize(("measure", "noise"), [("position", 0.1), ("pose", 0.05)])
def test_honest_data_with_their_noise_are_never_said(monkeypatch, measure, noise):
    """The right chain, the noise given the simulated one, seeds 0-9: no warning even with
    the 5 mm floor removed (the chi-square bar alone)."""
    monkeypatch.setattr(validation, "UNMODELLED", 0.0)
    on3 = load_chain("ur5", tool="wrist_3_link")
    for seed in range(10):
        rows = calib.simulate(on3, 40, measure, marker=MARKER, noise_mm=noise, seed=seed)
        result = calibrate(on3, rows.measurements, noise_mm=noise)
        assert not [w for w in result.warnings if SAID in w], seed


def _ratio(message: str) -> float:
    return float(message.split(" mm RMS, ")[1].split(" times")[0])


def test_the_bar_counts_the_positions_share_of_the_degrees_of_freedom():
    """Residuals of one value ``c``: the noise estimate is ``c sqrt(N / dof)``, by hand (the
    message gives 3 figures)."""
    noise, c = 5e-4, 6e-3
    positions = np.full((20, 3), c)  # 60 equations, 15 unknowns: 45 degrees of freedom
    said = far_above_noise(positions, 1, 15, noise)
    assert said is not None
    assert _ratio(said) == pytest.approx(12 * np.sqrt(60 / 45), rel=5e-3)
    assert "10.39 mm RMS" in said  # c sqrt(3) per point
    poses = np.hstack([positions, np.zeros((20, 3))])  # 120 rows: positions' share 60 * 105 / 120
    assert _ratio(far_above_noise(poses, 1, 15, noise) or "") == pytest.approx(
        12 * np.sqrt(60 / (60 * 105 / 120)), rel=5e-3
    )
    unseen = np.full((20, 6), c)
    unseen[:10, 3:] = np.nan  # marker 2 seen in 10 rows: 90 equations, 75 degrees of freedom
    assert _ratio(far_above_noise(unseen, 2, 15, noise) or "") == pytest.approx(
        12 * np.sqrt(90 / 75), rel=5e-3
    )
    assert far_above_noise(positions, 1, 15, c / 8) is None  # 9.24 times: under the bar
    assert far_above_noise(positions, 1, 15, None) is None  # no noise given
    assert far_above_noise(positions / 2.4, 1, 15, noise / 10) is None  # 4.33 mm: under 5 mm
