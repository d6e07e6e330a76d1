"""Chains between any two frames of a tree: up from the base to the common ancestor (joints
traversed backwards, ``sign`` -1), then down to the tool.

Every reference is Pinocchio alone on the URDF file (tests/pinref.py ``PathRef``): the
relative placement ``oMf[base]^-1 oMf[tool]``, its frame Jacobians, the finite-difference
rank of a generic error on every placement of the path, and the calibrated URDF reloaded.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import CI
from hypothesis import given
from hypothesis import strategies as st
from pinref import PathRef, own_random_q, rot, trans

import calib
from calib import (
    InvalidArgumentError,
    Measurement,
    analyze,
    calibrate,
    from_chain,
    load_chain,
    simulate,
)
from calib.cli.commands import main
from calib.exceptions import ChainError
from calib.identification.jacobian import identification_jacobian
from calib.identification.parameters import Kind, Parameter, ParameterSet, complete_parameters
from calib.kinematics.catalog import catalog_entry
from calib.kinematics.mdh import from_lines
from calib.kinematics.tree import load_tree
from calib.kinematics.urdf_export import calibrated_urdf, measurement_to_base

FK_TOL = 1e-10

HUMANOIDS = {
    # catalog tree: (left hand, right hand, left foot, right foot), as its tool list names them
    "talos": (
        "wrist_left_ft_tool_link",
        "wrist_right_ft_tool_link",
        "left_sole_link",
        "right_sole_link",
    ),
    "romeo": ("l_gripper", "r_gripper", "l_sole", "r_sole"),
    "icub": ("l_hand_dh_frame", "r_hand_dh_frame", "l_sole", "r_sole"),
    "g1": (
        "left_rubber_hand",
        "right_rubber_hand",
        "left_ankle_roll_link",
        "right_ankle_roll_link",
    ),
    "simple_humanoid": ("l_wrist", "r_wrist", "l_ankle", "r_ankle"),
    "human": ("left_hand", "right_hand", "left_foot", "right_foot"),
    "centauro": ("ball1_tip", "ball2_tip", "contact_1", "contact_2"),
}
PAIRS = (
    [
        pytest.param(robot, tools[2], tools[0], id=f"{robot}-foot-hand")
        for robot, tools in HUMANOIDS.items()
    ]
    + [
        pytest.param(robot, tools[2], tools[3], id=f"{robot}-foot-foot")
        for robot, tools in HUMANOIDS.items()
    ]
    + [pytest.param("talos", "left_sole_link", "gripper_left_base_link", id="talos-issue")]
)


def ref_of(chain) -> PathRef:
    return PathRef(chain.urdf_path, chain.base_frame, chain.tool_frame)


def joint_parameters(mdh) -> ParameterSet:
    """theta_k (revolute) or r_k (prismatic): the columns that a joint position moves."""
    kinds = [Kind.THETA if mdh.sigma[k] == 0 else Kind.R for k in range(1, mdh.n + 1)]
    return ParameterSet("joints", tuple(Parameter(k, kind) for k, kind in enumerate(kinds, 1)))


# --------------------------------------------------------------------------------------
# Structure of the path
# --------------------------------------------------------------------------------------


def test_humanoid_table_is_the_catalogs():
    for robot, tools in HUMANOIDS.items():
        assert set(tools) <= set(catalog_entry(robot).tools), robot


def test_two_branches_run_through_the_common_ancestor():
    chain = load_chain("anymal_lf", base="LF_FOOT", tool="RF_FOOT")
    assert chain.joint_names == ("LF_KFE", "LF_HFE", "LF_HAA", "RF_HAA", "RF_HFE", "RF_KFE")
    assert chain.sign.tolist() == [-1, -1, -1, 1, 1, 1]
    assert chain.reversed_joints == 3


def test_tool_above_base_is_a_chain_traversed_backwards():
    chain = load_chain("ur5", base="tool0", tool="base_link")
    assert chain.joint_names == tuple(reversed(load_chain("ur5").joint_names))
    assert chain.sign.tolist() == [-1] * 6


def test_forward_chains_are_unchanged():
    chain = load_chain("talos_left_leg")
    assert chain.sign.tolist() == [1] * chain.n and chain.reversed_joints == 0
    assert from_chain(chain).sign.tolist() == [1] * (chain.n + 2)


def test_no_joint_between_frames_of_one_body():
    with pytest.raises(ChainError, match="no joint between"):
        load_chain("talos", base="leg_left_6_link", tool="left_sole_link")


def test_a_tree_refuses_a_tool_that_is_not_below_its_base():
    with pytest.raises(ChainError, match="not below base frame 'left_sole_link'"):
        load_tree("talos", base="left_sole_link", tools=("gripper_left_base_link", "head_2_link"))
    assert (
        main(
            [
                "show",
                "talos",
                "--base",
                "left_sole_link",
                "--tool",
                "head_2_link",
                "--tool",
                "right_sole_link",
            ]
        )
        == 2
    )


def test_bad_signs_are_refused():
    p, u = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0]]), np.array([[0.0, 0.0, 1.0]] * 2)
    for sign in ([1, 0], [1], [2, -1], [1, float("nan")]):
        with pytest.raises(InvalidArgumentError, match="sign"):
            from_lines(p, u, [0, 0], np.eye(4), sign=sign)
    mdh = from_lines(p, u, [0, 0], np.eye(4), sign=[-1, 1])
    with pytest.raises(InvalidArgumentError, match="sign"):
        mdh.replace(sign=np.array([1, 1, 1]))


# --------------------------------------------------------------------------------------
# The rows reproduce Pinocchio's relative placement; the JSON contract rebuilt by hand
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(("robot", "base", "tool"), PAIRS)
def test_rows_equal_pinocchio_relative_placement(robot, base, tool):
    chain = load_chain(robot, base, tool)
    ref = ref_of(chain)
    assert set(chain.joint_names) == ref.names
    up = {ref.model.names[j] for j in ref.up}
    assert [s < 0 for s in chain.sign] == [n in up for n in chain.joint_names]
    assert chain.reversed_joints > 0
    q = own_random_q(chain.sigma, 60, seed=len(base) + len(tool))
    expected = ref.placements(chain.joint_names, q)
    assert np.abs(from_chain(chain).forward(q) - expected).max() <= FK_TOL
    assert np.abs(chain.tool_placements(q) - expected).max() <= FK_TOL


def rows_forward(rows: list[dict], q: np.ndarray) -> np.ndarray:
    """The contract: Rot(y,beta) Rot(x,alpha) Trans(x,d) Rot(z, theta + (1-sigma) sign q)
    Trans(z, r + sigma sign q), the fixed rows without q."""
    T, k = np.eye(4), 0
    for row in rows:
        theta, r = row["theta"], row["r"]
        if row["sigma"] is not None:
            theta += (1 - row["sigma"]) * row["sign"] * q[k]
            r += row["sigma"] * row["sign"] * q[k]
            k += 1
        T = T @ rot("y", row["beta"]) @ rot("x", row["alpha"]) @ trans("x", row["d"])
        T = T @ rot("z", theta) @ trans("z", r)
    assert k == len(q)
    return T


def test_show_json_rows_carry_the_sign(capsys):
    argv = ["show", "talos", "--base", "left_sole_link", "--tool", "gripper_left_base_link"]
    assert main([*argv, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["frames"]
    legs = [r["joint"].startswith("leg_left") for r in rows[1:-1]]
    assert legs == [True] * 6 + [False] * 9
    assert [r["sign"] for r in rows[1:-1]] == [-1 if leg else 1 for leg in legs]
    assert rows[0]["sign"] == rows[-1]["sign"] == 1
    chain = load_chain("talos", "left_sole_link", "gripper_left_base_link")
    ref = ref_of(chain)
    q = own_random_q(chain.sigma, 20, seed=4)
    expected = ref.placements([r["joint"] for r in rows[1:-1]], q)
    for qi, T in zip(q, expected, strict=True):
        assert np.abs(rows_forward(rows, qi) - T).max() <= FK_TOL
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert " -q1" in text and " -q6" in text and " q7" in text and "-q7" not in text


# --------------------------------------------------------------------------------------
# Jacobian, identifiability
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("marker", [(0.0, 0.0, 0.0), (0.03, -0.02, 0.05)], ids=["tool", "marker"])
@pytest.mark.parametrize(
    ("base", "tool"),
    [("left_sole_link", "gripper_left_base_link"), ("left_sole_link", "right_sole_link")],
)
def test_joint_columns_are_the_signed_pinocchio_jacobian(base, tool, marker):
    chain = load_chain("talos", base, tool)
    mdh = from_chain(chain)
    q = own_random_q(chain.sigma, 8, seed=9)
    W = identification_jacobian(mdh, joint_parameters(mdh), q, Measurement.of("pose", marker))
    J = ref_of(chain).relative_jacobian(chain.joint_names, q, marker)
    assert np.abs(J).max() > 0.1
    assert np.abs(W * chain.sign - J).max() <= 1e-10
    assert np.abs(W - J).max() > 0.1  # the sign matters


@pytest.mark.parametrize(("robot", "base", "tool"), PAIRS)
@pytest.mark.parametrize("measure", ["pose", "position"])
def test_identifiable_count_is_the_theory_and_the_pinocchio_rank(robot, base, tool, measure):
    """4R + 2P + 6 for poses, 4R + 2P + 3 for a point (off the joint axes), and the
    finite-difference rank of a generic error on every placement of the path (Pinocchio).
    The complete set: the paper set misses directions where lines coincide (Centauro's
    contact frame lies on its first axis, as in the forward leg chain)."""
    marker = (0.05, 0.03, 0.07)
    res = analyze(robot, base, tool, measure, marker, params="complete", configs=60, seed=2)
    chain = load_chain(robot, base, tool)
    R, P = chain.n_revolute, chain.n_prismatic
    theory = 4 * R + 2 * P + (6 if measure == "pose" else 3)
    assert res.n_base == res.n_complete == res.n_theory == theory
    rows = (0, 1, 2, 3, 4, 5) if measure == "pose" else (0, 1, 2)
    q = chain.random_configurations(40, 3)  # 120 position rows, more than any count here
    assert ref_of(chain).error_rank(chain.joint_names, q, rows, marker) == theory


# --------------------------------------------------------------------------------------
# Calibrated URDF of a chain with reversed joints
# --------------------------------------------------------------------------------------


def perturbed(chain, seed: int, mm: float = 2.0, mrad: float = 3.0):
    nominal = from_chain(chain)
    pset = complete_parameters(nominal)
    rng = np.random.default_rng(seed)
    scale = np.array([1e-3 * (mrad if p.kind.is_rotation else mm) for p in pset.parameters])
    return nominal, pset.apply(nominal, scale * rng.standard_normal(len(pset)))


def structure(path) -> tuple[str, dict]:
    """Root link and, per joint, (type, parent, child), read with ElementTree."""
    import xml.etree.ElementTree as ET

    root = ET.parse(str(path)).getroot()
    joints = {
        j.get("name"): (j.get("type"), j.find("parent").get("link"), j.find("child").get("link"))
        for j in root.findall("joint")
    }
    children = {c for _, _, c in joints.values()}
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    return roots[0], joints


@pytest.mark.parametrize(("robot", "base", "tool"), PAIRS)
def test_written_urdf_reproduces_the_calibrated_model(robot, base, tool, tmp_path):
    chain = load_chain(robot, base, tool)
    nominal, cal = perturbed(chain, seed=len(robot))
    path = tmp_path / "cal.urdf"
    kind = [t for t, _, child in structure(chain.urdf_path)[1].values() if child == tool]
    # a tool link on a moving joint: the calibrated tool is the link <tool>_calibrated
    written_tool = tool if kind == ["fixed"] else f"{tool}_calibrated"
    path.write_bytes(calibrated_urdf(chain, nominal, cal))
    q = own_random_q(chain.sigma, 40, seed=11)
    T = measurement_to_base(nominal, cal)
    written = PathRef(path, base, written_tool).placements(chain.joint_names, q)
    assert np.abs(T @ written - cal.forward(q)).max() <= FK_TOL
    assert np.abs(written - ref_of(chain).placements(chain.joint_names, q)).max() > 1e-4
    root, joints = structure(path)
    if written_tool != tool:  # the one link added
        del joints[f"{written_tool}_joint"]
    assert (root, joints) == structure(chain.urdf_path)


def test_written_urdf_keeps_the_bodies_mass_where_the_body_is(tmp_path):
    """A reversed joint's child link has a new frame; its inertia stays on its body: each
    body's centre of mass keeps its place relative to the MDH frame the body carries (the
    last body holds the tool link, which follows the calibrated tool frame)."""
    import pinocchio as pin

    chain = load_chain("talos", "left_sole_link", "gripper_left_base_link")
    nominal, cal = perturbed(chain, seed=5)
    path = tmp_path / "cal.urdf"
    path.write_bytes(calibrated_urdf(chain, nominal, cal))
    T = measurement_to_base(nominal, cal)
    F_nom = calib.kinematics.mdh.frames_at_zero(nominal)
    F_cal = calib.kinematics.mdh.frames_at_zero(cal)
    for urdf, frames, to_measured in ((chain.urdf_path, F_nom, np.eye(4)), (path, F_cal, T)):
        ref = PathRef(urdf, chain.base_frame, chain.tool_frame)
        model, data = ref.model, ref.data
        pin.forwardKinematics(model, data, pin.neutral(model))
        pin.updateFramePlacements(model, data)
        bMo = data.oMf[ref.base].inverse()
        coms = []
        for k, name in enumerate(chain.joint_names[:-1], start=1):
            jid = model.getJointId(name)
            body = jid if chain.sign[k - 1] > 0 else model.parents[jid]  # carries MDH frame k
            c = to_measured @ np.append((bMo * data.oMi[body]).act(model.inertias[body].lever), 1)
            coms.append((np.linalg.inv(frames[k]) @ c)[:3])
        if urdf == chain.urdf_path:
            nominal_coms = np.array(coms)
        else:
            assert np.abs(np.array(coms) - nominal_coms).max() <= 1e-10


def test_export_refuses_a_tool_above_the_chain(tmp_path):
    path = tmp_path / "up.urdf"
    path.write_text(
        """<robot name="up">
  <link name="root"/><link name="l1"/><link name="t"/><link name="l2"/>
  <joint name="j1" type="revolute"><parent link="root"/><child link="l1"/>
    <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="fix" type="fixed"><parent link="l1"/><child link="t"/>
    <origin xyz="0 0 0.1"/></joint>
  <joint name="j2" type="revolute"><parent link="t"/><child link="l2"/>
    <origin xyz="0.2 0 0"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
</robot>"""
    )
    chain = load_chain(path, base="l2", tool="t")
    assert chain.joint_names == ("j2",) and chain.sign.tolist() == [-1]
    nominal, cal = perturbed(chain, seed=1)
    with pytest.raises(calib.CalibError, match="carried by a link above joint 'j2'"):
        calibrated_urdf(chain, nominal, cal)


# --------------------------------------------------------------------------------------
# simulate -> calibrate -> written URDF, and design, on TALOS foot to hand
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("measure", ["pose", "position"])
def test_noise_free_round_trip_from_the_foot_to_the_hand(measure, tmp_path):
    chain = load_chain("talos", "left_sole_link", "gripper_left_base_link")
    marker = None if measure == "pose" else np.array([0.02, -0.03, 0.08])
    campaign = simulate(chain, configs=120, measure=measure, marker=marker, seed=6)
    res = calibrate(chain, campaign.measurements, marker=marker)  # default options
    assert res.accepted
    path = tmp_path / "cal.urdf"
    path.write_bytes(res.urdf())
    held = own_random_q(chain.sigma, 50, seed=77)
    truth = campaign.truth.true_mdh.forward(held)
    if measure == "pose":
        got = res.measurement_to_base @ PathRef(
            path, chain.base_frame, chain.tool_frame
        ).placements(chain.joint_names, held)
        assert np.abs(got[:, :3, 3] - truth[:, :3, 3]).max() < 1e-9
        err = [
            np.linalg.norm(pin_log3(a.T @ b))
            for a, b in zip(got[:, :3, :3], truth[:, :3, :3], strict=True)
        ]
        assert max(err) < 1e-9
    else:
        marker_link = f"{chain.tool_frame}_marker1"
        got = res.measurement_to_base @ PathRef(path, chain.base_frame, marker_link).placements(
            chain.joint_names, held
        )
        true_points = truth[:, :3, :3] @ marker + truth[:, :3, 3]
        assert np.abs(got[:, :3, 3] - true_points).max() < 1e-9


def pin_log3(R: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    return pin.log3(R)


def test_cli_simulate_calibrate_design_from_the_foot(tmp_path):
    chain_args = ["talos", "--base", "left_sole_link", "--tool", "gripper_left_base_link"]
    meas, out, report = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    assert (
        main(["simulate", *chain_args, "--out", str(meas), "--configs", "80", "--seed", "4"]) == 0
    )
    header = meas.read_text().splitlines()[0].split(",")
    assert header[:7] == [f"leg_left_{k}_joint" for k in (6, 5, 4, 3, 2, 1)] + ["torso_1_joint"]
    code = main(
        ["calibrate", *chain_args, "--data", str(meas), "--out", str(out), "--report", str(report)]
    )
    assert code == 0 and out.is_file()
    doc = json.loads(report.read_text())
    assert doc["accepted"] and doc["terms"][0]["base"] == "left_sole_link"  # format 3
    configs = tmp_path / "d.csv"
    code = main(
        [
            "design",
            *chain_args,
            "--configs",
            "30",
            "--candidates",
            "300",
            "--no-collision",
            "--out",
            str(configs),
        ]
    )
    assert code == 0
    rows = configs.read_text().splitlines()
    assert rows[0].split(",")[:6] == header[:6] and len(rows) == 31


# --------------------------------------------------------------------------------------
# Property: random trees with nasty geometry, base and tool on different branches
# --------------------------------------------------------------------------------------

GEOMETRY = ("generic", "parallel", "intersecting", "coincident", "perpendicular", "negative")
KINDS = ("revolute", "revolute", "continuous", "prismatic", "fixed")


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def rpy_of(R: np.ndarray) -> tuple[float, float, float]:
    import pinocchio as pin

    return tuple(float(a) for a in pin.rpy.matrixToRpy(R))


def random_rotation(rng) -> np.ndarray:
    Q, Rr = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(Rr)))
    return Q if np.linalg.det(Q) > 0 else -Q


class TreeWriter:
    """A random URDF tree: a trunk, then two branches (the base's and the tool's) and an
    off-path branch hanging from the base's branch. Each joint is placed relative to the
    previous joint's line in its parent link (parallel, intersecting, ...)."""

    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)
        self.links = ["root"]
        self.joints: list[str] = []
        self.moving: dict[str, list[str]] = {}

    def add(self, branch: str, parent: str, line, kind: str, geometry: str) -> tuple[str, tuple]:
        """A joint under ``parent`` whose previous line (point, direction) is ``line`` in
        ``parent``'s frame; returns its child link and its line in the child's frame."""
        rng, (point, u) = self.rng, line
        R = np.eye(3)
        xyz = rng.uniform(-0.4, 0.4, 3)
        axis = unit(rng.normal(size=3))
        if geometry == "generic":
            R = random_rotation(rng)
        elif geometry in ("parallel", "negative"):
            axis = (1.0 if geometry == "parallel" else -1.0) * u
        elif geometry == "intersecting":
            xyz, R = point + rng.uniform(-0.3, 0.3) * u, random_rotation(rng)
            axis = R.T @ unit(rng.normal(size=3))
        elif geometry == "coincident":
            xyz, axis = point + rng.uniform(-0.3, 0.3) * u, rng.choice([-1.0, 1.0]) * u
        else:  # perpendicular, through the line or not
            v = rng.normal(size=3)
            axis = unit(v - np.dot(v, u) * u)
            if rng.random() < 0.5:
                xyz = point + rng.uniform(-0.3, 0.3) * u
        if geometry != "generic" and rng.random() < 0.3:  # a turn about the axis keeps it
            R = np.array(pin_axis_angle(axis, rng.uniform(-3, 3)))
            axis = R.T @ axis
        name = f"{branch}{len(self.joints)}"
        child = f"L_{name}"
        self.links.append(child)
        limit = ""
        if kind in ("revolute", "prismatic"):
            lo = 2.5 if kind == "revolute" else 0.3
            limit = f'<limit lower="{-lo}" upper="{lo}" effort="1" velocity="1"/>'
        axis_text = (
            "" if kind == "fixed" else f'<axis xyz="{" ".join(repr(float(a)) for a in axis)}"/>'
        )
        rpy = " ".join(repr(a) for a in rpy_of(R))
        self.joints.append(
            f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{" ".join(repr(float(a)) for a in xyz)}" rpy="{rpy}"/>{axis_text}{limit}'
            f"</joint>"
        )
        if kind != "fixed":
            self.moving.setdefault(branch, []).append(name)
            return child, (np.zeros(3), axis)
        return child, (R.T @ (point - xyz), R.T @ u)

    def branch(self, branch: str, parent: str, line, spec) -> tuple[str, tuple]:
        for kind, geometry in spec:
            parent, line = self.add(branch, parent, line, kind, geometry)
        return parent, line

    def text(self) -> str:
        links = "".join(
            f'<link name="{n}"><inertial><origin xyz="0.01 0.02 0.03"/><mass value="1"/>'
            f'<inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>'
            f'<visual><origin xyz="0.1 0 0" rpy="0 0.2 0"/><geometry><box size="0.1 0.1 0.1"/>'
            f"</geometry></visual></link>"
            for n in self.links
        )
        return f'<robot name="tree">{links}{"".join(self.joints)}</robot>'


def pin_axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    import pinocchio as pin

    return pin.AngleAxis(angle, unit(axis)).matrix()


joint_specs = st.lists(st.tuples(st.sampled_from(KINDS), st.sampled_from(GEOMETRY)), max_size=4)


@CI
@given(
    seed=st.integers(0, 2**31 - 1),
    trunk=joint_specs,
    up=st.lists(
        st.tuples(st.sampled_from(KINDS[:4]), st.sampled_from(GEOMETRY)), min_size=1, max_size=4
    ),
    down=joint_specs,
    side=joint_specs,
)
def test_random_trees_base_and_tool_on_different_branches(
    tmp_path_factory, seed, trunk, up, down, side
):
    tree = TreeWriter(seed)
    common, line = tree.branch("T", "root", (np.zeros(3), np.array([0.0, 0.0, 1.0])), trunk)
    mid, mid_line = tree.branch("A", common, line, up[:1])
    base_link, base_line = tree.branch("A", mid, mid_line, up[1:])
    tree.branch("S", mid, mid_line, side)  # hangs from the base's branch, off the path
    tool_link, tool_line = tree.branch("B", common, line, down)
    base = tree.branch("A", base_link, base_line, [("fixed", "generic")])[0]
    tool = tree.branch("B", tool_link, tool_line, [("fixed", "generic")])[0]
    path = tmp_path_factory.mktemp("tree") / "tree.urdf"
    path.write_text(tree.text())

    chain = load_chain(path, base=base, tool=tool)
    expected = list(reversed(tree.moving.get("A", []))) + tree.moving.get("B", [])
    assert list(chain.joint_names) == expected
    assert chain.sign.tolist() == [-1] * len(tree.moving["A"]) + [1] * len(tree.moving.get("B", []))
    ref = PathRef(path, base, tool)
    q = own_random_q(chain.sigma, 25, seed=seed % 1000)
    mdh = from_chain(chain)
    assert np.abs(mdh.forward(q) - ref.placements(chain.joint_names, q)).max() <= FK_TOL

    # The calibrated URDF (every complete parameter perturbed) reproduces the model.
    nominal, cal = perturbed(chain, seed=seed % 997)
    written = tmp_path_factory.mktemp("cal") / "cal.urdf"
    written.write_bytes(calibrated_urdf(chain, nominal, cal))
    T = measurement_to_base(nominal, cal)
    got = PathRef(written, base, tool).placements(chain.joint_names, q)
    assert np.abs(T @ got - cal.forward(q)).max() <= 1e-9
    assert structure(written) == structure(path)

    # The identification Jacobian's joint columns are Pinocchio's, signed.
    W = identification_jacobian(mdh, joint_parameters(mdh), q[:5])
    J = ref.relative_jacobian(chain.joint_names, q[:5])
    assert np.abs(W * chain.sign - J).max() <= 1e-9 * max(1.0, float(np.abs(J).max()))
    assert math.isfinite(float(np.abs(W).max()))
