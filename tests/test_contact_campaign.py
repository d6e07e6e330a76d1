"""Contact campaigns: CSV with an id column and joints only; simulated touches on a true robot.

Independent route: the true robot is written as a URDF (calib's export) and its placements
come from Pinocchio; the gaps of the touches in the true planes and points are computed here
from their definitions.
"""

from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from test_contacts import pin_gap

from calib import DataError, InvalidArgumentError, from_chain, load_chain
from calib.cli.commands import main
from calib.kinematics.urdf_export import calibrated_urdf, measurement_to_base
from calib.measurements.contact_campaign import (
    contacts_csv,
    parse_contacts,
    read_contacts,
    simulate_contacts,
    write_contacts,
)
from calib.measurements.csvfile import DataWarning

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"


def true_placements(chain, true_mdh, q: np.ndarray) -> np.ndarray:
    """The true tool in the base frame, from Pinocchio on the true robot's URDF."""
    nominal = from_chain(chain)
    world = ("true_base", measurement_to_base(nominal, true_mdh))
    model = pin.buildModelFromXML(calibrated_urdf(chain, nominal, true_mdh, world=world).decode())
    data = model.createData()
    b, t = model.getFrameId("true_base"), model.getFrameId(chain.tool_frame)
    out = []
    for qi in q:
        qp = pin.neutral(model)
        for name, v in zip(chain.joint_names, qi, strict=True):
            qp[model.joints[model.getJointId(name)].idx_q] = v
        pin.framesForwardKinematics(model, data, qp)
        out.append(data.oMf[b].actInv(data.oMf[t]).homogeneous)
    return np.array(out)


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("ur5", "plane"),
        ("ur5", "plane-point"),
        ("ur5", "fixed-point"),
        ("panda", "plane"),
        ("panda", "fixed-point"),
        ("panda", "fixed-pose"),
    ],
)
def test_simulated_touches_hold_on_the_true_robot_and_round_trip(tmp_path, name, kind):
    chain = load_chain(name)
    camp = simulate_contacts(chain, 12, kind, contacts=2, seed=4)
    data, truth = camp.data, camp.truth
    assert data.m == 12 and len(data.contacts) == 2
    path = tmp_path / "touches.csv"
    write_contacts(path, data)
    back = read_contacts(path, chain, kind)
    np.testing.assert_array_equal(back.q, data.q)
    assert back.ids == data.ids
    assert np.all((data.q >= chain.lower - 1e-12) & (data.q <= chain.upper + 1e-12))
    T = true_placements(chain, truth.true_mdh, data.q)
    for i, contact in enumerate(data.ids):
        gap = pin_gap(kind, np.linalg.inv(truth.frames[contact]) @ T[i])
        assert np.abs(gap).max() < 1e-9
    # the nominal robot does not hold the contacts: the errors are there to find
    nominal = from_chain(chain).forward(data.q)
    worst = max(
        np.abs(pin_gap(kind, np.linalg.inv(truth.frames[c]) @ nominal[i])).max()
        for i, c in enumerate(data.ids)
    )
    assert worst > 1e-5


def test_seeded(tmp_path):
    chain = load_chain("ur5")
    a = simulate_contacts(chain, 6, "plane", seed=1).data
    b = simulate_contacts(chain, 6, "plane", seed=1).data
    np.testing.assert_array_equal(a.q, b.q)
    other = simulate_contacts(chain, 6, "plane", seed=2).data  # the seed is used, not ignored
    assert not np.allclose(a.q, other.q)


def _csv(header: str, row: str) -> str:
    return f"{header}\n{row}\n"


JOINTS = ",".join(load_chain("ur5").joint_names)  # ... wrist_3_joint last
ROW = "0.1,0.2,0.3,0.4,0.5,0.6"


@pytest.mark.parametrize(
    ("header", "row", "kind", "match"),
    [
        (f"plane,{JOINTS},x", f"t,{ROW},1.0", "plane", "no coordinates, found 'x'"),
        (f"plane,{JOINTS},qw", f"t,{ROW},1.0", "plane", "no coordinates"),
        (f"point,{JOINTS}", f"p,{ROW}", "plane", "needs a 'plane' column: it names points"),
        (f"plane,{JOINTS}", f"t,{ROW}", "fixed-point", "needs a 'point' column: it names planes"),
        (f"plane,point,{JOINTS}", f"t,p,{ROW}", "plane", "both 'plane' and 'point'"),
        (f"plane,{JOINTS[:-14]}", f"t,{ROW[:-4]}", "plane", "no column for joint wrist_3_joint"),
        (f"plane,{JOINTS}", f",{ROW}", "plane", "empty id"),
        (f"plane,{JOINTS}", f"t,{ROW[:-4]},abc", "plane", "not a number"),
        # the header and the rows' lengths checked as every calib CSV's (csv_text.csv_table)
        (f"plane,{JOINTS},,spot", f"t,{ROW},,s1", "plane", r"\(row 1\): header cell 8 is empty"),
        (f"plane,{JOINTS},spot,spot", f"t,{ROW},a,b", "plane", r"column 'spot'.*duplicate column"),
        (f"plane,{JOINTS}", f"t,{ROW},0.7", "plane", r"\(row 2\): expected 7 cells, found 8"),
        (f"plane,{JOINTS}", "", "plane", "no touches after the header"),
    ],
)
def test_bad_contact_files(header, row, kind, match):
    with pytest.raises(DataError, match=match):
        parse_contacts(_csv(header, row), load_chain("ur5"), kind, "f.csv")


def test_a_kind_that_is_no_contact_is_refused():
    with pytest.raises(InvalidArgumentError, match="not a contact"):
        parse_contacts(_csv(f"plane,{JOINTS}", f"t,{ROW}"), load_chain("ur5"), "pose")


def test_a_chain_through_a_leg_the_file_does_not_record_is_named_with_its_frames():
    """The left arm's touches read from the right sole, in a file without the right leg's
    columns: "no column for joint leg_right_6_joint of the chain" named neither the chain
    nor what chose that joint."""
    lines = [line.split(",") for line in (REAL / "left_train.csv").read_text().splitlines()]
    kept = [k for k, name in enumerate(lines[0]) if not name.startswith("leg_right_")]
    text = "\n".join(",".join(line[k] for k in kept) for line in lines)
    chain = load_chain("talos_full_v2.urdf", "right_sole_link", "gripper_left_base_link")
    with pytest.raises(DataError, match="leg_right_6_joint") as caught:
        parse_contacts(text, chain, "plane", "left.csv")
    assert str(caught.value).endswith(
        "of the chain right_sole_link -> gripper_left_base_link (its base and tool frames "
        "choose the joints read)"
    )


def test_the_real_talos_file_reads_with_one_note():
    chain = load_chain("talos_left_arm_full")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = read_contacts(REAL / "left_train.csv", chain, "plane")
    notes = [w for w in caught if issubclass(w.category, DataWarning)]
    assert len(notes) == 1 and "1 ignored (spot)" in str(notes[0].message)
    assert data.m == 21 and data.contacts == ("table",)
    assert data.joint_names == chain.joint_names
    # the other joints' readings: the header's URDF joints off the chain, as the file has them
    with open(REAL / "left_train.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    urdf = set(chain.model.names)
    others = [c for c in rows[0] if c in urdf and c not in chain.joint_names]
    assert data.readings is not None and data.readings.names == tuple(others)
    assert f"{len(others)} other joints" in str(notes[0].message)
    want = np.array([[float(r[c]) for c in others] for r in rows])
    assert np.array_equal(data.readings.values, want)
    again = parse_contacts(contacts_csv(data), chain, "plane")
    assert again.readings.names == data.readings.names
    assert np.array_equal(again.readings.values, data.readings.values)
    # a reading that is not a number: that column is left out with a note, not an error
    lines = [line.split(",") for line in contacts_csv(data).splitlines()]
    lines[4][lines[0].index(others[2])] = "up"
    with pytest.warns(DataWarning, match=others[2]):
        bad = parse_contacts("\n".join(",".join(c) for c in lines), chain, "plane")
    assert bad.readings.names == tuple(o for o in others if o != others[2])
    assert np.array_equal(bad.q, data.q)


def test_cli_simulate_contacts(tmp_path, capsys):
    out = tmp_path / "c.csv"
    args = ["simulate", "panda", "--measure", "fixed-point", "--configs", "8", "--out", str(out)]
    assert main([*args, "--contacts", "2", "--seed", "3"]) == 0
    header = out.read_text().splitlines()[0].split(",")
    assert header == ["point", *load_chain("panda").joint_names]
    truth = json.loads(out.with_suffix(".truth.json").read_text())
    assert set(truth["points"]) == {"point1", "point2"} and truth["measure"] == "fixed-point"
    assert "8 touches" in capsys.readouterr().out
    bad = tmp_path / "d.csv"
    argv = ["simulate", "panda", "--measure", "plane", "--marker", "0", "0", "1", "--out", str(bad)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "--marker is for measured campaigns" in err and "Traceback" not in err
    assert not bad.exists()


def test_fixed_pose_truth_names_its_objects_poses_as_the_report(tmp_path):
    out = tmp_path / "c.csv"
    args = ["simulate", "panda", "--measure", "fixed-pose", "--configs", "6", "--out", str(out)]
    assert main([*args, "--seed", "1"]) == 0
    truth = json.loads(out.with_suffix(".truth.json").read_text())
    assert set(truth["poses"]) == {"point1"} and truth["points"] == truth["poses"]
    assert set(truth["deprecated"]) == {"points"}
    T = np.array(truth["poses"]["point1"])
    assert T.shape == (4, 4) and np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-12)


def test_configurations_missing_some_readings_say_so(tmp_path):
    """calib predict's reader of the other joints: a column the fit read but the file lacks
    is named in a warning (it stays at neutral); none at all is the model's own warning."""
    from calib.design.configurations import read_readings

    path = tmp_path / "c.csv"
    path.write_text("a,head_1_joint,arm_left_1_joint\n1,0.25,-0.5\n2,0.125,0.75\n")
    names = ("head_1_joint", "arm_left_1_joint", "leg_left_4_joint")
    with pytest.warns(DataWarning, match="no column for 1 of the 3 joints.*leg_left_4_joint"):
        got = read_readings(path, names)
    assert got.names == names[:2]
    assert np.array_equal(got.values, [[0.25, -0.5], [0.125, 0.75]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_readings(path, ("leg_left_4_joint",)) is None


def test_repeated_touches_are_warned_about_as_repeated_configurations():
    """A touch of the same object at the same joints as an earlier one is a warning (as a
    measurement CSV's repeated row): not independent, the uncertainty overconfident. The same
    joints on another plane are two touches."""
    text = f"plane,{JOINTS}\nt,{ROW}\nu,{ROW}\nt,0.2,0.2,0.3,0.4,0.5,0.6\nt,{ROW}\n"
    with pytest.warns(DataWarning, match=r"1 of 4 touches repeat .* \(first: row 5\)"):
        parse_contacts(text, load_chain("ur5"), "plane", "t.csv")


@pytest.mark.parametrize("keep", [[5, 2, 9], np.arange(21) % 4 == 1])
def test_a_subset_of_touches_is_the_file_of_those_lines(keep):
    """``ContactData.subset`` (indices in their order, or a mask), as ``Measurements.subset``:
    the touches, ids, file rows and other joints' readings of a file holding only those lines."""
    chain = load_chain("talos_left_arm_full")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = read_contacts(REAL / "left_train.csv", chain, "plane")
        lines = (REAL / "left_train.csv").read_text().splitlines()
        picked = np.arange(data.m)[keep]
        text = "\n".join([lines[0], *(lines[data.rows[i] - 1] for i in picked)])
        want = parse_contacts(text, chain, "plane")
    sub = data.subset(keep)
    assert sub.m == len(picked) and np.array_equal(sub.q, want.q) and sub.ids == want.ids
    assert sub.rows == tuple(data.rows[i] for i in picked)
    assert np.array_equal(sub.readings.values, want.readings.values)
    assert sub.readings.names == want.readings.names and sub.source == data.source
