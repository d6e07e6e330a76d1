"""Contacts of many objects: the objects' unknowns eliminated object by object."""

from __future__ import annotations

import numpy as np
import pytest

from calib import load_chain
from calib.calibration import choice, contact_fit, engine
from calib.calibration.contact_blocks import BlockSystem, block_lstsq
from calib.calibration.entry import calibrate_contacts


def _dense(Jo, Js, index, K):
    """The whole Jacobian ``(m rows, K o + s)``, every object's columns (zero off its own)."""
    m, rows, o = Jo.shape
    A = np.zeros((m, rows, K * o + Js.shape[2]))
    for t in range(m):
        A[t, :, o * index[t] : o * index[t] + o] = Jo[t]
    A[:, :, K * o :] = Js
    return A.reshape(m * rows, -1)


@pytest.mark.parametrize("seed", range(3))
def test_block_least_squares_is_the_dense_least_squares(seed):
    """Objects of 1 to 40 touches (several padded sizes), damping and extra shared rows:
    the same solution as numpy's dense least squares of the whole system."""
    rng = np.random.default_rng(seed)
    K, rows, o, s = 7, 3, 3, 5
    counts = rng.integers(1, 40, K)
    index = rng.permutation(np.repeat(np.arange(K), counts))
    m = len(index)
    Jo, Js = rng.standard_normal((m, rows, o)), rng.standard_normal((m, rows, s))
    r = rng.standard_normal((m, rows))
    damping = rng.uniform(0.1, 1.0, (K, o))
    extra = rng.standard_normal((4, s + 1))
    sol = block_lstsq(BlockSystem(Jo, Js, r, index, K), damping, extra)
    A = np.vstack(
        [
            _dense(Jo, Js, index, K),
            np.c_[np.diag(damping.ravel()), np.zeros((K * o, s))],
            np.c_[np.zeros((4, K * o)), extra[:, :s]],
        ]
    )
    b = -np.r_[r.ravel(), np.zeros(K * o), extra[:, s]]
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    assert np.allclose(np.r_[sol.objects.ravel(), sol.shared], x, atol=1e-10, rtol=0)
    plain = block_lstsq(BlockSystem(Jo, Js, r, index, K))
    x0 = np.linalg.lstsq(_dense(Jo, Js, index, K), -r.ravel(), rcond=None)[0]
    assert np.allclose(np.r_[plain.objects.ravel(), plain.shared], x0, atol=1e-10, rtol=0)


@pytest.mark.parametrize(("params", "elastic"), [("complete", False), ("offsets", True)])
def test_the_engine_by_block_reaches_the_dense_engines_minimum(
    forty_planes, monkeypatch, params, elastic
):
    """TALOS touching 40 planes (conftest): the joint engine's structural check and fit by
    block keep the columns of the dense route (pivoted QR of every column) and reach its
    minimum (MINPACK on the whole Jacobian), the joint compliances (standing torques)
    included; the cost by block no higher."""
    _, _, train = forty_planes
    chain = load_chain("talos", base="left_sole_link", tool="gripper_left_base_link")
    calls: list[str] = []
    for name in ("block_fit", "block_structural"):
        real = getattr(contact_fit, name)
        spy = (lambda f, n: lambda *a, **k: calls.append(n) or f(*a, **k))(real, name)
        target = engine if name == "block_fit" else choice
        monkeypatch.setattr(target, name, spy)
    kw = {"params": params, "elastic": elastic, "holdout": 0.2, "seed": 1}
    block = calibrate_contacts(chain, train, **kw)
    assert {"block_fit", "block_structural"} <= set(calls)
    monkeypatch.setattr(contact_fit, "BLOCK_UNKNOWNS", 10**9)  # the dense route
    dense = calibrate_contacts(chain, train, **kw)
    assert block.accepted and dense.accepted
    assert block.fitted == dense.fitted and block.identifiable == dense.identifiable
    assert any(n.startswith("c") for n in block.fitted) == elastic  # compliances fitted
    assert np.allclose(block.estimate, dense.estimate, rtol=1e-6, atol=1e-9)
    costs = [r.stats["train"].weighted_mm for r in (block, dense)]
    assert costs[0] <= costs[1] * (1 + 1e-9) + 1e-12
    held = [r.stats["held_out"].weighted_mm for r in (block, dense)]
    assert abs(held[0] - held[1]) < 1e-6  # [mm]


def test_a_long_recording_of_one_plane_needs_no_touches_by_touches_matrix():
    """6,000 noise-free touches of one plane: registered (the plane recovered) with a peak of
    memory far below one 6,000 x 6,000 matrix (288 MB; the plane's start once built it)."""
    import tracemalloc

    from test_contact_registration import CONTACT, GUESS, PLANES, _flush_touches

    from calib.calibration.contact_checks import register_contacts
    from calib.identification.contacts import PlaneContact

    R, p = _flush_touches(PLANES["table"], CONTACT, 6000, 0)
    tracemalloc.start()
    try:
        reg = register_contacts(PlaneContact(), R, p, ["table"] * 6000, GUESS)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 60e6, peak
    assert np.allclose(reg.objects[0, :3, 2], PLANES["table"][:3, 2], atol=1e-9)
    assert np.max(np.abs(reg.gaps(R, p, np.zeros(6000, dtype=int)))) < 1e-9
