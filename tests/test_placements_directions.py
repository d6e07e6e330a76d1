"""The MDH directions (placements.mdh_directions) kept for a robot calibrated again."""

from __future__ import annotations

import numpy as np

import calib.calibration.placements as placements
from calib import load_chain
from calib.calibration.placements import Placements, mdh_directions
from calib.kinematics.mdh import from_chain


def fresh(chain, mdh, seed=0, label="complete"):
    """The directions made with nothing kept."""
    kept = list(placements._DIRECTIONS)
    placements._DIRECTIONS.clear()
    try:
        return mdh_directions(Placements.of((chain,)), chain, mdh, seed, label)
    finally:
        placements._DIRECTIONS[:] = kept


def test_a_robot_calibrated_again_reuses_its_directions(monkeypatch):
    """Equal inputs in new objects (a calibration run again): the directions are made once,
    and each call gets its own copy of them."""
    chain = load_chain("ur5")
    monkeypatch.setattr(placements, "_DIRECTIONS", [])
    made = []
    inner = placements.identification_jacobian
    monkeypatch.setattr(
        placements, "identification_jacobian", lambda *a: made.append(1) or inner(*a)
    )
    first = mdh_directions(Placements.of((chain,)), chain, from_chain(chain))
    second = mdh_directions(Placements.of((chain,)), chain, from_chain(chain))
    assert len(made) == 1
    np.testing.assert_array_equal(first[0], second[0])
    assert first[1] == second[1]
    second[0][:] = 0.0  # a copy: what is kept is untouched
    third = mdh_directions(Placements.of((chain,)), chain, from_chain(chain))
    np.testing.assert_array_equal(third[0], first[0])
    assert len(made) == 1


def test_other_inputs_get_their_own_directions(monkeypatch):
    """Another geometry (a fitted MDH model), seed, parameter set or chain: the directions
    made afresh, never the ones kept."""
    monkeypatch.setattr(placements, "_DIRECTIONS", [])
    ur5, ur10 = load_chain("ur5"), load_chain("ur10")
    mdh = from_chain(ur5)
    nominal = mdh_directions(Placements.of((ur5,)), ur5, mdh)
    fitted = mdh.replace(d=mdh.d + np.r_[0.0, 0.0, 2e-3, np.zeros(len(mdh.d) - 3)])
    cases = [(ur5, fitted, 0, "complete"), (ur5, mdh, 1, "complete"),
             (ur5, mdh, 0, "paper"), (ur10, from_chain(ur10), 0, "complete")]  # fmt: skip
    for chain, model, seed, label in cases:
        got = mdh_directions(Placements.of((chain,)), chain, model, seed, label)
        want = fresh(chain, model, seed, label)
        np.testing.assert_array_equal(got[0], want[0])
        assert got[1] == want[1]
        assert got[0].shape != nominal[0].shape or not np.array_equal(got[0], nominal[0])
