"""Experiment design on trees (several tools measured at every configuration), mimic chains
and the orientation weight of pose designs."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from conftest import chain_of
from pinref import MimicChain, pair_collides

from calib import InvalidArgumentError, analyze
from calib.calibration.entry import calibrate as calibrate_tree
from calib.calibration.instrument import tree_points
from calib.cli.commands import main
from calib.design.collision import collision_checker
from calib.design.configurations import parse_configurations
from calib.design.constraints import Constraints, filter_candidates, measured_points
from calib.design.design import candidate_configurations, design, evaluate
from calib.design.observability import observation_model
from calib.design.tree_error_model import TreeErrorModel, TreeState
from calib.identification.tree_jacobian import tree_parameters
from calib.kinematics.catalog import erd_robots_dir, resolve_urdf
from calib.kinematics.tree import load_tree
from calib.kinematics.tree_model import from_tree
from calib.measurements.tree_campaign import simulate_tree, true_points

HANDS = ("wrist_left_ft_tool_link", "wrist_right_ft_tool_link")
MARKERS = np.array([[0.05, 0.02, 0.1], [0.03, -0.02, 0.08]])
NO_COLLISION = Constraints(collision=False)


@functools.cache
def hands():
    return load_tree(resolve_urdf("erd:talos_data/robots/talos_reduced.urdf"), "base_link", HANDS)


def test_tree_model_counts_what_analyze_counts():
    """b: the frame, one marker per tool and the tree's base parameters, i.e. the base
    parameters of the tree's complete set with its base and tool frames (calib analyze)."""
    tree = hands()
    model = observation_model(tree, markers=MARKERS)
    ident = analyze(tree, measure="position", params="complete", configs=100)
    assert model.b == ident.n_base == ident.n_theory
    assert model.rows == 6 and model.n_markers == 2
    frames = observation_model(tree, markers=MARKERS, params="frames")
    assert frames.b == 6 + 3 * 2


def test_tree_rows_are_finite_differences_of_the_measured_points():
    """Each column of W_b (unscaled) against central differences of the points of both
    tools, the points at zero change against Pinocchio's tool frames."""
    tree = hands()
    model = observation_model(tree, markers=MARKERS)
    q = tree.random_configurations(3, 7)
    nominal = from_tree(tree).idealized()
    pset = tree_parameters(nominal, "complete")
    wide = TreeErrorModel(pset, pset.names, 2)
    start = TreeState(nominal, np.eye(4), MARKERS)

    def points(x):
        state = wide.apply(start, x)
        pts = true_points(state.mdh, q, state.markers)
        return pts @ state.frame[:3, :3].T + state.frame[:3, 3]

    F = tree.idealized().tool_placements(q)
    pin_points = F[..., :3, 3] + np.einsum("mtij,tj->mti", F[..., :3, :3], MARKERS)
    assert np.max(np.abs(points(np.zeros(wide.size())) - pin_points)) < 1e-12
    J = model.jacobian(q) * model.scale  # (3, 6, b), unscaled
    h = 1e-6
    for j, col in enumerate(model.columns):
        dx = np.zeros(wide.size())
        dx[col] = h
        fd = (points(dx) - points(-dx)) / (2 * h)  # (m, T, 3)
        assert np.max(np.abs(J[:, :, j] - fd.reshape(3, 6))) < 1e-7, model.names[j]


def test_tree_design_beats_random_sets_and_calibrates_better():
    """Same K: the designed set's D and I beat random sets of the same candidates, and the
    held-out error after simulate + calibrate (true points, never-seen configurations) is
    lower, median over seeds."""
    tree = hands()
    k = 40
    q_ref = tree.random_configurations(100, 99)
    designed, randoms = [], []
    for seed in range(4):
        d = design(
            tree,
            k,
            candidates=800,
            marker=MARKERS,
            seed=seed,
            random_sets=10,
            constraints=NO_COLLISION,
        )
        assert d.q.shape == (k, tree.n)
        for name in ("D", "I"):
            assert np.mean([d.indices.better(r, name) for r in d.random]) >= 0.9, name
        q_rand = candidate_configurations(tree, k, seed=100 + seed)
        for q, out in ((d.q, designed), (q_rand, randoms)):
            camp = simulate_tree(tree, q, MARKERS, 1.0, 1.0, 0.05, seed)
            res = calibrate_tree(tree, camp.measurements)
            pred = tree_points(res.chains, tree.paths, q_ref)
            err = np.linalg.norm(pred - true_points(camp.true_mdh, q_ref, MARKERS), axis=2)
            out.append(np.sqrt(np.mean(err**2)))
    assert np.median(designed) < np.median(randoms)


CROSSED = [
    0,
    0,
    -0.75,
    0.38,
    -0.07,
    -1.74,
    0.7,
    -0.74,
    -0.55,
    1.34,
    -0.76,
    -0.1,
    -1.8,
    -0.15,
    0.33,
    -0.28,
]  # hand-made: the wrists cross


def _pinocchio_wrists_collide(tree, q) -> bool:
    package = str(erd_robots_dir().parent.parent)
    wrists = ("arm_left_7_link", "arm_right_7_link")
    return pair_collides(tree.urdf_path, package, tree.joint_names, q, wrists)


def test_tree_collision_filter_sees_both_arms_move():
    """The wrists cross: the tree's filter rejects it; each arm's chain alone (the other arm
    at rest) cannot, and Pinocchio confirms the contact needs both arms."""
    tree = hands()
    q = np.array(CROSSED, dtype=float)
    assert _pinocchio_wrists_collide(tree, q)
    rest = q.copy()
    rest[tree.paths[1][2:]] = 0.0  # the right arm at rest
    assert not _pinocchio_wrists_collide(tree, rest)
    keep, report = filter_candidates(tree, np.array([q, np.zeros(tree.n)]), MARKERS, Constraints())
    assert keep.tolist() == [False, True] and dict(report.rejected)["collision"] == 1
    for chain, path in zip(tree.chains, tree.paths, strict=True):
        assert not collision_checker(chain).colliding(q[None, path])[0]


def test_tree_workspace_filter_holds_every_tool():
    tree = hands()
    q = tree.random_configurations(200, 3)
    F = tree.tool_placements(q)  # Pinocchio
    pts = F[..., :3, 3] + np.einsum("mtij,tj->mti", F[..., :3, :3], MARKERS)
    assert np.max(np.abs(measured_points(tree, q, MARKERS) - pts)) < 1e-9
    box = (0.0, -1.0, -1.0, 1.0, 1.0, 1.0)  # in front of the robot
    keep, _ = filter_candidates(tree, q, MARKERS, Constraints(workspace=box, collision=False))
    assert keep.tolist() == np.all(pts[..., 0] >= 0.0, axis=1).tolist()
    assert 0 < keep.sum() < len(q)


def test_tree_design_refuses_what_tree_calibration_cannot_fit():
    tree = hands()
    with pytest.raises(InvalidArgumentError, match="positions"):
        design(tree, 30, measure="pose")
    with pytest.raises(InvalidArgumentError, match="frames, complete"):
        design(tree, 30, params="paper")
    with pytest.raises(InvalidArgumentError, match="one marker for all or one per tool"):
        design(tree, 30, marker=np.zeros((3, 3)))


def test_cli_tree_design_simulate_calibrate(tmp_path, capsys):
    """calib design with two tools writes the tree's joints; simulate takes them."""
    out, meas = tmp_path / "configs.csv", tmp_path / "meas.csv"
    tools = ["--tool", HANDS[0], "--tool", HANDS[1]]
    assert (
        main(
            [
                "design",
                "talos",
                *tools,
                "--configs",
                "40",
                "--candidates",
                "600",
                "--no-collision",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "6 rows per configuration" in text and f"wrote {out}" in text
    tree = hands()
    q = parse_configurations(out.read_text(), tree)
    assert q.shape == (40, tree.n)
    assert (
        main(
            [
                "simulate",
                "talos",
                *tools,
                "--configs-file",
                str(out),
                "--measure",
                "position",
                "--out",
                str(meas),
            ]
        )
        == 0
    )
    lines = meas.read_text().splitlines()
    assert len(lines) == 1 + 2 * 40
    header = lines[0].split(",")
    first = dict(zip(header, lines[1].split(","), strict=True))
    assert float(first[tree.joint_names[3]]) == q[0, 3]
    capsys.readouterr()
    assert main(["design", "talos", *tools, "--evaluate", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["rank"] == 70
    assert (
        main(
            [
                "design",
                "talos",
                *tools,
                "--configs",
                "40",
                "--candidates",
                "300",
                "--no-collision",
                "--json",
            ]
        )
        == 0
    )
    assert json.loads(capsys.readouterr().out)["tools"] == list(HANDS)
    assert main(["design", "talos", *tools, "--configs", "40", "--measure", "pose"]) == 2
    assert "positions" in capsys.readouterr().err


# --- mimic chains and the orientation weight --------------------------------------------


def test_candidates_of_a_mimic_chain_follow_the_mimic_tags():
    """Mimic joints are not drawn: each is multiplier * master + offset (the URDF's tags,
    read with ElementTree by the test)."""
    chain = chain_of("mimic_arm")
    tags = MimicChain(chain.urdf_path, chain.base_frame, chain.tool_frame).tags
    q = candidate_configurations(chain, 50, seed=1, margin=0.01)
    col = {n: i for i, n in enumerate(chain.joint_names)}
    checked = 0
    for name, (master, factor, offset) in tags.items():
        if name in col and master in col:
            assert np.allclose(q[:, col[name]], factor * q[:, col[master]] + offset)
            checked += 1
    assert checked > 0
    d = design(chain, 20, candidates=300, constraints=NO_COLLISION)
    assert np.isfinite(d.indices.d)


def test_orientation_weight_scales_the_orientation_rows_only():
    chain = chain_of("ur5")
    q = candidate_configurations(chain, 5, seed=0)
    one = observation_model(chain, "pose", orientation_weight=1.0)
    half = observation_model(chain, "pose", orientation_weight=0.5)
    assert one.names == half.names
    J1, J2 = one.jacobian(q), half.jacobian(q)
    assert np.allclose(J2[:, :3], J1[:, :3], rtol=0, atol=1e-15)
    assert np.allclose(J2[:, 3:], 0.5 * J1[:, 3:], rtol=1e-12, atol=1e-15)
    ind = evaluate(chain, q, "pose", orientation_weight=0.5)
    assert ind.d == pytest.approx(
        np.linalg.slogdet(J2.reshape(-1, half.b).T @ J2.reshape(-1, half.b))[1], rel=1e-9
    )
    with pytest.raises(InvalidArgumentError, match="orientation weight"):
        design(chain, 30, measure="pose", orientation_weight=-1.0)


def test_tree_line_of_sight_checks_every_tool():
    """An instrument in front sees both hands' origins in some configurations; a wall
    between them hides every one; from the robot's left, the right hand is often behind the
    body, so checking both hands rejects more than checking the left one."""
    tree = hands()
    q = tree.random_configurations(60, 8)
    origins = np.zeros((2, 3))
    front, left = (2.0, 0.0, 0.3), (0.0, 3.0, 0.3)
    wall = (1.5, -3.0, -3.0, 1.6, 3.0, 3.0)
    seen, _ = filter_candidates(tree, q, origins, Constraints(line_of_sight=front))
    walled, _ = filter_candidates(
        tree, q, origins, Constraints(line_of_sight=front, obstacles=(wall,))
    )
    assert seen.sum() > 0 and walled.sum() == 0
    checker = collision_checker(tree)
    pts = measured_points(tree, q, origins)
    both = checker.blocked(q, pts, np.array(left))
    left_hand = checker.blocked(q, pts[:, :1], np.array(left))
    assert np.all(both >= left_hand) and both.sum() > left_hand.sum()
