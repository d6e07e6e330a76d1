"""``calib simulate --robot-seed R`` / ``robot_seed=R``: the true robot apart from the draws.

``--seed`` draws the configurations and the noise, ``--robot-seed`` (default: ``--seed``) the
true robot's errors: the same true robot at other configurations, or other true robots at the
same configurations. The independent routes: the configurations ``calib analyze --seed``
draws (``Chain.random_configurations``), the given-configurations route (``configs`` an
array: the robot of ``seed``), the true robot of ``seed=R`` alone, and each kind's own
geometry (touches flush with their contact on the true robot).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import calib
from calib.cli.commands import main
from calib.measurements.tree_campaign import simulate_tree


@pytest.fixture(scope="module")
def ur5():
    return calib.load_chain("ur5")


def test_a_robot_seed_measures_that_robot_at_the_seeds_configurations(ur5):
    """seed 2, robot seed 1: robot 1's errors, seed 2's configurations and noise."""
    both = calib.simulate(ur5, 30, noise_mm=0.05, seed=2, robot_seed=1)
    robot_1 = calib.simulate(ur5, 30, seed=1).truth
    q_2 = ur5.random_configurations(30, 2)
    assert np.array_equal(both.truth.errors, robot_1.errors)
    assert both.truth.true_mdh.rows() == robot_1.true_mdh.rows()
    assert np.array_equal(both.measurements.q, q_2)
    # noise-free, the points are robot 1's at those configurations (the array route)
    exact = calib.simulate(ur5, q_2, seed=1).measurements.position
    noise_2 = (
        calib.simulate(ur5, 30, noise_mm=0.05, seed=2).measurements.position
        - calib.simulate(ur5, 30, seed=2).measurements.position
    )
    assert np.allclose(both.measurements.position - exact, noise_2, rtol=0, atol=1e-15)
    assert 0.03e-3 < np.std(noise_2) < 0.07e-3
    assert both.truth.seed == 2 and both.truth.robot_seed == 1
    assert both.truth.to_dict()["robot_seed"] == 1 and "robot seed 1" in repr(both.truth)


def test_other_robots_at_the_same_configurations(ur5):
    runs = [calib.simulate(ur5, 20, "pose", seed=0, robot_seed=r) for r in (1, 2, 3)]
    for r, run in zip((1, 2, 3), runs, strict=True):
        assert np.array_equal(run.measurements.q, ur5.random_configurations(20, 0))
        assert np.array_equal(run.truth.errors, calib.simulate(ur5, 20, seed=r).truth.errors)
    assert not np.allclose(runs[0].truth.errors, runs[1].truth.errors)
    assert not np.allclose(runs[0].measurements.position, runs[1].measurements.position)


def test_the_robot_seed_of_the_seed_is_the_campaign_without_one(ur5):
    """Bit for bit, and the truth does not record it (a default campaign's files unchanged)."""
    plain = calib.simulate(ur5, 15, "pose", noise_mm=0.05, seed=4)
    same = calib.simulate(ur5, 15, "pose", noise_mm=0.05, seed=4, robot_seed=4)
    for name in ("q", "position", "quaternion"):
        assert np.array_equal(getattr(plain.measurements, name), getattr(same.measurements, name))
    assert plain.truth.to_dict() == same.truth.to_dict()
    assert "robot_seed" not in plain.truth.to_dict() and same.truth.robot_seed is None


def test_a_tree_campaign_takes_a_robot_seed():
    tree = calib.load_robot("bolt")
    both = simulate_tree(tree, 10, noise_mm=0.05, seed=5, robot_seed=6)
    assert np.array_equal(both.errors, simulate_tree(tree, 2, seed=6).errors)
    q = np.repeat(tree.random_configurations(10, 5), tree.n_tools, axis=0)
    assert np.array_equal(both.measurements.q, q) and both.robot_seed == 6
    plain = simulate_tree(tree, 10, noise_mm=0.05, seed=5)
    assert np.array_equal(
        simulate_tree(tree, 10, noise_mm=0.05, seed=5, robot_seed=5).measurements.position,
        plain.measurements.position,
    )


def test_touches_of_another_robot_start_from_the_same_configurations(ur5):
    """seed 3, robot seed 4: robot 4's errors; each touch is flush with its plane on robot 4,
    and most are near the touch of seed 3's own robot (the same start, projected onto the
    plane; an ill-conditioned projection may go further)."""
    both = calib.simulate_contacts(ur5, 12, "plane", seed=3, robot_seed=4)
    own = calib.simulate_contacts(ur5, 12, "plane", seed=3)
    robot_4 = calib.simulate_contacts(ur5, 12, "plane", seed=4)
    assert np.array_equal(both.truth.errors, robot_4.truth.errors)
    T = both.truth.true_mdh.forward(both.data.q)  # the contact frame on the true robot
    plane = both.truth.frames["table1"]
    gap = np.einsum("i,mi->m", plane[:3, 2], T[:, :3, 3] - plane[:3, 3])
    assert np.max(np.abs(gap)) < 1e-9
    near = np.max(np.abs(both.data.q - own.data.q), axis=1)  # [rad], per touch
    far = np.max(np.abs(both.data.q - robot_4.data.q), axis=1)
    assert np.median(near) < 0.03 and np.min(far) > 1.0
    assert both.truth.to_dict()["robot_seed"] == 4 and "robot_seed" not in own.truth.to_dict()


def _simulate(tmp_path, capsys, name: str, *argv) -> tuple[np.ndarray, dict, str]:
    out = tmp_path / f"{name}.csv"
    assert main(["simulate", "ur5", "--configs", "12", *argv, "--out", str(out)]) == 0
    text = capsys.readouterr().out
    q = np.loadtxt(out, delimiter=",", skiprows=1, usecols=range(6))
    return q, json.loads(out.with_suffix(".truth.json").read_text()), text


def test_the_command_line_takes_a_robot_seed(tmp_path, capsys):
    q_21, truth_21, text = _simulate(tmp_path, capsys, "a", "--seed", "2", "--robot-seed", "1")
    q_1, truth_1, _ = _simulate(tmp_path, capsys, "b", "--seed", "1")
    q_2, truth_2, _ = _simulate(tmp_path, capsys, "c", "--seed", "2")
    assert truth_21["errors"] == truth_1["errors"] != truth_2["errors"]
    assert np.array_equal(q_21, q_2) and not np.array_equal(q_21, q_1)
    assert truth_21["seed"] == 2 and truth_21["robot_seed"] == 1 and "robot_seed" not in truth_2
    assert "seed 2, robot seed 1" in text
    assert main(["simulate", "ur5", "--robot-seed", "-1", "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert err.strip() == "calib: error: --robot-seed must be an integer >= 0, got -1"


def test_simulated_pixels_take_a_robot_seed(tmp_path, capsys):
    """The true robot's joint errors of --robot-seed 1, seen at --seed 2's postures."""
    (tmp_path / "intr.yaml").write_text(
        "image_width: 640\nimage_height: 480\n"
        "camera_matrix: [[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]]\n"
        "distortion_coefficients: [0.0, 0.0, 0.0, 0.0]\n"
    )
    (tmp_path / "target.csv").write_text("point,x,y,z\na,0,0,0.02\nb,0.03,0,0.02\nc,0,0.03,0.02\n")
    camera = ["--camera", "cam", "world", str(tmp_path / "intr.yaml")]
    camera += ["1.6", "0.3", "0.8", "-1.8688", "0", "1.7561"]
    common = ["--measure", "pixels", *camera, "--target", str(tmp_path / "target.csv")]
    truths = {}
    for name, seeds in (("a", ("2", "1")), ("b", ("1", "1")), ("c", ("2", "2"))):
        argv = [*common, "--tool", "tool0", "--configs", "40", "--seed", seeds[0]]
        out = tmp_path / f"{name}.csv"
        assert main(["simulate", "ur5", *argv, "--robot-seed", seeds[1], "--out", str(out)]) == 0
        truths[name] = json.loads(out.with_suffix(".truth.json").read_text())["joint_errors"]
    capsys.readouterr()
    assert truths["a"] == truths["b"] != truths["c"]
    seen = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1, usecols=range(6))
    drawn = calib.load_chain("ur5", base="world", tool="tool0").random_configurations(40, 2)
    assert all(np.any(np.all(drawn == row, axis=1)) for row in seen)
