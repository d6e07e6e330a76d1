"""The default tool of a URDF loaded without one: a gripper's mimic fingers are passed over.

Expected frames are read off the URDFs written here (the deepest tip) and off Pinocchio's own
model of the file: of the frames on the hand's body, the one its model lists last (the rule
for frames equally deep); the Panda's ``panda_hand_tcp`` is that frame on ``panda_joint7``.
"""

from __future__ import annotations

from pathlib import Path

import pinocchio as pin
import pytest

from calib import load_chain
from calib.kinematics.catalog import catalog_entry

LIMIT = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'


def _joint(name: str, parent: str, child: str, kind: str = "revolute", extra: str = "") -> str:
    limit = LIMIT if kind in ("revolute", "prismatic") else ""
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 1 0"/>{limit}{extra}</joint>'
    )


def _fingers(on: str, mimic: bool, kind: str = "prismatic") -> list[str]:
    """Two fingers on link ``on``; the right one follows the left where ``mimic``."""
    tag = '<mimic joint="finger_left_joint" multiplier="-1"/>' if mimic else ""
    return [
        _joint("finger_left_joint", on, "finger_left", kind),
        _joint("finger_right_joint", on, "finger_right", kind, tag),
    ]


def _urdf(tmp_path: Path, joints: list[str], name: str = "arm") -> Path:
    links = {part.split('child link="')[1].split('"')[0] for part in joints}
    body = "".join(f'<link name="{link}"/>' for link in sorted(links))
    path = tmp_path / f"{name}.urdf"
    path.write_text(f'<robot name="{name}"><link name="base"/>{body}{"".join(joints)}</robot>')
    return path


def _last_on(path: Path, joint: str) -> str:
    """The frame Pinocchio's model of the file lists last among those on ``joint``'s body."""
    model = pin.buildModelFromUrdf(str(path))
    on = [f.name for f in model.frames if f.parentJoint == model.getJointId(joint)]
    return on[-1]


def _deepest_last(path: Path) -> str:
    """Of the frames with the most joints above them, the one Pinocchio's model lists last."""
    model = pin.buildModelFromUrdf(str(path))
    depth = [len(model.supports[f.parentJoint]) for f in model.frames]
    return model.frames[max(i for i, d in enumerate(depth) if d == max(depth))].name


def _arm(mimic: bool, kind: str = "prismatic") -> list[str]:
    """base -j1- l1 -j2- hand, tool0 then tcp fixed on the hand, two fingers on the hand."""
    return [
        _joint("j1", "base", "l1"),
        _joint("j2", "l1", "hand"),
        _joint("tool0_joint", "hand", "tool0", "fixed"),
        *_fingers("hand", mimic, kind),
        _joint("tcp_joint", "hand", "tcp", "fixed"),
    ]


@pytest.mark.parametrize("kind", ["prismatic", "revolute"])
def test_a_mimic_finger_pair_is_passed_over_for_the_frame_last_fixed_on_the_hand(tmp_path, kind):
    path = _urdf(tmp_path, _arm(mimic=True, kind=kind))
    chain = load_chain(path)
    assert (chain.base_frame, chain.tool_frame) == ("base", _last_on(path, "j2"))
    assert chain.tool_frame in ("hand", "tool0", "tcp")
    assert chain.joint_names == ("j1", "j2")


def test_fingers_without_a_mimic_tag_keep_the_deepest_tip(tmp_path):
    path = _urdf(tmp_path, _arm(mimic=False))
    chain = load_chain(path)
    assert chain.tool_frame == _deepest_last(path)
    assert chain.tool_frame in ("finger_left", "finger_right")
    assert chain.joint_names == ("j1", "j2", f"{chain.tool_frame}_joint")


def test_fingertips_following_the_same_joint_are_fingers_too(tmp_path):
    tip = '<mimic joint="finger_left_joint"/>'
    joints = [*_arm(mimic=True), _joint("tip_joint", "finger_right", "tip", "revolute", tip)]
    path = _urdf(tmp_path, joints)
    assert load_chain(path).tool_frame == _last_on(path, "j2")


def test_a_fingertip_moving_on_its_own_makes_the_pair_no_gripper(tmp_path):
    joints = [*_arm(mimic=True), _joint("tip_joint", "finger_right", "tip")]
    chain = load_chain(_urdf(tmp_path, joints))
    assert chain.tool_frame == "tip"
    assert chain.joint_names == ("j1", "j2", "finger_right_joint", "tip_joint")


def test_a_linkage_carrying_the_arm_is_no_gripper(tmp_path):
    joints = [
        _joint("j1", "base", "l1"),
        _joint("j1_bar", "base", "bar", extra='<mimic joint="j1"/>'),
        _joint("j2", "l1", "l2"),
        _joint("j3", "l2", "flange"),
    ]
    chain = load_chain(_urdf(tmp_path, joints))
    assert chain.tool_frame == "flange"
    assert chain.joint_names == ("j1", "j2", "j3")


def test_a_gripper_alone_keeps_a_finger(tmp_path):
    path = _urdf(tmp_path, _fingers("base", mimic=True), "gripper")
    assert load_chain(path).tool_frame == _deepest_last(path)
    assert load_chain(path).tool_frame in ("finger_left", "finger_right")


def test_the_panda_urdf_defaults_to_its_hand_tcp_frame():
    path = catalog_entry("panda").path
    model = pin.buildModelFromUrdf(str(path))
    tcp = model.frames[model.getFrameId("panda_hand_tcp")]
    assert model.names[tcp.parentJoint] == "panda_joint7"
    chain = load_chain(path)
    assert (chain.base_frame, chain.tool_frame) == ("panda_link0", "panda_hand_tcp")
    assert chain.joint_names == tuple(f"panda_joint{k}" for k in range(1, 8))
