"""Joint compliance for contacts (``elastic``): standing gravity torques, columns, round trip.

Independent routes: Pinocchio's generalized gravity (a chain hanging from the URDF root),
central differences of the potential energy summed body by body (the robot standing on the
chain's base frame), central differences of the contact residuals, a simulated robot whose
joints deflect, and the written URDF scored by Pinocchio (``contact_scorer``) at the joint
positions the compliance file's API gives.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from contact_scorer import plane_gaps, read_joints
from contact_states import plane_state

from calib import calibrate, load_calibrated, load_robot
from calib.calibration.entry import calibrate_contacts
from calib.exceptions import InvalidArgumentError
from calib.kinematics.standing import JointReadings, Support, standing_load
from calib.measurements.contact_campaign import ContactData, read_contacts, simulate_contacts

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
TALOS = ("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
RIGHT = ("talos_full_v2.urdf", "right_sole_link", "gripper_right_base_link")
SUPPORTS = (Support(), Support("right_sole_link"), Support("right_sole_link", 0.5))


def _energy(chain, q: np.ndarray, support: Support, others: dict | None = None) -> float:
    """Potential energy [J] of the robot standing on the base frame, body by body.

    Each joint's body (``model.inertias``) at its Pinocchio placement, heights along z of the
    base frame; the other leg's bodies left out (``own leg``) or the other foot's push as
    the potential of a constant vertical force (``share``); ``others``: joints off the chain
    set by name (each one Pinocchio coordinate).
    """
    model = chain.model
    data = model.createData()
    config = chain.pin_configurations(q[None])[0]
    for name, value in (others or {}).items():
        config[model.joints[model.getJointId(name)].idx_q] = value
    pin.framesForwardKinematics(model, data, config)
    oMb = data.oMf[chain.base_id]
    g = float(np.linalg.norm(model.gravity.linear))
    names = [f.name for f in model.frames]
    leg = set()
    if support.foot is not None and support.share is None:
        j = model.frames[names.index(support.foot)].parentJoint
        while model.names[j] != "leg_right_1_joint":
            leg.add(j)
            j = model.parents[j]
        leg.add(j)
    V = 0.0
    for j in range(1, model.njoints):
        if j in leg:
            continue
        c = oMb.actInv(data.oMi[j].act(model.inertias[j].lever))
        V += model.inertias[j].mass * g * c[2]
    if support.share is not None:
        foot = oMb.actInv(data.oMf[names.index(support.foot)]).translation
        total = sum(model.inertias[j].mass for j in range(1, model.njoints))
        V -= support.share * total * g * foot[2]
    return V


@pytest.mark.parametrize("support", SUPPORTS, ids=["single", "own-leg", "share"])
def test_standing_torques_are_the_energy_gradient(support):
    """tau = dV/dq with the sole held fixed: central differences of the energy."""
    chain = load_robot(*TALOS)
    q = chain.random_configurations(3, 1)
    tau = standing_load(chain, support).torques(q)
    h = 1e-6
    E = np.eye(chain.n)
    fd = np.array(
        [
            [(_energy(chain, r + h * e, support) - _energy(chain, r - h * e, support)) / (2 * h)]
            for r in q
            for e in E
        ]
    ).reshape(q.shape)
    assert np.max(np.abs(tau)) > 100.0  # a leg carries the robot
    assert np.max(np.abs(tau - fd)) < 1e-5


@pytest.mark.parametrize("support", SUPPORTS[:2], ids=["single", "own-leg"])
def test_standing_torques_with_recorded_joints_off_the_chain(support):
    """The other arm and leg as read move the load: still the gradient of the energy."""
    chain = load_robot(*TALOS)
    q = chain.random_configurations(2, 4)
    names = ("arm_right_1_joint", "arm_right_2_joint", "arm_right_4_joint", "leg_right_3_joint")
    values = np.array([[0.9, -1.2, -1.5, -0.8], [-0.4, -0.3, -2.0, -1.1]])
    tau = standing_load(chain, support).torques(q, JointReadings(names, values))
    h, E = 1e-6, np.eye(chain.n)
    fd = [
        (
            _energy(chain, r + h * e, support, dict(zip(names, v, strict=True)))
            - _energy(chain, r - h * e, support, dict(zip(names, v, strict=True)))
        )
        / (2 * h)
        for r, v in zip(q, values, strict=True)
        for e in E
    ]
    assert np.max(np.abs(tau - np.reshape(fd, q.shape))) < 1e-5
    moved = np.abs(tau - standing_load(chain, support).torques(q))
    assert np.max(moved) > 1.0  # an arm raised on the other side loads the standing leg
    with pytest.raises(InvalidArgumentError, match="off the chain"):
        standing_load(chain).torques(q, JointReadings(("arm_left_1_joint",), values[:, :1]))
    with pytest.raises(InvalidArgumentError, match="shape"):
        standing_load(chain).torques(q, JointReadings(names[:1], values[:1, :1]))


def test_standing_on_the_root_is_pinocchio_gravity():
    """Base = the URDF root (every joint forwards): Pinocchio's generalized gravity."""
    chain = load_robot("talos_full_v2.urdf", "base_link", "gripper_left_base_link")
    q = chain.random_configurations(4, 2)
    tau = standing_load(chain).torques(q)
    model = chain.model
    data = model.createData()
    idx = [model.joints[j].idx_v for j in chain.joint_ids]
    want = [pin.computeGeneralizedGravity(model, data, r)[idx] for r in chain.pin_configurations(q)]
    assert np.max(np.abs(tau - np.array(want))) < 1e-9
    assert np.max(np.abs(tau)) > 1.0


def test_support_checks():
    chain = load_robot(*TALOS)
    with pytest.raises(InvalidArgumentError, match="other foot"):
        Support(None, 0.5)
    with pytest.raises(InvalidArgumentError, match=r"\[0, 1\]"):
        Support("right_sole_link", 1.5)
    with pytest.raises(InvalidArgumentError, match="on the chain's path"):
        standing_load(chain, Support("gripper_left_base_link"))
    assert standing_load(chain, Support("right_sole_link")).excluded == chain.model.getJointId(
        "leg_right_1_joint"
    )


def read_kind():
    from calib.identification.contacts import PlaneContact

    return PlaneContact()


def _deflected_campaign(chain, compliance: np.ndarray, m: int, seed: int, planes: int = 1):
    """Touches whose commanded joints, deflected by ``c tau``, are flush on the true robot."""
    camp = simulate_contacts(chain, m, "plane", contacts=planes, seed=seed)
    load = standing_load(chain)
    target = camp.data.q
    q = target.copy()
    for _ in range(200):
        q = target - compliance * load.torques(q)
    assert np.max(np.abs(q + compliance * load.torques(q) - target)) < 1e-14
    return ContactData(chain.joint_names, q, camp.data.ids, camp.data.kind, "sim")


def test_noise_free_round_trip_recovers_compliance():
    """Deflected joints, every geometric error, through the joint engine: held-out < 1e-9
    and the compliances back to 1e-6 of the largest (3e-16 rad/(N m) measured)."""
    chain = load_robot(*TALOS)
    truth = np.zeros(chain.n)
    truth[:6] = 2e-4 * np.array([1.0, -0.5, 0.8, 1.2, -0.7, 0.4])  # the standing leg [rad/N m]
    truth[[7, 10]] = (3e-4, -2e-4)
    data = _deflected_campaign(chain, truth, 90, 5)
    r = calibrate_contacts(chain, data, params="complete", holdout=0.3, seed=1, elastic=True)
    assert r.accepted and r.elastic
    held = r.stats["held_out"]
    assert held.height_max_mm < 1e-6  # 1e-9 m
    assert max(held.roll_max_deg, held.pitch_max_deg) < math.degrees(1e-9)
    assert np.max(np.abs(r.chains[0].compliance - truth)) < 1e-6 * np.max(np.abs(truth))
    assert r.stats["held_out_urdf"].height_rms_mm > 1e-3  # the URDF alone is not the model


def test_two_planes_round_trip_recovers_compliance():
    """Two planes in one file (the contact kinds' objects) with deflected joints."""
    chain = load_robot(*TALOS)
    truth = np.zeros(chain.n)
    truth[[1, 3, 8]] = (4e-5, -2e-5, 6e-5)
    data = _deflected_campaign(chain, truth, 90, 6, planes=2)
    assert len(data.contacts) == 2
    r = calibrate_contacts(chain, data, params="complete", holdout=0.3, seed=1, elastic=True)
    assert r.accepted and r.elastic and len(r.chains[0].objects()) == 2
    assert r.stats["held_out"].height_max_mm < 1e-6  # 1e-9 m
    assert np.max(np.abs(r.chains[0].compliance - truth)) < 1e-9


@pytest.mark.parametrize("kind", ["plane-point", "fixed-point", "fixed-pose"])
def test_elastic_with_another_kind_is_one_error(kind, tmp_path):
    """Compliance is fitted for plane contacts only: the API and the CLI say so in one line."""
    chain = load_robot(*TALOS)
    data = simulate_contacts(chain, 40, kind, seed=0).data
    with pytest.raises(InvalidArgumentError, match=f"plane contacts only, not '{kind}'"):
        calibrate_contacts(chain, data, elastic=True)
    from calib.measurements.contact_campaign import write_contacts

    write_contacts(tmp_path / "t.csv", data)
    cli = [sys.executable, "-m", "calib.cli.launcher", "calibrate", TALOS[0]]
    run = subprocess.run(
        [
            *cli,
            "--base",
            TALOS[1],
            "--tool",
            TALOS[2],
            "--data",
            "t.csv",
            "--measure",
            kind,
            "--elastic",
            "--out",
            "cal.urdf",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1 and "plane contacts only" in run.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]


def _file_readings(path: Path, chain) -> JointReadings:
    """The other joints of a contact file, read with the csv module (not calib's reader)."""
    _ids, joints = read_joints(path)
    names = tuple(n for n in joints if n not in chain.joint_names)
    return JointReadings(names, np.column_stack([joints[n] for n in names]))


@pytest.fixture(scope="module")
def talos_elastic(tmp_path_factory):
    """``calib calibrate --elastic`` on the right TALOS touches, a quarter held out."""
    out = tmp_path_factory.mktemp("elastic")
    cmd = [
        sys.executable,
        "-m",
        "calib.cli.launcher",
        "calibrate",
        "talos_full_v2.urdf",
        "--base",
        "right_sole_link",
        "--tool",
        "gripper_right_base_link",
        "--data",
        str(REAL / "right_train.csv"),
        "--measure",
        "plane",
        "--contact",
        "0",
        "0",
        "-0.12",
        "--holdout",
        "0.25",
        "--elastic",
        "--out",
        str(out / "cal.urdf"),
        "--report",
        str(out / "r.json"),
    ]
    run = subprocess.run(cmd, capture_output=True, text=True, check=False)
    return out, run


def test_cli_writes_the_compliance_file_and_prints_both(talos_elastic):
    out, run = talos_elastic
    assert run.returncode == 0, run.stderr
    assert "URDF alone (no compliance)" in run.stdout
    assert "whole model (URDF + compliance)" in run.stdout
    assert "the base foot carries the whole robot" in run.stdout
    # here the URDF alone is worse than the registration: it comes with its compliance file
    assert "use it only with its compliance file" in run.stdout
    doc = json.loads((out / "cal.compliance.json").read_text())
    report = json.loads((out / "r.json").read_text())
    others = _file_readings(REAL / "right_train.csv", load_robot(*RIGHT)).names
    assert len(others) == 17  # the left arm and leg, the head, the grippers...
    single = {"foot": None, "share": None}
    assert doc["load"] == {"kind": "standing", "support": single, "readings": list(others)}
    assert report["load"] == doc["load"]
    assert doc["compliance"] == list(report["compliance"].values())
    assert any(doc["compliance"])
    assert set(report["gaps"]) >= {"held_out", "held_out_urdf", "held_out_registration"}


def test_written_compliance_file_reads_back_as_the_fit(talos_elastic):
    """The compliance file written (one builder for every kind), read by load_calibrated:
    the report's compliance, contact frame and plane, the load, gravity along -z."""
    out, run = talos_elastic
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "r.json").read_text())
    model = load_calibrated(out / "cal.urdf", out / "cal.compliance.json")
    tool = model.chain.tool_frame
    assert model.compliance.tolist() == list(report["compliance"].values())
    assert np.array_equal(model.contact, report["contact"]["frames"][tool]["matrix"])
    assert np.array_equal(model.plane, report["contact"]["planes"]["table"]["matrix"])
    assert model.readings == tuple(report["load"]["readings"]) and model.load is not None
    assert model.gravity[:2].tolist() == [0.0, 0.0] and model.gravity[2] < -9
    assert np.array_equal(model.measurement_to_base, np.eye(4))


def test_compliance_file_and_api_reproduce_the_whole_model(talos_elastic):
    """load_calibrated's deflected joints, scored by Pinocchio on the written URDF."""
    out, run = talos_elastic
    assert run.returncode == 0, run.stderr
    report = json.loads((out / "r.json").read_text())
    model = load_calibrated(out / "cal.urdf", out / "cal.compliance.json")
    chain = model.chain
    data = read_contacts(REAL / "right_train.csv", chain, "plane")
    from calib.calibration.contact_checks import split_contacts

    held = split_contacts(data, 0.25, 0)[1]
    _ids, joints = read_joints(REAL / "right_train.csv")
    rows = [int(np.flatnonzero(np.all(np.isclose(data.q, h), axis=1))[0]) for h in held.q]
    readings = _file_readings(REAL / "right_train.csv", chain).take(rows)
    q = model.deflected(held.q, readings)
    moved = {k: v[rows] for k, v in joints.items()}
    for k, name in enumerate(chain.joint_names):
        moved[name] = q[:, k]
    contact = np.array(report["contact"]["frames"][chain.tool_frame]["matrix"])
    plane = np.array(report["contact"]["planes"]["table"]["matrix"])
    g = plane_gaps(out / "cal.urdf", chain.base_frame, chain.tool_frame, contact, plane, moved)
    want = report["gaps"]["held_out"]
    rms = np.sqrt(np.mean(g**2, axis=0))
    assert abs(1e3 * rms[0] - want["height_rms_mm"]) < 1e-6
    assert abs(math.degrees(rms[1]) - want["roll_rms_deg"]) < 1e-6
    assert abs(math.degrees(rms[2]) - want["pitch_rms_deg"]) < 1e-6
    # the URDF alone at the commanded joints: the report's URDF-alone figure
    rigid = plane_gaps(
        out / "cal.urdf",
        chain.base_frame,
        chain.tool_frame,
        contact,
        plane,
        {k: v[rows] for k, v in joints.items()},
    )
    alone = report["gaps"]["held_out_urdf"]["height_rms_mm"]
    assert abs(1e3 * np.sqrt(np.mean(rigid[:, 0] ** 2)) - alone) < 1e-6
    # the contact frame's placement in the plane by the API: the same heights
    T = model.contact_placements(held.q, readings)
    assert np.max(np.abs(T[:, 2, 3] - g[:, 0])) < 1e-9
    # the commanded joints that reach given deflected ones
    command = model.command(q, readings=readings)
    assert np.max(np.abs(model.deflected(command, readings) - q)) < 1e-10
    # without the other joints' readings: a warning, and not the figure calib printed
    with pytest.warns(UserWarning, match="17 joints off the chain"):
        elsewhere = model.deflected(held.q)
    assert np.max(np.abs(elsewhere - q)) > 1e-4


def test_elastic_needs_a_file_beside_the_urdf(tmp_path):
    """``--elastic`` with an output that is no regular file: exit 2, one line, nothing."""
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "calib.cli.launcher",
            "calibrate",
            "talos_full_v2.urdf",
            "--base",
            "left_sole_link",
            "--tool",
            "gripper_left_base_link",
            "--data",
            str(REAL / "left_train.csv"),
            "--measure",
            "plane",
            "--elastic",
            "--out",
            "-",
        ],
        capture_output=True,
        text=True,
        check=False,
        cwd=tmp_path,
    )
    assert run.returncode == 2
    assert "compliance file" in run.stderr and "Traceback" not in run.stderr
    assert not list(tmp_path.iterdir())


def test_support_needs_elastic():
    chain = load_robot(*TALOS)
    data = read_contacts(REAL / "left_train.csv", chain, "plane")
    with pytest.raises(InvalidArgumentError, match="elastic"):
        calibrate_contacts(chain, data, support=Support("right_sole_link"))


def test_elastic_needs_masses(tmp_path):
    """A URDF without any ``<inertial>``: a one-line error, not a fit of nothing."""
    import re

    src = Path(__file__).resolve().parents[1] / "models" / "stanford.urdf"
    text = re.sub(r"<inertial>.*?</inertial>", "", src.read_text(), flags=re.S)
    urdf = tmp_path / "massless.urdf"
    urdf.write_text(text)
    chain = load_robot(urdf)
    data = simulate_contacts(load_robot(src), 30, "plane", seed=0).data
    with pytest.raises(InvalidArgumentError, match="no masses"):
        calibrate_contacts(chain, data, elastic=True)
    assert any(standing_load(load_robot(src)).torques(data.q).ravel())


def test_predict_gives_the_contact_and_the_joint_correction(talos_elastic):
    """``calib predict`` with the compliance file: deflected joints and the contact origin."""
    import csv

    out, run = talos_elastic
    assert run.returncode == 0, run.stderr
    pred = out / "pred.csv"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "calib.cli.launcher",
            "predict",
            str(out / "cal.urdf"),
            "--compliance",
            str(out / "cal.compliance.json"),
            "--configs",
            str(REAL / "right_train.csv"),
            "--out",
            str(pred),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "the contact's origin in the base frame" in done.stdout
    assert "17 joints off the chain as read" in done.stdout
    with open(pred, newline="") as f:
        rows = list(csv.DictReader(f))
    model = load_calibrated(out / "cal.urdf", out / "cal.compliance.json")
    names = model.chain.joint_names
    q = np.array([[float(r[n]) for n in names] for r in rows])
    deflected = np.array([[float(r[f"deflected_{n}"]) for n in names] for r in rows])
    readings = _file_readings(REAL / "right_train.csv", model.chain)
    assert np.max(np.abs(deflected - model.deflected(q, readings))) < 1e-12
    assert np.max(np.abs(deflected - q)) > 1e-4  # the correction is not nothing
    # the contact origin by Pinocchio on the written URDF at the deflected joints
    from contact_scorer import relative_placements

    _ids, joints = read_joints(REAL / "right_train.csv")
    for k, n in enumerate(names):
        joints[n] = deflected[:, k]
    report = json.loads((out / "r.json").read_text())
    C = np.array(report["contact"]["frames"][model.chain.tool_frame]["matrix"])
    chain = model.chain
    T = relative_placements(out / "cal.urdf", chain.base_frame, chain.tool_frame, joints)
    want = np.array([t.act(C[:3, 3]) for t in T])
    got = np.array([[float(r[a]) for a in ("x1", "y1", "z1")] for r in rows])
    assert np.max(np.abs(got - want)) < 1e-9


@pytest.mark.parametrize(
    "change, message",
    [
        ({"load": {"kind": "hanging", "support": {}}}, "'load' is not"),
        ({"load": {"kind": "standing", "support": {"foot": "no_such_frame"}}}, "does not fit"),
        ({"contact": [1, 2]}, "'contact' is not"),
        ({"contact": {"frame": [[1]], "plane": [[1]]}}, "'frame'"),
        ({"nominal_masses": {"base_link": {"mass": -1, "com": [0, 0, 0]}}}, "nominal_masses"),
    ],
)
def test_bad_compliance_file_is_one_data_error(talos_elastic, tmp_path, change, message):
    from calib.exceptions import DataError

    out, run = talos_elastic
    assert run.returncode == 0, run.stderr
    doc = json.loads((out / "cal.compliance.json").read_text())
    doc.update(change)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(DataError, match=message):
        load_calibrated(out / "cal.urdf", bad)


def test_cli_other_foot_splits_the_load(tmp_path, capsys):
    """``--other-foot FRAME SHARE``: recorded in both files; the API's torques are that load's."""
    from calib.cli.commands import main

    right = (TALOS[0], "right_sole_link", "gripper_right_base_link")
    args = ["calibrate", right[0], "--base", right[1], "--tool", right[2]]
    args += ["--data", str(REAL / "right_train.csv"), "--measure", "plane"]
    args += ["--contact", "0", "0", "-0.12", "--holdout", "0.25", "--elastic"]
    out = tmp_path / "cal.urdf"
    ok = [*args, "--other-foot", "left_sole_link", "0.5", "--out", str(out)]
    assert main([*ok, "--report", str(tmp_path / "r.json")]) == 0, capsys.readouterr().err
    assert "left_sole_link carries 0.5 of the weight" in capsys.readouterr().out
    split = {"foot": "left_sole_link", "share": 0.5}
    assert json.loads((tmp_path / "r.json").read_text())["load"]["support"] == split
    assert json.loads((tmp_path / "cal.compliance.json").read_text())["load"]["support"] == split
    model = load_calibrated(out, tmp_path / "cal.compliance.json")
    q = read_contacts(REAL / "right_train.csv", model.chain, "plane").q
    chain = load_robot(*right)
    readings = _file_readings(REAL / "right_train.csv", chain)
    expect = standing_load(chain, Support("left_sole_link", 0.5)).torques(q, readings)
    assert not np.allclose(expect, standing_load(chain, Support()).torques(q, readings))
    assert np.allclose(model.torques(q, readings), expect, rtol=1e-9, atol=1e-9)
    for bad, says in (
        ([*args[:-1], "--other-foot", "left_sole_link"], "give --elastic too"),
        ([*args, "--other-foot", "left_sole_link", "half"], "a number from 0 to 1"),
        ([*args, "--other-foot", "left_sole_link", "1.5"], "[0, 1]"),
        ([*args, "--other-foot", "a", "0.5", "x"], "FRAME [SHARE]"),
        ([*args, "--other-foot", "no_such_frame"], "no_such_frame"),
    ):
        assert main([*bad, "--out", str(tmp_path / "x.urdf")]) == 2
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err, err
    measured = ["calibrate", "ur5", "--data", "d.csv", "--other-foot", "x", "--out", "y.urdf"]
    assert main(measured) == 2 and "--other-foot is for contact kinds" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "cal.compliance.json",
        "cal.urdf",
        "r.json",
    ]


def test_held_out_touches_without_the_other_joints_are_noted():
    """A validation file lacking the joints off the chain: their load is at neutral, said."""
    from calib.calibration.contact_checks import split_contacts

    chain = load_robot(*RIGHT)
    data = read_contacts(REAL / "right_train.csv", chain, "plane")
    train, held = split_contacts(data, 0.25, 0)
    held = dataclasses.replace(held, source="held_out.csv")  # other rows, as another file
    bare = dataclasses.replace(held, readings=None)
    notes = calibrate_contacts(
        chain, train, contact=(0, 0, -0.12), validate=bare, elastic=True
    ).notes
    assert any(
        "the held-out touches record 0 joints off the chain, the fitted ones 17" in n for n in notes
    )
    same = calibrate_contacts(chain, train, contact=(0, 0, -0.12), validate=held, elastic=True)
    assert not any("joints off the chain" in n for n in same.notes)


def test_engine_compliance_columns_match_central_differences():
    """The joint engine's columns with compliances (every joint placement component, the
    plane, the contact; the reversed leg joints included) against central differences of
    its gaps under the standing torques; its blocks (the fit by block) are those columns."""
    from test_contact_chains import central_differences, moved_chains

    from calib.calibration.engine_model import ChainsData, ChainsModel, ChainsState

    chain = load_robot(*TALOS)
    rng = np.random.default_rng(2)
    pl, models, C, n = moved_chains((chain,), rng)
    s = dataclasses.replace(
        plane_state(models[0], C, n, 0.7, 0.3, "t"), compliance=1e-4 * np.arange(chain.n)
    )
    start = ChainsState((chain,), pl, (s,))
    q = chain.random_configurations(6, 4)
    data = ChainsData(
        (ContactData(chain.joint_names, q, ("t",) * 6, read_kind()),),
        (standing_load(chain).torques(q),),
    )
    comp = (0, 2, 5, 9, 14)
    model = ChainsModel((0,), 1, tuple(range(pl.y.size)), pl.names(), compliance=comp)
    assert model.names()[-5:] == ("c1", "c3", "c6", "c10", "c15")
    x = 1e-3 * rng.standard_normal(model.size())
    x[-5:] *= 0.1
    J = model.jacobian(start, x, data)
    num = central_differences(model, start, x, data, h=1e-7)
    assert np.max(np.abs(J[:, :, -5:])) > 1.0  # metres per rad/(N m)
    assert np.max(np.abs(J - num) / np.maximum(1.0, np.abs(num))) < 1e-6
    own, shared, index = model.blocks(start, x, data)
    assert not index.any() and np.allclose(own, J[:, :, :3], atol=1e-14)
    assert np.allclose(shared, J[:, :, 3:], atol=1e-14)


def _pinocchio_gaps(chain, q, tau, theta, plane, contact):
    """Plane gaps (height [m], tilt of the contact's z off the normal [rad] x 2) ``(m, 3)``
    by Pinocchio alone, at parameters ``theta``: 6 placement components of each chain joint
    (``jointPlacements * exp6``), each joint's compliance (``q + c tau``), the plane's
    height and 2 tilts, the contact's 2 tilts."""
    model = chain.model.copy()
    n = chain.n
    for k, jid in enumerate(chain.joint_ids):
        delta = pin.Motion(theta[6 * k : 6 * k + 3], theta[6 * k + 3 : 6 * k + 6])
        model.jointPlacements[jid] = model.jointPlacements[jid] * pin.exp6(delta)
    c, rest = theta[6 * n : 7 * n], theta[7 * n :]
    data = model.createData()
    R = pin.exp3(np.r_[rest[1], rest[2], 0.0])
    normal, height = plane[:3, :3] @ R[:, 2], plane[:3, 2] @ plane[:3, 3] + rest[0]
    Cm = contact @ np.block(
        [
            [pin.exp3(np.r_[rest[3], rest[4], 0.0]), np.zeros((3, 1))],
            [np.zeros((1, 3)), np.ones((1, 1))],
        ]
    )
    out = []
    for qi, ti in zip(q, tau, strict=True):
        config = chain.pin_configurations((qi + c * ti)[None])[0]
        pin.framesForwardKinematics(model, data, config)
        T = (data.oMf[chain.base_id].inverse() * data.oMf[chain.tool_id]).homogeneous @ Cm
        z = T[:3, :3] @ np.array([0.0, 0.0, 1.0])
        tilt = plane[:3, :3].T @ np.cross(normal, z)
        out.append([normal @ T[:3, 3] - height, tilt[0], tilt[1]])
    return np.array(out)


def test_elastic_count_is_the_pinocchio_finite_difference_rank():
    """The unknowns an elastic contact fit says the touches determine (``identifiable``:
    every joint placement component, every compliance, the plane and the contact) equal
    the rank of the central differences of the gaps computed by Pinocchio alone at the
    touches (noise-free, on the nominal robot; the standing torques: tested above)."""
    chain = load_robot(*TALOS)
    camp = simulate_contacts(chain, 60, "plane", error_mm=0.0, error_mrad=0.0, seed=4)
    r = calibrate(chain, camp.data, params="offsets", elastic=True)
    (plane,) = camp.truth.frames.values()
    q = camp.data.q
    tau = standing_load(chain).torques(q)
    size = 7 * chain.n + 5
    h = 1e-6
    columns = [
        (
            _pinocchio_gaps(chain, q, tau, h * e, plane, np.eye(4))
            - _pinocchio_gaps(chain, q, tau, -h * e, plane, np.eye(4))
        ).ravel()
        / (2 * h)
        for e in np.eye(size)
    ]
    sv = np.linalg.svd(np.column_stack(columns), compute_uv=False)
    rank = int(np.sum(sv > 1e-7 * sv[0]))
    assert sv[rank - 1] > 1e2 * sv[rank]  # a clear gap
    assert r.identifiable == rank


def test_one_note_says_when_elastic_kept_no_compliance():
    """A chain touching under its load, or a measured chain: one note each, none if kept."""
    from types import SimpleNamespace

    from calib.calibration.contact_elastic import none_kept_note

    chain = SimpleNamespace(joint_names=("a", "b"))
    rigid, kept = (SimpleNamespace(chain=chain, compliance=c) for c in (None, np.ones(2)))
    touching = none_kept_note(rigid, (0, 1), load=object())
    assert touching == ["elastic: no joint compliance was kept; the URDF is the whole model"]
    assert "offered (a, b) and none was kept" in none_kept_note(rigid, (0, 1), None)[0]
    assert none_kept_note(kept, (0, 1), object()) == none_kept_note(rigid, (), None) == []
