"""The registration's alternation, the error model's apply and Jacobian, and the fit's cache.

Each is checked against a route it does not share: the alternation against its plain form
(every predicted point formed, NumPy's least squares and SVD), the rigid fit against SciPy's
Kabsch solution, the Jacobian of several markers against central differences of the
residuals (the MDH values moved by ``ParameterSet.apply``), and the fit's kept evaluations
against a fresh evaluation at each x.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import chain_of, wide_minus_measured, wide_state
from scipy.spatial.transform import Rotation

from calib.calibration.model import (
    ErrorModel,
    MeasuredKind,
    generic_measurements,
    registration_state,
)
from calib.calibration.registration import ITERATIONS, register, rigid_fit
from calib.calibration.solve import Problem
from calib.identification.parameters import complete_parameters
from calib.kinematics.mdh import from_chain
from calib.kinematics.so3 import rotation_matrix

MARKERS = np.array([[0.05, 0.02, 0.1], [-0.03, 0.06, 0.08], [0.0, -0.04, 0.12]])


def _campaign(measure: str, m: int = 25, seed: int = 4):
    """Noisy measurements of three markers by a chain in a tilted, shifted instrument frame."""
    chain = chain_of("panda")
    nominal = from_chain(chain)
    rng = np.random.default_rng(seed)
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = rotation_matrix(rng.normal(size=3)), rng.normal(size=3)
    tool = np.eye(3) if measure == "pose" else None
    state = registration_state(nominal, frame, MARKERS, tool)
    q = chain.random_configurations(m, seed)
    data = generic_measurements(state, tuple(chain.joint_names), q)
    noisy = data.position + 1e-3 * rng.normal(size=data.position.shape)
    return nominal, state, dataclasses.replace(data, position=noisy)


def _plain_register(mdh, q, points):
    """The alternation in its plain form: every point predicted, NumPy's least squares."""
    kin = mdh.kinematics(q)
    Rt, pt = kin.R[:, -1], kin.p[:, -1]
    K = points.shape[1]
    mk = np.zeros((K, 3))
    A = Rt.reshape(-1, 3)
    for _ in range(ITERATIONS):
        pred = pt[:, None, :] + np.einsum("mij,kj->mki", Rt, mk)
        ca, cb = pred.reshape(-1, 3).mean(axis=0), points.reshape(-1, 3).mean(axis=0)
        U, _, Vt = np.linalg.svd((pred.reshape(-1, 3) - ca).T @ (points.reshape(-1, 3) - cb))
        R = Vt.T @ np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))]) @ U.T
        t = cb - R @ ca
        local = (points - t) @ R - pt[:, None, :]
        new = np.linalg.lstsq(A, local.transpose(0, 2, 1).reshape(-1, K), rcond=None)[0].T
        done = np.max(np.abs(new - mk)) < 1e-12
        mk = new
        if done:
            break
    return R, t, mk


def test_register_follows_the_plain_alternation():
    nominal, _, data = _campaign("position")
    state = register(nominal, data.q, data.points)
    R, t, mk = _plain_register(nominal, data.q, data.points)
    # the same iterates up to round-off, frame and markers computed afresh from them
    assert np.abs(state.markers - mk).max() < 1e-12
    assert np.abs(state.frame[:3, :3] - R).max() < 1e-12
    assert np.abs(state.frame[:3, 3] - t).max() < 1e-12


@pytest.mark.parametrize("mirror", [False, True])
def test_rigid_fit_is_kabsch(mirror):
    rng = np.random.default_rng(7)
    A = rng.normal(size=(12, 3))
    R0 = rotation_matrix(rng.normal(size=3))
    B = A @ R0.T + rng.normal(size=3) + 0.05 * rng.normal(size=A.shape)
    if mirror:  # a reflection fits best: the rotation must still be proper
        B = B * np.array([1.0, 1.0, -1.0])
    R, t = rigid_fit(A, B)
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    ref = Rotation.align_vectors(B - cb, A - ca)[0].as_matrix()
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)
    assert np.abs(R - ref).max() < 1e-9
    assert np.abs(t - (cb - ref @ ca)).max() < 1e-9


def _model(nominal, measure: str) -> ErrorModel:
    pset = complete_parameters(nominal)
    return ErrorModel(pset, pset.names[3:15], MeasuredKind(len(MARKERS), measure == "pose"))


def _central(f, x: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """Central differences of ``f`` at ``x`` ``(m, rows, len(x))``."""
    return np.stack([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(len(x))], axis=2)


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_jacobian_of_several_markers_matches_finite_differences(measure):
    """The own unknowns' at any x, joints deflected; with MDH columns at the state (x = 0)."""
    nominal, state, data = _campaign(measure, m=12)
    model = _model(nominal, measure)
    own, torque = model.own, np.random.default_rng(0).normal(size=data.q.shape)
    x = 1e-2 * np.random.default_rng(1).normal(size=own.size())
    J = own.jacobian(state, x, data, torque)
    fd = _central(lambda x: -own.apply(state, x).residuals(data, torque), x)
    assert J.shape == fd.shape == (data.m, own.rows, own.size())
    assert np.abs(J - fd).max() < 1e-6 * max(1.0, np.abs(J).max())
    J = model.jacobian(state, data)
    fd = _central(lambda x: wide_minus_measured(model, state, data, x), np.zeros(model.size()))
    assert J.shape == fd.shape == (data.m, own.rows, model.size())
    assert np.abs(J - fd).max() < 1e-6 * max(1.0, np.abs(J).max())


@dataclasses.dataclass(frozen=True)
class _Geometry:
    """A fit's model that moves the geometry too (MDH values, as the joint engine's moves it)."""

    wide: ErrorModel

    def size(self) -> int:
        return self.wide.size()

    def apply(self, start, x):
        return wide_state(self.wide, start, x)

    def jacobian(self, start, x, data, torque, state=None, kin=None):
        return self.wide.jacobian(self.apply(start, x) if state is None else state, data, kin)


@pytest.mark.parametrize("prior", [None, 0.1])
@pytest.mark.parametrize("frames", [False, True])
def test_problem_keeps_evaluations_without_mixing_them(prior, frames):
    nominal, state, data = _campaign("pose", m=10)
    model = _Geometry(_model(nominal, "pose"))
    if frames:  # x moves no geometry: the kinematics are shared by every x
        model = model.wide.own
    torque = np.random.default_rng(3).normal(size=data.q.shape)
    rng = np.random.default_rng(6)
    xs = [1e-2 * rng.normal(size=model.size()) for _ in range(3)]
    weights = None if prior is None else np.full(model.size(), prior)
    kept = Problem(model, state, data, torque, prior=weights)
    for i in (0, 1, 0, 2, 1, 2, 2, 0):
        fresh = Problem(model, state, data, torque, prior=weights)
        J = kept.jac(xs[i])
        assert np.array_equal(kept.fun(xs[i]), fresh.fun(xs[i]))
        assert np.array_equal(J, fresh.jac(xs[i]))
        J *= 2.0  # SciPy scales the Jacobian in place for a robust loss
        assert np.array_equal(kept.data_jac(xs[i]), fresh.data_jac(xs[i]))
        assert np.array_equal(kept.state(xs[i]).frame, model.apply(state, xs[i]).frame)
