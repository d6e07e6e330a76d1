"""A fitted direction the data barely see moves the written URDF: the fit says so (humanoid52).

TALOS's right arm touching the table, from the left sole, all 29 touches, ``params auto``:
the fit lengthens the left leg by 212.6 mm at ``leg_left_6_joint`` (between the ankle's two
axes), a direction the fitted table almost entirely takes up. Checked from an independent
route: the written URDF's joint origin against the nominal's (XML), and, with Pinocchio
alone, how much of the touches' height change that origin's shift makes is left once a table
is fitted again to it (an affine function of where each touch is on the table).
"""

from __future__ import annotations

import csv
import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import calib
from calib.cli.commands import main

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
RIGHT = ("talos_full_v2.urdf", "left_sole_link", "gripper_right_base_link")
SAID = "the fit moves "


def _origin(urdf: Path, joint: str) -> np.ndarray:
    """A joint's origin xyz [m] as the URDF file writes it."""
    (node,) = [j for j in ET.parse(urdf).getroot().findall("joint") if j.get("name") == joint]
    origin = node.find("origin")
    return np.array(
        [float(v) for v in (origin.get("xyz") if origin is not None else "0 0 0").split()]
    )


def _left_after_a_table(urdf: str, report: dict, joint: str, axis: int) -> float:
    """The share of the touches' height change per shift of ``joint``'s origin along ``axis``
    that a table fitted again (height and two tilts) leaves, by Pinocchio at the recorded
    postures of the nominal ``urdf``, the report's table and contact frame."""
    model = pin.buildModelFromUrdf(urdf)
    plane = np.array(report["objects"]["planes"]["table"]["matrix"])
    contact = np.array(report["frames"]["contacts"][RIGHT[2]]["matrix"])
    with open(REAL / "right_train.csv") as file:
        rows = list(csv.DictReader(file))

    def touches(m: pin.Model) -> np.ndarray:
        data, out = m.createData(), []
        for row in rows:
            q = pin.neutral(m)
            for name, value in row.items():
                if m.existJointName(name):
                    q[m.joints[m.getJointId(name)].idx_q] = float(value)
            pin.framesForwardKinematics(m, data, q)
            base, tool = data.oMf[m.getFrameId(RIGHT[1])], data.oMf[m.getFrameId(RIGHT[2])]
            out.append(
                (np.linalg.inv(plane) @ (base.inverse() * tool).homogeneous @ contact)[:3, 3]
            )
        return np.array(out)

    before, moved, step = touches(model), model.copy(), 1e-4
    placement = moved.jointPlacements[moved.getJointId(joint)]
    placement.translation = placement.translation + step * np.eye(3)[axis]
    moved.jointPlacements[moved.getJointId(joint)] = placement
    change = (touches(moved)[:, 2] - before[:, 2]) / step
    table = np.column_stack([np.ones(len(before)), before[:, :2]])  # a plane: height, 2 tilts
    left = change - table @ np.linalg.lstsq(table, change, rcond=None)[0]
    return float(np.linalg.norm(left) / np.linalg.norm(change))


@pytest.fixture(scope="module")
def right(tmp_path_factory):
    """The right arm's default fit on all touches, written, with the nominal URDF's path."""
    chain = calib.load_chain(*RIGHT)
    touches = calib.read_contacts(REAL / "right_train.csv", chain, "plane")
    result = calib.calibrate(chain, touches, marker=(0.0, 0.0, -0.12))
    out = tmp_path_factory.mktemp("weak") / "right.urdf"
    result.write(out, report=out.with_suffix(".json"))
    return result, out, chain.urdf_path


def test_a_long_move_the_table_takes_up_is_said_with_the_joint_and_its_size(right):
    result, out, nominal = right
    (note,) = [n for n in result.notes if n.startswith(SAID)]
    found = re.search(r"leg_left_6_joint:d2 by ([-\d.]+) \+- [\d.]+ mm .*take up ([\d.]+) %", note)
    assert found, note
    moved = _origin(out, "leg_left_6_joint") - _origin(nominal, "leg_left_6_joint")
    assert abs(1000 * np.linalg.norm(moved) - abs(float(found[1]))) < 0.1  # the URDF's move
    assert np.linalg.norm(moved) > 0.2  # the 212 mm the brief asked about
    assert float(found[2]) > 95.0
    report = json.loads(out.with_suffix(".json").read_text())
    assert note in report["notes"]
    axis = int(np.argmax(np.abs(moved)))  # the direction the URDF moved it
    assert _left_after_a_table(str(nominal), report, "leg_left_6_joint", axis) < 0.05


def test_a_direction_the_touches_see_is_not_said(right):
    """The control: the arm's elbow origin along x, well seen, and not in the note."""
    result, out, nominal = right
    report = json.loads(out.with_suffix(".json").read_text())
    assert _left_after_a_table(str(nominal), report, "arm_right_4_joint", 0) > 0.5
    (note,) = [n for n in result.notes if n.startswith(SAID)]
    assert "arm_right_4_joint" not in note


def test_a_measured_chain_without_such_a_move_has_no_note():
    chain = calib.load_chain("ur5")
    campaign = calib.simulate(
        chain, 60, "position", marker=(0.01, 0.02, 0.05), noise_mm=0.05, seed=1
    )
    result = calib.calibrate(chain, campaign.measurements, holdout=0.3)
    assert result.accepted
    assert not any(n.startswith(SAID) for n in result.notes)


def test_the_command_says_the_flag(tmp_path, capsys):
    assert main(_calibrate(tmp_path)) == 0
    out = capsys.readouterr().out
    assert "note: the fit moves leg_left_6_joint:d2 by 212.6" in out
    assert "compare --params offsets on held-out rows" in out


def _calibrate(tmp_path, *extra: str) -> list[str]:
    """``calib calibrate`` of the right arm's touches from the left sole; argv."""
    chain = f"{RIGHT[0]} --base {RIGHT[1]} --tool {RIGHT[2]}".split()
    touches = f"--data {REAL / 'right_train.csv'} --measure plane --contact 0 0 -0.12".split()
    return ["calibrate", *chain, *touches, *extra, "--out", str(tmp_path / "cal.urdf")]


def test_fix_holds_that_joint_at_the_nominal_for_touches(tmp_path, capsys, right):
    """``--fix`` for one chain touching: the written origin is the nominal URDF's (XML)."""
    nominal = right[2]
    assert main(_calibrate(tmp_path, "--fix", "leg_left_6_joint:d2")) == 0
    out = capsys.readouterr().out
    assert "leg_left_6_joint:d2" not in out and SAID not in out
    written = _origin(tmp_path / "cal.urdf", "leg_left_6_joint")
    assert np.allclose(written, _origin(nominal, "leg_left_6_joint"), atol=1e-9)
    refused = {
        ("--fix", "frame"): "touches have no instrument frame or markers",
        ("--free", "markers"): "touches have no instrument frame or markers",
        ("--elastic", "--fix", "c1"): "with touches, fix and free name joint parameters",
    }
    for extra, said in refused.items():
        assert main(_calibrate(tmp_path, *extra)) == 2
        (err,) = [x for x in capsys.readouterr().err.splitlines() if "warning" not in x]
        assert said in err
