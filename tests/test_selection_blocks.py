"""The selection with the objects' columns by block (issue 31).

Every figure is checked against the dense route: the same selection computed with every
object's columns in the Jacobian (dense QR bases, dense normal equations).
"""

from __future__ import annotations

import numpy as np
import pytest
from test_calibration import refit_loo

from calib import load_chain
from calib.calibration import contact_fit
from calib.calibration.contact_checks import MIN_TOUCHES
from calib.calibration.entry import calibrate_contacts
from calib.calibration.forward_paths import paths
from calib.calibration.object_columns import ObjectColumns
from calib.calibration.selection import select
from calib.measurements.contact_campaign import simulate_contacts


def _dense(own: np.ndarray, index: np.ndarray, K: int) -> np.ndarray:
    """Every object's columns ``(m, rows, K o)``, zero off each touch's own object."""
    m, rows, o = own.shape
    A = np.zeros((m, rows, K * o))
    for t in range(m):
        A[t, :, o * index[t] : o * index[t] + o] = own[t]
    return A


def _same(dense, block, rel: float = 1e-9) -> None:
    """Two selections alike: the same choices, their errors to ``rel``."""
    assert block.kept == dense.kept and block.winner == dense.winner
    assert block.strength == dense.strength and block.guarded == dense.guarded
    assert [s.name for s in block.steps] == [s.name for s in dense.steps]
    assert np.allclose([s.loo for s in block.steps], [s.loo for s in dense.steps], rtol=rel)
    for name in ("registration_cv", "selection_cv", "complete_cv"):
        a, b = getattr(dense, name), getattr(block, name)
        assert (np.isnan(a) and np.isnan(b)) or abs(a - b) <= rel * abs(a), name


def _both(own, index, K, shared, e, fixed, names, groups=None):
    """The dense and the block selection of the same problem."""
    J = np.concatenate([_dense(own, index, K), shared], axis=2)
    dense = select(J, e, K * own.shape[2] + fixed, names, groups=groups)
    block = select(shared, e, fixed, names, groups=groups, objects=ObjectColumns(own, index, K))
    assert np.allclose(block[1], dense[1], rtol=1e-9)  # the prior weights
    return dense[0], block[0]


def _problem(rng, index, K, fixed=2, cand=8, rows=3, o=3):
    """Object columns, dense columns, residuals of which some candidates explain part."""
    m = len(index)
    own = rng.standard_normal((m, rows, o))
    shared = rng.standard_normal((m, rows, fixed + cand))
    truth = np.r_[np.zeros(fixed), rng.standard_normal(cand) * (rng.random(cand) < 0.5)]
    e = shared @ truth + 0.3 * rng.standard_normal((m, rows))
    e += np.einsum("mro,mo->mr", own, rng.standard_normal((K, o))[index])
    return own, shared, e


@pytest.mark.parametrize("seed", range(3))
def test_a_random_block_problem_selects_as_the_dense_one(seed):
    """12 objects of 6 configurations each (each in several guard folds), with and without
    repeated postures: the same path, prior, errors and choice as with the dense columns."""
    rng = np.random.default_rng(seed)
    K, fixed = 12, 2
    index = np.arange(72) % K  # object k: configurations k, k + 12, ... (folds k, k + 2, ...)
    own, shared, e = _problem(rng, index, K, fixed)
    names = tuple(f"p{k}" for k in range(shared.shape[2] - fixed))
    _same(*_both(own, index, K, shared, e, fixed, names))
    repeat = np.r_[np.arange(72), [3, 7, 7]]  # configurations 3 and 7 recorded again
    noise = 0.01 * rng.standard_normal((len(repeat), 3))
    dense, block = _both(
        own[repeat], index[repeat], K, shared[repeat], e[repeat] + noise, fixed, names, repeat
    )
    _same(dense, block)


def test_a_subset_without_an_object_leaves_its_columns_out():
    """A guard fold that holds out every configuration of an object: its forward path by
    block is that of the dense leave-one-out (refits from scratch, ``refit_loo``) of the
    fold's rows without that object's columns, step by step (the dense route's QR
    turns the fold's zero columns into spurious unit columns, which fit arbitrary rows)."""
    rng = np.random.default_rng(7)
    K, fixed, rows = 6, 2, 3
    index = np.arange(60) % K
    index[[0, 10, 20]] = K  # object K: configurations 0, 10 and 20, all in fold 0
    own, shared, e = _problem(rng, index, K + 1, fixed)
    objects = ObjectColumns(own, index, K + 1)
    train = np.arange(60) % 10 != 0
    A = shared.reshape(-1, shared.shape[2])
    start, cand = [0, 1], list(range(2, shared.shape[2]))
    order, errors = paths(A, e.ravel(), rows, start, cand, train[None], objects)[0]
    assert len(order) == len(cand)
    assert not train[index == K].any()  # the object is wholly held out
    dense = np.concatenate([_dense(own, index, K + 1)[:, :, : K * 3], shared], axis=2)[train]
    for k in range(len(order) + 1):
        cols = list(range(K * 3)) + [K * 3 + c for c in start + order[:k]]
        Ak = dense[:, :, cols].reshape(-1, len(cols))
        loo = np.sqrt(refit_loo(Ak, e[train].ravel(), rows).sum() / (np.sum(train) * rows / 3))
        assert np.sqrt(np.sum(errors[k]) / (np.sum(train) * rows / 3)) == pytest.approx(loo)


def test_the_contact_selection_by_block_is_the_dense_one(forty_planes, monkeypatch):
    """TALOS touching 40 planes 6 times each (conftest): the joint engine's selection with the
    planes' columns by block chooses what its dense selection of the whole Jacobian
    chooses, and the fits by block and dense reach one minimum."""
    _, _, train = forty_planes
    chain = load_chain("talos", base="left_sole_link", tool="gripper_left_base_link")
    block = calibrate_contacts(chain, train)
    monkeypatch.setattr(contact_fit, "BLOCK_UNKNOWNS", 10**9)  # the dense route
    dense = calibrate_contacts(chain, train)
    assert dense.selection is not None and block.selection is not None
    assert len(dense.selection.kept) > 10
    _same(dense.selection, block.selection)
    assert np.allclose(block.estimate, dense.estimate, atol=1e-9, rtol=0)


def test_proposals_that_leave_a_plane_too_few_touches_are_not_started_from():
    """UR5 touching 40 planes 4 times each: the robust fit's proposals left a plane 2
    touches, and the calibration ended in a ContactGeometryError (on main); now each plane
    keeps its touches and the calibration is delivered."""
    chain = load_chain("ur5")
    data = simulate_contacts(chain, 160, "plane", contacts=40, noise_mrad=0.01, seed=1).data
    result = calibrate_contacts(chain, data, params="complete")
    ids = np.array(data.ids)
    out = np.isin(np.arange(1, data.m + 1), [o.row for o in result.chains[0].outliers])
    assert all(np.sum(ids[~out] == k) >= MIN_TOUCHES for k in data.contacts)
    assert result.stats["train"].length_rms_mm < result.stats["train_registration"].length_rms_mm
