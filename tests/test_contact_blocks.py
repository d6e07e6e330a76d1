"""Contacts of many objects: the objects' unknowns eliminated object by object."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from calib import load_chain
from calib.calibration import contact_choice, contact_fit, contact_pipeline
from calib.calibration.contact_blocks import BlockSystem, block_lstsq
from calib.calibration.contact_fit import block_fit, block_structural
from calib.calibration.contact_model import ContactModel
from calib.calibration.solve import fit
from calib.identification.parameters import ParameterSet


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


def test_block_structural_check_keeps_the_dense_check_columns(forty_planes, monkeypatch):
    nominal, start, train = forty_planes
    wide = ContactModel(contact_choice.level_candidates(nominal, "complete"), start.frames, ())
    assert contact_fit.by_block(wide)
    qf, _ = contact_pipeline.touching_postures(start, train.q, train.ids)
    held = dataclasses.replace(train, q=qf)
    blocks = block_structural(wide, start, held, None)
    monkeypatch.setattr(contact_fit, "BLOCK_UNKNOWNS", 10**9)  # the dense route
    dense = contact_choice.structural(wide, start, train, None)
    assert sorted(blocks) == sorted(dense) and len(dense) < wide.size()


@pytest.mark.parametrize("with_prior", [False, True])
def test_block_fit_reaches_minpacks_minimum(forty_planes, with_prior):
    """Levenberg-Marquardt by block against SciPy's MINPACK on the dense Jacobian (the
    parameters the touches determine, as the pipeline frees them)."""
    nominal, start, train = forty_planes
    offered = contact_choice.level_candidates(nominal, "complete")
    wide = ContactModel(offered, start.frames, ())
    kept = contact_choice.structural(wide, start, train, None)[wide.fixed :]
    params = tuple(offered.parameters[c - wide.fixed] for c in sorted(kept))
    model = ContactModel(ParameterSet("free", params), start.frames, ())
    prior = None
    if with_prior:
        rng = np.random.default_rng(0)
        prior = np.r_[np.zeros(model.fixed), rng.uniform(0.0, 0.1, model.size() - model.fixed)]
    dense = fit(model, start, train, None, 1.0, prior=prior)
    blocks = block_fit(model, start, train, None, prior=prior)
    assert dense.converged and blocks.converged
    assert np.allclose(blocks.x, dense.x, atol=1e-9, rtol=0)
    assert np.allclose(blocks.f, dense.f, atol=1e-11, rtol=0)  # 1e-8 mm
    assert np.allclose(blocks.J, dense.J, atol=1e-9, rtol=0)


def test_a_long_recording_of_one_plane_needs_no_touches_by_touches_matrix():
    """6,000 noise-free touches of one plane: registered (the plane recovered) with a peak of
    memory far below one 6,000 x 6,000 matrix (288 MB; the plane's start once built it)."""
    import tracemalloc

    from test_contact_registration import CONTACT, GUESS, PLANES, _flush_touches

    from calib.calibration.contact_registration import register_planes

    R, p = _flush_touches(PLANES["table"], CONTACT, 6000, 0)
    tracemalloc.start()
    try:
        reg = register_planes(R, p, ["table"] * 6000, GUESS)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 60e6, peak
    assert np.allclose(reg.planes[0, :3, 2], PLANES["table"][:3, 2], atol=1e-9)
    assert np.max(np.abs(reg.residuals)) < 1e-9


def test_block_fit_of_compliances_reaches_minpacks_minimum(forty_planes):
    """With the joint compliances too (standing torques): the same minimum as MINPACK's, the
    cost no higher (MINPACK stops a little earlier on these scales)."""
    from calib.calibration import contact_elastic

    nominal, start, train = forty_planes
    chain = load_chain("talos", base="left_sole_link", tool="gripper_left_base_link")
    load = contact_elastic.standing(chain, train.kind, True, None)
    torque = contact_elastic.torques(load, train, None)[0]
    offered = contact_choice.level_candidates(nominal, "offsets")
    comp = tuple(range(nominal.n))
    wide = ContactModel(offered, start.frames, comp)
    kept = contact_choice.structural(wide, start, train, load)
    split = wide.fixed + len(offered)
    params = tuple(offered.parameters[c - wide.fixed] for c in kept if wide.fixed <= c < split)
    joints = tuple(comp[c - split] for c in kept if c >= split)
    assert joints  # compliances are fitted
    model = ContactModel(ParameterSet("free", params), start.frames, joints)
    dense = fit(model, start, train, torque, 1.0)
    blocks = block_fit(model, start, train, torque)
    assert dense.converged and blocks.converged
    assert np.allclose(blocks.x, dense.x, atol=1e-7, rtol=0)
    assert np.allclose(blocks.f, dense.f, atol=1e-9, rtol=0)  # 1e-6 mm
    assert np.sum(blocks.f**2) <= np.sum(dense.f**2) * (1 + 1e-12)
