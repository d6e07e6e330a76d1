"""``calib.analyze(problem)``: what a problem's terms determine together, at their rows.

Every count is compared with the rank of central differences computed with Pinocchio alone
(tests/test_self_measure.py's ``_Robot``: every joint placement, the measuring frame, the
planes and contact frames and the marker twisted; tests/test_pixel_calibration.py's pixel
rank: the camera, every joint placement), never with a number calib printed.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from contact_scorer import configurations
from pixel_setups import INTRINSICS, setup
from test_pixel_calibration import _fd_rank as pixel_rank
from test_self_measure import _frame, _joints, _Robot

import calib
from calib.calibration.pixel_chain import pixel_rows
from calib.exceptions import InvalidArgumentError
from calib.measurements.pixel_simulation import simulate_pixels
from calib.measurements.tree_campaign import simulate_tree

URDF = "talos_full_v2.urdf"
ARMS = (
    ("left_sole_link", "gripper_left_base_link"),
    ("right_sole_link", "gripper_right_base_link"),
)
ZERO = {"error_mm": 0.0, "error_mrad": 0.0}


def _touches(chains, m=24):
    """Noise-free plane touches on the nominal robot, and the Pinocchio reference of them
    (each plane the first touch's placement: the touches are flush on it)."""
    data = [
        calib.simulate_contacts(c, m, "plane", seed=1 + k, **ZERO).data
        for k, c in enumerate(chains)
    ]
    terms = [
        (c.base_frame, c.tool_frame, _joints(c, d.q), "plane")
        for c, d in zip(chains, data, strict=True)
    ]
    robot = _Robot(chains[0].urdf_path, terms)
    for k, term in enumerate(terms):
        first = {n: v[:1] for n, v in term[2].items()}
        robot.extra[("plane", k)] = robot.rel(*term[:2], first)[0]
        robot.extra[("contact", k)] = pin.SE3.Identity()
    assert np.max(np.abs(robot.rows())) < 1e-9  # flush: the reference is right
    return data, robot


def test_one_chain_touching_counts_the_pinocchio_rank():
    chain = calib.load_robot(URDF, *ARMS[0])
    data, robot = _touches([chain])
    res = calib.analyze(calib.Problem(calib.Term(chain, data[0])))
    assert res.shape == "contacts" and res.n_unknowns == 3 + 2 + 6 * len(chain.joint_names)
    assert res.n_base == robot.rank(chain.joint_names, [])
    assert res.base[:5] == ("plane1_z", "plane1_rx", "plane1_ry", "contact1_rx", "contact1_ry")


def test_two_arms_touching_count_the_pinocchio_rank_shared_joints_once():
    chains = [calib.load_robot(URDF, *pair) for pair in ARMS]
    data, robot = _touches(chains)
    res = calib.analyze(
        calib.Problem(tuple(calib.Term(c, d) for c, d in zip(chains, data, strict=True)))
    )
    names = list(dict.fromkeys(n for c in chains for n in c.joint_names))
    assert res.shape == "chains" and res.n_base == robot.rank(names, [])
    pairs = zip(chains, data, strict=True)
    alone = [calib.analyze(calib.Problem(calib.Term(c, d))).n_base for c, d in pairs]
    assert res.n_base < sum(alone)  # the torso is not counted twice


def test_a_tracker_and_a_head_camera_measuring_the_hand_count_the_pinocchio_rank():
    """Measured terms: a point on the TIAGo's hand seen from the floor (the tracker's frame an
    unknown) and from the head camera (its frame on the robot), each alone."""
    marker = (0.02, 0.01, 0.05)
    for base in ("base_footprint", "xtion_optical_frame"):
        chain = calib.load_chain("tiago", base, "arm_tool_link")
        d = calib.simulate(chain, 40, marker=marker, seed=5, **ZERO).measurements
        robot = _Robot(chain.urdf_path, [(base, "arm_tool_link", _joints(chain, d.q), "position")])
        robot.extra["marker"] = np.array(marker)
        res = calib.analyze(calib.Problem(calib.Term(chain, d)))
        assert res.n_base == robot.rank(chain.joint_names, [_frame(robot.model, base)])


def _tree_rank(tree, d, markers, eps=1e-6, tol=1e-7) -> int:
    """Rank of central differences of a tree's rows (each row one tool's marker in the base
    frame) under a twist of every joint placement and of the base frame, and a shift of each
    tool's marker (Pinocchio alone)."""
    robot = _Robot(tree.urdf_path, [])
    model, data = robot.model, robot.data
    base = _frame(model, tree.base_frame)
    frames = [_frame(model, t) for t in d.tool]
    Q = configurations(model, _joints(tree, d.q))
    marker = {t: np.array(m, dtype=float) for t, m in zip(tree.tool_frames, markers, strict=True)}

    def rows() -> np.ndarray:
        out = []
        for q, f, tool in zip(Q, frames, d.tool, strict=True):
            pin.framesForwardKinematics(model, data, q)
            M = data.oMf[base].inverse() * data.oMf[f]
            out.append(M.rotation @ marker[tool] + M.translation)
        return np.concatenate(out)

    cols = []
    for get, put in robot.handles(tree.joint_names, [base]):
        nominal = get()
        for e in eps * np.eye(6):
            steps = []
            for sign in (1.0, -1.0):
                put(nominal * pin.exp6(pin.Motion(sign * e)))
                steps.append(rows())
            put(nominal)
            cols.append((steps[0] - steps[1]) / (2 * eps))
    for tool in tree.tool_frames:
        start = marker[tool].copy()
        for e in eps * np.eye(3):
            marker[tool] = start + e
            up = rows()
            marker[tool] = start - e
            cols.append((up - rows()) / (2 * eps))
        marker[tool] = start
    s = np.linalg.svd(np.array(cols).T, compute_uv=False)
    return int(np.sum(s > tol * s[0]))


def test_a_tree_measured_by_one_instrument_counts_the_pinocchio_rank():
    """TALOS's two hands measured by one tracker (its frame, each hand's marker, every joint
    placement of both arms and the torso)."""
    tree = calib.load_robot("talos", tool=["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"])
    markers = [(0.02, 0.01, 0.05), (-0.01, 0.03, 0.04)]
    d = simulate_tree(tree, 30, markers=markers, seed=2, **ZERO).measurements
    res = calib.analyze(calib.Problem(calib.Term(tree, d)))
    assert res.shape == "tree"
    assert res.n_base == _tree_rank(tree, d, markers)


def test_a_camera_seeing_a_board_counts_the_pinocchio_rank(tmp_path):
    """A pixel term (the UR5 seen by a camera in the cell): the camera's 6 and the joint
    placements the pixels determine, Pinocchio's and a textbook pinhole's rank."""
    s = setup("ur5", tmp_path, postures=60)
    obs = simulate_pixels(s.nominal, s.camera, s.placement, INTRINSICS, s.target, s.q)
    camera = calib.PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    problem = calib.Problem(calib.Term(s.nominal, calib.PixelData(camera, s.target, obs)))
    res = calib.analyze(problem)
    rows = pixel_rows(s.nominal, obs, s.target, s.camera)
    assert res.n_base == pixel_rank(s, rows, False)
    assert res.n_base < res.n_unknowns


def test_a_problem_takes_no_other_argument():
    chain = calib.load_chain("ur5")
    problem = calib.Problem(calib.Term(chain, calib.simulate(chain, 20, seed=0).measurements))
    with pytest.raises(InvalidArgumentError, match=r"analyze\(problem\) alone"):
        calib.analyze(problem, measure="pose")
    with pytest.raises(InvalidArgumentError, match=r"analyze\(problem\) alone"):
        calib.analyze(problem, configs=10)


def test_the_command_line_prints_what_the_python_function_counts(tmp_path, capsys):
    """``calib analyze URDF --term ...`` is ``calib.analyze(problem)`` of the files' terms; the
    options --term replaces are refused in one line."""
    import json

    from calib.cli.commands import main
    from calib.measurements.contact_campaign import write_contacts

    chains = [calib.load_robot(URDF, *pair) for pair in ARMS]
    data, _ = _touches(chains)
    argv = ["analyze", URDF]
    for chain, d, name in zip(chains, data, ("left.csv", "right.csv"), strict=True):
        write_contacts(tmp_path / name, d)
        argv += ["--term", "plane", chain.base_frame, chain.tool_frame, str(tmp_path / name)]
    read = [
        calib.read_contacts(tmp_path / n, c, "plane")
        for n, c in zip(("left.csv", "right.csv"), chains, strict=True)
    ]
    problem = calib.Problem(tuple(calib.Term(c, d) for c, d in zip(chains, read, strict=True)))
    assert main([*argv, "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == calib.analyze(problem).to_dict()
    for extra in (["--seed", "3"], ["--markers", "2"], ["--tool", "a"], ["--params", "paper"]):
        assert main([*argv, *extra]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--term" in err, err
