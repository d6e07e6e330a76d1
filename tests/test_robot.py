"""Loading chains from URDF (foundation): catalog, frames, trees, URDF quirks, bad input.

The reference everywhere is Pinocchio itself, driven directly from the test (own frame
lookup, own joint-path computation, own configuration vector), never calib's wrappers.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import ANALYSABLE, chain_of, mdh_of
from pinref import own_random_q, pin_config, pin_frame

import calib
from calib import CalibError, load_chain
from calib.exceptions import (
    AmbiguousFrameError,
    ChainError,
    FrameNotFoundError,
    RobotNotFoundError,
    UnsupportedJointError,
    URDFError,
)

DATA = Path(__file__).parent / "data"
FK_TOL = 1e-10


# --------------------------------------------------------------------------------------
# Independent Pinocchio reference
# --------------------------------------------------------------------------------------


def pin_path(model: pin.Model, base: int, tool: int) -> list[int]:
    """Joint ids between two frames, from base to tool (Pinocchio's supports)."""
    jb, jt = model.frames[base].parentJoint, model.frames[tool].parentJoint
    support = list(model.supports[jt])
    assert jb in support
    return support[support.index(jb) + 1 :]


def pin_tool_in_base(model, base: int, tool: int, q_full: np.ndarray) -> np.ndarray:
    data = model.createData()
    pin.framesForwardKinematics(model, data, q_full)
    return (data.oMf[base].inverse() * data.oMf[tool]).homogeneous


def is_prismatic(joint) -> bool:
    short = joint.shortname()
    return "Prismatic" in short or short in ("JointModelPX", "JointModelPY", "JointModelPZ")


def assert_one_line(exc: BaseException, *facts: str) -> None:
    text = str(exc)
    assert "\n" not in text, text
    assert text.strip(), "empty message"
    for fact in facts:
        assert fact in text, f"{fact!r} not in message {text!r}"


# --------------------------------------------------------------------------------------
# Catalog chains
# --------------------------------------------------------------------------------------


def test_catalog_is_not_empty_and_has_the_papers_robot():
    names = [e.name for e in calib.catalog()]
    assert "aid" in names
    assert len(names) == len(set(names)), "catalog names must be unique"
    assert len(ANALYSABLE) >= 50


@pytest.mark.parametrize("name", ANALYSABLE)
def test_catalog_chain_is_the_pinocchio_path(name):
    entry = next(e for e in calib.catalog() if e.name == name)
    chain = chain_of(name)
    model = chain.model
    base, tool = pin_frame(model, entry.base), pin_frame(model, entry.tool)
    assert chain.base_frame == model.frames[base].name
    assert chain.tool_frame == model.frames[tool].name
    path = pin_path(model, base, tool)
    assert list(chain.joint_names) == [model.names[j] for j in path]
    assert chain.n == len(path) >= 1
    n_p = sum(is_prismatic(model.joints[j]) for j in path)
    assert chain.n_prismatic == n_p
    assert chain.n_revolute == len(path) - n_p
    # Same frames as Pinocchio: calib's frames are the ones a direct lookup finds.
    T_ref = pin_tool_in_base(model, base, tool, pin.neutral(model))
    T = chain.tool_placements(np.zeros(chain.n))[0]
    assert np.abs(T - T_ref).max() <= FK_TOL


@pytest.mark.parametrize(
    "entry", [e for e in calib.catalog() if e.expect_error], ids=lambda e: e.name
)
def test_catalog_entries_known_not_to_load_raise_a_calib_error(entry):
    with pytest.raises(CalibError) as info:
        load_chain(entry.name)
    assert_one_line(info.value)


@pytest.mark.parametrize("name", ["double_pendulum_continuous", "kinova"])
def test_continuous_joints(name):
    chain = chain_of(name)
    model = chain.model
    nq2 = [model.joints[j].nq == 2 for j in chain.joint_ids]
    assert any(nq2), "the chain is expected to hold continuous joints (nq = 2)"
    assert list(chain.continuous) == nq2
    # A continuous joint is sampled over a full turn.
    q = chain.random_configurations(2000, seed=3)
    for k in np.flatnonzero(nq2):
        assert q[:, k].min() < -3.0 and q[:, k].max() > 3.0
    # FK through (cos, sin) equals the URDF angle, also beyond +-pi.
    base, tool = pin_frame(model, chain.base_frame), pin_frame(model, chain.tool_frame)
    path = pin_path(model, base, tool)
    rng = np.random.default_rng(11)
    qs = rng.uniform(-7.0, 7.0, (20, chain.n))
    T = chain.tool_placements(qs)
    M = mdh_of(name).forward(qs)
    for i, qi in enumerate(qs):
        ref = pin_tool_in_base(model, base, tool, pin_config(model, path, qi))
        assert np.abs(T[i] - ref).max() <= FK_TOL
        assert np.abs(M[i] - ref).max() <= FK_TOL


@pytest.mark.parametrize(
    "name", ["talos_left_leg", "tiago", "anymal_lf", "talos_left_arm_full", "baxter_left"]
)
def test_tree_robot_other_joints_do_not_matter(name):
    chain = chain_of(name)
    model = chain.model
    base, tool = pin_frame(model, chain.base_frame), pin_frame(model, chain.tool_frame)
    path = pin_path(model, base, tool)
    others = [j for j in range(1, model.njoints) if j not in path]
    assert others, "a tree robot has joints outside the chain"
    rng = np.random.default_rng(5)
    qs = own_random_q(chain.sigma, 20, seed=6)
    M = mdh_of(name).forward(qs)
    for i, qi in enumerate(qs):
        q_chain = pin_config(model, path, qi)
        ref = pin_tool_in_base(model, base, tool, q_chain)
        for _ in range(3):
            q_full = q_chain.copy()
            for j in others:
                joint = model.joints[j]
                if joint.nq == 2:
                    a = rng.uniform(-math.pi, math.pi)
                    q_full[joint.idx_q : joint.idx_q + 2] = (math.cos(a), math.sin(a))
                elif joint.nq == 1:
                    q_full[joint.idx_q] = rng.uniform(-1.5, 1.5)
            T = pin_tool_in_base(model, base, tool, q_full)
            assert np.abs(T - ref).max() <= FK_TOL
        assert np.abs(M[i] - ref).max() <= FK_TOL


# --------------------------------------------------------------------------------------
# URDF quirks
# --------------------------------------------------------------------------------------


def test_link_and_fixed_joint_sharing_a_name_at_one_place():
    path = DATA / "same_name_same_place.urdf"
    model = pin.buildModelFromUrdf(str(path))
    same = [f for f in model.frames if f.name == "flange"]
    assert len(same) == 2, "fixture: a link and a fixed joint named 'flange'"
    chain = load_chain(path, tool="flange")
    assert chain.tool_frame == "flange"
    assert chain.joint_names == ("j0", "j1")
    base = pin_frame(model, "base")
    ref = [
        pin_tool_in_base(model, base, i, pin.neutral(model))
        for i, f in enumerate(model.frames)
        if f.name == "flange"
    ]
    assert np.abs(ref[0] - ref[1]).max() < 1e-12, "fixture: both frames at one place"
    ids = [model.getJointId("j0"), model.getJointId("j1")]
    q = own_random_q(chain.sigma, 10, seed=1)
    M = calib.from_chain(chain).forward(q)
    for i, qi in enumerate(q):
        T = pin_tool_in_base(model, base, pin_frame(model, "flange"), pin_config(model, ids, qi))
        assert np.abs(M[i] - T).max() <= FK_TOL


def test_link_and_revolute_joint_sharing_a_name_at_different_places():
    path = DATA / "same_name_diff_place.urdf"
    with pytest.raises(AmbiguousFrameError) as info:
        load_chain(path, tool="j")
    assert_one_line(info.value, "'j'", "link:j", "joint:j")
    chain = load_chain(path, tool="link:j")
    assert chain.joint_names == ("a0", "a"), "link j is the child of joint a"
    model = chain.model
    base = pin_frame(model, "base")
    link_j = next(
        i for i, f in enumerate(model.frames) if f.name == "j" and f.type == pin.FrameType.BODY
    )
    ids = [model.getJointId("a0"), model.getJointId("a")]
    q = own_random_q(chain.sigma, 10, seed=2)
    M = calib.from_chain(chain).forward(q)
    for i, qi in enumerate(q):
        T = pin_tool_in_base(model, base, link_j, pin_config(model, ids, qi))
        assert np.abs(M[i] - T).max() <= FK_TOL
    # The joint frame 'j' is another place: moving joint j does not move link j.
    chain_joint = load_chain(path, tool="joint:j")
    assert chain_joint.joint_names == ("a0", "a", "j")


def test_single_joint_chain():
    """The smallest chain: one revolute joint (the whole Pinocchio model has nv = 1)."""
    path = DATA / "single_joint.urdf"
    chain = load_chain(path, tool="tool")
    assert chain.n == 1
    model = chain.model
    mdh = calib.from_chain(chain)
    base, tool = pin_frame(model, "base"), pin_frame(model, "tool")
    q = own_random_q(chain.sigma, 20, seed=4)
    M = mdh.forward(q)
    for i, qi in enumerate(q):
        T = pin_tool_in_base(model, base, tool, pin_config(model, [model.getJointId("j1")], qi))
        assert np.abs(M[i] - T).max() <= FK_TOL


def test_default_frames_are_root_link_and_deepest_tip():
    chain = load_chain(DATA / "negative_axes.urdf")
    assert chain.base_frame == "base"
    assert chain.tool_frame == "tool"
    assert chain.joint_names == ("j1", "j2", "j3")
    assert list(chain.sigma) == [0, 1, 0]


def test_urdf_path_given_as_str_or_path():
    a = load_chain(str(DATA / "fixed_middle.urdf"))
    b = load_chain(DATA / "fixed_middle.urdf")
    assert a.joint_names == b.joint_names == ("j1", "j2", "j3")
    assert a.name == "fixed_middle"


# --------------------------------------------------------------------------------------
# Bad input: one CalibError subclass, one line, the key fact in the message
# --------------------------------------------------------------------------------------


def test_missing_file(tmp_path):
    missing = tmp_path / "nope.urdf"
    with pytest.raises(URDFError) as info:
        load_chain(missing)
    assert_one_line(info.value, "nope.urdf")


def test_malformed_xml(tmp_path):
    bad = tmp_path / "broken.urdf"
    bad.write_text('<?xml version="1.0"?>\n<robot name="x">\n  <link name="a">\n</robot>\n')
    with pytest.raises(URDFError) as info:
        load_chain(bad)
    assert_one_line(info.value, "broken.urdf")


def test_not_a_robot_document(tmp_path):
    bad = tmp_path / "other.urdf"
    bad.write_text('<?xml version="1.0"?>\n<sdf version="1.6"><model name="m"/></sdf>\n')
    with pytest.raises(URDFError) as info:
        load_chain(bad)
    assert_one_line(info.value, "other.urdf")


def test_urdf_naming_a_missing_link(tmp_path):
    with pytest.raises(URDFError) as info:
        load_chain(DATA / "missing_link.urdf")
    assert_one_line(info.value, "missing_link.urdf")


def test_zero_joint_axis_is_rejected():
    """axis "0 0 0" gives no direction: a CalibError, not a model full of NaN."""
    with pytest.raises(CalibError) as info:
        calib.from_chain(load_chain(DATA / "zero_axis.urdf", tool="tool"))
    assert_one_line(info.value, "j2")


def test_unknown_robot_name():
    with pytest.raises(RobotNotFoundError) as info:
        load_chain("nosuchrobot")
    assert_one_line(info.value, "nosuchrobot")


def test_unknown_robot_name_suggests_close_names():
    with pytest.raises(RobotNotFoundError) as info:
        load_chain("pnada")
    assert_one_line(info.value, "pnada", "did you mean", "panda")


@pytest.mark.parametrize(
    ("name", "meant"),
    [("UR5", "(did you mean ur5"), ("talos_full_v2", "(did you mean talos_full_v2.urdf,")],
)
def test_an_unknown_robot_in_capitals_or_a_urdf_without_its_extension_is_suggested(name, meant):
    """``UR5`` had no suggestion (``ur-5`` had); ``talos_full_v2`` suggested catalog names,
    not the example-robot-data URDF calib reads by its bare file name."""
    with pytest.raises(RobotNotFoundError) as info:
        load_chain(name)
    assert_one_line(info.value, name, meant)


def test_unknown_frame_lists_closest_first():
    with pytest.raises(FrameNotFoundError) as info:
        load_chain("ur5", tool="tool1")
    exc = info.value
    assert_one_line(exc, "tool1")
    listed = str(exc).split("closest first:", 1)[1]
    assert listed.strip().startswith("tool0"), str(exc)
    # Every listed name is a real frame of the model.
    names = {f.name for f in chain_of("ur5").model.frames}
    assert set(exc.available) <= names
    assert exc.available[0] == "tool0"


def test_frames_on_two_branches():
    """A chain through the common ancestor (tests/test_reversed_chains.py checks its model)."""
    chain = load_chain("anymal_lf", base="LF_FOOT", tool="RF_FOOT")
    assert chain.joint_names[0] == "LF_KFE" and chain.joint_names[-1] == "RF_KFE"
    assert chain.sign.tolist() == [-1, -1, -1, 1, 1, 1]


def test_tool_above_base():
    chain = load_chain("ur5", base="tool0", tool="base_link")
    assert chain.joint_names[0] == "wrist_3_joint" and chain.sign.tolist() == [-1] * 6


def test_no_joint_between_base_and_tool():
    with pytest.raises(ChainError) as info:
        load_chain("ur5", base="tool0", tool="tool0")
    assert_one_line(info.value, "tool0")
    with pytest.raises(ChainError):
        load_chain("ur5", base="wrist_3_link", tool="tool0")


@pytest.mark.parametrize(
    ("fixture", "joint", "fact"),
    [
        ("planar_joint.urdf", "j_planar", "planar"),
        ("floating_joint.urdf", "j_floating", "floating"),
    ],
)
def test_unsupported_joint_in_chain(fixture, joint, fact):
    with pytest.raises(UnsupportedJointError) as info:
        load_chain(DATA / fixture, tool="tool")
    assert_one_line(info.value, joint, fact)


def test_mimic_joint_outside_chain_is_fine():
    chain = load_chain(DATA / "mimic_joint.urdf", tool="l1")
    assert chain.joint_names == ("j1",)
    assert chain.coupling is None and chain.variable_names == ("j1",)


def test_ambiguous_frame_in_catalog_robot():
    with pytest.raises(AmbiguousFrameError) as info:
        load_chain("so100", tool="gripper")
    assert_one_line(info.value, "gripper", "link:gripper")
    assert load_chain("so100", tool="link:gripper").tool_frame == "gripper"


def test_errors_are_one_hierarchy():
    for cls in (
        AmbiguousFrameError,
        ChainError,
        FrameNotFoundError,
        RobotNotFoundError,
        UnsupportedJointError,
        URDFError,
        calib.InvalidArgumentError,
    ):
        assert issubclass(cls, CalibError)


def test_bad_joint_positions_shape():
    chain = chain_of("aid")
    with pytest.raises(calib.InvalidArgumentError):
        chain.tool_placements(np.zeros((2, 5)))
    with pytest.raises(calib.InvalidArgumentError):
        chain.tool_placements(np.full(6, np.nan))
    with pytest.raises(calib.InvalidArgumentError):
        chain.random_configurations(0, seed=0)
