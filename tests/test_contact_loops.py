"""A ``fixed-pose`` chain (a closed loop: TALOS's two soles on the ground) in a joint fit.

Checked by routes that share nothing with the fit: central differences of the gaps, a true
robot made by editing the URDF's joint origins (simulated touches on it), and the independent
Pinocchio scorer (``contact_scorer``) on the written URDF.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from contact_scorer import contact_gaps
from contact_states import plane_state
from test_contact_chains import central_differences, moved_chains, true_robot

from calib import load_robot
from calib.calibration.contact_checks import split_contacts
from calib.calibration.contact_model import ContactFrames, ContactState
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.engine_model import ChainsData, ChainsModel, ChainsState
from calib.cli.commands import main
from calib.exceptions import InvalidArgumentError
from calib.identification.contacts import FixedPointContact, FixedPoseContact, PlaneContact
from calib.measurements.contact_campaign import ContactData, read_contacts, simulate_contacts
from calib.measurements.contact_loops import as_loop, join_loops, read_loop

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
URDF = "talos_full_v2.urdf"
ARM = ("left_sole_link", "gripper_left_base_link")
LOOP = ("left_sole_link", "right_sole_link")


def _chains(urdf=URDF):
    return [load_robot(urdf, *ARM), load_robot(urdf, *LOOP)]


def test_jacobian_matches_central_differences():
    """Every column (plane, contact, two poses, every joint's six components) of both chains,
    the loop's rows weighted 3."""
    chains = tuple(_chains())
    rng = np.random.default_rng(3)
    pl, models, C, n = moved_chains(chains, rng)
    plane = plane_state(models[0], C, n, 0.7, 0.3, "t")
    F = np.repeat(np.eye(4)[None], 2, axis=0)  # two poses (two sessions)
    F[:, :3, 3] = [(0.01, -0.2, 0.02), (0.03, -0.18, 0.0)]
    two = ContactFrames(FixedPoseContact(), np.eye(4), F, ("p", "q"))
    pose = ContactState(models[1], two, 0.2)
    start = ChainsState(chains, pl, (plane, pose), (1.0, 3.0))
    q0 = chains[0].random_configurations(5, 3)
    q1 = chains[1].random_configurations(4, 4)
    data = ChainsData(
        (
            ContactData(chains[0].joint_names, q0, ("t",) * 5, PlaneContact()),
            ContactData(chains[1].joint_names, q1, ("p", "q", "q", "p"), FixedPoseContact()),
        )
    )
    kinds = (PlaneContact(), FixedPoseContact())
    model = ChainsModel((0, 1), 2, tuple(range(pl.y.size)), pl.names(), None, kinds, (1, 2))
    assert model.fixed == 3 + 12 + 2  # a plane, two poses, one flush contact's tilts
    assert model.names()[3:6] == ("pose2.1_x", "pose2.1_y", "pose2.1_z")
    assert model.names()[15:17] == ("contact1_rx", "contact1_ry")
    x = 1e-3 * rng.standard_normal(model.size())
    J = model.jacobian(start, x, data)
    assert J.shape == (9, 6, model.size())
    assert not np.any(J[:5, 3:])  # the plane chain's padding rows
    num = central_differences(model, start, x, data)
    assert np.max(np.abs(J - num)) < 1e-6 * np.max(np.abs(num))
    loop_cols = np.abs(J[5:, :, model.fixed :]).max(
        axis=(0, 1)
    )  # the pose rows see the legs' joints
    assert np.count_nonzero(loop_cols > 1e-6) >= 12 * 5


@pytest.fixture(scope="module")
def round_trip(tmp_path_factory):
    """A true TALOS (every joint origin of both chains moved ~1 mm / 1 mrad), touches."""
    folder = tmp_path_factory.mktemp("truth")
    nominal = _chains()
    true_urdf = true_robot(folder, nominal)
    arm, loop = _chains(true_urdf)
    data = [
        simulate_contacts(arm, 150, "plane", error_mm=0.0, error_mrad=0.0, seed=1).data,
        simulate_contacts(loop, 150, "fixed-pose", error_mm=0.0, error_mrad=0.0, seed=2).data,
    ]
    r = calibrate_contact_chains(nominal, data, params="complete", holdout=0.2, seed=0)
    out = folder / "cal.urdf"
    r.write_urdf(out)
    return nominal, data, r, out


def test_noise_free_round_trip_gaps_vanish_on_both_chains(round_trip):
    _, _, r, _ = round_trip
    assert r.accepted, r.refusal
    assert r.shared == tuple(f"leg_left_{k}_joint" for k in range(6, 0, -1))
    assert [c.kind.label for c in r.chains] == ["plane", "fixed-pose"]
    for part in r.chains:
        held = part.stats["held_out"]
        assert held.m == 30
        assert max(v for v, a in zip(held.max, held.angular, strict=True) if not a) < 1e-6  # mm
        assert max(v for v, a in zip(held.max, held.angular, strict=True) if a) < math.degrees(1e-9)
        assert part.stats["held_out_registration"].weighted_mm > 0.1  # something to fix


def test_written_urdf_scored_independently(round_trip):
    """Pinocchio on the written URDF, the report's plane, pose and contacts: held-out gaps."""
    nominal, data, r, out = round_trip
    doc = json.loads(json.dumps(r.to_dict()))
    for chain, d, part, report in zip(nominal, data, r.chains, doc["chains"], strict=True):
        held = split_contacts(d, 0.2, 0)[1]
        joints = {name: held.q[:, k] for k, name in enumerate(chain.joint_names)}
        kind = part.kind.label
        (obj,) = report["contact"][f"{part.kind.object_name}s"].values()
        (frame,) = report["contact"]["frames"].values()
        F, C = np.array(obj["matrix"]), np.array(frame["matrix"])
        g = contact_gaps(kind, out, chain.base_frame, chain.tool_frame, C, [F] * held.m, joints)
        assert np.max(np.abs(g)) < 1e-9
        rms = np.sqrt(np.mean(g**2, axis=0))
        s = part.stats["held_out"]
        scale = np.where(np.array(part.kind.angular), math.degrees(1.0), 1e3)
        assert np.allclose(rms * scale, s.rms, atol=1e-6)
    assert doc["chains"][1]["kind"] == "fixed-pose"


def test_loop_from_plane_touches_files():
    """read_loop: every row of a plane CSV (all joints recorded) is a touch of one pose."""
    loop = load_robot(URDF, *LOOP)
    d = read_loop(REAL / "left_train.csv", loop, "soles")
    plane = read_contacts(REAL / "left_train.csv", load_robot(URDF, *ARM), "plane")
    assert isinstance(d.kind, FixedPoseContact) and d.contacts == ("soles",)
    assert d.m == plane.m == 21 and d.joint_names == loop.joint_names
    raw = np.genfromtxt(
        REAL / "left_train.csv", delimiter=",", names=True, dtype=None, encoding=None
    )
    for k, name in enumerate(loop.joint_names):
        assert np.array_equal(d.q[:, k], raw[name].astype(float))
    both = join_loops([d, read_loop(REAL / "right_train.csv", loop, "right")])
    assert both.m == 50 and np.array_equal(both.q[:21], d.q)
    assert both.contacts == ("soles", "right") and both.ids[20:22] == ("soles", "right")
    arm = read_contacts(REAL / "left_train.csv", load_robot(URDF, *ARM), "plane")
    with pytest.raises(InvalidArgumentError, match="one chain"):
        join_loops([d, as_loop(arm)])
    with pytest.raises(InvalidArgumentError, match="non-empty"):
        as_loop(d, " ")


def test_a_fixed_point_term_joins_a_joint_fit():
    """Every contact kind is a term of the joint engine (the single chain's kinds too)."""
    arm, loop = _chains()
    d = simulate_contacts(arm, 30, "plane", seed=1).data
    p = simulate_contacts(loop, 30, "fixed-point", seed=1).data
    assert isinstance(p.kind, FixedPointContact)
    r = calibrate_contact_chains([arm, loop], [d, p], params="offsets", holdout=0.3)
    assert r.accepted and [c.kind.label for c in r.chains] == ["plane", "fixed-point"]
    for c in r.chains:  # better than the nominal robot on the held-out touches of each term
        assert c.stats["held_out"].weighted_mm < c.stats["held_out_registration"].weighted_mm


@pytest.mark.filterwarnings("ignore")
def test_real_talos_loop_on_the_command_line(capsys, tmp_path, monkeypatch):
    """--loop: the soles' loop from the left arm's file, weighted 10; one URDF; the scorer
    reproduces both chains' held-out gaps from it and the report's frames (without the
    held-out outliers the warnings name, set aside as a single chain's: the loop's row 7)."""
    shutil.copy(REAL / "left_train.csv", tmp_path)
    monkeypatch.chdir(tmp_path)
    argv = ["calibrate", URDF, "--measure", "plane", "--contact", "0", "0", "-0.12"]
    argv += ["--chain", *ARM, "left_train.csv", "--loop", *LOOP, "left_train.csv"]
    argv += ["--pose-weight", "10", "--holdout", "0.25", "--out", "cal.urdf", "--report", "r.json"]
    code = main(argv)
    _, err = capsys.readouterr()
    assert code == 0, err
    report = json.loads(Path("r.json").read_text())
    assert report["accepted"]
    assert [c["kind"] for c in report["chains"]] == ["plane", "fixed-pose"]
    for chain, part in zip(_chains(), report["chains"], strict=True):
        d = read_contacts("left_train.csv", chain, "plane")
        held = split_contacts(d, 0.25, 0)[1]  # the loop's held-out postures are the arm's
        named = {
            int(row)
            for w in report["warnings"]
            if w.startswith(f"{chain.base_frame} -> {chain.tool_frame}: held out:")
            for row in re.findall(r"row (\d+)", w)
        }
        held = held.subset(np.array([r not in named for r in held.rows]))
        joints = {name: held.q[:, k] for k, name in enumerate(chain.joint_names)}
        (obj,) = part["contact"]["planes" if part["kind"] == "plane" else "poses"].values()
        (frame,) = part["contact"]["frames"].values()
        F, C = np.array(obj["matrix"]), np.array(frame["matrix"])
        g = contact_gaps(
            part["kind"],
            Path("cal.urdf"),
            chain.base_frame,
            chain.tool_frame,
            C,
            [F] * held.m,
            joints,
        )
        s = part["gaps"]["held_out"]
        assert s["m"] == held.m == 5 - len(named)
        rms = np.sqrt(np.mean(g**2, axis=0))
        first = "height_rms_mm" if part["kind"] == "plane" else "x_rms_mm"
        assert abs(1e3 * rms[0] - s[first]) < 1e-6
        assert (
            abs(
                math.degrees(rms[-1])
                - s["pitch_rms_deg" if part["kind"] == "plane" else "rz_rms_deg"]
            )
            < 1e-6
        )


BAD = [
    (["--loop", *LOOP, "DATA"], "give --chain too"),
    (["--chain", *ARM, "DATA", "--pose-weight", "3"], "give --loop too"),
    (["--chain", *ARM, "DATA", "--loop", *LOOP], "--loop takes BASE TOOL DATA [VALIDATION]"),
    (["--chain", *ARM, "DATA", "--loop", *LOOP, "DATA", "--pose-weight", "-1"], "pose_weight"),
]


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(("extra", "message"), BAD)
def test_bad_loop_command_lines_fail_in_one_line(capsys, tmp_path, extra, message):
    shutil.copy(REAL / "left_train.csv", tmp_path / "DATA")
    extra = [str(tmp_path / e) if e == "DATA" else e for e in extra]
    argv = ["calibrate", URDF, "--measure", "plane", *extra]
    code = main([*argv, "--out", str(tmp_path / "o.urdf"), "--report", str(tmp_path / "r.json")])
    _, err = capsys.readouterr()
    errors = [line for line in err.splitlines() if not line.startswith("calib: warning:")]
    assert code == 2, err
    assert len(errors) == 1 and message in errors[0] and "Traceback" not in err
    assert not (tmp_path / "o.urdf").exists() and not (tmp_path / "r.json").exists()
