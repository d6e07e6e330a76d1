"""Modified DH conversion (foundation): forward kinematics against Pinocchio, the JSON
contract rebuilt by hand, published tables (docs/method.md Table 1, Franka's Panda table) and
URDF quirks (negative axes, fixed joints in the middle, rounded angles).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import ANALYSABLE, chain_of, mdh_of
from pinref import own_random_q, pin_frame, rot, trans

import calib
from calib import load_chain
from calib.cli.commands import main
from calib.identification.parameters import paper_parameters
from calib.kinematics.mdh import PARALLEL_TOL

DATA = Path(__file__).parent / "data"
FK_TOL = 1e-10
N_CONFIGS = 100


# --------------------------------------------------------------------------------------
# Independent references
# --------------------------------------------------------------------------------------


class PinChain:
    """Pinocchio directly: the chain's joints by name, frames by name, own configuration map."""

    def __init__(self, model: pin.Model, base: str, tool: str, joint_names):
        self.model = model
        self.data = model.createData()
        self.base = pin_frame(model, base)
        self.tool = pin_frame(model, tool)
        self.joints = [model.getJointId(name) for name in joint_names]

    def config(self, q):
        out = pin.neutral(self.model)
        for jid, qk in zip(self.joints, q, strict=True):
            joint = self.model.joints[jid]
            if joint.nq == 2:
                out[joint.idx_q : joint.idx_q + 2] = (math.cos(qk), math.sin(qk))
            else:
                out[joint.idx_q] = qk
        return out

    def tool_in_base(self, q) -> np.ndarray:
        pin.framesForwardKinematics(self.model, self.data, self.config(q))
        return (self.data.oMf[self.base].inverse() * self.data.oMf[self.tool]).homogeneous

    def joint_lines(self, q):
        """(point, unit direction) of every chain joint axis in the base frame at q.

        The direction is the motion Pinocchio gives a positive joint velocity: angular
        part for a revolute joint, linear part for a prismatic one.
        """
        model, data = self.model, self.data
        qp = self.config(q)
        pin.framesForwardKinematics(model, data, qp)
        J = pin.computeFrameJacobian(model, data, qp, self.tool, pin.LOCAL_WORLD_ALIGNED)
        J = np.asarray(J).reshape(6, model.nv)
        Rb = data.oMf[self.base].rotation
        pb = data.oMf[self.base].translation
        out = []
        for jid in self.joints:
            col = J[:, model.joints[jid].idx_v]
            u = col[3:] if np.linalg.norm(col[3:]) > 1e-12 else col[:3]
            point = Rb.T @ (data.oMi[jid].translation - pb)
            out.append((point, Rb.T @ u / np.linalg.norm(u)))
        return out


def pin_of(chain) -> PinChain:
    return PinChain(chain.model, chain.base_frame, chain.tool_frame, chain.joint_names)


def rows_forward(rows: list[dict], q: np.ndarray) -> np.ndarray:
    """The JSON contract: product of Rot(y,beta) Rot(x,alpha) Trans(x,d)
    Rot(z, theta + (1-sigma) sign q) Trans(z, r + sigma sign q), fixed rows without q."""
    T = np.eye(4)
    k = 0
    for row in rows:
        theta, r = row["theta"], row["r"]
        if row["sigma"] is not None:
            qk = row["sign"] * q[k]
            k += 1
            theta += (1 - row["sigma"]) * qk
            r += row["sigma"] * qk
        T = T @ rot("y", row["beta"]) @ rot("x", row["alpha"]) @ trans("x", row["d"])
        T = T @ rot("z", theta) @ trans("z", r)
    assert k == len(q)
    return T


def show_json(capsys, robot: str) -> dict:
    assert main(["show", robot, "--json"]) == 0
    out = capsys.readouterr().out
    return json.loads(out)


# --------------------------------------------------------------------------------------
# Forward kinematics of every catalog chain
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ANALYSABLE)
def test_mdh_forward_equals_pinocchio(name):
    chain, mdh = chain_of(name), mdh_of(name)
    ref = pin_of(chain)
    q = own_random_q(chain.sigma, N_CONFIGS, seed=len(name))
    T = mdh.forward(q)
    T_pin = np.array([ref.tool_in_base(qi) for qi in q])
    assert np.abs(T - T_pin).max() <= FK_TOL
    # calib's own Pinocchio wrapper agrees too.
    assert np.abs(chain.tool_placements(q) - T_pin).max() <= FK_TOL


@pytest.mark.parametrize("name", ANALYSABLE)
def test_mdh_frames_follow_the_joint_axes(name):
    """z_k is joint k's axis, oriented so that theta_k (r_k) grows with the URDF position."""
    chain, mdh = chain_of(name), mdh_of(name)
    ref = pin_of(chain)
    q = own_random_q(chain.sigma, 5, seed=7)
    kin = mdh.kinematics(q)
    for i, qi in enumerate(q):
        for k, (point, u) in enumerate(ref.joint_lines(qi), start=1):
            z = kin.R[i, k, :, 2]
            assert np.abs(z - u).max() <= 1e-9, (name, k)
            if chain.sigma[k - 1] == 0:
                # frame k's origin lies on the axis line (a prismatic line sits anywhere)
                assert np.linalg.norm(np.cross(kin.p[i, k] - point, u)) <= 1e-9, (name, k)


@pytest.mark.parametrize("name", ANALYSABLE)
def test_parallel_flags_match_the_geometry(name):
    """Hayati rows exactly where consecutive z axes (base z, joints, tool z) are parallel."""
    chain, mdh = chain_of(name), mdh_of(name)
    ref = pin_of(chain)
    lines = [u for _, u in ref.joint_lines(np.zeros(chain.n))]
    tool_z = ref.tool_in_base(np.zeros(chain.n))[:3, 2]
    zs = [np.array([0.0, 0.0, 1.0]), *lines, tool_z]
    for k in range(1, mdh.n + 2):
        angle = math.acos(min(1.0, abs(float(np.dot(zs[k - 1], zs[k])))))
        if abs(angle - PARALLEL_TOL) < 1e-6:
            continue  # on the threshold: either answer is acceptable
        assert bool(mdh.parallel[k]) == (angle < PARALLEL_TOL), (name, k, angle)
        if not mdh.parallel[k]:
            assert mdh.beta[k] == 0.0
    assert mdh.parallel[0] == 0


@pytest.mark.parametrize("name", ANALYSABLE)
def test_mdh_values_are_bounded(name):
    mdh = mdh_of(name)
    size = max(1.0, float(np.abs(chain_of(name).joint_lines()[0]).max()))
    assert np.abs(mdh.d).max() < 10 * size
    assert np.abs(mdh.r).max() < 10 * size
    assert np.all(np.abs(mdh.alpha) <= math.pi + 1e-12)
    assert np.all(np.abs(mdh.theta) <= math.pi + 1e-12)
    assert np.all(np.abs(mdh.beta) <= math.pi / 2 + 1e-12)
    assert np.all(mdh.y == 0.0)


# --------------------------------------------------------------------------------------
# The JSON contract (calib show --json) rebuilt by hand
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["aid", "panda", "tiago", "stanford", "so100", "kinova"])
def test_show_json_rows_rebuild_pinocchio(capsys, name):
    doc = show_json(capsys, name)
    rows = doc["frames"]
    chain = load_chain(name)
    assert len(rows) == chain.n + 2
    assert [r["joint"] for r in rows[1:-1]] == list(chain.joint_names)
    assert rows[0]["joint"] is None and rows[-1]["joint"] is None
    assert rows[0]["sigma"] is None and rows[-1]["sigma"] is None
    assert [r["sigma"] for r in rows[1:-1]] == [int(s) for s in chain.sigma]
    ref = pin_of(chain)
    for qi in own_random_q(chain.sigma, 30, seed=17):
        assert np.abs(rows_forward(rows, qi) - ref.tool_in_base(qi)).max() <= FK_TOL


def test_show_json_header(capsys):
    doc = show_json(capsys, "panda")
    assert doc["robot"] == "panda"
    assert doc["base"] == "panda_link0"
    assert doc["tool"] == "panda_hand"
    assert Path(doc["urdf"]).name == "panda.urdf"
    for row in doc["frames"]:
        assert set(row) >= {"name", "joint", "sigma", "beta", "alpha", "d", "theta", "r"}


# --------------------------------------------------------------------------------------
# Published tables
# --------------------------------------------------------------------------------------

# docs/method.md, Table 1 (Khalil & Gautier 1991), frames 0..7: sigma, alpha [deg], d, theta, r.
AID_TABLE_1 = [
    (None, 0, 0.0, 0, 0.0),
    (0, 0, 0.0, 0, 0.0),
    (0, 90, 0.0, 0, 0.0),
    (0, 0, 0.3, 0, 0.0),
    (0, -90, 0.0, 0, 0.4),
    (0, 90, 0.0, 0, 0.0),
    (0, -90, 0.0, 0, 0.0),
    (None, 0, 0.0, 0, 0.21),
]

# Franka Emika's published modified DH (Craig) table of the Panda: a, d, alpha [deg], theta
# offset [deg]; the last row is the flange (d = 0.107) turned by -45 deg to panda_hand.
FRANKA_PANDA = [
    (0.0, 0.333, 0, 0),
    (0.0, 0.0, -90, 0),
    (0.0, 0.316, 90, 0),
    (0.0825, 0.0, 90, 0),
    (-0.0825, 0.384, -90, 0),
    (0.0, 0.0, 90, 0),
    (0.088, 0.0, 90, 0),
    (0.0, 0.107, 0, -45),
]


def test_show_aid_reproduces_table_1(capsys):
    rows = show_json(capsys, "aid")["frames"]
    assert len(rows) == len(AID_TABLE_1)
    for row, (sigma, alpha, d, theta, r) in zip(rows, AID_TABLE_1, strict=True):
        assert row["sigma"] == sigma
        assert row["beta"] == pytest.approx(0.0, abs=1e-12)
        assert row["alpha"] == pytest.approx(math.radians(alpha), abs=1e-12)
        assert row["d"] == pytest.approx(d, abs=1e-12)
        assert row["theta"] == pytest.approx(math.radians(theta), abs=1e-12)
        assert row["r"] == pytest.approx(r, abs=1e-12)


def test_show_aid_text(capsys):
    assert main(["show", "aid"]) == 0
    out = capsys.readouterr().out
    for joint in ("joint1", "joint6"):
        assert joint in out
    assert "0.3000" in out and "0.4000" in out and "0.2100" in out
    assert "-90.000" in out


def test_panda_gives_frankas_table():
    mdh = mdh_of("panda")
    assert mdh.n == 7
    assert np.allclose(mdh.beta, 0.0, atol=1e-12)
    assert abs(mdh.theta[0]) < 1e-12 and abs(mdh.r[0]) < 1e-12
    assert abs(mdh.alpha[0]) < 1e-12 and abs(mdh.d[0]) < 1e-12
    for k, (a, d, alpha, theta) in enumerate(FRANKA_PANDA, start=1):
        assert mdh.d[k] == pytest.approx(a, abs=1e-9), f"a{k}"
        assert mdh.r[k] == pytest.approx(d, abs=1e-9), f"d{k}"
        assert mdh.alpha[k] == pytest.approx(math.radians(alpha), abs=1e-9), f"alpha{k}"
        assert mdh.theta[k] == pytest.approx(math.radians(theta), abs=1e-9), f"theta{k}"


# --------------------------------------------------------------------------------------
# URDF quirks
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "fixture",
    ["negative_axes.urdf", "fixed_middle.urdf", "rounded_angles.urdf", "unnormalised_axes.urdf"],
)
def test_quirky_urdf_forward_equals_pinocchio(fixture):
    chain = load_chain(DATA / fixture, tool="tool")
    mdh = calib.from_chain(chain)
    ref = pin_of(chain)
    q = own_random_q(chain.sigma, N_CONFIGS, seed=3)
    T = mdh.forward(q)
    for i, qi in enumerate(q):
        assert np.abs(T[i] - ref.tool_in_base(qi)).max() <= FK_TOL


def test_negative_axes_joint_variables_grow_with_urdf_position():
    chain = load_chain(DATA / "negative_axes.urdf", tool="tool")
    assert list(chain.sigma) == [0, 1, 0]
    mdh = calib.from_chain(chain)
    ref = pin_of(chain)
    # Pinocchio's own directions of the URDF axes "0 0 -1", "0 -1 0", "-1 0 0" at q = 0.
    lines = ref.joint_lines(np.zeros(3))
    assert np.allclose(lines[0][1], [0.0, 0.0, -1.0], atol=1e-12)
    kin = mdh.kinematics(np.zeros(3))
    for k, (_, u) in enumerate(lines, start=1):
        assert np.allclose(kin.R[0, k, :, 2], u, atol=1e-12)
    # A step +h on joint k moves the tool as Pinocchio says (revolute and prismatic).
    h = 0.05
    rng = np.random.default_rng(8)
    for q in rng.uniform(-1.0, 1.0, (10, 3)):
        for k in range(3):
            qh = q.copy()
            qh[k] += h
            T0, T1 = mdh.forward(np.stack([q, qh]))
            assert np.abs(T0 - ref.tool_in_base(q)).max() <= FK_TOL
            assert np.abs(T1 - ref.tool_in_base(qh)).max() <= FK_TOL
    # The prismatic row: r grows with q by exactly h along z.
    T0 = mdh.kinematics(np.zeros(3))
    T1 = mdh.kinematics(np.array([0.0, h, 0.0]))
    dp = T1.p[0, 2] - T0.p[0, 2]
    assert np.allclose(dp, h * lines[1][1], atol=1e-12)


def test_fixed_joints_in_the_middle_are_merged():
    chain = load_chain(DATA / "fixed_middle.urdf", tool="tool")
    assert chain.joint_names == ("j1", "j2", "j3")
    assert bool(chain.continuous[2])
    assert chain.n == 3


def test_rounded_angles_give_hayati_rows_not_kilometres():
    chain = load_chain(DATA / "rounded_angles.urdf", tool="tool")
    mdh = calib.from_chain(chain)
    ref = pin_of(chain)
    lines = ref.joint_lines(np.zeros(chain.n))
    tilt12 = math.acos(abs(float(np.dot(lines[0][1], lines[1][1]))))
    tilt23 = math.acos(abs(float(np.dot(lines[1][1], lines[2][1]))))
    assert 1e-7 < tilt12 < 1e-5, "fixture: 1.5708 tilts axis 2 by ~3.7e-6 rad"
    assert 1e-4 < tilt23 < 1e-3, "fixture: 1.57 tilts axis 3 by ~8e-4 rad"
    assert bool(mdh.parallel[2]) and bool(mdh.parallel[3])
    # Rot(y, beta) Rot(x, alpha) tilts z by acos(cos(alpha) cos(beta)).
    for k, tilt in ((2, tilt12), (3, tilt23)):
        c = abs(math.cos(mdh.alpha[k]) * math.cos(mdh.beta[k]))
        assert math.acos(min(1.0, c)) == pytest.approx(tilt, abs=1e-9)
    assert max(np.abs(mdh.d).max(), np.abs(mdh.r).max()) < 10.0
    assert max(np.abs(mdh.d).max(), np.abs(mdh.r).max()) < 1.0
    q = own_random_q(chain.sigma, N_CONFIGS, seed=9)
    T = mdh.forward(q)
    for i, qi in enumerate(q):
        assert np.abs(T[i] - ref.tool_in_base(qi)).max() <= FK_TOL


@pytest.mark.parametrize("name", ["xarm7", "so100", "so101", "icub_left_arm", "borinot_arm"])
def test_catalog_rounded_angles_stay_small(name):
    """Catalog URDFs with rounded pi/2 (1.5708, 1.57079): no kilometre offsets."""
    mdh = mdh_of(name)
    assert max(np.abs(mdh.d).max(), np.abs(mdh.r).max()) < 2.0


def test_mdh_model_is_a_value_object():
    mdh = mdh_of("aid")
    d_before = mdh.d.copy()
    pset = paper_parameters(mdh)
    shifted = pset.apply(mdh, np.full(len(pset), 1e-3))
    assert np.array_equal(mdh.d, d_before)
    assert not np.array_equal(shifted.d, mdh.d)
    assert mdh.replace().n == mdh.n


def test_kinematics_keep_no_state():
    """A model is a value: its kinematics are made afresh at each call (no memo of the last
    result held in the model; the joint fit passes the frames it made instead)."""
    mdh = mdh_of("ur5")
    fields = dict(vars(mdh))
    q = own_random_q(np.zeros(mdh.n), 4, 3)
    first, again = mdh.kinematics(q), mdh.kinematics(q)
    assert first.R is not again.R and first.R.flags.writeable
    assert np.array_equal(first.R, again.R)
    assert vars(mdh).keys() == fields.keys()
    assert all(vars(mdh)[k] is v for k, v in fields.items())
