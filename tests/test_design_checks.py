"""Design's lazy collision checks: only the candidates the design considers are checked."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import chain_of

import calib
from calib import InvalidArgumentError
from calib.cli.commands import main
from calib.design.collision import _geometry
from calib.design.constraints import Constraints, filter_candidates
from calib.design.design import (
    RANDOM_POOL,
    _draw,
    _random_sets,
    candidate_configurations,
    design,
    evaluate,
)
from calib.design.exchange import optimal_subset
from calib.exceptions import URDFError


def _same_rows(a: np.ndarray, b: np.ndarray) -> bool:
    return sorted(map(tuple, np.round(a, 12).tolist())) == sorted(
        map(tuple, np.round(b, 12).tolist())
    )


def test_lazy_checks_pick_the_design_of_the_collision_free_candidates():
    """Checking every candidate first (brute force, then a design among the collision-free
    ones) and checking only those the design considers pick the same configurations; fewer
    are checked, and every configuration picked is collision-free."""
    chain = chain_of("tiago")
    q = candidate_configurations(chain, 1500, seed=3)
    keep, report = filter_candidates(chain, q, np.zeros((1, 3)), Constraints())
    assert dict(report.rejected)["collision"] > 0  # the check has something to reject
    first = design(chain, 20, candidates=q[keep], seed=3, constraints=Constraints(collision=False))
    lazy = design(chain, 20, candidates=q, seed=3)
    assert _same_rows(first.q, lazy.q)
    assert lazy.filters.checked is not None and lazy.filters.checked < len(q)
    assert filter_candidates(chain, lazy.q, np.zeros((1, 3)), Constraints())[0].all()
    rejected = dict(lazy.filters.rejected)["collision"]
    assert lazy.candidates == len(q) - rejected
    assert lazy.filters.to_dict()["checked"] == lazy.filters.checked


def test_a_rejected_candidate_is_replaced_by_the_next_best():
    """A check that rejects the unchecked design's picks: the design avoids them and equals
    the design of the candidates without them (brute force)."""
    rng = np.random.default_rng(0)
    J = rng.standard_normal((300, 3, 9))
    plain = optimal_subset(J, 6)
    banned = np.zeros(len(J), dtype=bool)
    banned[list(plain.design)[:3]] = True
    asked: list[int] = []

    def check(idx):
        asked.extend(idx.tolist())
        return ~banned[idx]

    lazy = optimal_subset(J, 6, check=check)
    kept = np.flatnonzero(~banned)
    first = optimal_subset(J[kept], 6)
    assert not banned[list(lazy.design)].any()
    assert sorted(lazy.design) == sorted(kept[list(first.design)].tolist())
    assert set(asked) < set(range(len(J)))


def test_random_sets_hold_only_candidates_the_check_accepts():
    ok = np.arange(100) % 3 != 0
    rows = _draw(100, 20, np.random.default_rng(1), lambda idx: ok[idx])
    assert len(rows) == 20 and ok[rows].all() and len(set(rows.tolist())) == 20
    few = _draw(10, 20, np.random.default_rng(1), lambda idx: ok[idx])
    assert sorted(few.tolist()) == np.flatnonzero(ok[:10]).tolist()


def test_random_sets_come_from_a_checked_pool():
    ok = np.arange(5000) % 4 != 0
    asked: list[int] = []

    def check(idx):
        asked.extend(idx.tolist())
        return ok[idx]

    sets = list(_random_sets(5000, 30, np.random.default_rng(2), check, range(20)))
    assert len(sets) == 20 and all(len(set(r.tolist())) == 30 and ok[r].all() for r in sets)
    assert len(set(np.concatenate(sets).tolist())) > 30  # not one set repeated
    assert len(asked) < 2 * RANDOM_POOL * 30  # the pool's checks, not 20 sets' apart


def test_too_few_collision_free_candidates_is_one_error():
    chain = chain_of("ur5")
    box = (-3.0, -3.0, -3.0, 3.0, 3.0, 3.0)  # around the whole robot: every candidate touches it
    with pytest.raises(InvalidArgumentError, match="collision rejects 40"):
        design(chain, 10, candidates=40, constraints=Constraints(obstacles=(box,)))


MISSING_MESH = """<robot name="mesh">
  <link name="base"><collision><geometry><mesh filename="/nonexistent/base.stl"/></geometry>
  </collision></link><link name="a"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="a"/><axis xyz="0 0 1"/>
    <origin xyz="0 0 0.3"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="a"/><child link="tool"/><axis xyz="0 1 0"/>
    <origin xyz="0.2 0 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
</robot>
"""


def one_line_error(capsys, argv) -> str:
    """Exit 2 and one line on stderr: the line."""
    from calib.cli.commands import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err, err
    return err


def test_a_missing_mesh_names_the_mesh_and_the_option_that_skips_it(tmp_path, capsys):
    """Pinocchio's message names its C++ source file first: the error names the mesh instead,
    and the option that skips the collision check (there is no option named like the hint)."""
    from calib.cli.commands import main

    urdf = tmp_path / "mesh.urdf"
    urdf.write_text(MISSING_MESH)
    argv = ["design", str(urdf), "--base", "base", "--tool", "tool", "--configs", "5"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "assimp.cpp" not in err, err
    assert "Could not load resource /nonexistent/base.stl" in err and "(--no-collision)" in err
    # the URDF loads, only its meshes do not: the message says which, and what needs none
    assert err.startswith(f"calib: error: cannot load the collision geometry of URDF '{urdf}'")
    assert "its kinematics loads (show, analyze, simulate and calibrate need no mesh)" in err
    assert main(["show", str(urdf), "--base", "base", "--tool", "tool"]) == 0
    capsys.readouterr()
    assert main([*argv, "--no-collision"]) == 0
    capsys.readouterr()
    sight = one_line_error(capsys, [*argv, "--no-collision", "--line-of-sight", "2", "0", "1"])
    assert sight.endswith("(the line of sight and the obstacles are checked against the meshes)")
    chain = calib.load_chain(urdf, "base", "tool")
    hint = "(constraints=calib.design.constraints.Constraints(collision=False))"
    with pytest.raises(URDFError) as info:  # Constraints is not in calib's namespace
        design(chain, 5)
    assert str(info.value).endswith(hint), info.value
    assert design(chain, 5, constraints=calib.design.constraints.Constraints(collision=False))


def test_candidates_in_degrees_are_named_as_a_candidates_file_is():
    """The user's candidates far past a joint limit (degrees for radians): "0 of 60
    candidates pass the filters (margin rejects 60 ...)", where ``--candidates-file`` names
    the row, the joint and the likely mistake; now the same line."""
    from calib import DataError

    chain = chain_of("ur5")
    q = chain.random_configurations(60, seed=0)
    with pytest.raises(DataError, match=r"row 1, column 'shoulder_pan_joint'.*degrees"):
        design(chain, 12, candidates=np.degrees(q))
    assert len(design(chain, 12, candidates=q, random_sets=2).q) == 12
    with pytest.raises(DataError, match=r"configurations \(row 1, .*degrees"):
        evaluate(chain, np.degrees(q))  # it scored them (as --evaluate FILE refuses them)


@pytest.mark.parametrize("urdf", ["talos_full_v2.urdf", "talos_reduced.urdf"])
def test_the_srdf_named_after_the_robot_is_found_for_any_of_its_urdfs(urdf):
    """example-robot-data ships talos.srdf for TALOS's URDFs (``<robot name="talos">``):
    a design on talos_full_v2.urdf (the contact data's URDF) disabled none of its 225 pairs
    on the left sole's chain to the gripper."""
    from calib.design.collision import collision_checker, find_srdf

    chain = calib.load_chain(urdf, "left_sole_link", "gripper_left_base_link")
    assert find_srdf(chain.urdf_resolved, chain.model.name).name == "talos.srdf"
    notes = collision_checker(chain).notes
    assert any(note.endswith("disabled by talos.srdf") for note in notes), notes


TWO_ARMS = """<robot name="two_arms">
  <link name="base"/><link name="tool"/>
  <link name="arm_a"><collision><origin xyz="0.6 0 0"/><geometry><box size="0.8 0.1 0.1"/>
  </geometry></collision></link>
  <link name="arm_b"><collision><origin xyz="0 0.6 0"/><geometry><box size="0.1 0.8 0.1"/>
  </geometry></collision></link>
  <joint name="a1" type="revolute"><parent link="base"/><child link="arm_a"/><axis xyz="0 0 1"/>
    <origin xyz="0 0 0.3"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="a2" type="revolute"><parent link="arm_a"/><child link="tool"/><axis xyz="0 1 0"/>
    <origin xyz="1.0 0 0"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="b1" type="revolute"><parent link="base"/><child link="arm_b"/><axis xyz="0 0 1"/>
    <origin xyz="0 0 0.3"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
</robot>
"""
"""Two arms on one base, apart at zero: arm a (the chain base -> tool) turned a quarter turn
lies on arm b at zero, not on arm b turned back (b1 = 3 rad)."""


def test_candidates_recording_the_joints_off_the_chain_are_checked_as_recorded(tmp_path, capsys):
    """A recorded posture's other arm (off the chain) is where the file records it in the
    collision check, not at zero: TALOS's recorded touches were 15 of 21 rejected (the right
    arm at zero in the base link, the right leg at zero in the moved left leg). A file without
    those columns keeps them at zero, as before."""
    from pinref import pair_collides

    from calib.design.configurations import recorded_off_chain

    urdf = tmp_path / "two_arms.urdf"
    urdf.write_text(TWO_ARMS)
    chain = calib.load_chain(urdf, "base", "tool")
    rng = np.random.default_rng(0)
    q = np.column_stack([1.5708 + rng.uniform(-0.2, 0.2, 30), rng.uniform(-2, 2, 30)])
    b1 = 3.0 + rng.uniform(-0.1, 0.1, 30)
    names, links = ("a1", "a2", "b1"), ("arm_a", "arm_b")
    assert pair_collides(urdf, str(tmp_path), names, [*q[0], 0.0], links)  # Pinocchio alone
    assert not pair_collides(urdf, str(tmp_path), names, [*q[0], b1[0]], links)
    path = tmp_path / "touches.csv"
    np.savetxt(path, np.column_stack([q, b1]), delimiter=",", header="a1,a2,b1", comments="")
    readings = recorded_off_chain(path, chain)
    assert readings is not None and readings.names == ("b1",)
    keep, report = filter_candidates(chain, q, np.zeros((1, 3)), Constraints(), readings)
    assert keep.all() and "1 joints off the chain at each candidate's recorded" in report.notes[-1]
    keep, report = filter_candidates(chain, q, np.zeros((1, 3)), Constraints())
    assert not keep.any() and dict(report.rejected)["collision"] == 30
    argv = ["design", str(urdf), "--base", "base", "--tool", "tool", "--configs", "8"]
    from calib.cli.commands import main

    chosen = tmp_path / "chosen.csv"
    assert main([*argv, "--candidates-file", str(path), "--out", str(chosen)]) == 0
    out = capsys.readouterr().out
    assert "rejected: none of the" in out and "1 joints off the chain at each" in out
    written = np.loadtxt(chosen, delimiter=",", skiprows=1)  # each with its own b1
    rows = [int(np.flatnonzero(np.all(q == w[:2], axis=1))[0]) for w in written]
    assert chosen.read_text().startswith("a1,a2,b1\n") and np.array_equal(written[:, 2], b1[rows])
    np.savetxt(path, q, delimiter=",", header="a1,a2", comments="")  # no b1: at zero
    err = one_line_error(capsys, [*argv, "--candidates-file", str(path)])
    assert "collision rejects 30" in err
    with pytest.raises(InvalidArgumentError, match="JointReadings of the joints off a chain"):
        design(chain, 8, candidates=30, readings=readings)


TRIANGLE_STL = """solid t
facet normal 0 0 1
outer loop
vertex 0 0 0
vertex 0.01 0 0
vertex 0 0.01 0
endloop
endfacet
endsolid t
"""


def test_package_meshes_of_a_ros_package_layout_are_found(tmp_path, monkeypatch):
    """A user's description package, NAME/urdf/robot.urdf with package://NAME/meshes/...:
    the mesh is found without ROS_PACKAGE_PATH (it was looked up one and two folders up
    only, and the design refused the file)."""
    monkeypatch.delenv("ROS_PACKAGE_PATH", raising=False)
    package = tmp_path / "scara_description"
    (package / "urdf").mkdir(parents=True)
    (package / "meshes").mkdir()
    (package / "meshes" / "link1.stl").write_text(TRIANGLE_STL)
    mesh = '<collision><geometry><mesh filename="package://scara_description/meshes/link1.stl"/>'
    text = (Path(__file__).parent / "data" / "scara.urdf").read_text()
    urdf = package / "urdf" / "scara.urdf"
    urdf.write_text(
        text.replace(
            '<link name="link1"/>', f'<link name="link1">{mesh}</geometry></collision></link>'
        )
    )
    chain = calib.load_chain(urdf, "base_link", "tool0")
    geometry = _geometry(chain)
    assert [g.meshPath for g in geometry.geometryObjects] == [str(package / "meshes" / "link1.stl")]
    assert design(chain, 5).q.shape == (5, 4)
    (package / "meshes" / "link1.stl").unlink()
    with pytest.raises(URDFError, match="package:// is looked up in the URDF's folders"):
        design(chain, 5)


def test_a_joint_without_limit_tag_does_not_stop_the_collision_check(tmp_path):
    """A revolute or prismatic joint without <limit> (calib: no usable limits, sampled over
    a default range) made Pinocchio's geometry parser refuse the file: the design said
    "cannot load its collision geometry (Unable to parse URDF): check the mesh paths"."""
    text = (Path(__file__).parent / "data" / "scara.urdf").read_text()
    quill = '<limit lower="0" upper="0.2" effort="100" velocity="1"/>'
    shoulder = '<limit lower="-2.5" upper="2.5" effort="100" velocity="3"/>'
    box = '<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>'
    bare = text.replace(quill, "").replace(shoulder, "", 1)
    urdf = tmp_path / "scara_no_limits.urdf"
    urdf.write_text(bare.replace('<link name="link1"/>', f'<link name="link1">{box}</link>'))
    assert bare.count("<limit") == 2  # j2 and j4 keep theirs
    chain = calib.load_chain(urdf, "base_link", "tool0")
    assert [g.name for g in _geometry(chain).geometryObjects] == ["link1_0"]
    with pytest.warns(calib.DataWarning, match=r"for j1 \(drawn .*\), j3 \(drawn "):
        assert design(chain, 5, constraints=Constraints(collision=True)).q.shape == (5, 4)


SCARA = Path(__file__).parent / "data" / "scara.urdf"
QUILL_LIMIT = '<limit lower="0" upper="0.2" effort="100" velocity="1"/>'
DEFAULT_RANGE = (
    "no usable <limit> in the URDF for j3 (drawn in [-0.1, 0.1] m): calib's default "
    "range, which the robot may not reach (add the <limit>, or give your own {}"
)


def _default_range_said(draw) -> list[str]:
    """The ``<limit>`` warnings ``draw()`` gives (it must give a DataWarning)."""
    with pytest.warns(calib.DataWarning) as caught:
        draw()
    return [str(w.message) for w in caught if "<limit>" in str(w.message)]


def test_candidates_in_a_default_range_are_named(tmp_path):
    """A joint without usable URDF limits is drawn in calib's default range (a turn, +-0.1 m:
    conventions.md), which the robot may not reach: the design says which joints; not for
    limited or continuous joints, nor for candidates the user gives."""
    wrist = '<joint name="j4" type="revolute">'
    urdf = tmp_path / "scara_no_quill_limit.urdf"
    bare = SCARA.read_text().replace(QUILL_LIMIT, "")
    urdf.write_text(bare.replace(wrist, wrist.replace("revolute", "continuous")))
    chain = calib.load_chain(urdf, "base_link", "tool0")
    free = Constraints(collision=False)
    picked = []
    said = _default_range_said(lambda: picked.append(design(chain, 5, constraints=free)))
    assert said == [DEFAULT_RANGE.format("candidates)")]
    with warnings.catch_warnings():
        warnings.simplefilter("error", calib.DataWarning)
        design(calib.load_chain(SCARA, "base_link", "tool0"), 5, constraints=free)
        design(chain, 5, candidates=picked[0].q, constraints=free)


def test_simulated_configurations_in_a_default_range_are_named(tmp_path, capsys):
    """``simulate`` draws its random configurations as ``design`` draws candidates: the same
    warning names the joint without usable URDF limits (the range from conventions.md); not
    for configurations the user gives, nor for the limited SCARA; the CLI prints it once."""
    urdf = tmp_path / "scara_no_quill_limit.urdf"
    urdf.write_text(SCARA.read_text().replace(QUILL_LIMIT, ""))
    chain = calib.load_chain(urdf, "base_link", "tool0")
    drawn = []
    said = _default_range_said(lambda: drawn.append(calib.simulate(chain, 12, seed=3)))
    assert said == [DEFAULT_RANGE.format("configurations)")]
    with warnings.catch_warnings():
        warnings.simplefilter("error", calib.DataWarning)
        calib.simulate(calib.load_chain(SCARA, "base_link", "tool0"), 12, seed=3)
        calib.simulate(chain, drawn[0].measurements.q, seed=3)
    argv = ["simulate", str(urdf), "--tool", "tool0", "--configs", "12", "--out"]
    with warnings.catch_warnings():  # as the command line runs: warnings printed, not raised
        warnings.simplefilter("default")
        assert main([*argv, str(tmp_path / "sim.csv")]) == 0
    assert capsys.readouterr().err.count("no usable <limit> in the URDF for j3") == 1


def test_simulated_touches_in_a_default_range_are_named(tmp_path):
    """``simulate_contacts`` draws its touches and contacts at random postures as ``simulate``
    does: the same warning names the joint without usable URDF limits, with no other remedy
    than the ``<limit>`` (touches take no configurations); none for the limited SCARA."""
    urdf = tmp_path / "scara_no_quill_limit.urdf"
    urdf.write_text(SCARA.read_text().replace(QUILL_LIMIT, ""))
    chain = calib.load_chain(urdf, "base_link", "tool0")
    said = _default_range_said(lambda: calib.simulate_contacts(chain, 12, "fixed-point", seed=3))
    assert said == [
        "no usable <limit> in the URDF for j3 (drawn in [-0.1, 0.1] m): calib's default "
        "range, which the robot may not reach (add the <limit>)"
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("error", calib.DataWarning)
        limited = calib.load_chain(SCARA, "base_link", "tool0")
        calib.simulate_contacts(limited, 12, "fixed-point", seed=3)
