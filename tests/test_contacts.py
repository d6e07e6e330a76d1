"""Contact kinds (plane, plane-point, fixed-point, fixed-pose): gaps, Jacobian rows, counts.

The independent routes: Pinocchio's placements (the raw URDF, no MDH) give the gap of each
touch, its central differences in the joints and, perturbing every joint placement, the tool
frame and the contact's frame by 6-DOF errors, the rank of the complete model at the postures
calib projected onto the contact. The closed forms are checked on random generic chains.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import CI
from hypothesis import given, settings
from hypothesis import strategies as st
from test_properties import build_chain, convert, random_q

import calib
from calib import InvalidArgumentError, Measurement, analyze, load_chain
from calib.cli.commands import main
from calib.identification.contact_postures import contact_configurations, joint_offsets
from calib.identification.contacts import contact_kind
from calib.identification.identifiability import analyze_model
from calib.identification.jacobian import identification_jacobian
from calib.identification.kinds import kind_of
from calib.kinematics.mdh import from_chain

KINDS = ("plane", "plane-point", "fixed-point", "fixed-pose")
ROBOTS = ("ur5", "panda", "tiago")


def pin_gap(kind: str, T: np.ndarray) -> np.ndarray:
    """The gap of a contact frame T (4x4, in the contact's frame), written from its definition."""
    p, R = T[:3, 3], T[:3, :3]
    if kind == "plane":  # height, then Pinocchio's roll and pitch (R = Rz Ry Rx)
        return np.r_[p[2], pin.rpy.matrixToRpy(R)[:2]]
    if kind == "plane-point":
        return p[2:3]
    if kind == "fixed-point":
        return p
    return np.concatenate([p, pin.log3(R)])


class PinChain:
    """The chain's tool in its base frame from Pinocchio, with perturbable placements."""

    def __init__(self, chain):
        self.chain = chain
        self.model = chain.model.copy()
        self.data = self.model.createData()

    def tool(self, q: np.ndarray) -> np.ndarray:
        qp = self.chain.pin_configurations(q[None])[0]
        pin.framesForwardKinematics(self.model, self.data, qp)
        b, t = self.data.oMf[self.chain.base_id], self.data.oMf[self.chain.tool_id]
        return b.actInv(t).homogeneous


def setup(name: str, kind: str, m: int = 40, seed: int = 0):
    """calib's contact model and postures, as :func:`calib.analyze` draws them."""
    chain = load_chain(name)
    mdh = from_chain(chain).idealized()
    model, q = contact_configurations(
        mdh, contact_kind(kind), lambda c, r: chain.random_configurations(c, seed + r), m
    )
    return chain, model, q


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_postures_hold_the_contact_in_pinocchio(name, kind):
    chain, _, q = setup(name, kind, 30)
    ref = PinChain(chain)
    P = np.linalg.inv(ref.tool(chain.random_configurations(1, 0)[0]))  # the reference touch
    gaps = np.array([pin_gap(kind, P @ ref.tool(qi)) for qi in q])
    assert np.abs(gaps).max() < 1e-9
    assert len(q) == 30
    if kind == "plane":  # flush, not upside down
        assert all((P @ ref.tool(qi))[2, 2] > 0.99 for qi in q)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_analytic_rows_are_central_differences_of_pinocchio(name, kind):
    """The joint offsets' columns are d gap / dq: the kind's rows against Pinocchio."""
    chain, model, q = setup(name, kind, 5)
    # away from the contact too: the rows are exact at any posture
    q = np.vstack([q, chain.random_configurations(3, 99)])
    ref = PinChain(chain)
    P = np.linalg.inv(ref.tool(chain.random_configurations(1, 0)[0]))
    k = contact_kind(kind)
    W = identification_jacobian(model, joint_offsets(model), q, k).reshape(len(q), k.n_rows, -1)
    h = 1e-6
    for i, qi in enumerate(q):
        for j in range(chain.n):
            e = np.zeros(chain.n)
            e[j] = h
            num = (pin_gap(kind, P @ ref.tool(qi + e)) - pin_gap(kind, P @ ref.tool(qi - e))) / (
                2 * h
            )
            np.testing.assert_allclose(W[i, :, j], num, atol=1e-7)


def perturbed_rank(chain, kind: str, q: np.ndarray) -> int:
    """Rank of the gap's central differences under 6-DOF errors of every joint placement on
    the chain, the tool frame and the contact's frame: Pinocchio only."""
    ref = PinChain(chain)
    P0 = np.linalg.inv(ref.tool(chain.random_configurations(1, 0)[0]))
    h = 1e-6
    cols = []

    def gaps(P):
        return np.concatenate([pin_gap(kind, P @ ref.tool(qi)) for qi in q])

    def through(placements, index):
        for a in range(6):
            d = np.zeros(6)
            d[a] = h
            old = pin.SE3(placements[index])
            placements[index] = old * pin.exp6(pin.Motion(d))
            plus = gaps(P0)
            placements[index] = old * pin.exp6(pin.Motion(-d))
            minus = gaps(P0)
            placements[index] = old
            cols.append((plus - minus) / (2 * h))

    for j in chain.joint_ids:
        through(ref.model.jointPlacements, j)
    frame = ref.model.frames[chain.tool_id]
    for a in range(6):  # the tool (contact) frame in its joint
        d = np.zeros(6)
        d[a] = h
        old = pin.SE3(frame.placement)
        frame.placement = old * pin.exp6(pin.Motion(d))
        ref.model.frames[chain.tool_id] = frame
        plus = gaps(P0)
        frame.placement = old * pin.exp6(pin.Motion(-d))
        ref.model.frames[chain.tool_id] = frame
        minus = gaps(P0)
        frame.placement = old
        ref.model.frames[chain.tool_id] = frame
        cols.append((plus - minus) / (2 * h))
    for a in range(6):  # the plane, point or pose
        d = np.zeros(6)
        d[a] = h
        plus = gaps(pin.exp6(pin.Motion(d)).homogeneous @ P0)
        minus = gaps(pin.exp6(pin.Motion(-d)).homogeneous @ P0)
        cols.append((plus - minus) / (2 * h))
    s = np.linalg.svd(np.array(cols).T, compute_uv=False)
    return int(np.sum(s > 1e-6 * s[0]))


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("name", ROBOTS)
def test_count_is_the_independent_pinocchio_rank(name, kind):
    chain, _, q = setup(name, kind, 40)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        res = analyze(name, measure=kind, params="complete", configs=40)
    assert res.n_base == res.n_complete == perturbed_rank(chain, kind, q)


# The counts in docs/howto/identifiable.md (calib analyze ROBOT --measure KIND --params complete).
EXPECTED = {
    ("ur5", "plane"): 20,
    ("ur5", "plane-point"): 21,
    ("ur5", "fixed-point"): 21,
    ("ur5", "fixed-pose"): 23,
    ("panda", "plane"): 24,
    ("panda", "plane-point"): 25,
    ("panda", "fixed-point"): 25,
    ("panda", "fixed-pose"): 27,
    ("tiago", "plane"): 27,
    ("tiago", "plane-point"): 26,
    ("tiago", "fixed-point"): 28,
    ("tiago", "fixed-pose"): 30,
}


def test_cli_prints_the_counts_and_what_a_plane_cannot_see(capsys):
    assert main(["analyze", "ur5", "--measure", "plane", "--params", "complete", "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["measure"] == "plane" and d["base_frame"] == "plane"
    assert d["rows"] == ["height", "roll", "pitch"]
    assert d["n_base"] == EXPECTED[("ur5", "plane")]
    assert any("height" in u for u in d["unseen"])
    assert main(["analyze", "panda", "--measure", "fixed-point"]) == 0
    out = capsys.readouterr().out
    assert "measure fixed-point" in out and "theory 25" in out
    assert "can never identify" in out


@pytest.mark.parametrize("name", ROBOTS)
def test_counts_per_robot(name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        for kind in KINDS:
            res = analyze(name, measure=kind, params="complete")
            assert res.n_complete == EXPECTED[(name, kind)], kind


def test_bad_contact_arguments(capsys):
    with pytest.raises(InvalidArgumentError, match="no marker"):
        kind_of("plane", (0.0, 0.0, 0.1))
    with pytest.raises(InvalidArgumentError, match="one chain"):
        analyze("ur5", tool=["tool0", "wrist_2_link"], measure="plane", params="paper")
    assert main(["analyze", "ur5", "--measure", "planes"]) == 2
    err = capsys.readouterr().err
    assert "unknown measure 'planes'" in err and "Traceback" not in err


def test_measurement_residual_is_measured_minus_predicted():
    rng = np.random.default_rng(3)
    R = np.array([pin.exp3(rng.normal(size=3)) for _ in range(4)])
    p = rng.normal(size=(4, 3))
    dphi, dp = 1e-3 * rng.normal(size=(4, 3)), 1e-3 * rng.normal(size=(4, 3))
    M = np.zeros((4, 4, 4))
    M[:, :3, :3] = np.array([pin.exp3(a) for a in dphi]) @ R
    M[:, :3, 3], M[:, 3, 3] = p + dp, 1.0
    out = Measurement.of("pose").residual(R, p, M)
    np.testing.assert_allclose(out, np.hstack([dp, dphi]), atol=1e-14)
    np.testing.assert_allclose(Measurement.of("x,rz").residual(R, p, M), out[:, [0, 5]])


# --------------------------------------------------------------------------------------
# Closed forms on random generic chains
# --------------------------------------------------------------------------------------


@st.composite
def generic_chains(draw, kind: str):
    n = draw(st.integers({"fixed-pose": 7, "plane-point": 2}.get(kind, 4), 8))
    sigma = draw(st.lists(st.sampled_from([0, 0, 0, 1]), min_size=n, max_size=n))
    if kind in ("plane", "plane-point"):
        sigma[0] = 0  # a prismatic first joint: the formula is silent
    if kind == "plane":
        sigma[-1] = 0
    seed = draw(st.integers(0, 2**32 - 1))
    return build_chain(seed, ["generic"] * n, sigma, "generic", -4.0)


def _count(ch, kind: str) -> tuple[int, int | None]:
    k = contact_kind(kind)
    mdh = convert(ch)
    model, q = contact_configurations(mdh, k, lambda c, r: random_q(ch, c, 1 + r), 80)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        res = analyze_model(model, "complete", k, q)
    return res.n_complete, res.n_theory


@settings(CI, max_examples=8, deadline=None)
@pytest.mark.parametrize("kind", KINDS)
@given(data=st.data())
def test_closed_form_on_random_chains(kind, data):
    ch = data.draw(generic_chains(kind))
    try:
        count, theory = _count(ch, kind)
    except InvalidArgumentError:  # the contact cannot hold often enough on this chain
        return
    R, P = int(np.sum(ch.sigma == 0)), int(np.sum(ch.sigma == 1))
    base = 4 * R + 2 * P
    expected = {
        "plane": base - (1 if P else 2),
        "plane-point": base - (0 if P else 1),
        "fixed-point": base - (0 if P else 1),
        "fixed-pose": base - (0 if P else 1),
    }[kind]
    assert theory == expected
    assert count == expected


# --------------------------------------------------------------------------------------
# Closed forms with the contact on, or turning about, the last axis
# --------------------------------------------------------------------------------------


def _expected_on_last_axis(kind: str, n: int, P: int, tool_kind: str, along: bool):
    """The rule stated in docs/method.md §6, or None where it is silent."""
    R = n - P
    scale = 0 if P else 1
    if kind == "plane":
        # origin on the last axis changes nothing; the last axis along the normal hides 2
        blind = 1 if along else 0
        seen = n - blind
        if seen <= 3 or (blind and P and seen == n // 2 + 1):  # a prismatic joint last seen
            return None
        return 4 * R + 2 * P - 1 - scale - 2 * blind
    moving = n - 1  # the tip on the last axis: the last joint does not move it
    if moving <= {"plane-point": 1, "fixed-point": 3}[kind]:
        return None
    if kind == "plane-point" and moving == 2 and P:
        return None
    return 4 * R + 2 * P - scale - 2


ON_LAST_AXIS = [  # the normal means nothing to a point: normal_only is the plane's alone
    (kind, tool_kind)
    for kind in ("plane", "plane-point", "fixed-point")
    for tool_kind in ("origin_on_last_axis", "along_last_axis", "normal_only")
    if kind == "plane" or tool_kind != "normal_only"
]


@settings(CI, max_examples=10, deadline=None)
@pytest.mark.parametrize(("kind", "tool_kind"), ON_LAST_AXIS)
@given(data=st.data())
def test_closed_form_with_the_contact_on_the_last_axis(kind, tool_kind, data):
    n = data.draw(st.integers(2 if kind == "plane-point" else 4, 7))
    sigma = [0] * n
    if data.draw(st.booleans()) and n >= 3:
        sigma[n // 2] = 1  # a prismatic joint inside the chain
    seed = data.draw(st.integers(0, 2**32 - 1))
    built = "along_last_axis" if tool_kind == "normal_only" else tool_kind
    ch = build_chain(seed, ["generic"] * n, sigma, built, -4.0)
    if tool_kind == "normal_only":  # the normal along the last axis, the origin off it
        tool = ch.tool.copy()
        tool[:3, 3] += np.random.default_rng(seed).uniform(0.1, 0.3, 3)
        ch = dataclasses.replace(ch, tool=tool)
    try:
        count, theory = _count(ch, kind)
    except InvalidArgumentError:  # the contact cannot hold often enough on this chain
        return
    along = tool_kind != "origin_on_last_axis"
    expected = _expected_on_last_axis(kind, n, sum(sigma), tool_kind, along)
    assert theory == expected
    if expected is not None:
        assert count == expected


@pytest.mark.parametrize(("name", "revolute"), [("ur5", 6), ("panda", 7)])
def test_flange_on_a_plane_hides_the_last_joint(name, revolute):
    """The flange's z is the last axis: the plane sees one joint fewer (docs/method.md §6)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        res = analyze(name, measure="plane", params="complete")
    assert res.n_theory == res.n_complete == 4 * revolute - 4
