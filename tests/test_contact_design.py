"""calib design with contact kinds: every designed posture holds the contact (Pinocchio on the
URDF, the gap written here from the kind's definition), within the joint limits, and the
design identifies as many parameters as calib analyze counts for the contact."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from pinref import PathRef
from test_contacts import pin_gap

import calib
from calib import InvalidArgumentError, analyze, load_chain
from calib.cli.commands import main
from calib.design.configurations import read_configurations
from calib.design.constraints import Constraints
from calib.design.design import design, evaluate
from calib.kinematics.tree import load_tree

ROOT = Path(__file__).resolve().parents[1]

CASES = (
    pytest.param("ur5", None, None, "plane", id="ur5-plane"),
    pytest.param("panda", None, None, "fixed-point", id="panda-fixed-point"),
    pytest.param("talos", "left_sole_link", "gripper_left_base_link", "plane", id="talos-hand"),
    pytest.param("talos", "left_sole_link", "gripper_left_base_link", "plane-point", id="talos-pp"),
    pytest.param("talos", "left_sole_link", "right_sole_link", "fixed-pose", id="talos-feet"),
)


def gaps(chain, frame: np.ndarray, kind: str, q: np.ndarray) -> np.ndarray:
    """The gap of every posture in the contact's frame, from Pinocchio's placements."""
    ref = PathRef(chain.urdf_path, chain.base_frame, chain.tool_frame)
    T = np.linalg.inv(frame) @ ref.placements(chain.joint_names, q)
    return np.array([pin_gap(kind, t) for t in T])


@pytest.mark.parametrize(("robot", "base", "tool", "kind"), CASES)
def test_designed_postures_hold_the_contact_and_identify_analyzes_count(robot, base, tool, kind):
    chain = load_chain(robot, base, tool)
    k = 70 if kind == "plane-point" else 30
    d = design(
        chain,
        k,
        candidates=300,
        measure=kind,
        constraints=Constraints(collision=False),
        seed=3,
        random_sets=3,
    )
    assert d.q.shape == (k, chain.n) and d.contact is not None
    assert np.abs(gaps(chain, d.contact, kind, d.q)).max() < 1e-9
    assert np.all((d.q >= chain.lower - 1e-12) & (d.q <= chain.upper + 1e-12))
    if kind == "plane":
        ref = PathRef(chain.urdf_path, chain.base_frame, chain.tool_frame)
        T = np.linalg.inv(d.contact) @ ref.placements(chain.joint_names, d.q)
        assert (T[:, 2, 2] > 0.99).all()  # flush, not upside down
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        count = analyze(robot, base, tool, kind, params="complete").n_base
    assert d.model.b == count
    assert d.indices.rank == count  # the chosen postures identify all of them
    assert d.indices.value("D") >= d.random_median("D")


def test_cli_design_plane_from_the_foot(tmp_path, capsys):
    base, tool = "left_sole_link", "gripper_left_base_link"
    out = tmp_path / "touches.csv"
    argv = ["design", "talos", "--base", base, "--tool", tool, "--measure", "plane"]
    argv += ["--configs", "30", "--candidates", "300", "--no-collision", "--seed", "1"]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    chain = load_chain("talos", base, tool)
    q = read_configurations(out, chain)
    assert q.shape == (30, chain.n)
    assert np.abs(gaps(chain, np.array(result["contact"]), "plane", q)).max() < 1e-9
    assert result["design"]["rank"] == result["design"]["parameters"] == 58


def test_contact_design_errors(tmp_path, capsys):
    chain = load_chain("ur5")
    with pytest.raises(InvalidArgumentError, match="measures no point"):
        design(chain, 10, measure="plane", marker=(0.0, 0.0, 0.1))
    with pytest.raises(InvalidArgumentError, match="complete model"):
        design(chain, 10, measure="plane", params="joints")
    tree = load_tree("talos", None, ["gripper_left_base_link", "gripper_right_base_link"])
    with pytest.raises(InvalidArgumentError, match="one chain"):
        design(tree, 10, measure="plane")
    out = tmp_path / "c.csv"
    argv = ["design", "ur5", "--measure", "plane", "--configs", "5", "--marker", "0", "0", "1"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "measures no point" in err and "Traceback" not in err and not out.exists()


def test_contact_design_options_it_refuses_name_the_way_out(tmp_path, capsys):
    """A user's table touches given to --evaluate: "unknown measure 'plane'" said neither
    that --evaluate does not score contacts nor how to choose postures (calib.design's
    evaluate names the Python call); --params offsets: "use params complete"."""
    touches = ROOT / "data" / "realdata" / "talos_contact" / "left_train.csv"
    argv = ["design", "talos_full_v2.urdf", "--base", "left_sole_link", "--tool"]
    argv += ["gripper_left_base_link", "--measure", "plane"]
    assert main([*argv, "--evaluate", str(touches)]) == 2
    err = capsys.readouterr().err
    assert "unknown measure" not in err and len(err.strip().splitlines()) == 1
    assert "not yet touches (--measure plane): --configs K chooses" in err
    chain = load_chain("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
    with pytest.raises(InvalidArgumentError, match=r"calib\.design\(chain, K, measure='plane'\)"):
        evaluate(chain, np.zeros((5, chain.n)), "plane")
    out = tmp_path / "c.csv"
    assert main([*argv, "--configs", "30", "--params", "offsets", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "use params='complete' (the default)" in err and not out.exists()


@pytest.mark.parametrize(("arm", "touches", "colliding"), [("left", 21, 15), ("right", 29, 19)])
def test_recorded_touches_are_checked_for_collisions_as_recorded(arm, touches, colliding):
    """TALOS's recorded table touches as a contact design's candidates: the collision check
    held the joints off the chain at zero (the other arm in the base link, the other leg in
    the moved one) and rejected most of them; at the file's recorded joints, none."""
    from calib.design.configurations import recorded_off_chain

    path = ROOT / "data" / "realdata" / "talos_contact" / f"{arm}_train.csv"
    chain = load_chain("talos_full_v2.urdf", f"{arm}_sole_link", f"gripper_{arm}_base_link")
    q = read_configurations(path, chain)
    readings = recorded_off_chain(path, chain)
    assert len(q) == touches and len(readings.names) == 17  # the other arm and leg, the head
    with pytest.raises(InvalidArgumentError, match=f"collision rejects {colliding}"):
        design(chain, touches, candidates=q, measure="plane", random_sets=1)
    got = design(chain, touches, candidates=q, measure="plane", random_sets=1, readings=readings)
    assert len(got.q) == touches and dict(got.filters.rejected)["collision"] == 0
    assert got.readings.names == readings.names and len(got.readings.values) == touches


def test_too_few_postures_of_candidates_that_identify_everything_ask_for_more(capsys):
    """TALOS's left hand on a plane, 24 postures: "a joint that never moves, or too few
    distinct candidates?", while the candidates together identify the 58 parameters and 30
    postures are designed."""
    argv = ["design", "talos", "--base", "left_sole_link", "--tool", "gripper_left_base_link"]
    argv += ["--measure", "plane", "--candidates", "300", "--no-collision", "--seed", "1"]
    assert main([*argv, "--configs", "24"]) == 2
    err = capsys.readouterr().err
    assert "do not identify the 58 parameters with 24 configurations" in err
    assert "(all 300 together do: choose more configurations)" in err
    assert main([*argv, "--configs", "30"]) == 0


def test_a_numerically_singular_newton_system_takes_the_least_norm_step():
    """Rows so large that the damping is lost in round-off (near the flipped side): the
    step is the least-norm one (numpy's lstsq), not a LinAlgError; a UR5 plane design
    that met one completes."""
    from calib.identification.contact_postures import _newton_step

    J = np.array([[[1e9, 0.0, 0.0], [1e9, 0.0, 0.0]]])  # two equal rows: J J^T singular
    gap = np.array([[2e9, 2e9]])
    expected = -np.linalg.lstsq(J[0], gap[0], rcond=None)[0]
    assert np.allclose(_newton_step(J, gap)[0], expected, rtol=1e-9, atol=0)
    d = design(load_chain("ur5"), 20, candidates=300, measure="plane")
    assert len(d.q) == 20
