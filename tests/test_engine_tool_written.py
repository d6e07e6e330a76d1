"""One chain measured, fitted by the joint engine: its calibrated tool and an instrument on the
robot, as the written URDF holds them (issue 28).

Every number is Pinocchio's on the written file against simulated noise-free rows the fit
never saw (or against the chain's own frames): nothing read from the fit's prediction.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from pinref import PathRef, PinTree

from calib import calibrate, load_calibrated, load_chain, simulate
from calib.cli.commands import main

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata"
MARKER = (0.03, -0.02, 0.05)


def _quaternion_matrices(quat: np.ndarray) -> np.ndarray:
    return np.array([pin.Quaternion(w, x, y, z).toRotationMatrix() for x, y, z, w in quat])


@pytest.mark.parametrize(
    ("urdf", "base", "tool", "written"),
    [
        (REAL / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link", "wrist_3_link_calibrated"),
        ("ur5", "base_link", "tool0", "tool0"),
    ],
    ids=["tool-on-a-revolute-joint", "tool-on-a-fixed-joint"],
)
def test_pose_data_written_tool_is_the_measured_frame(urdf, base, tool, written, tmp_path):
    """Pose data (the measured frame 5 cm off the tool frame): Pinocchio's base -> calibrated
    tool of the written URDF, placed by ``measurement_to_base``, is every unseen measured pose
    (position and rotation) to 1e-9. UR10's tool link is wrist_3_joint's: the calibrated tool
    is a link ``wrist_3_link_calibrated`` fixed to it; UR5's tool0 has its fixed joint moved.
    Failed before: the marker hung from the tool link and the rotation was not written."""
    chain = load_chain(urdf, base, tool)
    seen = simulate(chain, 40, "pose", marker=MARKER, seed=4).measurements
    q = chain.random_configurations(20, 9)
    truth = simulate(chain, q, "pose", marker=MARKER, seed=4).measurements
    result = calibrate(chain, seen, params="complete")
    assert result.accepted and result.urdf_tool_frame == written
    path = tmp_path / "cal.urdf"
    path.write_bytes(result.urdf())
    T = (
        result.measurement_to_base
        @ PinTree.of_file(path, base, [written]).poses(chain.joint_names, truth.q)[:, 0]
    )
    assert np.abs(T[:, :3, 3] - truth.position[:, :3]).max() < 1e-9
    R = _quaternion_matrices(truth.quaternion)
    assert (
        max(np.linalg.norm(pin.log3(a.T @ b)) for a, b in zip(R, T[:, :3, :3], strict=True)) < 1e-9
    )
    report = result.to_dict()["frames"]
    assert report["tool_link"] == written and report["markers"] == {f"{tool}_marker1": [0.0] * 3}
    assert np.linalg.norm(report["measured"]["xyz"] - np.array(MARKER)) < 5e-3  # the 5 cm offset


def test_on_robot_report_predicts_the_measured_points(tmp_path):
    """The TIAGo head camera measuring a marker on the hand, ``--on-robot``: the report and
    the written URDF read back by ``load_calibrated`` (the camera in its joint, no measurement
    frame) predict every row to 1e-9, and Pinocchio's camera -> marker link of that file too."""
    data, out, report = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    frames = ["tiago", "--base", "xtion_optical_frame", "--tool", "arm_tool_link"]
    sim = ["--measure", "position", "--marker", *map(str, MARKER), "--noise-mm", "0"]
    assert main(["simulate", *frames, *sim, "--configs", "60", "--out", str(data)]) == 0
    cal = ["calibrate", *frames, "--data", str(data), "--params", "complete", "--on-robot"]
    assert main([*cal, "--out", str(out), "--report", str(report)]) == 0
    doc = json.loads(report.read_text())
    assert doc["frames"]["on_robot"] is True
    chain = load_chain("tiago", "xtion_optical_frame", "arm_tool_link")
    rows = np.loadtxt(data, delimiter=",", skiprows=1, usecols=range(chain.n + 3))
    q, measured = rows[:, : chain.n], rows[:, chain.n :]
    model = load_calibrated(out, report)
    assert np.abs(model.points(q)[:, 0] - measured).max() < 1e-9
    pinocchio = PathRef(out, "xtion_optical_frame", "arm_tool_link_marker1")
    assert np.abs(pinocchio.placements(chain.joint_names, q)[:, :3, 3] - measured).max() < 1e-9


def test_on_robot_from_a_base_the_chain_hangs_from_is_refused_before_the_fit(tmp_path, capsys):
    """UR5's base_link is fixed to ``world``: moving that joint would move the whole arm, so
    the URDF could not give measured coordinates. One line, exit 2, nothing written, before
    the fit (the pipeline wrote such a file; the engine route refused every on_robot)."""
    data, out = tmp_path / "m.csv", tmp_path / "cal.urdf"
    assert main(["simulate", "ur5", "--configs", "30", "--out", str(data)]) == 0
    capsys.readouterr()
    code = main(["calibrate", "ur5", "--data", str(data), "--on-robot", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 2 and not out.exists() and captured.out == ""
    assert captured.err.startswith("calib: error: --on-robot: the chain hangs from the base frame")
    assert len(captured.err.strip().splitlines()) == 1 and "Traceback" not in captured.err


def test_pose_data_compliance_file_goes_with_the_written_urdf(tmp_path):
    """Pose data and ``elastic`` on UR5 (tool0 on a fixed joint, the measured frame 5 cm off
    it): ``load_calibrated(urdf, compliance file)`` predicts every unseen noise-free point to
    1e-9 m. Failed before: the file recorded the tool frame and the markers as fitted, not
    the calibrated tool the URDF holds (the points 5 cm off)."""
    chain = load_chain("ur5")
    seen = simulate(chain, 40, "pose", marker=MARKER, seed=4).measurements
    q = chain.random_configurations(20, 9)
    truth = simulate(chain, q, "pose", marker=MARKER, seed=4).measurements
    result = calibrate(chain, seen, params="complete", elastic=True)
    assert result.accepted and result.elastic
    path = tmp_path / "cal.urdf"
    result.write(path)
    comp = tmp_path / "cal.compliance.json"
    model = load_calibrated(path, comp)
    assert np.abs(model.points(truth.q)[:, 0] - truth.position[:, :3]).max() < 1e-9
