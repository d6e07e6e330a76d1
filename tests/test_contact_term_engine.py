"""One chain touching goes through the joint engine: every contact kind, several objects.

Independent routes: the truth the simulation used (the true robot and objects, compared
through what no gauge changes: ``test_contact_kinds``' invariants), and Pinocchio on the
written URDF (``test_contact_kinds``' command-line test, which now takes this route too).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_contact_kinds import _invariants, _placements, _scale_fit, _similarity_fit

from calib import Problem, Term, calibrate, load_robot, simulate_contacts
from calib.calibration.engine_result import ContactChainsCalibration
from calib.exceptions import DataError, InvalidArgumentError

KINDS = ("plane", "plane-point", "fixed-point", "fixed-pose")
TALOS = ("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("params", ["complete", "paper"])
def test_every_kind_with_two_objects_round_trips_through_the_engine(kind, params):
    """Noise-free touches of two objects: held-out gaps vanish, the truth is recovered."""
    chain = load_robot("panda")
    touches = 160 if kind == "plane-point" else 80
    camp = simulate_contacts(chain, touches, kind, contacts=2, seed=3)
    r = calibrate(chain, camp.data, params=params, holdout=0.3, seed=1)
    assert isinstance(r, ContactChainsCalibration) and r.accepted, r.refusal
    (part,) = r.chains
    held, reg = part.stats["held_out"], part.stats["held_out_registration"]
    objects = part.objects()
    assert held.m >= 20 and set(objects) == set(camp.truth.frames)
    top = np.array(held.max) * np.where(held.angular, math.radians(1.0), 1e-3)  # [m, rad]
    assert np.max(top) < 1e-9 and reg.weighted_mm > 1e-3
    q = chain.random_configurations(40, 7)  # postures where no contact holds
    true_T = _placements(camp.truth.true_mdh, np.eye(4), q)
    got_T = _placements(part.calibrated, part.contact, q)
    for name, F_true in camp.truth.frames.items():
        exact_t, scaled_t = _invariants(kind, true_T, F_true)
        exact_g, scaled_g = _invariants(kind, got_T, objects[name])
        assert np.max(np.abs(exact_g - exact_t), initial=0.0) < 1e-8
        if scaled_t.size:
            fit = _similarity_fit if kind == "fixed-point" else _scale_fit
            s, residual = fit(scaled_g, scaled_t)
            assert residual < 1e-8 and abs(abs(s) - 1) < 0.1
    assert r.stats is part.stats  # what a single chain's result offered (notebook 06)
    doc = r.to_dict()
    assert doc["shape"] == "contacts" and doc["measure"] == kind
    group = f"{camp.data.kind.object_name}s"
    assert set(doc["objects"][group]) == set(camp.truth.frames)
    assert doc["errors"]["held_out"]["calibrated"]["configs"] == held.m


def test_talos_plane_touches_round_trip_through_the_engine():
    """TALOS sole to gripper, one table: the default level through ``calibrate(Problem)``."""
    chain = load_robot(*TALOS)
    camp = simulate_contacts(chain, 80, "plane", seed=3)
    r = calibrate(Problem((Term(chain, camp.data),), params="complete", holdout=0.3, seed=1))
    assert isinstance(r, ContactChainsCalibration) and r.accepted, r.refusal
    held = r.chains[0].stats["held_out"]
    assert max(held.height_max_mm, 1e3 * math.radians(held.roll_max_deg)) < 1e-6


def test_joint_compliance_and_many_objects_are_fitted_by_the_engine(monkeypatch):
    """``elastic`` and 30 planes or more: the engine's result. Many objects go by block
    (:func:`~calib.calibration.contact_fit.block_fit`, called) and reach the minimum of the
    dense fit (MINPACK on the whole Jacobian) at every level."""
    from calib.calibration import contact_fit, engine

    chain = load_robot(*TALOS)
    few = simulate_contacts(chain, 60, "plane", seed=3).data
    r = calibrate(chain, few, params="offsets", elastic=True)
    assert isinstance(r, ContactChainsCalibration) and r.elastic
    many = simulate_contacts(chain, 150, "plane", contacts=30, noise_mrad=0.1, seed=3).data
    calls = []

    def spy(*args, **kwargs):
        calls.append(1)
        return contact_fit.block_fit(*args, **kwargs)

    for params in ("offsets", "auto"):
        with monkeypatch.context() as m:
            m.setattr(engine, "block_fit", spy)
            blocks = calibrate(chain, many, params=params, holdout=0.2)
        with monkeypatch.context() as m:
            m.setattr(contact_fit, "BLOCK_UNKNOWNS", 10**9)  # the dense route
            dense = calibrate(chain, many, params=params, holdout=0.2)
        assert blocks.accepted and dense.accepted and blocks.fitted == dense.fitted
        assert np.allclose(blocks.estimate, dense.estimate, atol=1e-8, rtol=0)
        gaps = [r.chains[0].stats["held_out"].weighted_mm for r in (blocks, dense)]
        assert gaps[0] > 1e-3 and abs(gaps[0] - gaps[1]) < 1e-6  # [mm]
    assert len(calls) == 2


def test_too_few_touches_for_a_level_and_empty_touches_are_refused():
    chain = load_robot("ur5")
    data = simulate_contacts(chain, 30, "fixed-point", seed=0).data
    with pytest.raises(DataError, match="equations"):  # 3 touches kept
        calibrate(chain, data, params="complete", holdout=0.9)
    empty = simulate_contacts(chain, 12, "fixed-point", seed=0).data
    empty = type(empty)(empty.joint_names, empty.q[:0], (), empty.kind, "none.csv")
    with pytest.raises(DataError, match="empty contact set"):
        calibrate(chain, empty)


def test_shared_planes_take_one_object_per_chain():
    chain = load_robot(*TALOS)
    right = load_robot(TALOS[0], "right_sole_link", "gripper_right_base_link")
    two = simulate_contacts(chain, 40, "plane", contacts=2, seed=3).data
    one = simulate_contacts(right, 40, "plane", seed=3).data
    with pytest.raises(InvalidArgumentError, match="one object"):
        calibrate(Problem((Term(chain, two), Term(right, one)), shared_planes=True))
    both = calibrate(Problem((Term(chain, two), Term(right, one)), params="frames"))
    with pytest.raises(InvalidArgumentError, match=r"chains\[k\]\.stats"):
        _ = both.stats
