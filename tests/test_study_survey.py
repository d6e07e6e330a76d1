"""Identifiable parameters across the catalog: the checks of the robot-survey study.

Every count is compared with a formula that does not come from calib: the count of
standard parameters 4(n + 2) - 2, Everett's completeness formula (Everett, Driels &
Mooring, ICRA 1987: 4R + 2P + 6 for the pose, 4R + 2P + 3 for a point, 2 fewer on the last
axis), and for trees 4R + 2P + 6T, also reached as the sum of the chains alone minus what
sharing a trunk counts twice.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import calib
from calib.kinematics.tree import load_tree
from calib.outputs.sweep import sweep

pytestmark = pytest.mark.slow

MARKER_ROBOTS = ("aid", "stanford", "ur5", "panda", "kinova")


@pytest.fixture(scope="module")
def pose_rows():
    return sweep(measure="pose")


@pytest.fixture(scope="module")
def position_rows():
    return sweep(measure="position")


def _chains(rows):
    return [r for r in rows if r.error is None and r.tools == 1]


def test_every_chain_reaches_everett_with_the_complete_set(pose_rows):
    chains = _chains(pose_rows)
    for r in chains:
        assert r.n_standard == 4 * (r.revolute + r.prismatic + 2) - 2, r
        assert r.n_base_complete == r.n_complete, r
        assert r.n_base_paper <= r.n_base_complete, r
        if r.n_theory is not None:
            assert r.n_complete == r.n_theory == 4 * r.revolute + 2 * r.prismatic + 6, r
    coupled = [r for r in chains if r.n_theory is None]  # chains through mimic joints
    assert coupled and all(r.n_complete <= 4 * r.revolute + 2 * r.prismatic + 6 for r in coupled)
    assert any(r.robot == "aid" and r.n_base_paper == 27 for r in pose_rows if r.error is None)


def test_the_chains_known_not_to_load_are_rows_with_a_reason(pose_rows):
    expected = {e.name for e in calib.catalog() if e.expect_error}
    errors = [r for r in pose_rows if r.error is not None]
    assert errors, "the catalog has chains known not to load"
    assert all(isinstance(r.error, str) and r.error.strip() for r in errors)
    assert all(r.verdict == "error" and r.n_base_paper is None for r in errors)
    assert {r.robot for r in errors} == expected


def test_position_counts_and_notes(pose_rows, position_rows):
    coupled = {r.robot for r in _chains(pose_rows) if r.n_theory is None}
    for r in _chains(position_rows):
        assert r.n_base_paper <= r.n_base_complete == r.n_complete, r
        if r.n_theory is None and "coupled" in r.note:  # mimic joints: no formula
            assert r.robot in coupled, r
        elif r.n_theory is None:  # the point lies on several joint axes
            assert r.note.startswith("point on axes ") and "," in r.note.split(";")[0], r
        else:
            assert r.n_complete == r.n_theory, r
        assert "rank" not in r.note, r  # no RankWarning anywhere


def test_position_loses_3_or_5_against_the_pose(pose_rows, position_rows):
    by_robot = {r.robot: r for r in _chains(position_rows)}
    compared = 0
    for r in _chains(pose_rows):
        p = by_robot[r.robot]
        if p.n_theory is None:
            continue
        on_last = p.n_theory == 4 * p.revolute + 2 * p.prismatic + 1
        assert r.n_complete - p.n_complete == (5 if on_last else 3), (r, p)
        compared += 1
    assert compared > 20


def test_a_marker_off_the_last_axis_gains_two():
    on, off = (0.0, 0.0, 0.0), (0.01, 0.02, 0.05)
    marker = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        for name in MARKER_ROBOTS:
            for label, mk in (("on", on), ("off", off)):
                marker[name, label] = calib.analyze(
                    name, measure="position", marker=mk, params="complete"
                )
    for name in MARKER_ROBOTS:
        a, b = marker[name, "on"], marker[name, "off"]
        assert a.on_last_axis and not b.on_last_axis
        assert b.n_theory == a.n_theory + 2
        assert a.n_base == a.n_complete == a.n_theory, name
        assert b.n_base == b.n_complete == b.n_theory, name
        assert not a.warnings and not b.warnings, name
    assert marker["panda", "on"].n_complete == 4 * 7 + 3 - 2 == 29
    assert marker["panda", "off"].n_complete == 4 * 7 + 3 == 31
    assert marker["ur5", "off"].n_complete == 4 * 6 + 3 == 27


def test_trees_count_4r_2p_6t_and_sharing_removes_the_repeats(pose_rows):
    trees = [r for r in pose_rows if r.error is None and r.tools > 1]
    assert len(trees) >= 20
    for r in trees:
        tree = load_tree(r.robot)
        alone = [
            4 * int(np.sum(tree.sigma[p] == 0)) + 2 * int(np.sum(tree.sigma[p] == 1)) + 6
            for p in tree.paths
        ]
        carried = np.bincount(np.concatenate(tree.paths), minlength=tree.n)  # tools per joint
        removed = sum(
            (k - 1) * (4 if s == 0 else 2) for k, s in zip(carried, tree.sigma, strict=True)
        )
        theory = 4 * r.revolute + 2 * r.prismatic + 6 * r.tools
        assert r.n_base_complete == r.n_complete == r.n_theory == theory, r
        assert sum(alone) - removed == r.n_complete, r


def test_talos_limbs_alone_against_the_whole_tree():
    talos = load_tree("talos")
    alone = {
        t: calib.analyze("talos", tool=t, measure="pose", params="complete").n_base
        for t in talos.tool_frames
    }
    whole = calib.analyze("talos", measure="pose", params="complete")
    arms = calib.analyze(
        "talos", tool=list(talos.tool_frames[:2]), measure="pose", params="complete"
    )
    assert sum(alone.values()) - whole.n_base == 2 * 2 * 4
    assert alone[talos.tool_frames[0]] + alone[talos.tool_frames[1]] - arms.n_base == 2 * 4
    assert whole.n_base == whole.n_complete == 4 * 30 + 6 * 5 == 150
    paper = calib.analyze("talos", measure="pose", params="paper")
    assert paper.n_base + len(paper.missing) == whole.n_base
    first_joints = {k for k in range(1, paper.mdh.n + 1) if paper.mdh.antecedent[k] == 0}
    missing_rows = {int(name.lstrip("betay")) for name in paper.missing_parameters}
    assert missing_rows <= first_joints, (missing_rows, first_joints)


def test_position_trees_reach_their_complete_model(position_rows):
    trees = [r for r in position_rows if r.error is None and r.tools > 1]
    assert trees
    for r in trees:
        assert r.n_base_complete == r.n_complete, r
        if r.n_theory is not None:
            assert r.n_complete == r.n_theory <= 4 * r.revolute + 2 * r.prismatic + 3 * r.tools, r
