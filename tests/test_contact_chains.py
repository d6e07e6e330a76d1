"""Several contact chains of one robot in one fit: shared joints once, one URDF.

Checked by routes that share nothing with the fit: central differences of the gaps, the
independent Pinocchio scorer (``contact_scorer``) on the written URDF, Pinocchio's relative
placements against each chain's calibrated model, and a true robot made by editing the
URDF's joint origins (simulated touches on it, no calib model of the truth).
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from contact_scorer import plane_gaps, read_joints, relative_placements
from contact_states import plane_state

from calib import load_robot, simulate
from calib.calibration.contact_checks import split_contacts
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.engine_model import ChainsData, ChainsModel, ChainsState
from calib.calibration.placements import Placements
from calib.cli.commands import main
from calib.exceptions import CalibrationRefusedError, DataError, InvalidArgumentError
from calib.identification.contacts import PlaneContact
from calib.kinematics.placement_export import moved_origins_urdf
from calib.measurements.contact_campaign import ContactData, simulate_contacts, write_contacts

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
URDF = "talos_full_v2.urdf"
PAIRS = (
    ("left_sole_link", "gripper_left_base_link"),
    ("right_sole_link", "gripper_right_base_link"),
)


def _chains(urdf=URDF):
    return [load_robot(urdf, base, tool) for base, tool in PAIRS]


def central_differences(model, start, x, data, h=1e-5):
    """d(model - data)/dx of a joint contact model by central differences ``(m, rows, size)``."""
    num = []
    for e in h * np.eye(model.size()):
        up = -model.apply(start, x + e).residuals(data)
        down = -model.apply(start, x - e).residuals(data)
        num.append((up - down) / (2 * h))
    return np.stack(num, axis=2)


def moved_chains(chains, rng):
    """Placements moved by ~1 cm / 10 mrad, each chain's model (of the robot the errors act
    on), a contact frame 12 cm below the tool and a slightly tilted plane normal, for
    central differences."""
    pl = Placements.of(chains)
    models = pl.chain_models(chains)
    pl = pl.shifted(1e-2 * rng.standard_normal(pl.y.size))
    C = np.eye(4)
    C[2, 3] = -0.12
    n = np.array([0.01, 0.02, 1.0]) / np.linalg.norm([0.01, 0.02, 1.0])
    return pl, models, C, n


def test_jacobian_matches_central_differences():
    """Every column (planes, contacts, every joint's six components) of both chains."""
    chains = tuple(_chains())
    rng = np.random.default_rng(1)
    pl, models, C, n = moved_chains(chains, rng)
    states = tuple(plane_state(m, C, n, 0.7, 0.3, "t") for m in models)
    start = ChainsState(chains, pl, states)
    data = ChainsData(
        tuple(
            ContactData(c.joint_names, c.random_configurations(5, 3), ("t",) * 5, PlaneContact())
            for c in chains
        )
    )
    model = ChainsModel((0, 1), 2, tuple(range(pl.y.size)), pl.names())
    x = 1e-3 * rng.standard_normal(model.size())
    J = model.jacobian(start, x, data)
    num = central_differences(model, start, x, data)
    assert np.max(np.abs(J - num)) < 1e-6 * np.max(np.abs(num))


def true_robot(folder, nominal):
    """The URDF of a true robot: every joint origin of the chains moved by ~1 mm / 1 mrad."""
    pl = Placements.of(tuple(nominal))
    truth = pl.shifted(1e-3 * np.random.default_rng(7).standard_normal(pl.y.size))
    true_urdf = folder / "true.urdf"
    true_urdf.write_bytes(moved_origins_urdf(nominal[0], truth.errors()))
    return true_urdf


@pytest.fixture(scope="module")
def round_trip(tmp_path_factory):
    """A true TALOS (every joint origin of both chains moved by ~1 mm / 1 mrad), touches."""
    folder = tmp_path_factory.mktemp("truth")
    nominal = _chains()
    true_urdf = true_robot(folder, nominal)
    camps = [
        simulate_contacts(c, 150, "plane", error_mm=0.0, error_mrad=0.0, seed=1)
        for c in _chains(true_urdf)
    ]
    data = [c.data for c in camps]
    r = calibrate_contact_chains(nominal, data, params="complete", holdout=0.2, seed=0)
    out = folder / "cal.urdf"
    r.write_urdf(out)
    return nominal, data, r, out


def test_noise_free_round_trip_gaps_vanish_on_both_chains(round_trip):
    _, _, r, _ = round_trip
    assert r.accepted
    assert r.shared == ("torso_1_joint", "torso_2_joint")
    for part in r.chains:
        held = part.stats["held_out"]
        assert held.m == 30
        assert held.height_max_mm < 1e-6  # 1e-9 m
        assert max(held.roll_max_deg, held.pitch_max_deg) < math.degrees(1e-9)
        assert part.stats["held_out_registration"].height_rms_mm > 1.0  # something to fix


def test_one_urdf_holds_both_chains(round_trip):
    """Each chain's calibrated model is the written URDF's (Pinocchio), the torso once."""
    nominal, _, r, out = round_trip
    for chain, part in zip(nominal, r.chains, strict=True):
        q = chain.random_configurations(20, 5)
        joints = {name: q[:, k] for k, name in enumerate(chain.joint_names)}
        pin_T = np.array(
            [T.homogeneous for T in relative_placements(out, *PAIRS[r.chains.index(part)], joints)]
        )
        assert np.allclose(part.calibrated.forward(q), pin_T, atol=1e-10)
    origins = r.to_dict()["joint_origins"]
    assert "torso_1_joint" in origins and "torso_2_joint" in origins
    assert len(origins) == len(set(nominal[0].joint_names) | set(nominal[1].joint_names))


def test_written_urdf_scored_independently(round_trip):
    """Pinocchio on the written URDF, the report's planes and contacts: the held-out gaps."""
    nominal, data, r, out = round_trip
    for chain, d, part in zip(nominal, data, r.chains, strict=True):
        held = split_contacts(d, 0.2, 0)[1]
        joints = {name: held.q[:, k] for k, name in enumerate(chain.joint_names)}
        g = plane_gaps(out, chain.base_frame, chain.tool_frame, part.contact, part.plane, joints)
        assert np.max(np.abs(g[:, 0])) < 1e-9 and np.max(np.abs(g[:, 1:])) < 1e-9
        rms = np.sqrt(np.mean(g**2, axis=0))
        s = part.stats["held_out"]
        assert abs(1e3 * rms[0] - s.height_rms_mm) < 1e-6
        assert abs(math.degrees(rms[1]) - s.roll_rms_deg) < 1e-6
        assert abs(math.degrees(rms[2]) - s.pitch_rms_deg) < 1e-6


def test_urdf_edits_only_the_moved_joints(round_trip):
    """No error: the nominal bytes; one error: that joint's origin alone changes, by E."""
    import xml.etree.ElementTree as ET

    from calib.kinematics.urdf_export import origin_of

    nominal, _, _, _ = round_trip
    raw = nominal[0].urdf_path.read_bytes()
    assert moved_origins_urdf(nominal[0], {}) == raw
    E = np.eye(4)
    E[0, 3] = 1e-3
    moved = moved_origins_urdf(nominal[0], {"torso_2_joint": E})
    before = {j.get("name"): origin_of(j) for j in ET.fromstring(raw).findall("joint")}
    after = {j.get("name"): origin_of(j) for j in ET.fromstring(moved).findall("joint")}
    assert before.keys() == after.keys()
    changed = [n for n in before if not np.array_equal(before[n], after[n])]
    assert changed == ["torso_2_joint"]
    assert np.allclose(after["torso_2_joint"], before["torso_2_joint"] @ E, atol=1e-12)
    with pytest.raises(Exception, match="no <joint name='nope'>"):
        moved_origins_urdf(nominal[0], {"nope": E})


@pytest.mark.filterwarnings("ignore")
def test_real_talos_both_arms_on_the_command_line(capsys, tmp_path, monkeypatch):
    """The issue's data, both arms from the left sole (left leg and torso shared): one URDF;
    the scorer reproduces the held-out gaps of both chains."""
    for side in ("left", "right"):
        shutil.copy(REAL / f"{side}_train.csv", tmp_path)
    monkeypatch.chdir(tmp_path)
    argv = ["calibrate", URDF, "--measure", "plane", "--contact", "0", "0", "-0.12"]
    for (_, tool), side in zip(PAIRS, ("left", "right"), strict=True):
        argv += ["--chain", "left_sole_link", tool, f"{side}_train.csv"]
    argv += ["--holdout", "0.25", "--out", "cal.urdf", "--report", "r.json"]
    code = main(argv)
    _, err = capsys.readouterr()
    assert code == 0, err
    report = json.loads(Path("r.json").read_text())
    assert report["accepted"]
    assert report["shared_joints"][-2:] == ["torso_1_joint", "torso_2_joint"]
    assert len(report["shared_joints"]) == 8  # the left leg's six and the torso's two
    for (_, tool), side, part in zip(PAIRS, ("left", "right"), report["chains"], strict=True):
        base = "left_sole_link"
        assert (part["base"], part["tool"]) == (base, tool)
        chain = load_robot(URDF, base, tool)
        data = ContactData(*_read(chain, f"{side}_train.csv"))
        held = split_contacts(data, 0.25, 0)[1]
        _, joints = read_joints(Path(f"{side}_train.csv"))
        rows = [i for i in range(data.m) if any(np.array_equal(data.q[i], h) for h in held.q)]
        (plane,) = part["contact"]["planes"].values()
        (frame,) = part["contact"]["frames"].values()
        g = plane_gaps(
            Path("cal.urdf"),
            base,
            tool,
            np.array(frame["matrix"]),
            np.array(plane["matrix"]),
            {k: v[rows] for k, v in joints.items()},
        )
        rms = np.sqrt(np.mean(g**2, axis=0))
        s = part["gaps"]["held_out"]
        assert len(rows) == s["m"]
        assert abs(1e3 * rms[0] - s["height_rms_mm"]) < 1e-6
        assert abs(math.degrees(rms[1]) - s["roll_rms_deg"]) < 1e-6
        assert abs(math.degrees(rms[2]) - s["pitch_rms_deg"]) < 1e-6
        train = part["gaps"]["train"]
        assert train["height_rms_mm"] < part["gaps"]["train_registration"]["height_rms_mm"]


def _read(chain, path):
    from calib.measurements.contact_campaign import read_contacts

    d = read_contacts(path, chain, "plane")
    return d.joint_names, d.q, d.ids, d.kind, d.source


def test_worse_on_one_chain_is_refused(capsys, tmp_path):
    """Few noisy touches, every offset: better held out on the left, worse on the right:
    the whole model is refused (one URDF holds both chains)."""
    chains = _chains()
    data = [
        simulate_contacts(c, 20, "plane", seed=5, noise_mrad=3.0, error_mm=0.0, error_mrad=0.0).data
        for c in chains
    ]
    r = calibrate_contact_chains(chains, data, params="offsets", holdout=0.4, seed=0)
    assert not r.accepted and "worse than the registration" in r.refusal
    assert "right_sole_link -> gripper_right_base_link" in r.refusal
    left, right = (p.stats for p in r.chains)
    assert left["held_out"].weighted_mm < left["held_out_registration"].weighted_mm
    assert right["held_out"].weighted_mm > right["held_out_registration"].weighted_mm
    with pytest.raises(CalibrationRefusedError):
        r.write_urdf(tmp_path / "x.urdf")
    assert not (tmp_path / "x.urdf").exists()
    files = []
    for k, d in enumerate(data):
        files.append(tmp_path / f"c{k}.csv")
        write_contacts(files[-1], d)
    argv = ["calibrate", URDF, "--measure", "plane", "--params", "offsets", "--holdout", "0.4"]
    for (base, tool), f in zip(PAIRS, files, strict=True):
        argv += ["--chain", base, tool, str(f)]
    code = main([*argv, "--out", str(tmp_path / "x.urdf"), "--report", str(tmp_path / "r.json")])
    _, err = capsys.readouterr()
    assert code != 0 and "refused" in err and len(_errors(err)) == 1
    assert not (tmp_path / "x.urdf").exists()
    assert json.loads((tmp_path / "r.json").read_text())["accepted"] is False


BAD = [
    (["--chain", "left_sole_link", "gripper_left_base_link"], "BASE TOOL DATA"),
    (["--chain", *PAIRS[0], "DATA", "--data", "DATA"], "--data is for one chain measured"),
    (["--chain", *PAIRS[0], "DATA", "--base", "x"], "--base is for one chain measured"),
    (["--chain", *PAIRS[0], "DATA", "--measure", "fixed-point"], "--measure plane"),
    (["--chain", *PAIRS[0], "DATA", "--params", "paper"], "paper"),
    (["--chain", *PAIRS[0], "DATA", "--chain", *PAIRS[0], "DATA"], "given twice"),
    (["--chain", "left_sole_link", "nowhere_link", "DATA"], "nowhere_link"),
    (["--chain", *PAIRS[0], "missing.csv"], "missing.csv"),
    (["--chain", *PAIRS[0], "DATA", "--shared-planes"], "--shared-planes is for several terms"),
    (["--chain", *PAIRS[0], "DATA", "--contact", "1", "2"], "--contact"),
]


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(("extra", "message"), BAD)
def test_bad_command_lines_fail_in_one_line(capsys, tmp_path, extra, message):
    shutil.copy(REAL / "left_train.csv", tmp_path / "DATA")
    extra = [str(tmp_path / e) if e in ("DATA", "missing.csv") else e for e in extra]
    argv = ["calibrate", URDF, "--measure", "plane", *extra]
    if "--measure" in extra[:-1] and extra[extra.index("--measure") + 1] != "plane":
        argv = ["calibrate", URDF, *extra]
    code = main([*argv, "--out", str(tmp_path / "o.urdf"), "--report", str(tmp_path / "r.json")])
    _, err = capsys.readouterr()
    assert code == 2, err
    assert len(_errors(err)) == 1 and message in _errors(err)[0]
    assert "Traceback" not in err
    assert not (tmp_path / "o.urdf").exists() and not (tmp_path / "r.json").exists()


def test_calibrate_without_data_or_chain_is_one_line(capsys, tmp_path):
    code = main(["calibrate", "ur5", "--out", str(tmp_path / "o.urdf")])
    _, err = capsys.readouterr()
    assert code == 2 and "--data is required" in err and len(err.strip().splitlines()) == 1


def _errors(err: str) -> list[str]:
    """The error lines of stderr (the data's warnings come after)."""
    return [line for line in err.splitlines() if not line.startswith("calib: warning:")]


def test_bad_arguments():
    chains = _chains()
    data = [simulate_contacts(c, 12, "plane", seed=2).data for c in chains]
    with pytest.raises(InvalidArgumentError, match="one set of touches per chain"):
        calibrate_contact_chains(chains, data[:1])
    with pytest.raises(InvalidArgumentError, match="non-empty"):
        calibrate_contact_chains([], [])
    with pytest.raises(InvalidArgumentError, match="unknown parameter level 'some'"):
        calibrate_contact_chains(chains, data, params="some")  # the options' check
    with pytest.raises(InvalidArgumentError, match="not both"):
        calibrate_contact_chains(chains, data, validate=data, holdout=0.2)
    with pytest.raises(InvalidArgumentError, match="seed"):
        calibrate_contact_chains(chains, data, seed=-1)
    with pytest.raises(InvalidArgumentError, match="holdout"):
        calibrate_contact_chains(chains, data, holdout=1.5)
    with pytest.raises(InvalidArgumentError, match="the orientation weight must be"):
        calibrate_contact_chains(chains, data, orientation_weight=-1.0)
    with pytest.raises(InvalidArgumentError, match="one robot"):
        calibrate_contact_chains([chains[0], load_robot("ur5")], data)
    with pytest.raises(DataError, match="joints"):
        calibrate_contact_chains(chains, data[::-1])
    point = simulate_contacts(chains[0], 12, "fixed-point", seed=0).data
    kinds = "validation touches of kind 'fixed-point' for 'plane'"
    with pytest.raises(InvalidArgumentError, match=kinds):
        calibrate_contact_chains(chains, data, validate=[point, None])


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize("side", ["left", "right"])
def test_one_chain_offsets_equal_the_single_chain_pipeline(side):
    """Joint offsets of one chain: the placement model and the MDH pipeline agree."""
    from calib.calibration.entry import calibrate_contacts
    from calib.measurements.contact_campaign import read_contacts

    chain = load_robot(URDF, f"{side}_sole_link", f"gripper_{side}_base_link")
    data = read_contacts(REAL / f"{side}_train.csv", chain, "plane")
    kw = {"contact": (0.0, 0.0, -0.12), "params": "offsets", "holdout": 0.25, "seed": 0}
    mine = calibrate_contact_chains([chain], [data], **kw).chains[0].stats
    theirs = calibrate_contacts(chain, data, **kw).stats
    for key in ("train", "held_out", "held_out_registration"):
        a, b = mine[key], theirs[key]
        assert a.m == b.m
        assert abs(a.height_rms_mm - b.height_rms_mm) < 1e-6
        assert abs(a.roll_rms_deg - b.roll_rms_deg) < 1e-6
        assert abs(a.pitch_rms_deg - b.pitch_rms_deg) < 1e-6


@pytest.mark.filterwarnings("ignore")
def test_shared_plane_is_one_plane():
    """Both sessions from the left sole, --shared-planes: one table in the report."""
    from calib.measurements.contact_campaign import read_contacts

    chains = [load_robot(URDF, "left_sole_link", tool) for _, tool in PAIRS]
    data = [
        read_contacts(REAL / f"{side}_train.csv", c, "plane")
        for c, side in zip(chains, ("left", "right"), strict=True)
    ]
    r = calibrate_contact_chains(
        chains, data, contact=(0, 0, -0.12), params="frames", shared_planes=True
    )
    assert r.planes == 1 and r.accepted
    a, b = (c.plane for c in r.chains)
    assert np.allclose(a[:3, 2], b[:3, 2], atol=1e-12)
    assert abs(a[:3, 2] @ (a[:3, 3] - b[:3, 3])) < 1e-12  # one height
    own = calibrate_contact_chains(chains, data, contact=(0, 0, -0.12), params="frames")
    assert own.planes == 2
    assert not np.allclose(own.chains[0].plane[:3, 2], own.chains[1].plane[:3, 2], atol=1e-4)


def test_a_fit_step_makes_each_chains_frames_once(monkeypatch):
    """The solver's residuals and Jacobian at one x: each chain's frames made once, from the
    placements (no MDH model made)."""
    from calib.calibration import engine_model, placements
    from calib.calibration.solve import Problem

    chains = tuple(_chains())
    pl, models, C, n = moved_chains(chains, np.random.default_rng(4))
    start = ChainsState(chains, pl, tuple(plane_state(m, C, n, 0.7, 0.3, "t") for m in models))
    q = [c.random_configurations(5, 3) for c in chains]
    data = ChainsData(
        tuple(
            ContactData(c.joint_names, qc, ("t",) * 5, PlaneContact())
            for c, qc in zip(chains, q, strict=True)
        )
    )
    model = ChainsModel((0, 1), 2, tuple(range(pl.y.size)), pl.names())
    made = []
    frames = placements.Placements.frames
    monkeypatch.setattr(
        placements.Placements, "frames", lambda self, *a: made.append(a[0]) or frames(self, *a)
    )
    monkeypatch.setattr(engine_model.MDHModel, "kinematics", lambda *a: pytest.fail("an MDH model"))
    problem = Problem(model, start, data, None)
    x = 1e-3 * np.ones(model.size())
    problem.fun(x)
    problem.jac(x)
    problem.fun(x)
    assert made == list(chains)


def test_the_engines_keywords_are_its_run_and_its_options():
    """calibrate_contact_chains's keywords are a Run's fields, its options those of Options
    the joint fit takes; a bad one refused in one line (``elastic`` is True, False or None)."""
    import dataclasses
    import inspect

    from calib.calibration.engine import Run
    from calib.calibration.options import Options

    given = set(list(inspect.signature(calibrate_contact_chains).parameters)[2:])
    run = {f.name for f in dataclasses.fields(Run)} - {"chains", "data", "options"}
    options = {"params", "fix", "free", "orientation_weight", "max_iterations", "holdout", "seed"}
    options |= {"elastic"}
    assert given == run | options and options <= {f.name for f in dataclasses.fields(Options)}
    chains = _chains()
    data = [simulate_contacts(c, 12, "plane", seed=2).data for c in chains]
    with pytest.raises(InvalidArgumentError, match="elastic is True, False or None"):
        calibrate_contact_chains(chains[:1], data[:1], elastic="yes")
    # one chain measured: its elastic is the measured chain's (compliances offered), as
    # calibrate's; it was refused here as if it were touches
    ur5 = load_robot("ur5")
    rows = simulate(ur5, 40, "position", (0.01, 0.02, 0.05), seed=1).measurements
    fitted = calibrate_contact_chains(
        [ur5], [rows], elastic=True, params="complete", instrument=True
    )
    assert "c2" in fitted.free


def test_a_touch_error_hidden_by_the_geometric_errors_is_set_aside_after_the_joint_fit(tmp_path):
    """Issue 28, several terms: both arms of a true TALOS (joint origins ~1 mm / 1 mrad off:
    5.3 mm RMS registration gaps), one left touch's arm joint 15 mrad off (1.8 mm): hidden
    at its registration, set aside after the joint fit, which then fits the rest exactly."""
    nominal = _chains()
    true = _chains(true_robot(tmp_path, nominal))
    data = [
        simulate_contacts(c, 60, "plane", error_mm=0.0, error_mrad=0.0, seed=1).data for c in true
    ]
    data = [dataclasses.replace(d, rows=tuple(range(2, 62))) for d in data]
    q = data[0].q.copy()
    q[10, 10] += 0.015
    data[0] = dataclasses.replace(data[0], q=q)
    r = calibrate_contact_chains(nominal, data, params="complete")
    assert [[o.row for o in p.outliers] for p in r.chains] == [[12], []]
    assert 1e-3 < r.chains[0].outliers[0].error < 3e-3
    assert all(p.stats["train"].length_rms_mm < 1e-6 for p in r.chains)
    assert r.chains[0].stats["train"].m == 59
