"""``calib simulate --marker ... --marker ...`` / ``calib.simulate(marker=[...])``: several
markers on the tool, as a motion-capture campaign records them (x1, y1, z1, ..., zK).

The independent routes: a rigid body's geometry (each row's marker distances are the
given ones) and the pose campaign of the same seed (marker k = p1 + R (m_k - m_1)).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import calib
from calib.cli.commands import main
from calib.kinematics.so3 import quaternion_to_matrix

MARKERS = np.array([(0.05, 0.0, 0.1), (-0.03, 0.04, 0.1), (-0.03, -0.04, 0.12)])


@pytest.fixture(scope="module")
def panda():
    return calib.load_chain("panda")


def test_several_markers_are_the_points_of_one_rigid_tool(panda):
    many = calib.simulate(panda, 40, "position", marker=MARKERS, seed=4)
    pose = calib.simulate(panda, 40, "pose", marker=MARKERS[0], seed=4)
    p = many.measurements.position.reshape(40, 3, 3)
    assert many.measurements.n_markers == 3 and many.measurements.position_columns[-1] == "z3"
    for i, j in ((0, 1), (0, 2), (1, 2)):
        distance = np.linalg.norm(p[:, i] - p[:, j], axis=1)
        assert np.allclose(distance, np.linalg.norm(MARKERS[i] - MARKERS[j]), atol=1e-12)
    R = quaternion_to_matrix(pose.measurements.quaternion)
    expected = pose.measurements.position[:, None] + np.einsum(
        "mij,kj->mki", R, MARKERS - MARKERS[0]
    )
    assert np.allclose(p, expected, atol=1e-12)
    assert many.truth.to_dict()["markers"] == MARKERS.tolist()


def test_marker_one_of_several_is_the_one_marker_campaign_bit_for_bit(panda):
    """Marker 1's columns (noise included) are those of its campaign alone; the others have
    noise of their own (not marker 1's repeated)."""
    one = calib.simulate(panda, 30, "position", marker=MARKERS[0], noise_mm=0.1, seed=2)
    many = calib.simulate(
        panda, 30, "position", marker=list(map(tuple, MARKERS)), noise_mm=0.1, seed=2
    )
    assert np.array_equal(many.measurements.position[:, :3], one.measurements.position)
    exact = calib.simulate(panda, 30, "position", marker=MARKERS, seed=2).measurements.position
    noise = (many.measurements.position - exact).reshape(30, 3, 3)
    assert 0.05e-3 < np.std(noise[:, 1]) < 0.2e-3 and 0.05e-3 < np.std(noise[:, 2]) < 0.2e-3
    assert not np.allclose(noise[:, 1], noise[:, 0]) and not np.allclose(noise[:, 2], noise[:, 1])
    assert one.truth.to_dict()["markers"] == [MARKERS[0].tolist()]


def test_the_command_line_simulates_and_calibrates_three_markers(tmp_path, capsys):
    out = tmp_path / "meas.csv"
    markers = [a for m in MARKERS for a in ["--marker", *map(str, m)]]
    argv = ["simulate", "panda", "--configs", "30", *markers, "--noise-mm", "0.05"]
    assert main([*argv, "--out", str(out)]) == 0
    assert "base values of marker 1" in capsys.readouterr().out
    assert out.read_text().splitlines()[0].endswith("x1,y1,z1,x2,y2,z2,x3,y3,z3")
    truth = json.loads((tmp_path / "meas.truth.json").read_text())
    assert truth["markers"] == MARKERS.tolist() and truth["marker"] == MARKERS[0].tolist()
    cal = ["calibrate", "panda", "--data", str(out), "--out", str(tmp_path / "c.urdf")]
    assert main(cal) == 0 and "accepted" in capsys.readouterr().out
