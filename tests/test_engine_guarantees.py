"""The joint engine keeps the single chain's guarantees: the memory bound checked before any
work, and a fit whose Jacobian at the solution is rank-deficient refused."""

from __future__ import annotations

import pytest

from calib import calibrate, load_chain, simulate_contacts
from calib.calibration import choice, engine, register
from calib.calibration.engine_result import ContactChainsCalibration
from calib.exceptions import InvalidArgumentError


def _touches():
    return simulate_contacts(load_chain("ur5"), 40, "plane", contacts=2, seed=0).data


def test_one_chain_touching_too_big_for_memory_is_refused_before_any_work(monkeypatch):
    """The bound (per touch and object column) exceeded: one line, before the registration."""
    chain, data = load_chain("ur5"), _touches()
    monkeypatch.setattr(choice, "SELECTION_BYTES", (0, 0, 2**31 // (40 * 6) + 1))
    registered = []
    monkeypatch.setattr(register, "_checked", lambda *a: registered.append(a))
    with pytest.raises(InvalidArgumentError, match=r"GB: fewer touches or planes$") as err:
        calibrate(chain, data, params="complete")
    assert "40 touches of 2 planes (6 of their unknowns)" in str(err.value)
    assert registered == []  # no work done


def test_one_chain_touching_at_the_memory_bound_is_fitted(monkeypatch):
    chain, data = load_chain("ur5"), _touches()
    monkeypatch.setattr(choice, "SELECTION_BYTES", (0, 0, 2**31 // (40 * 6)))
    r = calibrate(chain, data, params="complete")
    assert isinstance(r, ContactChainsCalibration) and r.accepted, r.refusal


def test_a_rank_deficient_fit_is_refused(monkeypatch):
    """The same direction offered twice (two equal columns): an SVD of the Jacobian the test
    builds from the result confirms the deficiency, and the engine refuses in one line."""
    chain, data = load_chain("ur5"), _touches()
    choose = engine.choose

    def twice(*args):
        model, wide, selection, prior = choose(*args)
        return model.with_free((*model.free, model.free[0])), wide, selection, prior

    monkeypatch.setattr(engine, "choose", twice)
    r = calibrate(chain, data, params="complete")
    assert r.free.count(r.free[-1]) == 2  # offered twice indeed
    assert not r.accepted
    assert r.refusal.startswith(f"the data do not determine the {len(r.free)} fitted parameters")
    assert "\n" not in r.refusal
