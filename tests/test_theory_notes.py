"""``theory n/a`` says why, and the reason is true of the robot (checked with Pinocchio alone).

The reasons are the kinds' own (calib.identification: a contact's or a measurement's
``theory``); each one here is checked on the URDF by Pinocchio: the joint's type, the joint
axes along the tool's z axis, the loop's joints.
"""

from __future__ import annotations

import json

import numpy as np
import pinocchio as pin
import pytest
from pinref import pin_config, pin_frame

from calib import load_chain
from calib.cli.commands import main


def _run(capsys, *argv) -> str:
    assert main(list(argv)) == 0
    return capsys.readouterr().out


def _theory_line(text: str) -> str:
    return next(line for line in text.splitlines() if line.startswith("standard "))


def _pinocchio(name: str):
    """The chain's Pinocchio model (the URDF calib loads), its joint ids and frames."""
    chain = load_chain(name)
    model = pin.buildModelFromUrdf(str(chain.urdf_path))
    ids = [model.getJointId(j) for j in chain.joint_names]
    return chain, model, ids


def _axes_along_tool_z(name: str) -> list[int]:
    """Joints (1..n) whose turning leaves the tool's z axis still, at random postures."""
    chain, model, ids = _pinocchio(name)
    data, tool = model.createData(), pin_frame(model, chain.tool_frame)
    rng = np.random.default_rng(3)
    along = []
    for k in range(len(ids)):
        still = True
        for q in rng.uniform(-2, 2, (4, len(ids))):
            z = []
            for h in (1e-6, -1e-6):
                moved = q.copy()
                moved[k] += h
                pin.framesForwardKinematics(model, data, pin_config(model, ids, moved))
                z.append(data.oMf[tool].rotation[:, 2].copy())
            still &= bool(np.linalg.norm(z[0] - z[1]) < 1e-12)
        if still:
            along.append(k + 1)
    return along


def test_a_prismatic_first_joint_is_said(capsys):
    """The TIAGo's plane and plane-point: no formula, because its first joint slides."""
    _, model, ids = _pinocchio("tiago")
    assert model.joints[ids[0]].shortname().startswith("JointModelP")  # prismatic
    assert all(not model.joints[i].shortname().startswith("JointModelP") for i in ids[1:])
    for kind in ("plane", "plane-point"):
        line = _theory_line(_run(capsys, "analyze", "tiago", "--measure", kind))
        assert line.endswith("theory n/a (prismatic first joint)"), line


@pytest.mark.parametrize(("kind", "extra"), [("plane-point", 1), ("plane", 3)])
def test_a_planar_arm_touching_the_plane_it_moves_in_has_its_own_count(capsys, kind, extra):
    """Every axis along the normal: 2R + 1 and 2R + 3 (docs/method.md §6), not 4R - 1, 4R - 2
    (twodof printed base 5 against theory 7 for plane-point)."""
    along = _axes_along_tool_z("twodof")
    assert along == [1, 2]
    line = _theory_line(_run(capsys, "analyze", "twodof", "--measure", kind))
    count = 2 * len(along) + extra
    assert line.endswith(f"base {count}, complete model {count}, theory {count}"), line


@pytest.mark.parametrize(
    ("robot", "kind", "reason"),
    [
        ("ur5", "fixed-pose", "a {n}-joint loop cannot move"),
        (
            "twodof",
            "fixed-point",
            "{n} joints move the tip in its plane: it cannot stay on the point and move",
        ),
        ("twodof", "fixed-pose", "a planar loop of {n} joints cannot move"),
        ("ur5", "x,y", "the formula is for the pose or a point, not the rows x,y"),
    ],
)
def test_the_reason_names_the_joints_pinocchio_counts(capsys, robot, kind, reason):
    _, model, ids = _pinocchio(robot)
    moving = [i for i in ids if model.joints[i].nv == 1]
    line = _theory_line(_run(capsys, "analyze", robot, "--measure", kind))
    assert line.endswith(f"theory n/a ({reason.format(n=len(moving))})"), line


def test_json_and_sweep_carry_the_reason_and_a_count_has_none(capsys):
    found = json.loads(_run(capsys, "analyze", "tiago", "--measure", "plane", "--json"))
    assert (found["n_theory"], found["theory_note"]) == (None, "prismatic first joint")
    found = json.loads(_run(capsys, "analyze", "ur5", "--measure", "plane", "--json"))
    assert found["n_theory"] == 20 and found["theory_note"] == ""
    rows = json.loads(
        _run(capsys, "sweep", "--robots", "tiago", "ur5", "--measure", "plane", "--json")
    )["rows"]
    assert [r["note"] for r in rows] == ["no theory: prismatic first joint", ""]


def test_sweep_with_markers_names_no_parameter_set(capsys):
    """``--markers K`` counts the complete set: the JSON's ``params`` is null there."""
    argv = ["sweep", "--robots", "twodof", "--configs", "20", "--json"]
    assert json.loads(_run(capsys, *argv))["params"] == "paper"
    assert json.loads(_run(capsys, *argv, "--markers", "3"))["params"] is None


def test_a_tip_on_the_last_axis_is_not_the_reason_a_contact_has_no_theory(capsys):
    """The double pendulum's tip lies on its last axis (Pinocchio: the tool's origin does not
    move when that joint turns); held at a point, it cannot move: that is the reason printed,
    not ``point on the last axis: 2 fewer`` (the position's note, printed before)."""
    chain, model, ids = _pinocchio("double_pendulum")
    data, tool = model.createData(), pin_frame(model, chain.tool_frame)
    origins = []
    for angle in (0.0, 1.0, 2.0):
        pin.framesForwardKinematics(model, data, pin_config(model, ids, [0.3, angle]))
        origins.append(data.oMf[tool].translation.copy())
    assert np.ptp(np.array(origins), axis=0).max() < 1e-12  # on the last axis
    line = _theory_line(_run(capsys, "analyze", "double_pendulum", "--measure", "fixed-point"))
    assert line.endswith(
        "theory n/a (1 joint moves the tip in its plane: it cannot stay on the point and move)"
    ), line
