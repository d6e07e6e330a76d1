"""The robot measuring itself: a frame on the robot (a head camera) measures a point or a
pose on another chain (the hand), the camera's placement on its link an unknown.

The chain runs from the camera down through the head and torso and up the arm (joints
traversed backwards first). Checked by routes that share nothing with calib: Pinocchio's
forward kinematics of the written URDF (no measurement frame: the camera itself is moved),
and the rank of finite differences of Pinocchio's placements under a 6-DOF error on every
joint placement, the camera's and the tool's.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pinocchio as pin
import pytest

from calib import analyze, calibrate, load_chain, simulate
from calib.cli.commands import main

CAMERA, HAND = "xtion_optical_frame", "arm_tool_link"


def _frame(model: pin.Model, name: str) -> int:
    ids = [i for i, f in enumerate(model.frames) if f.name == name]
    bodies = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
    return bodies[0] if bodies else ids[0]


def _config(model: pin.Model, names, q: np.ndarray) -> np.ndarray:
    x = pin.neutral(model)
    for name, v in zip(names, q, strict=True):
        joint = model.joints[model.getJointId(name)]
        if joint.nq == 2:
            x[joint.idx_q], x[joint.idx_q + 1] = math.cos(v), math.sin(v)
        else:
            x[joint.idx_q] = v
    return x


def _camera_to_hand(model: pin.Model, names, q: np.ndarray, base=CAMERA, tool=HAND):
    """``oMf[camera]^-1 oMf[hand]`` per configuration, Pinocchio alone ``(m, 4, 4)``."""
    data = model.createData()
    b, t = _frame(model, base), _frame(model, tool)
    out = []
    for qi in q:
        pin.framesForwardKinematics(model, data, _config(model, names, qi))
        out.append((data.oMf[b].inverse() * data.oMf[t]).homogeneous)
    return np.array(out)


def _fd_rank(urdf: str, names, q: np.ndarray, marker: np.ndarray) -> int:
    """Rank of the camera-frame marker position under a 6-DOF error on every joint placement
    of the path, on the camera frame's placement and on the hand frame's (Pinocchio only)."""
    model = pin.buildModelFromUrdf(urdf)
    joints = [model.getJointId(n) for n in names]
    frames = [_frame(model, CAMERA), _frame(model, HAND)]
    point = np.append(marker, 1.0)

    def positions() -> np.ndarray:
        return (_camera_to_hand(model, names, q) @ point)[:, :3].ravel()

    def place(kind: str, index: int, M: pin.SE3) -> None:
        if kind == "joint":
            model.jointPlacements[index] = M
        else:
            frame = model.frames[index]
            frame.placement = M
            model.frames[index] = frame

    cols, eps = [], 1e-6
    for kind, index in [("joint", j) for j in joints] + [("frame", f) for f in frames]:
        nominal = (
            model.jointPlacements[index].copy()
            if kind == "joint"
            else model.frames[index].placement.copy()
        )
        for i in range(6):
            steps = []
            for sign in (1.0, -1.0):
                xi = np.zeros(6)
                xi[i] = sign * eps
                place(kind, index, nominal * pin.exp6(pin.Motion(xi)))
                steps.append(positions())
            place(kind, index, nominal)
            cols.append((steps[0] - steps[1]) / (2 * eps))
    s = np.linalg.svd(np.array(cols).T, compute_uv=False)
    return int(np.sum(s > 1e-7 * s[0]))


def test_counts_equal_an_independent_finite_difference_rank():
    chain = load_chain("tiago", CAMERA, HAND)
    assert chain.joint_names[:2] == ("head_2_joint", "head_1_joint")  # down the head first
    q = np.random.default_rng(7).uniform(-1.0, 1.0, (40, chain.n))
    urdf = str(chain.urdf_path)
    for marker in ((0.0, 0.0, 0.0), (0.03, -0.02, 0.05)):  # on the last axis, and off it
        result = analyze(chain, measure="position", marker=marker, params="paper")
        assert result.n_complete == _fd_rank(urdf, chain.joint_names, q, np.array(marker))
    everett = 4 * chain.n + 3 - 2
    assert analyze(chain, measure="position", params="paper").n_complete == everett


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_noise_free_round_trip_writes_the_camera_into_the_urdf(measure, tmp_path):
    """The camera's fitted placement goes into its own joint: Pinocchio's camera -> hand of
    the written URDF (no measurement frame) reproduces held-out measurements to 1e-9."""
    chain = load_chain("tiago", CAMERA, HAND)
    train = simulate(chain, 80, measure=measure, params="complete", seed=4).measurements
    res = calibrate(chain, train, params="complete", holdout=0.25, seed=2).check()
    held = res.stats["held_out"]  # the 20 held-out rows' errors [mm] per axis
    assert held.m == 20 and np.linalg.norm(held.max[:3]) < 1e-6  # >= the largest point error
    urdf = tmp_path / "cal.urdf"
    urdf.write_bytes(res.urdf(on_robot=True))
    model = pin.buildModelFromUrdf(str(urdf))
    truth_q = train.q  # every row: the 60 fitted and the 20 held out
    T = _camera_to_hand(model, chain.joint_names, truth_q, tool=res.urdf_tool_frame)
    point = T[:, :3, 3] if measure == "pose" else (T @ np.append(res.urdf_markers[0], 1))[:, :3]
    assert np.max(np.linalg.norm(point - train.position[:, :3], axis=1)) < 1e-9
    before = _camera_to_hand(
        pin.buildModelFromUrdf(str(chain.urdf_path)), chain.joint_names, truth_q
    )
    assert np.max(np.abs(before[:, :3, 3] - T[:, :3, 3])) > 1e-4  # the camera did move


def test_command_line_on_robot(tmp_path, capsys):
    data, out, report = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    frames = ["tiago", "--base", CAMERA, "--tool", HAND]
    assert (
        main(
            [
                "simulate",
                *frames,
                "--measure",
                "position",
                "--configs",
                "60",
                "--noise-mm",
                "0",
                "--out",
                str(data),
            ]
        )
        == 0
    )
    code = main(
        [
            "calibrate",
            *frames,
            "--data",
            str(data),
            "--on-robot",
            "--params",
            "complete",
            "--out",
            str(out),
            "--report",
            str(report),
        ]
    )
    assert code == 0, capsys.readouterr().err
    doc = json.loads(report.read_text())
    assert doc["frames"]["on_robot"] is True
    assert (
        main(
            [
                "calibrate",
                *frames,
                "--data",
                str(data),
                "--on-robot",
                "--world-link",
                "w",
                "--out",
                str(tmp_path / "x.urdf"),
            ]
        )
        == 2
    )
    assert "--on-robot" in capsys.readouterr().err
