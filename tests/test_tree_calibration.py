"""Calibration of trees: TALOS's two arms with the torso, several tools in one campaign."""

from __future__ import annotations

import dataclasses
import functools
import json

import numpy as np
import pytest

from calib import DataError, InvalidArgumentError, Measurements, calibrate
from calib.design.tree_error_model import TreeErrorModel, TreeState
from calib.identification.tree_jacobian import tree_parameters
from calib.kinematics.catalog import resolve_urdf
from calib.kinematics.tree import load_tree
from calib.kinematics.tree_model import from_tree
from calib.measurements.tree_campaign import simulate_tree, true_points

HANDS = ("wrist_left_ft_tool_link", "wrist_right_ft_tool_link")
MARKERS = np.array([[0.05, 0.02, 0.1], [0.03, -0.02, 0.08]])


@functools.cache
def talos(tools=HANDS):
    return load_tree(resolve_urdf("erd:talos_data/robots/talos_reduced.urdf"), "base_link", tools)


def urdf_points(res, tree, q: np.ndarray, tmp_path) -> np.ndarray:
    """Each tool's marker in the measurement frame ``(m, T, 3)`` [m], from the written URDF
    reloaded by Pinocchio, the report's markers and measurement frame."""
    path = tmp_path / "cal.urdf"
    res.write(path)
    T = load_tree(path, tree.base_frame, tree.tool_frames).tool_placements(q)
    frames = res.to_dict()["frames"]
    markers = np.array([frames["markers"][t][0] for t in tree.tool_frames])
    F = np.array(frames["measurement"][tree.base_frame]["matrix"])
    pts = T[..., :3, 3] + np.einsum("mtij,tj->mti", T[..., :3, :3], markers)
    return pts @ F[:3, :3].T + F[:3, 3]


def _held_out(res, tree, truth, q: np.ndarray, tmp_path) -> np.ndarray:
    """Distance from the calibrated (its URDF's) to the true point of every tool ``(m, T)``."""
    truth_pts = true_points(truth.true_mdh, q, truth.markers)
    return np.linalg.norm(urdf_points(res, tree, q, tmp_path) - truth_pts, axis=2)


def _train_max_mm(res) -> float:
    """The largest fitted row error of every tool [mm]."""
    return max(c.stats["train"].per_row.max() for c in res.chains)


def test_noise_free_two_arms_and_torso_recover_both_hands(tmp_path):
    tree = talos()
    camp = simulate_tree(tree, 40, markers=MARKERS, error_mm=2, error_mrad=3, seed=1)
    res = calibrate(tree, camp.measurements).check()
    assert _train_max_mm(res) < 1e-9
    q = tree.random_configurations(100, 11)  # configurations the fit never saw
    assert _held_out(res, tree, camp, q, tmp_path).max() < 1e-9


def test_noise_free_recovers_the_true_base_parameters(tmp_path):
    """A truth that differs from the nominal tree along every MDH parameter of the tree's
    complete set (errors of 2 mm, 3 mrad; those of the first joints are the instrument
    frame's too): the calibrated URDF and frame give the true points at configurations never
    seen."""
    tree = talos()
    nominal = from_tree(tree)
    pset = tree_parameters(nominal, "complete")
    rng = np.random.default_rng(5)
    rot = np.array([p.kind.is_rotation for p in pset.parameters])
    errors = rng.normal(0, 1, len(pset)) * np.where(rot, 3e-3, 2e-3)
    true_mdh = pset.apply(nominal, errors)
    q = tree.random_configurations(40, 2)
    points = true_points(true_mdh, q, MARKERS).reshape(-1, 3)
    data = Measurements(tree.joint_names, np.repeat(q, 2, axis=0), points, tool=HANDS * len(q))
    res = calibrate(tree, data).check()
    unseen = tree.random_configurations(50, 3)
    truth = true_points(true_mdh, unseen, MARKERS)
    assert np.abs(urdf_points(res, tree, unseen, tmp_path) - truth).max() < 1e-9


def test_with_noise_each_hand_is_better_than_calibrating_its_arm_alone(tmp_path):
    tree = talos()
    tree_err, arm_err = [], []
    for seed in range(5):
        camp = simulate_tree(tree, 30, markers=MARKERS, noise_mm=0.1, seed=seed)
        q = tree.random_configurations(200, 100 + seed)
        res = calibrate(tree, camp.measurements)
        err = _held_out(res, tree, camp, q, tmp_path)
        tree_err.append(np.sqrt(np.mean(err**2, axis=0)))
        data, per_arm = camp.measurements, []
        for t, chain in enumerate(tree.chains):
            rows = np.array([name == HANDS[t] for name in data.tool])
            arm = Measurements(
                chain.joint_names, data.q[rows][:, tree.paths[t]], data.position[rows]
            )
            pts, _ = calibrate(chain, arm, params="complete").state.predict(q[:, tree.paths[t]])
            truth = true_points(camp.true_mdh, q, camp.markers)[:, t]
            per_arm.append(np.sqrt(np.mean(np.sum((pts[:, 0] - truth) ** 2, axis=1))))
        arm_err.append(per_arm)
    assert np.all(np.median(tree_err, axis=0) < np.median(arm_err, axis=0))


def test_analytic_jacobian_matches_finite_differences():
    """The design's tree Jacobian (every tool at each configuration) at a moved x."""
    tree = talos()
    q = tree.random_configurations(6, 3)
    nominal = from_tree(tree)
    pset = tree_parameters(nominal, "complete")
    model = TreeErrorModel(pset, pset.names, 2)
    start = TreeState(nominal, np.eye(4), MARKERS)
    x = np.random.default_rng(0).normal(0, 1e-3, model.size())
    tool = np.tile(np.arange(2), len(q))
    J = model.jacobian_at(start, x, np.repeat(q, 2, axis=0), tool).reshape(-1, model.size())

    def model_points(x):
        state = model.apply(start, x)
        pts = true_points(state.mdh, q, state.markers)
        return (pts @ state.frame[:3, :3].T + state.frame[:3, 3]).ravel()

    h = 1e-6
    fd = np.stack(
        [(model_points(x + h * e) - model_points(x - h * e)) / (2 * h) for e in np.eye(len(x))],
        axis=1,
    )
    assert np.allclose(J, fd, atol=1e-7 * max(1.0, np.abs(fd).max()))


@pytest.mark.parametrize(
    "tools",
    [HANDS, ("left_sole_link", "right_sole_link"), (*HANDS, "rgbd_link")],
)
def test_calibrated_urdf_moves_every_branch(tools, tmp_path):
    """Reloaded in Pinocchio, the calibrated URDF gives the calibrated model of every tool."""
    tree = talos(tools)
    camp = simulate_tree(tree, 40, markers=[0.05, 0.02, 0.1], error_mm=2, error_mrad=3, seed=4)
    res = calibrate(tree, camp.measurements).check()
    q = tree.random_configurations(30, 7)
    assert _held_out(res, tree, camp, q, tmp_path).max() < 1e-9


def test_far_measurement_frame_is_registered():
    tree = talos()
    camp = simulate_tree(tree, 30, markers=MARKERS, seed=6)
    yaw = np.array([[np.cos(2.5), -np.sin(2.5), 0], [np.sin(2.5), np.cos(2.5), 0], [0, 0, 1]])
    data = camp.measurements
    moved = dataclasses.replace(data, position=data.position @ yaw.T + [3.0, -1.0, 0.5])
    res = calibrate(tree, moved).check()
    assert _train_max_mm(res) < 1e-6


def test_bad_tree_data_is_a_one_line_error():
    tree = talos()
    data = simulate_tree(tree, 5, seed=0).measurements
    with pytest.raises(DataError, match="'tool' column must name"):
        calibrate(tree, dataclasses.replace(data, tool=None))
    with pytest.raises(InvalidArgumentError, match="choose frames, complete"):
        calibrate(tree, data, params="auto")
    with pytest.raises(DataError, match="unknown tool 'head'"):
        calibrate(tree, dataclasses.replace(data, tool=("head",) * data.m))


def test_cli_simulates_and_calibrates_a_tree(tmp_path, capsys):
    from calib.cli.commands import main

    tools = ["--tool", HANDS[0], "--tool", HANDS[1], "--base", "base_link"]
    data, out, report = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    sim = ["simulate", "talos", *tools, "--measure", "position", "--configs", "30"]
    assert main([*sim, "--out", str(data), "--marker", "0.05", "0.02", "0.1"]) == 0
    assert data.read_text().splitlines()[0].endswith(",tool")
    cal = ["calibrate", "talos", *tools, "--data", str(data)]
    assert main([*cal, "--out", str(out), "--report", str(report), "--json"]) == 0
    rep = json.loads(report.read_text())
    assert rep["accepted"] and [t["tool"] for t in rep["terms"]] == list(HANDS)
    assert rep["shape"] == "tree" and rep["tools"] == list(HANDS)  # format 2's, kept
    for term in rep["errors"]["terms"]:  # noise-free
        assert term["train"]["calibrated"]["x_max_mm"] < 1e-6
    tree = talos()
    nominal = from_tree(tree)
    reloaded = load_tree(out, "base_link", HANDS)
    q = tree.random_configurations(20, 3)
    base = np.array(rep["measurement_to_base"]["matrix"])  # measurement frame <- URDF base
    truth = json.loads(data.with_suffix(".truth.json").read_text())
    pset = tree_parameters(nominal, "complete")
    true_mdh = pset.apply(nominal, np.array([truth["errors"][n] for n in pset.names]))
    expected = true_points(true_mdh, q, np.array(truth["markers"]))
    T = reloaded.tool_placements(q)
    got = T[..., :3, 3] + np.einsum(
        "mtij,tj->mti", T[..., :3, :3], np.array(list(rep["markers"].values()))
    )
    got = got @ base[:3, :3].T + base[:3, 3]
    assert np.abs(got - expected).max() < 1e-9
    capsys.readouterr()
    assert main([*cal, "--out", str(tmp_path / "x.urdf"), "--loss", "huber"]) == 2
    assert "--loss is for one chain" in capsys.readouterr().err
    pose = [*sim[:-4], "--measure", "pose"]  # the default instrument measures positions
    assert main([*pose, "--out", str(tmp_path / "p.csv")]) == 2
    assert "add --measure position" in capsys.readouterr().err


def test_held_out_rows_are_registered_once(monkeypatch):
    """A tree's holdout rows are diagnosed with the file they come from (prepare_tree's
    registration of every row), not registered and diagnosed again tool by tool as a
    validation file is; a validation file still is."""
    import calib.calibration.chain_registration as chain_registration

    tree = talos()
    data = simulate_tree(tree, 30, markers=MARKERS, noise_mm=0.05, seed=1).measurements
    seen: list[int] = []
    inner = chain_registration._validation_steps

    def counted(chain, nominal, held, guess, opts, hold):
        seen.append(0 if held is None else held.m)
        return inner(chain, nominal, held, guess, opts, hold)

    monkeypatch.setattr(chain_registration, "_validation_steps", counted)
    assert calibrate(tree, data, holdout=0.25).accepted
    assert seen == [0, 0]  # one call per tool, nothing to diagnose
    seen.clear()
    train, other = data.subset(np.arange(40)), data.subset(np.arange(40, 60))
    calibrate(tree, train, validate=other)
    assert sum(seen) == other.m  # each tool's validation rows diagnosed


def test_a_trees_tool_on_its_last_joints_link_is_written(tmp_path):
    """A tree whose tool is the link of its chain's last joint (the UR5's ``wrist_2_link``
    beside ``tool0``): a chain to that tool writes its URDF, the tree's fit was accepted and
    then refused at the write ("not by a fixed joint: nowhere to go"), though its markers
    hang from the tool's link as a chain's do. Now written: Pinocchio's placement of each
    tool's marker on the written URDF is the data (noise-free) and ``load_calibrated``'s
    prediction, to 1e-9 m."""
    import pinocchio as pin

    from calib import load_calibrated, load_robot

    tree = load_robot("ur5", tool=("wrist_2_link", "tool0"))
    data = simulate_tree(tree, 30, seed=0).measurements
    out, report = tmp_path / "cal.urdf", tmp_path / "cal.json"
    calibrate(tree, data).write(out, report)
    model = pin.buildModelFromUrdf(str(out))
    pose = model.createData()
    frames = json.loads(report.read_text())["frames"]["measurement"]
    M = np.array(frames["base_link"]["matrix"])
    for tool in tree.tool_frames:
        rows = np.array([t == tool for t in data.tool])
        seen = []
        for q in data.q[rows]:
            pin.framesForwardKinematics(model, pose, q)
            base = pose.oMf[model.getFrameId("base_link")]
            x = base.actInv(pose.oMf[model.getFrameId(f"{tool}_marker1")]).translation
            seen.append(M[:3, :3] @ x + M[:3, 3])
        assert np.max(np.abs(np.array(seen) - data.position[rows])) < 1e-9, tool
        predicted = load_calibrated(out, report, tool)
        joints = [tree.joint_names.index(n) for n in predicted.chain.joint_names]
        points = predicted.points(data.q[rows][:, joints])[:, 0]
        assert np.max(np.abs(points - data.position[rows])) < 1e-9, tool


def test_a_tree_holds_a_posture_out_whole_every_tool_with_it():
    """A posture held out is held out for every tool: none of its rows is fitted through
    another tool (the draw was per (posture, tool) pair: 7 postures of one hand and 8 of the
    other held out of 30, some of them fitted through the other hand)."""
    tree = talos()
    data = simulate_tree(tree, 30, markers=MARKERS, noise_mm=0.05, seed=1).measurements
    res = calibrate(tree, data, holdout=0.25)
    terms = res.to_dict()["errors"]["terms"]
    held = [t["held_out"]["calibrated"]["configs"] for t in terms]
    assert held == [8, 8]  # round(0.25 * 30) postures, both hands at each
    by_tool = [data.q[np.asarray(data.tool) == t] for t in HANDS]
    assert all(len(q) == 30 for q in by_tool)  # every posture measured by both hands
