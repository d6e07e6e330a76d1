"""Trees through coupled (mimic) joints: a PR2 gripper's two fingers and a hand-made tree.

References computed without calib (``tests/pinref.py``, :class:`MimicTree`): Pinocchio builds
its model from the URDF file itself and the test applies the ``<mimic>`` relation it reads
with ElementTree (``q = multiplier * q_leader + offset``). The counts are the numeric rank of
finite differences of Pinocchio's tool placements under a generic 6-DOF error on every joint
placement, the base and the tools; the calibrations fit a "true robot" that is Pinocchio's
model with every such placement perturbed, and are scored on configurations they never saw.
"""

from __future__ import annotations

import functools
import json
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from pinref import MimicTree

import calib
from calib import Measurements, analyze, from_tree
from calib.calibration.entry import calibrate as calibrate_tree
from calib.cli.commands import main
from calib.design.constraints import Constraints
from calib.design.design import design
from calib.kinematics.catalog import resolve_urdf
from calib.kinematics.tree import load_tree

DATA = Path(__file__).parent / "data"
PR2 = resolve_urdf("erd:pr2_description/urdf/pr2.urdf")
FINGERS = ("r_gripper_l_finger_tip_link", "r_gripper_r_finger_tip_link")
CASES = {
    "pr2_gripper": (PR2, "r_gripper_palm_link", FINGERS),
    "pr2_arm_gripper": (PR2, "base_footprint", FINGERS),
    "mimic_tree": (DATA / "mimic_tree.urdf", "base", ("tool_a", "tool_b")),
}
FINGER_JOINTS = tuple(f"r_gripper_{s}_finger{t}_joint" for s in "lr" for t in ("", "_tip"))
MARKERS = np.array([[0.012, -0.007, 0.004], [0.009, 0.011, -0.006]])


@functools.cache
def tree_of(case: str) -> calib.Tree:
    path, base, tools = CASES[case]
    return load_tree(path, base, tools)


def reference(case: str) -> MimicTree:
    path, base, tools = CASES[case]
    return MimicTree(path, base, tools)


def own_variables(tree: calib.Tree, ref: MimicTree, m: int, seed: int) -> np.ndarray:
    """Independent joint positions drawn by the test within Pinocchio's limits of each joint,
    at most +-1 rad (+-0.02 m for a prismatic joint)."""
    rng = np.random.default_rng(seed)
    model = ref.model
    values = np.empty((m, len(tree.variable_names)))
    for i, name in enumerate(tree.variable_names):
        joint = model.joints[model.getJointId(name)]
        cap = 0.02 if joint.shortname().startswith("JointModelP") else 1.0
        lo, hi = -cap, cap
        if joint.nq == 1:
            lo = max(lo, model.lowerPositionLimit[joint.idx_q])
            hi = min(hi, model.upperPositionLimit[joint.idx_q])
        values[:, i] = rng.uniform(lo, hi, m)
    return values


def quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        return fn(*args, **kwargs)


# --------------------------------------------------------------------------------------
# Structure and forward kinematics
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES)
def test_variables_are_the_independent_joints_that_move_the_tree(case):
    tree, ref = tree_of(case), reference(case)
    assert list(tree.joint_names) == ref.joint_names
    assert set(tree.variable_names) == ref.variables
    mimic = {mj.name for mj in tree.coupling.mimic}
    assert mimic == set(ref.tags) & set(ref.joint_names)
    assert not mimic & set(tree.variable_names)


def test_the_hand_made_tree_has_each_kind_of_coupling():
    """A mimic of a mimic across branches, a leader outside the tree, a prismatic mimic."""
    tree = tree_of("mimic_tree")
    assert tree.variable_names == ("j1", "a1", "b2", "c1")  # tree order, then outside
    follows = {mj.name: (mj.master, mj.multiplier, mj.offset) for mj in tree.coupling.mimic}
    assert follows == {"a2": ("a1", -0.5, 0.2), "b1": ("a1", -1.0, 0.5), "b3": ("c1", 0.05, 0.02)}


def test_cli_show_lists_the_coupled_joints_of_a_tree(capsys):
    argv = ["show", str(DATA / "mimic_tree.urdf"), "--tool", "tool_a", "--tool", "tool_b"]
    assert main([*argv, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["variables"] == ["j1", "a1", "b2", "c1"]
    ref = reference("mimic_tree")
    rows = {m["name"]: (m["row"], m["master"]) for m in out["mimic"]}
    names = [f["joint"] for f in out["frames"]]
    assert {n: (names.index(n), ref.leader(n)) for n in ref.tags if n in names} == rows
    assert main(argv) == 0
    assert "  row 4: b1 = -1 a1 + 0.5" in capsys.readouterr().out.splitlines()


@pytest.mark.parametrize("case", CASES)
def test_joint_values_and_forward_kinematics_equal_pinocchio_with_the_relation(case):
    tree, ref = tree_of(case), reference(case)
    qv = own_variables(tree, ref, 15, seed=1)
    q = tree.joint_values(qv)
    assert np.allclose(q, ref.values(tree.variable_names, qv), atol=1e-15, rtol=0)
    T = from_tree(tree).forward(q)
    assert np.abs(T - ref.poses(tree.variable_names, qv)).max() < 1e-10


@pytest.mark.parametrize("case", CASES)
def test_random_configurations_follow_the_mimic_tags(case):
    tree, ref = tree_of(case), reference(case)
    q = tree.random_configurations(30, seed=2)
    col = {n: i for i, n in enumerate(tree.joint_names)}
    qv = np.stack([q[:, col[n]] for n in tree.variable_names if n in col], axis=1)
    inside = [n for n in tree.variable_names if n in col]
    if len(inside) == len(tree.variable_names):  # every leader in the tree: q is determined
        assert np.allclose(q, ref.values(inside, qv), atol=1e-14, rtol=0)
    for name in tree.variable_names:
        if name in col:
            i = tree.variable_names.index(name)
            lo, hi = tree.coupling.lower[i], tree.coupling.upper[i]
            assert np.all((q[:, col[name]] >= lo) & (q[:, col[name]] <= hi))


# --------------------------------------------------------------------------------------
# Counts against the independent complete model
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES)
def test_identifiable_count_equals_the_rank_of_the_independent_reference(case):
    tree, ref = tree_of(case), reference(case)
    qv = own_variables(tree, ref, 30, seed=3)
    marker = tuple(MARKERS[0])
    W = ref.placement_jacobian(tree.variable_names, qv, marker)
    ranks = {}
    for measure, rows in (("pose", np.arange(6)), ("position", np.arange(3))):
        keep = np.concatenate([6 * k + rows for k in range(len(W) // 6)])
        s = np.linalg.svd(W[keep], compute_uv=False)
        ranks[measure] = int(np.sum(s > 1e-7 * s[0]))
        assert s[ranks[measure]] < 1e-9 * s[0]  # a clear gap
    for measure, rank in ranks.items():
        full = quiet(analyze, tree, measure=measure, marker=marker, params="complete")
        paper = quiet(analyze, tree, measure=measure, marker=marker, params="paper")
        assert full.n_base == full.n_complete == paper.n_complete == rank
        assert paper.n_base <= rank
        assert full.n_theory is None and paper.n_theory is None
        assert [mj.name for mj in full.mimic] == [mj.name for mj in tree.coupling.mimic]
        assert all(n is None for _, n in full.per_tool)  # each chain has mimic joints


def test_mimic_joints_lose_what_independent_joints_have():
    """Coupling removes identifiable directions: fewer than the same tree moved freely."""
    tree, ref = tree_of("pr2_gripper"), reference("pr2_gripper")
    rng = np.random.default_rng(4)
    q_free = rng.uniform(0.0, 0.5, (30, tree.n))
    W = ref.placement_jacobian(tree.joint_names, q_free)
    s = np.linalg.svd(W, compute_uv=False)
    free = int(np.sum(s > 1e-7 * s[0]))
    assert free == 4 * tree.n + 6 * tree.n_tools  # Everett's count, independent joints
    assert quiet(analyze, tree, measure="pose", params="complete").n_base < free


def test_cli_analyze_the_pr2_fingers_through_their_mimic_joints(capsys):
    argv = ["analyze", str(PR2), "--base", "base_footprint", "--tool", FINGERS[0]]
    argv += ["--tool", FINGERS[1], "--params", "complete", "--measure", "pose"]
    argv += ["--json"]  # pose: the reference is the placements' Jacobian
    assert main(argv) == 0
    out = json.loads(capsys.readouterr().out)
    tree, ref = tree_of("pr2_arm_gripper"), reference("pr2_arm_gripper")
    W = ref.placement_jacobian(tree.variable_names, own_variables(tree, ref, 30, seed=5))
    s = np.linalg.svd(W, compute_uv=False)
    assert out["n_base"] == int(np.sum(s > 1e-7 * s[0]))
    assert out["n_theory"] is None
    assert {m["joint"] for m in out["mimic"]} == set(ref.tags) & set(ref.joint_names)
    assert main(argv[:-1]) == 0
    text = capsys.readouterr().out
    assert "coupled joints (URDF <mimic>" in text and "n/a with coupled joints" in text


# --------------------------------------------------------------------------------------
# Calibration: a true robot made by perturbing Pinocchio's placements
# --------------------------------------------------------------------------------------


def perturbed(ref: MimicTree, seed: int, untilted=()) -> MimicTree:
    """The reference with every joint, tool and base placement moved by ~1 mm, 1 mrad.

    The joints named in ``untilted`` turn only about their own axis: their axes keep their
    nominal directions (a PR2 finger and its tip stay parallel, as its linkage holds them).
    """
    rng = np.random.default_rng(seed)
    names = [*ref.joint_names, "base", *(["tool"] * len(ref.tools))]
    for name, (get, put) in zip(names, ref._perturbable(), strict=True):
        xi = np.concatenate([rng.normal(0, 1e-3, 3), rng.normal(0, 1e-3, 3)])
        if name in untilted:
            u = ref.axes[name] / np.linalg.norm(ref.axes[name])
            xi[3:] = (xi[3:] @ u) * u
        put(get() * pin.exp6(pin.Motion(xi)))
    return ref


def measured(true: MimicTree, names, qv: np.ndarray, frame: pin.SE3) -> np.ndarray:
    """Points of every tool ``(m, T, 3)`` in a measurement frame (base in it: ``frame``)."""
    T = true.poses(names, qv)
    pts = T[..., :3, 3] + np.einsum("mtij,tj->mti", T[..., :3, :3], MARKERS)
    return pts @ frame.rotation.T + frame.translation


def campaign(tree: calib.Tree, true: MimicTree, m: int, seed: int, frame: pin.SE3):
    qv = own_variables(tree, true, m, seed)
    pts = measured(true, tree.variable_names, qv, frame).reshape(-1, 3)
    q = np.repeat(tree.joint_values(qv), tree.n_tools, axis=0)
    data = Measurements(tree.joint_names, q, pts, tool=tree.tool_frames * m, coupling=tree.coupling)
    return qv, data


TIP_FRAME = """  <link name="test_l_tip_frame"/>
  <joint name="test_l_tip_frame_joint" type="fixed">
    <parent link="r_gripper_l_finger_tip_link"/><child link="test_l_tip_frame"/>
    <origin xyz="0.01 0.002 0" rpy="0 0 0"/>
  </joint>
</robot>"""


@pytest.fixture(scope="module")
def exportable(tmp_path_factory) -> dict:
    """Trees whose tools are carried by fixed joints, as a written URDF needs. PR2's right
    tip carries the fixed frame named r_gripper_l_finger_tip_frame (sic); the test adds one
    to the left tip, in a copy of the file."""
    path = tmp_path_factory.mktemp("pr2") / "pr2_tips.urdf"
    text = Path(PR2).read_text()
    path.write_text(text[: text.rindex("</robot>")] + TIP_FRAME + "\n")
    tools = ("test_l_tip_frame", "r_gripper_l_finger_tip_frame")
    return {"pr2_arm_gripper": (path, "base_footprint", tools), "mimic_tree": CASES["mimic_tree"]}


@pytest.mark.parametrize("case", ["pr2_arm_gripper", "mimic_tree"])
def test_noise_free_tree_calibration_through_mimic_joints_is_exact(case, exportable, tmp_path):
    """(The palm-based gripper moves in parallel planes: position rows cannot tell the
    measurement frame's height from the markers', and calibrate_tree refuses it.)"""
    src, base, tools = exportable[case]
    tree = load_tree(src, base, tools)
    true = perturbed(MimicTree(src, base, tools), seed=6, untilted=FINGER_JOINTS)
    frame = pin.SE3(pin.exp3(np.array([0.3, -0.2, 1.1])), np.array([1.5, -0.4, 0.2]))
    _, data = campaign(tree, true, 60, seed=7, frame=frame)
    res = calibrate_tree(tree, data).check()
    assert max(c.stats["train"].per_row.max() for c in res.chains) < 1e-7  # [mm]
    # held-out configurations of both tools, scored against the true robot, on the written
    # URDF read by Pinocchio with the relation applied by the test
    qv_new = own_variables(tree, true, 40, seed=8)
    truth = measured(true, tree.variable_names, qv_new, frame)
    path = tmp_path / "cal.urdf"
    res.write(path)
    cal = MimicTree(path, base, tools)
    rep = res.to_dict()
    to_base = np.array(rep["measurement_to_base"]["matrix"])
    markers = np.array([rep["frames"]["markers"][t][0] for t in tools])
    T_cal = cal.poses(tree.variable_names, qv_new)
    urdf_pts = T_cal[..., :3, 3] + np.einsum("mtij,tj->mti", T_cal[..., :3, :3], markers)
    urdf_pts = urdf_pts @ to_base[:3, :3].T + to_base[:3, 3]
    assert np.abs(urdf_pts - truth).max() < 1e-9
    tags = [
        {
            j.get("name"): j.find("mimic").attrib
            for j in root.iter("joint")
            if j.find("mimic") is not None
        }
        for root in (ET.parse(str(src)).getroot(), ET.parse(str(path)).getroot())
    ]
    assert tags[0] == tags[1]


@pytest.mark.parametrize("case", ["pr2_arm_gripper", "mimic_tree"])
def test_tree_calibration_counts_the_rank_of_pinocchio_alone(case, exportable):
    """The joint fit of a tree (one measured term per tool, the instrument's frame shared)
    determines as many unknowns as the finite-difference rank of Pinocchio's own model at the
    measured configurations (every joint, tool and base placement moved), and fits them all."""
    src, base, tools = exportable[case]
    tree = load_tree(src, base, tools)
    true = perturbed(MimicTree(src, base, tools), seed=6, untilted=FINGER_JOINTS)
    qv, data = campaign(tree, true, 60, seed=7, frame=pin.SE3.Identity())
    res = calibrate_tree(tree, data).check()
    W = MimicTree(src, base, tools).placement_jacobian(tree.variable_names, qv, MARKERS[0])
    keep = np.concatenate([6 * k + np.arange(3) for k in range(len(W) // 6)])
    s = np.linalg.svd(W[keep], compute_uv=False)
    rank = int(np.sum(s > 1e-7 * s[0]))
    assert s[rank] < 1e-9 * s[0]  # a clear gap
    assert res.identifiable == res.unknowns == rank


def test_tilted_finger_axes_add_weak_directions_and_a_second_order_error():
    """The count is taken at the nominal geometry, where each PR2 finger and its tip turn
    about parallel axes by one angle and the tip keeps its orientation. Tilted by ~1 mrad,
    the axes give Pinocchio's complete model 4 more directions, 1e-8 of the largest: too
    weak to estimate, so the fit on the nominal count leaves a second-order error."""
    tree = tree_of("pr2_arm_gripper")
    n = quiet(analyze, tree, measure="position", marker=tuple(MARKERS[0]), params="complete")
    weak = []
    for untilted in (FINGER_JOINTS, ()):
        true = perturbed(reference("pr2_arm_gripper"), seed=6, untilted=untilted)
        qv = own_variables(tree, true, 40, seed=3)
        W = true.placement_jacobian(tree.variable_names, qv, tuple(MARKERS[0]), eps=1e-5)
        keep = np.concatenate([6 * k + np.arange(3) for k in range(len(W) // 6)])
        s = np.linalg.svd(W[keep], compute_uv=False)
        weak.append(s[n.n_base : n.n_base + 4] / s[0])
        assert s[n.n_base - 1] / s[0] > 1e-5
        _, data = campaign(tree, true, 60, seed=7, frame=pin.SE3.Identity())
        res = calibrate_tree(tree, data)
        error = 1e-3 * max(c.stats["train"].per_row.max() for c in res.chains)  # [m]
    assert weak[0].max() < 1e-10 < 1e-9 < weak[1].min() < weak[1].max() < 1e-7
    assert error < 1e-7  # measured 1.3e-8 m: errors of 1 mm, 1 mrad squared


def test_cli_simulates_and_calibrates_a_tree_through_mimic_joints(tmp_path, capsys):
    urdf = str(DATA / "mimic_tree.urdf")
    tools = ["--tool", "tool_a", "--tool", "tool_b"]
    csv, out = tmp_path / "d.csv", tmp_path / "cal.urdf"
    argv = ["simulate", urdf, *tools, "--measure", "position", "--configs", "40"]
    assert main([*argv, "--out", str(csv), "--seed", "3"]) == 0
    capsys.readouterr()
    header = csv.read_text().splitlines()[0].split(",")
    assert header == ["j1", "a1", "b2", "c1", "x", "y", "z", "tool"]  # independent joints
    argv = ["calibrate", urdf, *tools, "--data", str(csv), "--out", str(out), "--json"]
    assert main(argv) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["accepted"] and report["residuals"]["calibrated"]["position_max"] < 1e-10
    assert out.is_file()


# --------------------------------------------------------------------------------------
# Design
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("case", ["pr2_arm_gripper", "mimic_tree"])
def test_design_of_a_tree_through_mimic_joints_follows_the_tags(case):
    tree, ref = tree_of(case), reference(case)
    d = design(tree, 15, candidates=300, constraints=Constraints(collision=False), seed=1)
    col = {n: i for i, n in enumerate(tree.joint_names)}
    checked = 0
    for name, (leader, factor, offset) in ref.tags.items():
        if name in col and leader in col:
            assert np.allclose(d.q[:, col[name]], factor * d.q[:, col[leader]] + offset)
            checked += 1
    assert checked >= 2
    assert np.isfinite(d.indices.d)
    assert d.model.b == quiet(analyze, tree, measure="position", params="complete").n_base


def test_cli_design_simulate_calibrate_a_tree_through_mimic_joints(tmp_path, capsys):
    urdf = str(DATA / "mimic_tree.urdf")
    tools = ["--tool", "tool_a", "--tool", "tool_b"]
    configs, csv = tmp_path / "configs.csv", tmp_path / "d.csv"
    argv = ["design", urdf, *tools, "--configs", "20", "--candidates", "400"]
    assert main([*argv, "--out", str(configs)]) == 0
    rows = configs.read_text().splitlines()
    names = rows[0].split(",")
    q = np.array([[float(v) for v in r.split(",")] for r in rows[1:]])
    ref = reference("mimic_tree")
    for name, (leader, factor, offset) in ref.tags.items():
        if name in names and leader in names:
            i, j = names.index(name), names.index(leader)
            assert np.allclose(q[:, i], factor * q[:, j] + offset)
    argv = ["simulate", urdf, *tools, "--measure", "position", "--configs-file", str(configs)]
    assert main([*argv, "--out", str(csv)]) == 0
    argv = ["calibrate", urdf, *tools, "--data", str(csv), "--out", str(tmp_path / "c.urdf")]
    assert main(argv) == 0
    capsys.readouterr()
