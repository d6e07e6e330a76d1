"""A frame given one link too near: its chain leaves out a joint the file logs (nearlink50).

Markers or a contact fixed to the UR5's wrist_3_link, the chain given to wrist_2_link: the
file's wrist_3_joint column is not the chain's, and was only named as "columns ignored". The
usual-mistake diagnosis reads that column again and registers the data on the chain to the
link beyond: it names the joint and the link. (The TIAGo's head camera on head_2_link given
on head_1_link: tests/test_pixels_cli.py.) A tree's tool one link too far is named by its
own term's diagnosis.
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from pinref import urdf_links

import calib
from calib import Problem, Term, calibrate, load_chain
from calib.calibration.entry import calibrate_contacts
from calib.exceptions import DataError
from calib.kinematics.catalog import resolve_urdf
from calib.kinematics.frames import beyond_ends
from calib.kinematics.tree import load_tree
from calib.measurements.contact_campaign import read_contacts, simulate_contacts, write_contacts
from calib.measurements.csvfile import read_measurements, write_measurements
from calib.measurements.joint_columns import logged_joints
from calib.measurements.tree_campaign import simulate_tree

MARKERS = np.array([[0.05, 0.08, 0.03], [-0.04, 0.1, 0.0], [0.0, 0.12, 0.05]])  # off wrist_3's axis
NAMED = "the file logs wrist_3_joint beyond wrist_2_link (is the {} on wrist_3_link?)"
PROBE = (  # a contact point fixed to wrist_3_link, off its axis
    '<link name="probe"/><joint name="probe_joint" type="fixed"><parent link="wrist_3_link"/>'
    '<child link="probe"/><origin xyz="0.05 0.08 0.03" rpy="0 0 0"/></joint></robot>'
)


def _read_on_wrist_2(path, data):
    """``data`` written to ``path`` and read for the chain to wrist_2_link (wrist_3_joint
    ignored: its warning checked)."""
    write_measurements(path, data)
    with pytest.warns(UserWarning, match="columns ignored .*: wrist_3_joint"):
        return read_measurements(path, load_chain("ur5", tool="wrist_2_link"))


@pytest.mark.parametrize(("k", "measure"), [(1, "position"), (3, "position"), (1, "pose")])
def test_markers_one_link_too_near_are_refused_naming_the_link(tmp_path, k, measure):
    """Failed before: refused as "another robot's data" (55.5 mm), the joint not named."""
    on3 = load_chain("ur5", tool="wrist_3_link")
    marker = MARKERS[:k] if k > 1 else MARKERS[0]
    seen = calib.simulate(on3, 100, measure, marker=marker, noise_mm=0.1, seed=2)
    data = _read_on_wrist_2(tmp_path / "m.csv", seen.measurements)
    with pytest.raises(DataError, match="the data look like a joint left out of the chain") as e:
        calibrate(load_chain("ur5", tool="wrist_2_link"), data, noise_mm=0.1)
    assert NAMED.format("tool") in str(e.value)


def test_rows_not_read_from_a_file_are_not_named(tmp_path):
    """The same rows built in Python (no file, no column to read again): refused as before."""
    on3 = load_chain("ur5", tool="wrist_3_link")
    seen = calib.simulate(on3, 100, "position", marker=MARKERS[0], noise_mm=0.1, seed=2)
    data = _read_on_wrist_2(tmp_path / "m.csv", seen.measurements)
    with pytest.raises(DataError, match="the data do not match") as e:
        calibrate(load_chain("ur5", tool="wrist_2_link"), dataclasses.replace(data, path=None))
    assert "left out" not in str(e.value)


@pytest.mark.parametrize("measure", ["fixed-point", "plane"])
def test_touches_one_link_too_near_are_refused_naming_the_link(tmp_path, measure):
    """Failed before: fixed points accepted (56.6 mm registration, a note), planes refused
    as "another robot's data"."""
    urdf = tmp_path / "ur5_probe.urdf"
    urdf.write_text(load_chain("ur5").urdf_path.read_text().replace("</robot>", PROBE))
    probe = load_chain(urdf, base="base_link", tool="probe")
    touches = simulate_contacts(probe, 60, measure, contacts=2, seed=4, noise_mrad=0.1).data
    write_contacts(tmp_path / "t.csv", touches)
    on2 = load_chain(urdf, base="base_link", tool="wrist_2_link")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # wrist_3_joint: read as a joint off the chain
        data = read_contacts(tmp_path / "t.csv", on2, measure)
    with pytest.raises(DataError, match="the touches look like a joint left out") as e:
        calibrate_contacts(on2, data, contact=[0, 0, 0])
    assert NAMED.format("contact frame") in str(e.value)


@pytest.mark.parametrize(
    ("robot", "base", "tool", "expected"),
    [  # read off the URDFs: the joints at each end off the chain, and the link beyond them
        ("ur5", "base_link", "wrist_2_link", {"wrist_3_joint": (1, "wrist_3_link")}),
        ("ur5", "base_link", "tool0", {}),
        (
            "tiago",
            "torso_lift_link",
            "arm_6_link",  # the torso's own joint (its parent link), the head's, the arm's next
            {
                "torso_lift_joint": (0, "torso_fixed_link"),
                "head_1_joint": (0, "head_1_link"),
                "arm_7_joint": (1, "arm_7_link"),
            },
        ),
    ],
)
def test_beyond_ends_are_the_links_one_joint_out(robot, base, tool, expected):
    """Each joint off the chain next to an end, and the link on its far side."""
    chain = load_chain(robot, base=base, tool=tool)
    ends = (chain.base_id, chain.tool_id)
    assert beyond_ends(chain.model, chain.joint_ids, ends) == expected
    assert all(link in urdf_links(chain.urdf_resolved, j) for j, (_, link) in expected.items())
    assert not set(expected) & set(chain.joint_names)


def test_logged_joints_reads_the_columns_a_file_has():
    """``joint:NAME`` or NAME, at the rows asked; a column with no number there is left out."""
    text = "# an export\nx,joint:x,a,b\n1,2,3,4\n5,6,7,\n8,9,10,11\n"
    found = logged_joints(text, "<t>", ("x", "a", "b", "c"), (3, 5))
    assert set(found) == {"x", "a", "b"}
    np.testing.assert_array_equal(found["x"], [2.0, 9.0])
    np.testing.assert_array_equal(found["a"], [3.0, 10.0])
    assert set(logged_joints(text, "<t>", ("b",), (4,))) == set()  # row 4's cell is empty


def test_a_tree_tool_one_link_too_far_is_named_by_its_own_term():
    """TALOS's left tool on arm_left_6_link given on arm_left_7_link, whose joint moves within
    +-0.69 rad: each tool's term of a tree is a chain whose registration tries its end joints
    (39.6 mm, 2.6 mm once held at 0), in calibrate and in analyze alike. Passed before too: it
    pins what a tree's diagnosis of its shared registration (28.4 mm) would only repeat."""
    urdf = resolve_urdf("erd:talos_data/robots/talos_reduced.urdf")
    right = "wrist_right_ft_tool_link"
    true = load_tree(urdf, "base_link", ("arm_left_6_link", right))
    given = load_tree(urdf, "base_link", ("arm_left_7_link", right))
    markers = [[0.05, 0.02, 0.1], [0.03, -0.02, 0.08]]
    seen = simulate_tree(true, 60, markers=markers, noise_mm=0.1, seed=1).measurements
    moved = np.repeat(np.random.default_rng(3).uniform(-0.69, 0.69, seen.m // 2), 2)
    columns = [
        seen.q[:, seen.joint_names.index(n)] if n in seen.joint_names else moved
        for n in given.joint_names
    ]
    tools = tuple("arm_left_7_link" if t == "arm_left_6_link" else t for t in seen.tool)
    data = dataclasses.replace(
        seen, joint_names=given.joint_names, q=np.column_stack(columns), tool=tools
    )
    for route in (
        lambda: calib.analyze(Problem((Term(given, data),))),
        lambda: calibrate(given, data),
    ):
        with pytest.raises(DataError, match="arm_left_7_joint does not move what is fix") as e:
            route()
        assert "arm_left_7_link (is it on arm_left_6_link?)" in str(e.value)
