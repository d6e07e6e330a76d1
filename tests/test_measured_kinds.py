"""Measured data through the measurement kind: the calibration's residual and Jacobian rows.

The kind (:class:`calib.Measurement`) holds the one implementation of a measured residual
(K markers, the measurement frame, the measured frame's rotation) and of its Jacobian rows;
the calibration's :class:`~calib.calibration.model.State` and
:class:`~calib.calibration.model.ErrorModel` use it. Checked against Pinocchio's forward
kinematics of the URDF file and against finite differences.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import wide_minus_measured, wide_state
from pinref import file_chain_poses

from calib import Measurement, Measurements, from_chain, load_chain
from calib.calibration.model import ErrorModel, MeasuredKind, registration_state
from calib.design.observability import MARKER_WORK_COPIES, marker_work_bytes
from calib.identification.kinds import kind_of
from calib.identification.measures import POSE, POSITION, Observed
from calib.identification.parameters import complete_parameters
from calib.kinematics.so3 import matrix_to_quaternion

M = 12


def _setup(seed: int, pose: bool):
    """A UR5 state (frame, 2 markers, measured-frame rotation) and noisy data of it."""
    rng = np.random.default_rng(seed)
    chain = load_chain("ur5")
    q = chain.random_configurations(M, seed)
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = pin.exp3(rng.normal(size=3)), rng.normal(size=3)
    markers = 0.1 * rng.normal(size=(2, 3))
    tool = pin.exp3(0.3 * rng.normal(size=3)) if pose else None
    state = registration_state(from_chain(chain), frame, markers, tool)
    # Pinocchio's tool placement in the chain's base frame, from the URDF file
    poses = [
        T for _, T, _ in file_chain_poses(chain.urdf_path, chain.base_frame, chain.tool_frame, q)
    ]
    Rt = np.array([T.rotation for T in poses])
    pt = np.array([T.translation for T in poses])
    true_pts = (
        np.einsum("ij,mkj->mki", frame[:3, :3], pt[:, None] + np.einsum("mij,kj->mki", Rt, markers))
        + frame[:3, 3]
    )
    measured = true_pts + 1e-3 * rng.normal(size=true_pts.shape)
    quat, true_rot, meas_rot = None, None, None
    if pose:
        true_rot = frame[:3, :3] @ Rt @ tool
        meas_rot = np.array([pin.exp3(1e-2 * rng.normal(size=3)) for _ in range(M)]) @ true_rot
        quat = matrix_to_quaternion(meas_rot)
    data = Measurements(chain.joint_names, q, measured.reshape(M, -1), quat)
    expected = [(measured - true_pts).reshape(M, -1)]
    if pose:
        expected.append(
            np.array([pin.log3(a @ b.T) for a, b in zip(meas_rot, true_rot, strict=True)])
        )
    return chain, state, data, np.hstack(expected)


@pytest.mark.parametrize("pose", [False, True])
def test_state_residuals_are_pinocchio_measured_minus_predicted(pose):
    _, state, data, expected = _setup(5, pose)
    assert data.kind == (POSE if pose else POSITION)
    np.testing.assert_allclose(state.residuals(data), expected, rtol=0, atol=1e-12)


def test_row_subset_residual_is_its_rows_of_the_pose_residual():
    _, state, data, expected = _setup(6, True)
    kind = kind_of("x,z,ry")
    kin = state.mdh.kinematics(data.q)
    out = kind.residual(
        kin.R[:, -1], kin.p[:, -1], data.observed, state.markers, state.frame, state.tool_rotation
    )
    # x, z of marker 1, x, z of marker 2, then ry: columns of (x1 y1 z1 x2 y2 z2 rx ry rz)
    np.testing.assert_allclose(out, expected[:, [0, 2, 3, 5, 7]], rtol=0, atol=1e-12)
    assert kind.rows_of(2) == 5 and kind.full_rows(2) == 9


def test_measured_poses_of_two_markers():
    rng = np.random.default_rng(2)
    R = np.array([pin.exp3(rng.normal(size=3)) for _ in range(4)])
    p = rng.normal(size=(4, 3))
    markers = rng.normal(size=(2, 3))
    dphi, dp = 1e-3 * rng.normal(size=(4, 3)), 1e-3 * rng.normal(size=(4, 3))
    Mpose = np.zeros((4, 4, 4))
    Mpose[:, :3, :3] = np.array([pin.exp3(a) for a in dphi]) @ R
    Mpose[:, :3, 3], Mpose[:, 3, 3] = p + dp, 1.0
    out = POSE.residual(R, p, Mpose, markers)
    for k in range(2):  # each marker: the measured pose moves it by dp + dphi x (R m_k)
        seen = Mpose[:, :3, 3] + Mpose[:, :3, :3] @ markers[k]
        np.testing.assert_allclose(
            out[:, 3 * k : 3 * k + 3], seen - (p + R @ markers[k]), atol=1e-14
        )
    np.testing.assert_allclose(out[:, 6:], dphi, atol=1e-14)
    obs = Observed.of_poses(Mpose, markers)
    assert obs.points.shape == (4, 2, 3)


def _central(f, x: np.ndarray, h: float = 1e-7) -> np.ndarray:
    """Central differences of ``f`` at ``x`` ``(m, rows, len(x))``."""
    return np.stack([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(len(x))], axis=2)


@pytest.mark.parametrize("measure", ["pose", "position"])
def test_error_model_jacobian_of_a_kind_matches_finite_differences(measure):
    """The own unknowns' at any x, joints deflected; the MDH columns' at the state (x = 0)."""
    _, start, data, _ = _setup(7, True)
    kind = kind_of(measure)
    if not kind.rotation_rows:
        start = registration_state(start.mdh, start.frame, start.markers, None)
    pset = complete_parameters(start.mdh)
    model = ErrorModel(pset, pset.names, MeasuredKind(2, measure == "pose"))
    own, torque = model.own, np.random.default_rng(1).normal(size=data.q.shape)
    x = 1e-2 * np.random.default_rng(3).normal(size=own.size())
    J = own.jacobian(start, x, data, torque)
    fd = _central(lambda x: -own.apply(start, x).residuals(data, torque), x)
    assert J.shape == fd.shape == (M, kind.rows_of(2), own.size())
    assert np.abs(J - fd).max() < 1e-6 * max(1.0, np.abs(J).max())
    J = model.jacobian(start, data)
    fd = _central(lambda x: wide_minus_measured(model, start, data, x), np.zeros(model.size()))
    assert J.shape == fd.shape == (M, kind.rows_of(2), model.size())
    assert own.rows == kind.rows_of(2) and model.names()[: own.size()] == own.names()
    assert np.abs(J - fd).max() < 1e-6 * max(1.0, np.abs(J).max())


def test_marker_work_counts_the_kinds_rows_and_constants():
    # pose at 2 markers: 3 x 2 + 3 rows; frame 6 + markers 6 + measured frame 3 columns
    assert marker_work_bytes(10, 2, 30, POSE) == MARKER_WORK_COPIES * 8 * (10 * 9) * (15 + 30)
    assert marker_work_bytes(10, 2, 30, POSITION) == MARKER_WORK_COPIES * 8 * 60 * (12 + 30)
    assert isinstance(POSE, Measurement)


def test_design_data_linearise_at_zero_residual():
    """The counts' and designs' data: the Jacobian is the plain linearisation of the pose.

    Rotation rows: the derivative of ``Log(R(x) R(0)^T)`` at x = 0 (pin.log3), not scaled by
    the rotation error to an arbitrary measured orientation.
    """
    from calib.calibration.model import generic_measurements

    chain, start, _, _ = _setup(5, True)
    pset = complete_parameters(start.mdh)
    model = ErrorModel(pset, pset.names, MeasuredKind(2, True))
    q = chain.random_configurations(6, 2)
    data = generic_measurements(start, chain.joint_names, q)
    J = model.jacobian(start, data)
    _, R0 = start.predict(q)
    h = 1e-6

    def rot(x):
        return wide_state(model, start, x).predict(q)[1]

    fd = np.stack(
        [
            np.array(
                [
                    pin.log3(a @ b.T) - pin.log3(c @ b.T)
                    for a, b, c in zip(rot(h * e), R0, rot(-h * e), strict=True)
                ]
            )
            / (2 * h)
            for e in np.eye(model.size())
        ],
        axis=2,
    )
    assert np.abs(J[:, -3:] - fd).max() < 1e-6 * max(1.0, np.abs(fd).max())
