"""Objects given: ``simulate_contacts(objects=)`` / ``simulate --plane`` and ``known_planes``
/ ``calibrate --known-plane``: the touches on them (Pinocchio), the count, one-line errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
from contact_scorer import contact_gaps, read_joints

import calib
from calib.cli.commands import main
from calib.exceptions import DataError, InvalidArgumentError
from calib.kinematics.mdh import from_chain
from calib.measurements.contact_campaign import simulate_contacts, write_contacts

pytestmark = pytest.mark.filterwarnings("ignore")

FLOOR = {"floor": (0.0, 0.0, 0.0, 0.0, 0.0, 1.0)}


@pytest.fixture(scope="module")
def feet():
    """Both TALOS soles on the floor, the left sole's plane: 40 touches, noise-free."""
    chain = calib.load_chain("talos", "left_sole_link", "right_sole_link")
    return chain, simulate_contacts(chain, 40, "plane", objects=FLOOR, seed=2).data


@pytest.mark.parametrize(
    ("kind", "given"),
    [
        ("plane", (0.4, 0.1, 0.2, 0.3, 0.1, 1.0)),
        ("plane-point", (0.4, 0.1, 0.2, 0.0, 0.3, 1.0)),
        ("fixed-point", (0.4, 0.1, 0.3)),
        ("fixed-pose", None),
    ],
)
def test_touches_are_on_the_objects_given(tmp_path, kind, given):
    """Without errors or noise, the nominal URDF's contact frame is on each object given
    (Pinocchio), which the truth records."""
    chain = calib.load_chain("ur5")
    if given is None:  # a pose: the tool's at a posture of the nominal robot
        given = from_chain(chain).forward(chain.random_configurations(1, 4))[0]
    campaign = simulate_contacts(
        chain, 12, kind, objects={"spot": given}, error_mm=0, error_mrad=0, seed=3
    )
    frame = campaign.truth.frames["spot"]
    if len(np.shape(given)) == 1:
        assert np.allclose(frame[:3, 3], given[:3])
        if len(given) == 6:
            assert np.allclose(frame[:3, 2], np.divide(given[3:], np.linalg.norm(given[3:])))
    write_contacts(tmp_path / "t.csv", campaign.data)
    ids, joints = read_joints(tmp_path / "t.csv")
    gaps = contact_gaps(
        kind, chain.urdf_path, chain.base_frame, chain.tool_frame, np.eye(4), [frame] * 12, joints
    )
    assert set(ids) == {"spot"} and np.abs(gaps).max() < 1e-9


@pytest.mark.parametrize(
    ("objects", "message"),
    [
        ({"floor": (0, 0, -1, 0, 0, 0)}, "its normal is zero"),
        ({"floor": (0, 0, np.nan, 0, 0, 1)}, "must be finite"),
        ({"floor": (0, 0, -1000, 0, 0, 1)}, "1000 m from the base frame"),
        ({"floor": (0, 0, -3, 0, 0, 1)}, "only 0 of .* reach"),
        ({"floor": np.diag([1.0, 1.0, 2.0, 1.0])}, "not a rigid frame"),
        ({"floor": (0, 0, 1)}, "a point and a normal"),
        ({}, "by name"),
        ({"floor": (0, 0, -1, 0, 0, 1), "wall": (0, 0, -1, 0, 0, 1)}, "^contacts=3 for 2 objects"),
        ({"floor": (0, 0, -1, 0, 0, 1)}, "^contacts=3 for 1 object given: give as many objects"),
    ],
)
def test_bad_objects_are_one_line_errors(objects, message):
    chain = calib.load_chain("talos", "torso_2_link", "left_sole_link")
    with pytest.raises(InvalidArgumentError, match=message) as error:
        simulate_contacts(
            chain, 10, "plane", contacts=3 if "=3" in message else 1, objects=objects, seed=1
        )
    assert "\n" not in str(error.value)


def test_a_known_plane_is_held_and_counted(feet):
    """The plane's 3 unknowns leave, the contact frame's height comes: 2 fewer unknowns; the
    report's plane is the one given."""
    chain, touches = feet
    counts = [
        calib.analyze(calib.Problem((calib.Term(chain, touches),), known_planes=k)).n_unknowns
        for k in (None, FLOOR)
    ]
    assert counts[1] == counts[0] - 3 + 1
    result = calib.calibrate(chain, touches, known_planes=FLOOR)
    plane = result.to_dict()["objects"]["planes"]["floor"]["matrix"]
    assert np.allclose(np.array(plane)[:3, 2], [0, 0, 1]) and abs(plane[2][3]) < 1e-12
    assert any("'floor' given: held" in n for n in result.notes)


@pytest.mark.parametrize(
    ("planes", "error", "message"),
    [
        ({"floor": (0, 0, 0, 0, 0, 0)}, InvalidArgumentError, "normal is zero"),
        ({"floor": (0, np.nan, 0, 0, 0, 1)}, InvalidArgumentError, "finite"),
        ({"table": (0, 0, 0, 0, 0, 1)}, InvalidArgumentError, "no plane or plane-point term"),
        ({"floor": (0, 0, 0.2, 0, 0, 1)}, DataError, r"0\.199 m and .* from where it is given"),
        ({"floor": (0, 0, 0, 0, 0, -1)}, DataError, "180 deg"),
    ],
)
def test_bad_known_planes_are_one_line_errors(feet, planes, error, message):
    chain, touches = feet
    with pytest.raises(error, match=message) as raised:
        calib.calibrate(chain, touches, known_planes=planes)
    assert "\n" not in str(raised.value)


def test_known_planes_apply_to_touches_only(feet):
    arm = calib.load_chain("ur5")
    rows = calib.simulate(arm, 30, seed=1).measurements
    with pytest.raises(InvalidArgumentError, match="known_planes is for contact kinds"):
        calib.calibrate(arm, rows, known_planes=FLOOR)


def test_a_term_touching_planes_given_and_not_is_refused(feet):
    chain, touches = feet
    ids = tuple("floor" if k % 2 else "step" for k in range(touches.m))
    mixed = type(touches)(touches.joint_names, touches.q, ids, touches.kind)
    with pytest.raises(InvalidArgumentError, match="give every plane of a term, or none"):
        calib.Problem((calib.Term(chain, mixed),), known_planes=FLOOR)


def test_a_shared_plane_given_is_said_held_not_fitted():
    """Both soles on one floor, shared: fitted once; the same floor given: held (its frame
    is the one given), never "fitted"."""
    urdf = calib.load_chain("talos_left_leg").urdf_path
    floor = {"floor": (0.0, 0.0, -1.105, 0.0, 0.0, 1.0)}
    legs = [calib.load_chain(urdf, "torso_2_link", f"{s}_sole_link") for s in ("left", "right")]
    terms = tuple(
        calib.Term(leg, simulate_contacts(leg, 40, "plane", objects=floor, seed=10 + k).data)
        for k, leg in enumerate(legs)
    )
    shared = [
        [n for n in calib.calibrate(problem).notes if "several chains" in n]
        for problem in (
            calib.Problem(terms, shared_planes=True, params="complete"),
            calib.Problem(terms, shared_planes=True, params="complete", known_planes=floor),
        )
    ]
    assert shared[0] == ["a plane touched by several chains is fitted once (shared planes)"]
    assert len(shared[1]) == 1 and "given: held" in shared[1][0]
    assert "fitted" not in shared[1][0]


def test_command_lines(tmp_path, capsys, monkeypatch):
    """``simulate --plane`` writes touches of the plane named; ``calibrate --known-plane``
    holds it (the report's plane is the one given); bad values are one-line errors."""
    monkeypatch.chdir(tmp_path)
    feet = ["talos", "--base", "left_sole_link", "--tool", "right_sole_link", "--measure", "plane"]
    floor = ["floor", "0", "0", "0", "0", "0", "1"]
    code = main(["simulate", *feet, "--plane", *floor, "--configs", "40", "--out", "t.csv"])
    assert code == 0 and "1 plane" in capsys.readouterr().out
    assert json.loads((tmp_path / "t.truth.json").read_text())["planes"]["floor"][2][3] == 0.0
    argv = ["calibrate", *feet, "--data", "t.csv", "--out", "c.urdf", "--report", "c.json"]
    assert main([*argv, "--known-plane", *floor]) == 0
    report = json.loads((tmp_path / "c.json").read_text())
    assert abs(report["objects"]["planes"]["floor"]["matrix"][2][3]) < 1e-12
    assert "'floor' given: held" in capsys.readouterr().out
    for extra, said in (
        (["--known-plane", "floor", "0", "0", "x", "0", "0", "1"], "NAME X Y Z NX NY NZ"),
        (["--known-plane", *floor, "--known-plane", *floor], "names plane 'floor' twice"),
    ):
        assert main([*argv, *extra]) == 2
        assert said in capsys.readouterr().err
    bad = ["simulate", *feet, "--out", "u.csv", "--plane", "floor", "0", "0", "0", "0", "0", "0"]
    assert main(bad) == 2 and "its normal is zero" in capsys.readouterr().err
    two = ["simulate", *feet, "--out", "u.csv", "--plane", *floor, "--contacts", "2"]
    said = "--contacts 2 for 1 plane given (--plane): give as many --plane, or leave --contacts out"
    assert main(two) == 2 and said in capsys.readouterr().err
