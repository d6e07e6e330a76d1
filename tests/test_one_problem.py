"""The guarantees a measured chain had, for every shape and kind (one set of checks).

Validation data that are the training data (the same file, a copy of it, or some of its
rows) are refused for measured chains, trees, every contact kind and several chains; a
held-out orientation that gets worse refuses a pose calibration as a held-out position does.
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from calib import DataError, DataWarning, calibrate, load_chain, load_robot, simulate
from calib.calibration.contact_checks import held_out_refusal
from calib.calibration.contact_result import GapStats
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.entry import calibrate_contacts
from calib.cli.commands import main
from calib.measurements.contact_campaign import simulate_contacts, write_contacts
from calib.measurements.tree_campaign import simulate_tree

TALOS = "talos_full_v2.urdf"
LEFT = ("left_sole_link", "gripper_left_base_link")
RIGHT = ("right_sole_link", "gripper_right_base_link")


@pytest.mark.parametrize("kind", ["plane", "plane-point", "fixed-point", "fixed-pose"])
def test_contact_validation_that_is_the_data_is_refused(kind, tmp_path, capsys):
    """The data file itself, a copy of it, and a file holding some of its touches."""
    chain = load_robot(TALOS, *LEFT)
    data = simulate_contacts(chain, 30, kind, seed=3).data
    train = tmp_path / "touches.csv"
    write_contacts(train, data)
    copy = tmp_path / "copy.csv"
    shutil.copy(train, copy)
    some = tmp_path / "some.csv"
    write_contacts(some, data.subset(np.arange(30) < 5))
    frames = ["--base", LEFT[0], "--tool", LEFT[1], "--measure", kind]
    for check in (train, copy, some):
        out = tmp_path / "cal.urdf"
        code = main(
            [
                "calibrate",
                TALOS,
                *frames,
                "--data",
                str(train),
                "--validate",
                str(check),
                "--out",
                str(out),
            ]
        )
        err = capsys.readouterr().err
        assert code != 0 and not out.exists()
        assert "held out must mean held out" in err and "Traceback" not in err
        assert len(err.strip().splitlines()) == 1


def test_several_chains_validation_that_is_the_data_is_refused():
    chains = [load_robot(TALOS, *pair) for pair in (LEFT, RIGHT)]
    data = [simulate_contacts(c, 20, "plane", seed=4).data for c in chains]
    other = simulate_contacts(chains[1], 20, "plane", seed=9).data
    with pytest.raises(DataError, match="held out must mean held out"):
        calibrate_contact_chains(chains, data, validate=[data[0], other])


def test_api_contact_validation_rows_of_the_data_are_refused():
    chain = load_robot(TALOS, *LEFT)
    data = simulate_contacts(chain, 30, "plane", seed=3).data
    with pytest.raises(DataError, match="validation rows are rows of the data"):
        calibrate_contacts(
            chain, data, validate=data.subset((np.arange(30) >= 3) & (np.arange(30) < 9))
        )


def test_tree_and_chain_validation_rows_of_the_data_are_refused():
    tree = load_robot("talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"])
    camp = simulate_tree(tree, 30, noise_mm=0.05, seed=2)
    with pytest.raises(DataError, match="held out must mean held out"):
        calibrate(tree, camp.measurements, validate=camp.measurements)
    chain = load_chain("ur5")
    data = simulate(chain, 30, seed=1, measure="pose").measurements
    with pytest.raises(DataError, match="held out must mean held out"):
        calibrate(chain, data, validate=data)


def test_validation_rows_at_postures_of_the_data_are_warned():
    """A random campaign and a noise-free check campaign of one seed share their first
    configurations (the same draws): no row is a copy, but the check scores seen postures."""
    chain = load_chain("ur5")
    data = simulate(chain, 30, seed=1, noise_mm=0.05).measurements
    check = simulate(chain, 60, seed=1).measurements
    assert np.array_equal(data.q, check.q[:30])  # the shared draws
    assert not np.allclose(data.position, check.position[:30], atol=1e-6, rtol=0)  # the noise
    with pytest.warns(DataWarning, match="30 of the 60 validation rows are at postures of"):
        calibrate(chain, data, validate=check)
    unseen = check.subset(np.arange(60) >= 30)
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        calibrate(chain, data, validate=unseen)


def test_held_out_orientation_worse_refuses_a_pose_calibration():
    """Positions better, orientations worse on held-out rows: refused, as the held-out rule
    weighs the angle rows (one refusal rule over position and orientation); the same
    positions with orientations as good pass."""
    chain = load_chain("ur5")

    def held(pos_mm: float, rot_deg: float) -> GapStats:  # weight 1 m/rad: 1 mrad is 1 mm
        weighted = math.hypot(pos_mm, 1e3 * math.radians(rot_deg))
        return GapStats(
            10, ("xyz", "rot"), (False, True), (pos_mm, rot_deg), (pos_mm, rot_deg), weighted
        )

    worse = {"held_out_registration": held(3.0, 0.1), "held_out": held(2.0, 0.3)}
    why = held_out_refusal(worse, chain, "errors")
    assert why is not None and "worse than the registration's" in why
    assert "(5.605 > 3.471 mm weighted RMS)" in why  # hypot(2, 5.236) and hypot(3, 1.745)
    good = {"held_out_registration": held(3.0, 0.1), "held_out": held(2.0, 0.1)}
    assert held_out_refusal(good, chain, "errors") is None


REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"


def test_several_chains_refuse_another_arms_file_as_validation(tmp_path, capsys):
    """The right arm's touches given as the left arm's validation: the registration misses
    them by half a metre while it fits the data: one line, no file (was accepted)."""
    out = tmp_path / "cal.urdf"
    code = main(
        [
            "calibrate",
            TALOS,
            "--measure",
            "plane",
            "--contact",
            "0",
            "0",
            "-0.12",
            "--chain",
            *LEFT,
            str(REAL / "left_train.csv"),
            str(REAL / "right_train.csv"),
            "--chain",
            LEFT[0],
            RIGHT[1],
            str(REAL / "right_train.csv"),
            "--out",
            str(out),
        ]
    )
    err = capsys.readouterr().err
    assert code != 0 and not out.exists()
    lines = [line for line in err.splitlines() if "warning" not in line]
    assert len(lines) == 1 and "another robot" in lines[0] and "Traceback" not in err


@pytest.mark.parametrize("shape", ["contacts", "chains"])
def test_warnings_printed_on_the_way_are_in_every_report(shape, tmp_path, capsys):
    """The data's warnings (columns off the chain) go into the report, as for a chain."""
    report = tmp_path / "r.json"
    args = ["calibrate", TALOS, "--measure", "plane", "--contact", "0", "0", "-0.12"]
    if shape == "contacts":
        args += ["--base", LEFT[0], "--tool", LEFT[1], "--data", str(REAL / "left_train.csv")]
    else:
        args += [
            "--chain",
            *LEFT,
            str(REAL / "left_train.csv"),
            "--chain",
            LEFT[0],
            RIGHT[1],
            str(REAL / "right_train.csv"),
        ]
    code = main(
        [*args, "--params", "frames", "--out", str(tmp_path / "c.urdf"), "--report", str(report)]
    )
    err = capsys.readouterr().err
    assert code == 0, err
    doc = json.loads(report.read_text())
    assert any("columns not on the chain" in w for w in doc["warnings"]), doc["warnings"]
    assert "columns not on the chain" in err


@pytest.mark.parametrize(
    ("extra", "flag", "shape"),
    [
        (["--units", "mm"], "--units", "contact kinds"),
        (["--orientation", "rpy"], "--orientation", "contact kinds"),
        (["--world-link", "w"], "--world-link", "contact kinds"),
        (["--shared-planes"], "--shared-planes", "contact kinds"),
    ],
)
def test_an_option_that_does_not_apply_is_an_error_for_contacts(extra, flag, shape, capsys):
    """Options a shape ignores were silently ignored for contacts (``--units``)."""
    data = str(REAL / "left_train.csv")
    args = [
        "calibrate",
        TALOS,
        "--base",
        LEFT[0],
        "--tool",
        LEFT[1],
        "--measure",
        "plane",
        "--data",
        data,
        "--out",
        "/nonexistent/c.urdf",
        *extra,
    ]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith(f"calib: error: {flag} is for ")
    assert err.endswith(f"not {shape} (--measure plane|plane-point|fixed-point|fixed-pose)")


@pytest.mark.parametrize("extra", [["--units", "mm"], ["--orientation", "rpy"], ["--elastic"]])
def test_an_option_that_does_not_apply_is_an_error_for_several_chains(extra, capsys):
    args = [
        "calibrate",
        TALOS,
        "--measure",
        "plane",
        "--chain",
        *LEFT,
        str(REAL / "left_train.csv"),
        "--chain",
        LEFT[0],
        RIGHT[1],
        str(REAL / "right_train.csv"),
        "--out",
        "/nonexistent/c.urdf",
        *extra,
    ]
    assert main(args) == 2
    assert "not several terms in one fit" in capsys.readouterr().err


@pytest.mark.parametrize("free", [["--elastic"], ["--free", "c2"]])
def test_compliance_on_a_urdf_without_masses_is_an_error(free, tmp_path, capsys):
    """It was silently not fitted (no gravity torque, no compliance column)."""
    urdf = str(Path(__file__).parent / "data" / "negative_axes.urdf")
    data = tmp_path / "m.csv"
    assert main(["simulate", urdf, "--measure", "position", "--out", str(data)]) == 0
    out = tmp_path / "c.urdf"
    assert main(["calibrate", urdf, "--data", str(data), "--out", str(out), *free]) == 2
    err = capsys.readouterr().err
    assert "needs gravity torques" in err and not out.exists()


def test_a_tool_link_carried_by_a_revolute_joint_is_written(tmp_path, capsys):
    """The UR10 data's own chain, ``universe -> wrist_3_link`` (no flange link): the
    calibrated tool (measured frame) is written as ``wrist_3_link_calibrated`` fixed to the
    tool link; Pinocchio on the written file reproduces the report's held-out errors."""
    import pinocchio as pin

    ur10 = Path(__file__).resolve().parents[1] / "data" / "realdata" / "ur10"
    urdf, data = ur10 / "ur10_robot.urdf", ur10 / "calibration.csv"
    out, report = tmp_path / "cal.urdf", tmp_path / "r.json"
    code = main(
        [
            "calibrate",
            str(urdf),
            "--base",
            "universe",
            "--tool",
            "wrist_3_link",
            "--data",
            str(data),
            "--orientation",
            "rpy",
            "--orientation-columns",
            "phix1",
            "phiy1",
            "phiz1",
            "--holdout",
            "0.3",
            "--params",
            "offsets",
            "--out",
            str(out),
            "--report",
            str(report),
        ]
    )
    assert code == 0, capsys.readouterr().err
    doc = json.loads(report.read_text())
    assert doc["frames"]["tool_link"] == "wrist_3_link_calibrated"
    # Independent route: the held-out rows, re-read with the csv module, scored by Pinocchio.
    import csv

    from calib.calibration.validation import split  # the same seeded rows the fit held out
    from calib.measurements.csvfile import Columns, read_measurements

    chain = load_chain(urdf, "universe", "wrist_3_link")
    measured = read_measurements(data, chain, Columns("rpy", ("phix1", "phiy1", "phiz1")))
    _, held = split(measured, 0.3, 0)
    rows = list(csv.DictReader(data.open()))
    model = pin.buildModelFromUrdf(str(out))
    pdata = model.createData()
    M = np.array(doc["frames"]["measurement"]["matrix"])
    marker = np.array(doc["frames"]["markers"]["wrist_3_link_marker1"])
    errors = []
    for i, r in enumerate(held.rows):
        row = rows[r - 2]
        q = np.array([float(row[j]) for j in chain.joint_names])
        assert np.allclose(q, held.q[i])
        x = pin.neutral(model)
        for name, v in zip(chain.joint_names, q, strict=True):
            x[model.joints[model.getJointId(name)].idx_q] = v
        pin.framesForwardKinematics(model, pdata, x)
        oMb = pdata.oMf[model.getFrameId("universe")]
        oMt = pdata.oMf[model.getFrameId("wrist_3_link_calibrated")]
        T = M @ (oMb.inverse() * oMt).homogeneous
        point = T[:3, :3] @ marker + T[:3, 3]
        errors.append(np.linalg.norm(point - [float(row[k]) for k in ("x1", "y1", "z1")]))
    rms = 1e3 * float(np.sqrt(np.mean(np.square(errors))))
    assert math.isclose(
        rms, doc["errors"]["held_out"]["calibrated"]["position_rms_mm"], rel_tol=1e-6
    )


def test_validation_far_off_is_refused_for_touches_as_for_points():
    """Validation rows fitting their own registration but far from the data's (another
    robot and plane, an instrument moved 0.5 m): one DataError naming the validation data, in the
    words of the rows' kind."""
    chain = load_robot("ur5")
    train = simulate_contacts(chain, 40, "plane", seed=3).data
    other = simulate_contacts(chain, 20, "plane", seed=4).data  # another robot and plane
    with pytest.raises(DataError, match=r"held-out touches are .* mm RMS from the registered "):
        calibrate_contacts(chain, train, validate=other)
    chain = load_chain("ur5")
    rows = simulate(chain, 60, seed=1).measurements
    data, val = rows.subset(np.arange(60) < 40), rows.subset(np.arange(60) >= 40)
    moved = dataclasses.replace(val, position=val.position + 0.5)
    with pytest.raises(
        DataError,
        match=r"validation rows are .* mm RMS from the registered model .*instrument moved",
    ):
        calibrate(chain, data, validate=moved)
    calibrate(chain, data, validate=val).check()  # the same rows in the data's frame
