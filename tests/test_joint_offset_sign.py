"""A joint's angle offset in the report is the correction to its reading, whichever way the
chain runs through the joint (formats.md, ``parameters``).

Independent route: the data are simulated without error, then one joint's column is read
0.01 rad too high, as an encoder whose zero is off would read it. The report must give that
joint -0.01 rad (the joint's angle is the reading plus the value), on a chain that runs
through it forward, backward (base and tool swapped), and on a chain that runs backward down
a leg and forward up an arm.
"""

import dataclasses
import warnings

import pytest

import calib

EXCESS = 0.01
"""How much the encoder reads above the joint's angle [rad]."""


def _offset_found(robot, base, tool, joint):
    """The report's parameters of ``joint`` after calibrating data whose reading is off."""
    chain = calib.load_robot(robot, base, tool)
    camp = calib.simulate(chain, 60, "pose", seed=1, error_mm=0.0, error_mrad=0.0)
    q = camp.measurements.q.copy()
    q[:, list(chain.joint_names).index(joint)] += EXCESS
    data = dataclasses.replace(camp.measurements, q=q)
    with warnings.catch_warnings():  # a reading past a joint limit by the excess: warned
        warnings.simplefilter("ignore", calib.DataWarning)
        report = calib.calibrate(chain, data, params="offsets").to_dict()
    return [p for p in report["parameters"] if p["joint"] == joint]


@pytest.mark.parametrize(
    ("robot", "base", "tool", "joint"),
    [
        ("ur5", "base_link", "tool0", "elbow_joint"),
        ("ur5", "tool0", "base_link", "elbow_joint"),
        ("talos", "left_sole_link", "gripper_left_base_link", "leg_left_4_joint"),
        ("talos", "left_sole_link", "gripper_left_base_link", "arm_left_4_joint"),
    ],
)
def test_an_encoder_reading_high_gives_its_joint_a_negative_offset(robot, base, tool, joint):
    """One parameter names the joint, in rad, equal to minus the reading's excess."""
    found = _offset_found(robot, base, tool, joint)
    assert len(found) == 1, found
    assert found[0]["unit"] == "rad"
    assert found[0]["value"] == pytest.approx(-EXCESS, abs=1e-7)
