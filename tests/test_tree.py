"""Trees (several tools sharing joints): the structure against Pinocchio's supports, forward
kinematics of every tool against Pinocchio reading the URDF itself, the JSON contract rebuilt
by hand, the Jacobian against finite differences, and identifiability of every catalog tree
against an independent complete model (finite differences of Pinocchio placements).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
import scipy.linalg
from conftest import TREES
from pinref import PinTree, own_random_q, rot, trans

import calib
from calib import InvalidArgumentError, Measurement, analyze, from_chain, from_tree, load_chain
from calib.cli.commands import main
from calib.exceptions import ChainError
from calib.identification.identifiability import analyze_model
from calib.identification.jacobian import identification_jacobian
from calib.identification.parameters import paper_parameters
from calib.identification.tree_jacobian import (
    tree_complete_jacobian,
    tree_jacobian,
    tree_parameters,
)
from calib.kinematics.catalog import CatalogEntry
from calib.kinematics.tree import load_tree

FK_TOL = 1e-10
MARKER = (0.011, 0.023, 0.037)


def entry(name: str) -> CatalogEntry:
    return next(e for e in calib.catalog() if e.name == name)


_TREES: dict[str, calib.Tree] = {}


def tree_of(name: str) -> calib.Tree:
    if name not in _TREES:
        _TREES[name] = load_tree(name)
    return _TREES[name]


def pin_tree_of(name: str) -> PinTree:
    e = entry(name)
    return PinTree.of_file(e.path, e.base, e.tools)


def own_rank(W: np.ndarray) -> int:
    """docs/method.md section 3: pivoted QR, b = #{|R_ii| > tau}, tau = r eps |R_11|."""
    R = scipy.linalg.qr(W, mode="r", pivoting=True)[0]
    d = np.abs(np.diag(R))
    return int(np.sum(d > W.shape[0] * np.finfo(float).eps * d[0]))


def quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        return fn(*args, **kwargs)


# --------------------------------------------------------------------------------------
# Structure and forward kinematics of every catalog tree
# --------------------------------------------------------------------------------------


def test_catalog_has_the_whole_robots():
    assert {"talos", "romeo", "icub", "g1", "human", "solo12", "anymal", "go2", "pr2"} <= set(TREES)
    assert all(len(entry(n).tools) >= 2 for n in TREES)


@pytest.mark.parametrize("name", TREES)
def test_tree_joints_are_the_union_of_the_pinocchio_paths(name):
    tree, ref = tree_of(name), pin_tree_of(name)
    assert list(tree.joint_names) == ref.joint_names
    assert tree.tool_frames == tuple(ref.model.frames[t].name for t in ref.tools)
    for t, path in enumerate(tree.paths):
        support = list(ref.model.supports[ref.model.frames[ref.tools[t]].parentJoint])
        on_path = [ref.model.names[j] for j in support if ref.model.names[j] in tree.joint_names]
        assert [tree.joint_names[i] for i in path] == on_path


@pytest.mark.parametrize("name", TREES)
def test_tree_forward_of_every_tool_equals_pinocchio(name):
    tree, ref = tree_of(name), pin_tree_of(name)
    q = own_random_q(tree.sigma, 30, seed=len(name))
    T_ref = ref.poses(tree.joint_names, q)
    assert np.abs(from_tree(tree).forward(q) - T_ref).max() <= FK_TOL
    assert np.abs(tree.tool_placements(q) - T_ref).max() <= FK_TOL  # calib's own wrapper
    # the structural model (round-off removed) moves the tools by round-off only
    assert np.abs(from_tree(tree).idealized().forward(q) - T_ref).max() <= 1e-4


def rows_forward(rows: list[dict], q: np.ndarray) -> dict[str, np.ndarray]:
    """The JSON contract of a tree: frame k = frame a(k) Rot(z,gamma) Trans(z,b) Trans(y,y)
    Rot(y,beta) Rot(x,alpha) Trans(x,d) Rot(z, theta + (1-sigma) q) Trans(z, r + sigma q)."""
    frames = {-1: np.eye(4)}
    tools, k_joint = {}, 0
    for k, row in enumerate(rows):
        theta, r = row["theta"], row["r"]
        if row["sigma"] is not None:
            theta += (1 - row["sigma"]) * q[k_joint]
            r += row["sigma"] * q[k_joint]
            k_joint += 1
        T = frames[row["antecedent"]] @ rot("z", row["gamma"]) @ trans("z", row["b"])
        T = T @ trans("y", row["y"]) @ rot("y", row["beta"]) @ rot("x", row["alpha"])
        frames[k] = T @ trans("x", row["d"]) @ rot("z", theta) @ trans("z", r)
        if row["tool"] is not None:
            tools[row["tool"]] = frames[k]
    return tools


@pytest.mark.parametrize("name", ["talos", "pr2", "solo12", "centauro"])
def test_show_json_rows_rebuild_pinocchio(capsys, name):
    assert main(["show", name, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    tree, ref = tree_of(name), pin_tree_of(name)
    assert doc["tools"] == list(tree.tool_frames)
    rows = doc["frames"]
    assert [r["joint"] for r in rows if r["sigma"] is not None] == list(tree.joint_names)
    for qi in own_random_q(tree.sigma, 10, seed=4):
        tools = rows_forward(rows, qi)
        T_ref = ref.poses(tree.joint_names, qi)[0]
        for t, tool in enumerate(tree.tool_frames):
            assert np.abs(tools[tool] - T_ref[t]).max() <= FK_TOL


def test_show_text_has_the_antecedents(capsys):
    assert main(["show", "talos", "--tool", "left_sole_link", "--tool", "right_sole_link"]) == 0
    out = capsys.readouterr().out
    assert "a(j)" in out and "gamma[deg]" in out and "(tool right_sole_link)" in out


# --------------------------------------------------------------------------------------
# A one-tool tree is the chain
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "tool"), [("aid", None), ("tiago", None), ("talos", "left_sole_link")]
)
def test_one_tool_tree_is_the_chain_row_for_row(name, tool):
    chain = load_chain(name, tool=tool)
    tree = load_tree(name, tools=[chain.tool_frame])
    mdh, model = from_chain(chain), from_tree(tree)
    for k in ("beta", "alpha", "d", "theta", "r", "y", "sigma"):
        assert np.array_equal(getattr(mdh, k), getattr(model, k)), k
    assert not model.gamma.any() and not model.b.any()
    q = chain.random_configurations(20, 1)
    assert np.array_equal(tree.random_configurations(20, 1), q)
    pset, tset = paper_parameters(mdh), tree_parameters(model, "paper")
    assert pset.names == tset.names
    assert np.array_equal(identification_jacobian(mdh, pset, q), tree_jacobian(model, tset, q))
    a = quiet(analyze, chain, measure="pose", params="complete")
    b = quiet(analyze, tree, measure="pose", params="complete")
    assert (a.base, a.n_complete, a.n_theory) == (b.base, b.n_complete, b.n_theory)


# --------------------------------------------------------------------------------------
# The identification Jacobian of a tree
# --------------------------------------------------------------------------------------


def pose_difference(T1: np.ndarray, T0: np.ndarray) -> np.ndarray:
    """(dp, dr) between homogeneous poses, dr the small rotation R1 R0^T, in the base frame."""
    dp = T1[..., :3, 3] - T0[..., :3, 3]
    Rw = np.einsum("...ij,...kj->...ik", T1[..., :3, :3], T0[..., :3, :3])
    dr = 0.5 * np.stack(
        [
            Rw[..., 2, 1] - Rw[..., 1, 2],
            Rw[..., 0, 2] - Rw[..., 2, 0],
            Rw[..., 1, 0] - Rw[..., 0, 1],
        ],
        axis=-1,
    )
    return np.concatenate([dp, dr], axis=-1)


@pytest.mark.parametrize("name", ["talos", "tiago_dual", "anymal_kinova"])
@pytest.mark.parametrize("label", ["paper", "complete"])
def test_tree_jacobian_equals_finite_differences(name, label):
    model = from_tree(tree_of(name))
    pset = tree_parameters(model, label)
    q = own_random_q(model.sigma[1 : model.n + 1], 4, seed=5)
    eps = 1e-6
    W_fd = np.empty((len(q) * model.n_tools * 6, len(pset)))
    for c in range(len(pset)):
        dx = np.zeros(len(pset))
        dx[c] = eps
        plus, minus = pset.apply(model, dx).forward(q), pset.apply(model, -dx).forward(q)
        W_fd[:, c] = (pose_difference(plus, minus) / (2 * eps)).reshape(-1)
    assert np.abs(tree_jacobian(model, pset, q) - W_fd).max() <= 1e-7


def test_measured_tools_select_rows_and_the_factor_keeps_the_geometry():
    model = from_tree(tree_of("pr2"))
    pset = tree_parameters(model, "complete")
    q = own_random_q(model.sigma[1 : model.n + 1], 12, seed=6)
    meas = Measurement.of("position", MARKER)
    W = tree_jacobian(model, pset, q, meas)
    mask = np.random.default_rng(7).random((12, model.n_tools)) < 0.5
    rows = np.repeat(mask.ravel(), 3)  # configuration-major, then tool, then x, y, z
    assert np.array_equal(tree_jacobian(model, pset, q, meas, measured=mask), W[rows])
    F = tree_jacobian(model, pset, q, meas, factor=True)
    assert F.shape[0] < W.shape[0]
    assert np.allclose(F.T @ F, W.T @ W, atol=1e-10 * np.abs(W.T @ W).max(), rtol=0)
    Wc = tree_complete_jacobian(model, q, meas)
    Fc = tree_complete_jacobian(model, q, meas, factor=True)
    assert np.allclose(Fc.T @ Fc, Wc.T @ Wc, atol=1e-10 * np.abs(Wc.T @ Wc).max(), rtol=0)
    with pytest.raises(InvalidArgumentError, match="measured"):
        tree_jacobian(model, pset, q, meas, measured=mask[:3])


def test_tree_complete_jacobian_spans_the_pinocchio_placement_errors():
    """Column space of calib's complete model == that of the finite-difference reference."""
    name = "tiago_dual"
    tree, ref = tree_of(name), pin_tree_of(name)
    model = from_tree(tree)
    q = own_random_q(tree.sigma, 8, seed=8)
    W = tree_complete_jacobian(model, q)
    W_ref = ref.placement_jacobian(tree.joint_names, q)
    both = np.hstack([W / np.abs(W).max(), W_ref / np.abs(W_ref).max()])
    s = np.linalg.svd(both, compute_uv=False)
    rank_both = int(np.sum(s > 1e-7 * s[0]))
    assert rank_both == own_rank(W) == ref.complete_rank(tree.joint_names, q)


# --------------------------------------------------------------------------------------
# Identifiability of every catalog tree against the independent reference
# --------------------------------------------------------------------------------------


def counts(tree) -> tuple[int, int, int]:
    return tree.n_revolute, tree.n_prismatic, tree.n_tools


@pytest.mark.parametrize("name", TREES)
def test_tree_identifiable_count_is_the_pinocchio_complete_rank(name):
    tree, ref = tree_of(name), pin_tree_of(name)
    R, P, T = counts(tree)
    q = own_random_q(tree.sigma, 30, seed=9)
    W_ref = ref.placement_jacobian(tree.joint_names, q, MARKER)
    s = np.linalg.svd(W_ref, compute_uv=False)
    pose_ref = int(np.sum(s > 1e-7 * s[0]))
    position_rows = np.concatenate([6 * k + np.arange(3) for k in range(len(W_ref) // 6)])
    s = np.linalg.svd(W_ref[position_rows], compute_uv=False)
    position_ref = int(np.sum(s > 1e-7 * s[0]))
    pose = quiet(analyze, tree, measure="pose", params="complete", configs=40, seed=1)
    assert pose.n_base == pose.n_complete == pose_ref == 4 * R + 2 * P + 6 * T
    assert pose.n_theory == pose_ref and pose.missing == ()
    position = quiet(analyze, tree, measure="position", marker=MARKER, params="complete")
    assert position.n_base == position.n_complete == position_ref
    assert position.n_theory in (None, position_ref)
    paper = quiet(analyze, tree, measure="pose", params="paper", configs=40, seed=1)
    assert paper.n_base + len(paper.missing) == pose.n_base
    assert paper.n_base == own_rank(tree_jacobian(paper.mdh, paper.params, q))


def test_talos_hands_count_and_what_sharing_the_torso_removes():
    hands = ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    res = analyze("talos", tool=hands, params="complete", measure="pose")
    left = analyze("talos", tool=hands[0], params="complete", measure="pose")
    right = analyze("talos", tool=hands[1], params="complete", measure="pose")
    # 2 torso joints + 7 per arm, each chain alone 4 * 9 + 6 = 42
    assert left.n_base == right.n_base == 42
    assert res.n_base == res.n_complete == res.n_theory == 4 * 16 + 6 * 2 == 76
    assert left.n_base + right.n_base - res.n_base == 2 * 4  # the torso, counted once
    assert dict(res.per_tool) == {hands[0]: 42, hands[1]: 42}


def test_regrouping_identity_on_a_tree():
    model = from_tree(tree_of("tiago_dual")).idealized()
    q = own_random_q(model.sigma[1 : model.n + 1], 30, seed=10)
    meas = Measurement.of("position", MARKER)
    res = quiet(analyze_model, model, "paper", meas, q)
    W = tree_jacobian(model, res.params, q, meas)
    names = list(res.params.names)
    i1, i2 = [names.index(n) for n in res.base], [names.index(n) for n in res.others]
    dX = np.random.default_rng(11).normal(size=len(names)) * 1e-3
    assert np.allclose(W @ dX, W[:, i1] @ (dX[i1] + res.B @ dX[i2]), atol=1e-10, rtol=0)
    assert own_rank(W[:, i1]) == len(i1) == own_rank(W)


# --------------------------------------------------------------------------------------
# The command line
# --------------------------------------------------------------------------------------


def test_cli_analyze_talos_two_hands_text_and_json(capsys):
    argv = ["analyze", "talos", "--tool", "wrist_left_ft_tool_link"]
    argv += ["--tool", "wrist_right_ft_tool_link", "--params", "complete"]
    argv += ["--measure", "pose"]  # the counts below are pose's (the default is position)
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert out.startswith("talos: base_link -> wrist_left_ft_tool_link, wrist_right_ft_tool_link")
    # paper set 2 + 4 (16 joints + 2 tools) + gamma, b of the second arm = 76; complete: + beta1,
    # y1 (the base z axis lies on the first torso axis)
    assert "standard 78, base 76, complete model 76, theory 76" in out
    assert "the chains alone sum to 84; the tree has 8 fewer" in out
    assert main([*argv, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["tool_frames"] == ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    assert doc["n_base"] == doc["n_complete"] == doc["n_theory"] == 76
    assert doc["per_tool_theory"] == {"wrist_left_ft_tool_link": 42, "wrist_right_ft_tool_link": 42}
    assert doc["joints"] == {"revolute": 16, "prismatic": 0}


def test_cli_analyze_catalog_tree_uses_its_tools(capsys):
    assert main(["analyze", "solo12", "--json", "--configs", "40"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["tool_frames"] == list(entry("solo12").tools)
    assert doc["measure"] == "position" and doc["params"] == "complete"  # the defaults
    assert doc["n_complete"] == 4 * 12 + 3 * 4  # Everett's count for points: 3 per tool
    assert main(["analyze", "solo12", "--json", "--configs", "40", "--measure", "pose"]) == 0
    assert json.loads(capsys.readouterr().out)["n_complete"] == 4 * 12 + 6 * 4


@pytest.mark.parametrize(
    ("argv", "fact"),
    [
        (["analyze", "ur5", "--measure", "pose", "--measure", "position"], "--measure"),
        (["analyze", "ur5", "--base", "base_link", "--base", "tool0"], "--base"),
        (["simulate", "ur5", "--out", "x.csv", "--seed", "1", "--seed", "2"], "--seed"),
        (
            ["calibrate", "ur5", "--data", "d", "--out", "o.urdf", "--base", "a", "--base", "b"],
            "--base",
        ),
        (["analyze", "ur5", "--seed", "1", "--seed", "2"], "--seed"),
        (["analyze", "ur5", "--marker", "0", "0", "0", "--marker", "1", "1", "1"], "--marker"),
    ],
)
def test_cli_repeated_single_options_are_errors(capsys, tmp_path, monkeypatch, argv, fact):
    monkeypatch.chdir(tmp_path)
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and err.count("\n") == 1 and fact in err, err
    assert list(tmp_path.iterdir()) == []


def test_cli_tree_errors_are_one_line(capsys):
    cases = [
        (["analyze", "talos", "--tool", "left_sole_link", "--tool", "left_sole_link"], "twice"),
        (["analyze", "talos", "--tool", "left_sole_link", "--tool", "nope"], "nope"),
        (["analyze", "ur5", "--tool", "tool0", "--tool", "base_link"], "base_link"),
        (["analyze", "talos", "--tool", "left_sole_link", "--tool", "x", "--markers", "2"], "x"),
        (["analyze", "pr2", "--markers", "2"], "one --tool"),
    ]
    for argv, fact in cases:
        code = main(argv)
        out, err = capsys.readouterr()
        assert code == 2 and out == "" and err.count("\n") == 1 and fact in err, (argv, err)


def test_load_chain_of_a_catalog_tree_names_its_tools():
    with pytest.raises(ChainError, match="tree of 5 tools"):
        load_chain("talos")
    assert load_chain("talos", tool="left_sole_link").n == 6


@pytest.mark.parametrize(
    ("kwargs", "fact"),
    [
        ({"tools": []}, "tools"),
        ({"tools": ["left_sole_link", None]}, "tools"),
        ({"tools": ["left_sole_link", 3]}, "string"),
        ({"tools": ["left_sole_link", "left_sole_link"]}, "twice"),
        ({"tools": ["left_sole_link", ""]}, "empty"),
    ],
)
def test_load_tree_rejects_bad_tools(kwargs, fact):
    with pytest.raises(calib.CalibError, match=fact):
        load_tree("talos", **kwargs)


def test_tree_model_refuses_arrays_that_are_no_tree():
    model = from_tree(tree_of("bolt"))
    with pytest.raises(InvalidArgumentError, match="antecedent"):
        model.replace(antecedent=np.roll(model.antecedent, 1))
    with pytest.raises(InvalidArgumentError, match="same length"):
        model.replace(gamma=model.gamma[:-1])
    with pytest.raises(InvalidArgumentError, match="TreeMDH"):
        tree_parameters(from_chain(load_chain("ur5")))


def test_a_tool_row_names_the_frame_pinocchio_places_there():
    """``tool_frame_of``, the one map of a tree's tool rows to their frames (the analysis's
    ``frame``, the tables, the JSON rows, the rank notes): the frame it names is, by
    Pinocchio reading the URDF, where the row's path ends."""
    tree, ref = tree_of("solo12"), pin_tree_of("solo12")
    model = from_tree(tree)
    q = own_random_q(tree.sigma, 5, seed=12)
    T_ref = ref.poses(tree.joint_names, q)
    by_name = {ref.model.frames[f].name: T_ref[:, i] for i, f in enumerate(ref.tools)}
    T = model.forward(q)
    for t in range(model.n_tools):
        name = model.tool_frame_of(int(model.path_rows(t)[-1]))
        assert np.abs(T[:, t] - by_name[name]).max() <= FK_TOL
    assert [model.tool_frame_of(k) for k in range(model.n + 1)] == [None] * (model.n + 1)
    found = quiet(analyze_model, model, "complete", Measurement.of("pose"), q)
    assert found.row_frame(model.tool_rows[1]) == model.tool_frame_of(model.tool_rows[1])
    chain = from_chain(load_chain("ur5"))
    assert chain.tool_frame_of(chain.n + 1) == "tool0" and chain.tool_frame_of(chain.n) is None


def test_a_tree_model_without_tool_names_is_shown_and_explained():
    """A TreeMDH may leave its tools unnamed: its table says ``(tool)`` (a KeyError
    before), and the rank notes say "the tool z axis" as for a chain."""
    from calib.identification.parameters import Kind, Parameter
    from calib.identification.rank_notes import explain
    from calib.identification.report import tree_table

    named = from_tree(tree_of("solo12"))
    model = named.replace(tool_frames=())
    lines = tree_table(model).splitlines()
    assert [line.split()[2] for line in lines[-model.n_tools :]] == ["(tool)"] * model.n_tools
    row = model.tool_rows[2]
    assert "the tool z axis" in explain(Parameter(row, Kind.BETA), model)
    text = explain(Parameter(row, Kind.BETA), named)
    assert f"the z axis of tool {named.tool_frames[2]}" in text
