"""The analytic identification Jacobian: joint columns against Pinocchio's frame Jacobian,
every parameter column against central finite differences of the MDH forward kinematics,
the complete reference model against perturbed Pinocchio joint placements, row layout.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from conftest import chain_of, mdh_of
from pinref import own_random_q, pin_config, pin_frame

import calib
from calib import Measurement
from calib.identification.jacobian import complete_jacobian, identification_jacobian
from calib.identification.parameters import (
    Kind,
    Parameter,
    ParameterSet,
    complete_parameters,
    paper_parameters,
)

ROBOTS = ["aid", "panda", "stanford", "tiago", "ur5", "so100", "kinova", "talos_left_leg"]
MARKER = (0.011, 0.023, 0.037)
POSE = Measurement.of("pose")


def joint_parameters(mdh) -> ParameterSet:
    """theta_k for a revolute row, r_k for a prismatic one: the joint variables."""
    return ParameterSet(
        "joints",
        tuple(
            Parameter(k, Kind.THETA if mdh.sigma[k] == 0 else Kind.R) for k in range(1, mdh.n + 1)
        ),
    )


def pin_joint_jacobian(chain, q: np.ndarray, marker=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Pinocchio's frame Jacobian (LOCAL_WORLD_ALIGNED) of the tool (or a marker frame added to
    a copy of the model), chain columns only, rotated into the base frame: (m * 6, n)."""
    model = pin.Model(chain.model)
    base = pin_frame(model, chain.base_frame)
    tool = pin_frame(model, chain.tool_frame)
    f = model.frames[tool]
    placement = f.placement * pin.SE3(np.eye(3), np.asarray(marker, dtype=float))
    target = model.addFrame(pin.Frame("test_marker", f.parentJoint, tool, placement, pin.OP_FRAME))
    joints = [model.getJointId(name) for name in chain.joint_names]
    data = model.createData()
    out = []
    for qi in q:
        qp = pin_config(model, joints, qi)
        pin.framesForwardKinematics(model, data, qp)
        J = np.asarray(pin.computeFrameJacobian(model, data, qp, target, pin.LOCAL_WORLD_ALIGNED))
        J = J.reshape(6, model.nv)[:, [model.joints[j].idx_v for j in joints]]
        Rb = data.oMf[base].rotation
        out.append(np.vstack([Rb.T @ J[:3], Rb.T @ J[3:]]))
    return np.vstack(out)


def mdh_point_pose(mdh, q, marker):
    T = mdh.forward(q)
    p = T[:, :3, 3] + T[:, :3, :3] @ np.asarray(marker, dtype=float)
    return p, T[:, :3, :3]


def fd_jacobian(mdh, pset: ParameterSet, q, marker=(0.0, 0.0, 0.0), h=1e-6) -> np.ndarray:
    """Central differences of the MDH forward kinematics, pose rows, (m * 6, len(pset))."""
    m = len(q)
    cols = []
    for i in range(len(pset)):
        delta = np.zeros(len(pset))
        delta[i] = h
        p_plus, R_plus = mdh_point_pose(pset.apply(mdh, delta), q, marker)
        p_minus, R_minus = mdh_point_pose(pset.apply(mdh, -delta), q, marker)
        lin = (p_plus - p_minus) / (2 * h)
        ang = np.array([pin.log3(R_plus[j] @ R_minus[j].T) for j in range(m)]) / (2 * h)
        cols.append(np.hstack([lin, ang]).reshape(-1))
    return np.array(cols).T


def assert_close(A: np.ndarray, B: np.ndarray, rel: float) -> None:
    assert A.shape == B.shape
    scale = max(1.0, float(np.abs(B).max()))
    err = float(np.abs(A - B).max())
    assert err <= rel * scale, f"max error {err:.3g} (scale {scale:.3g})"


def select_rows(W_pose: np.ndarray, rows) -> np.ndarray:
    k = W_pose.shape[1]
    return W_pose.reshape(-1, 6, k)[:, list(rows), :].reshape(-1, k)


# --------------------------------------------------------------------------------------
# Joint columns = Pinocchio's frame Jacobian
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize("marker", [(0.0, 0.0, 0.0), MARKER], ids=["tool", "marker"])
def test_joint_columns_equal_pinocchio_frame_jacobian(name, marker):
    chain, mdh = chain_of(name), mdh_of(name)
    q = own_random_q(chain.sigma, 12, seed=21)
    meas = Measurement.of("pose", marker)
    W = identification_jacobian(mdh, joint_parameters(mdh), q, meas)
    assert_close(W, pin_joint_jacobian(chain, q, marker), 1e-10)


def test_prismatic_joint_column_is_its_direction():
    chain, mdh = chain_of("tiago"), mdh_of("tiago")
    assert chain.sigma[0] == 1, "tiago's torso lift is prismatic"
    q = own_random_q(chain.sigma, 5, seed=2)
    J = pin_joint_jacobian(chain, q).reshape(5, 6, chain.n)
    assert np.abs(J[:, 3:, 0]).max() <= 1e-12, "a prismatic joint does not rotate the tool"
    W = identification_jacobian(mdh, paper_parameters(mdh), q, POSE)
    col = W[:, paper_parameters(mdh).index("r1")].reshape(5, 6)
    assert_close(col, J[:, :, 0], 1e-10)


# --------------------------------------------------------------------------------------
# Every column = finite differences of the forward kinematics
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ROBOTS)
@pytest.mark.parametrize(
    "set_of", [paper_parameters, complete_parameters], ids=["paper", "complete"]
)
def test_every_column_equals_finite_differences(name, set_of):
    chain, mdh = chain_of(name), mdh_of(name)
    pset = set_of(mdh)
    q = own_random_q(chain.sigma, 6, seed=31)
    W = identification_jacobian(mdh, pset, q, POSE)
    assert_close(W, fd_jacobian(mdh, pset, q), 1e-7)


@pytest.mark.parametrize("name", ["aid", "panda", "tiago", "stanford"])
def test_marker_and_position_only_columns_equal_finite_differences(name):
    chain, mdh = chain_of(name), mdh_of(name)
    pset = complete_parameters(mdh)
    q = own_random_q(chain.sigma, 6, seed=41)
    fd = fd_jacobian(mdh, pset, q, MARKER)
    W_pose = identification_jacobian(mdh, pset, q, Measurement.of("pose", MARKER))
    assert_close(W_pose, fd, 1e-7)
    W_pos = identification_jacobian(mdh, pset, q, Measurement.of("position", MARKER))
    assert W_pos.shape == (len(q) * 3, len(pset))
    assert_close(W_pos, select_rows(fd, (0, 1, 2)), 1e-7)


def test_complete_set_has_y_where_lines_coincide_and_its_column_is_right():
    """aid: base z and axis 1 coincide, so the complete set carries y1 and beta1."""
    mdh = mdh_of("aid")
    names = complete_parameters(mdh).names
    assert "y1" in names and "beta1" in names
    assert "y1" not in paper_parameters(mdh).names
    assert "beta1" not in paper_parameters(mdh).names
    pset = ParameterSet("two", (Parameter(1, Kind.Y), Parameter(1, Kind.BETA)))
    q = own_random_q(chain_of("aid").sigma, 8, seed=1)
    W = identification_jacobian(mdh, pset, q, POSE)
    assert_close(W, fd_jacobian(mdh, pset, q), 1e-7)
    assert np.linalg.norm(W[:, 0]) > 1.0, "y1 moves the tool"


# --------------------------------------------------------------------------------------
# The complete reference model spans every rigid error of the links
# --------------------------------------------------------------------------------------


def pin_placement_errors(chain, q, marker=(0.0, 0.0, 0.0), h=1e-6) -> np.ndarray:
    """Central differences of Pinocchio's tool pose (in base) w.r.t. a 6-DOF error on every
    chain joint placement, on the base frame placement and on the tool frame placement."""
    model = pin.Model(chain.model)
    base = pin_frame(model, chain.base_frame)
    tool = pin_frame(model, chain.tool_frame)
    joints = [model.getJointId(name) for name in chain.joint_names]
    marker_T = pin.SE3(np.eye(3), np.asarray(marker, dtype=float))

    def pose(mdl, qi):
        data = mdl.createData()
        pin.framesForwardKinematics(mdl, data, pin_config(mdl, joints, qi))
        T = data.oMf[base].inverse() * data.oMf[tool] * marker_T
        return T.translation.copy(), T.rotation.copy()

    cols = []
    targets = [("joint", j) for j in joints] + [("frame", base), ("frame", tool)]
    for kind, idx in targets:
        for i in range(6):
            twist = np.zeros(6)
            twist[i] = h
            res = []
            for sign in (1.0, -1.0):
                mdl = pin.Model(model)
                E = pin.exp6(pin.Motion(sign * twist))
                if kind == "joint":
                    mdl.jointPlacements[idx] = mdl.jointPlacements[idx] * E
                else:
                    f = mdl.frames[idx]
                    f.placement = f.placement * E
                    mdl.frames[idx] = f
                res.append([pose(mdl, qi) for qi in q])
            col = []
            for (p1, R1), (p2, R2) in zip(res[0], res[1], strict=True):
                col.append(np.hstack([(p1 - p2) / (2 * h), pin.log3(R1 @ R2.T) / (2 * h)]))
            cols.append(np.concatenate(col))
    return np.array(cols).T


def rank(W: np.ndarray) -> int:
    s = np.linalg.svd(W, compute_uv=False)
    return int(np.sum(s > 1e-6 * s[0]))


@pytest.mark.parametrize("name", ["aid", "stanford", "tiago", "so100"])
def test_complete_jacobian_spans_pinocchio_placement_errors(name):
    chain, mdh = chain_of(name), mdh_of(name)
    q = own_random_q(chain.sigma, 12, seed=51)
    Wc = complete_jacobian(mdh, q, POSE)
    assert Wc.shape == (12 * 6, 6 * (chain.n + 1))
    Wp = pin_placement_errors(chain, q)
    r_c, r_p = rank(Wc), rank(Wp)
    assert r_c == r_p == rank(np.hstack([Wc, Wp])), "same column space"
    assert r_c == 4 * chain.n_revolute + 2 * chain.n_prismatic + 6


# --------------------------------------------------------------------------------------
# Row layout
# --------------------------------------------------------------------------------------


def test_rows_are_configuration_major_and_subsets_of_the_pose():
    chain, mdh = chain_of("stanford"), mdh_of("stanford")
    pset = complete_parameters(mdh)
    q = own_random_q(chain.sigma, 7, seed=61)
    W = identification_jacobian(mdh, pset, q, POSE)
    assert W.shape == (7 * 6, len(pset))
    for i in range(len(q)):
        Wi = identification_jacobian(mdh, pset, q[i : i + 1], POSE)
        assert np.array_equal(W[6 * i : 6 * (i + 1)], Wi)
    for measure, rows in [("position", (0, 1, 2)), ("x,z,ry", (0, 2, 4)), ("rz,x", (0, 5))]:
        meas = Measurement.of(measure)
        assert meas.rows == rows
        Ws = identification_jacobian(mdh, pset, q, meas)
        assert Ws.shape == (7 * len(rows), len(pset))
        assert np.array_equal(Ws, select_rows(W, rows))
    Wc = complete_jacobian(mdh, q, POSE)
    assert np.array_equal(
        complete_jacobian(mdh, q, Measurement.of("x,z,ry")), select_rows(Wc, (0, 2, 4))
    )


def test_single_configuration_as_vector():
    mdh = mdh_of("aid")
    pset = paper_parameters(mdh)
    q = np.array([0.1, -0.2, 0.3, 0.4, -0.5, 0.6])
    assert np.array_equal(
        identification_jacobian(mdh, pset, q, POSE),
        identification_jacobian(mdh, pset, q[None], POSE),
    )


def test_measurement_of_rejects_bad_input():
    for bad in ("orientation", "x,w", "", "pose,"):
        with pytest.raises(calib.InvalidArgumentError):
            Measurement.of(bad)
    for bad in ((1.0, 2.0), "abc", (1.0, 2.0, float("nan")), (1, 2, 3, 4)):
        with pytest.raises(calib.InvalidArgumentError):
            Measurement.of("pose", bad)
