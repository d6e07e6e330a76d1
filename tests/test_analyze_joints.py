"""``calib analyze`` names the URDF joint of every MDH row (issue 28): the joint checked against
Pinocchio's model, the one whose axis is row k's z axis at q = 0 (from Pinocchio's joint
placements and the rows of ``calib show --json`` multiplied out by hand), on a chain with a
prismatic joint, a tree and a mimic arm; and its closing line, checked against ``calib design``.
"""

from __future__ import annotations

import json
import re
import shlex
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from pinref import pin_config, pin_frame, rot, trans

from calib.cli.commands import build_parser, main

MODELS = Path(__file__).resolve().parents[1] / "models"
CASES = {
    "ur5": ["ur5"],
    "tiago": ["tiago", "--measure", "pose"],  # a prismatic joint (the torso lift) first
    "mimic": [str(MODELS / "mimic_arm.urdf")],
    "talos": ["talos", "--tool", "wrist_left_ft_tool_link", "--tool", "wrist_right_ft_tool_link"],
}
ROBOT_ARGS = {"ur5": 1, "tiago": 1, "mimic": 1, "talos": 5}
"""How many of a case's words say the robot (the rest: what is measured)."""


def run(capsys, args: list[str]) -> str:
    assert main(args) == 0
    return capsys.readouterr().out


def row_frames(rows: list[dict], q: np.ndarray) -> dict[int, np.ndarray]:
    """Every row's frame in the base frame, multiplied out from the JSON rows at joint values
    q (one per joint row): frame a(k) Rot(z,gamma) Trans(z,b) Trans(y,y) Rot(y,beta)
    Rot(x,alpha) Trans(x,d) Rot(z, theta + (1-sigma) s q) Trans(z, r + sigma s q) (a chain:
    a(k) = k - 1, gamma = b = 0)."""
    frames, joint = {-1: np.eye(4)}, 0
    for k, row in enumerate(rows):
        theta, r = row["theta"], row["r"]
        if row["sigma"] is not None:
            qk = row.get("sign", 1) * q[joint]
            theta, r, joint = theta + (1 - row["sigma"]) * qk, r + row["sigma"] * qk, joint + 1
        T = frames[row.get("antecedent", k - 1)] @ rot("z", row.get("gamma", 0.0))
        T = T @ trans("z", row.get("b", 0.0)) @ trans("y", row["y"]) @ rot("y", row["beta"])
        T = T @ rot("x", row["alpha"]) @ trans("x", row["d"])
        frames[k] = T @ rot("z", theta) @ trans("z", r)
    return frames


def axis_lines(doc: dict, q: dict[str, float]) -> list[tuple[str, bool, np.ndarray, np.ndarray]]:
    """Every joint of the URDF, read by Pinocchio itself, at the positions q (by name, the
    others at 0): its name, whether it is prismatic, its axis and a point of it in the base
    frame."""
    model = pin.buildModelFromUrdf(doc["urdf"])
    data = model.createData()
    ids = [model.getJointId(name) for name in q]
    pin.forwardKinematics(model, data, pin_config(model, ids, np.array(list(q.values()))))
    pin.updateFramePlacements(model, data)
    bMo = data.oMf[pin_frame(model, doc["base"])].inverse()
    out = []
    for j in range(1, model.njoints):
        S = np.asarray(data.joints[j].S).reshape(6, -1)[:, 0]  # one degree of freedom
        prismatic = bool(np.linalg.norm(S[3:]) < 1e-12)
        X = bMo * data.oMi[j]
        out.append(
            (model.names[j], prismatic, X.rotation @ S[: 3 if prismatic else 6][-3:], X.translation)
        )
    return out


def check_rows_on_their_joints(doc: dict, joint_of_row: dict[int, str], seed: int) -> None:
    """Row k's z axis is the axis of the joint named for it (a prismatic joint: its
    direction), and of no other joint, at random joint values each given to the joint named
    for its row: a name on the wrong row moves the wrong joint and misses."""
    rows = [k for k, row in enumerate(doc["frames"]) if row["sigma"] is not None]
    assert sorted(joint_of_row) == rows
    q = np.random.default_rng(seed).uniform(-1.0, 1.0, len(rows))
    frames = row_frames(doc["frames"], q)
    lines = axis_lines(doc, {joint_of_row[k]: qk for k, qk in zip(rows, q, strict=True)})
    for k in rows:
        z, p = frames[k][:3, 2], frames[k][:3, 3]
        on = [
            name
            for name, prismatic, u, o in lines
            if prismatic == (doc["frames"][k]["sigma"] == 1)
            and np.linalg.norm(np.cross(u, z)) < 1e-6
            and (prismatic or np.linalg.norm(np.cross(p - o, u)) < 1e-6)
        ]
        assert on == [joint_of_row[k]], (k, on)


@pytest.mark.parametrize("case", CASES)
def test_every_row_is_named_by_the_joint_pinocchio_puts_on_its_axis(capsys, case):
    args = CASES[case]
    doc = json.loads(run(capsys, ["show", *args[: ROBOT_ARGS[case]], "--json"]))
    analysis = json.loads(run(capsys, ["analyze", *args, "--json"]))
    entries = analysis["parameters"]
    assert [e["name"] for e in entries] == analysis["standard_parameters"]
    joints = {e["row"]: e["joint"] for e in entries if e["joint"] is not None}
    for seed in range(3):
        check_rows_on_their_joints(doc, joints, seed)
    third, fifth = sorted(joints)[2], sorted(joints)[4]
    with pytest.raises(AssertionError):  # the check sees two names swapped
        check_rows_on_their_joints(doc, joints | {third: joints[fifth], fifth: joints[third]}, 0)
    fixed = {0: doc["base"]} | {
        k: r.get("tool") or doc.get("tool")
        for k, r in enumerate(doc["frames"])
        if k and r["sigma"] is None
    }
    for e in entries:
        assert e["frame"] == fixed.get(e["row"]), e
        assert (e["joint"] is None) == (e["row"] in fixed), e
        expected = "identifiable" if e["name"] in analysis["base_parameters"] else "regrouped"
        expected = "zero" if e["name"] in analysis["nonidentifiable"] else expected
        assert e["status"] == expected
    # the printed text: the status table's joint column, each base parameter's joint, and
    # the parameters of no effect, with the same names
    text = run(capsys, ["analyze", *args])
    labels = joints | {
        k: "(base frame)" if k == 0 else "(tool frame)" if "tool" in doc else f"(tool {frame})"
        for k, frame in fixed.items()
    }
    for k, label in labels.items():
        assert re.search(rf"^ *{k}  +{re.escape(label)}  +", text, re.M), (k, label)
    rows = {e["name"]: e["row"] for e in entries}
    base = re.findall(r"^ +(\w+) (\S+(?: \S+)?) += \1", text, re.M)
    assert [n for n, _ in base] == analysis["base_parameters"]
    for name, label in base:
        assert label == labels[rows[name]], name
    zero = re.search(r"^no effect \(not identifiable\): (.*)$", text, re.M)
    said = [] if zero is None else zero.group(1).split(", ")
    in_parentheses = {k: v if v.startswith("(") else f"({v})" for k, v in labels.items()}
    assert said == [f"{n} {in_parentheses[rows[n]]}" for n in analysis["nonidentifiable"]]


def test_the_json_keeps_its_names_and_prints_no_next_step(capsys):
    out = run(capsys, ["analyze", "ur5", "--json"])
    doc = json.loads(out)  # the whole output is the JSON document
    assert "next:" not in out
    assert len(doc["base_parameters"]) == doc["n_base"] == 25
    assert doc["regrouping"]["theta5"] == "theta5 + 12.15 d6"
    by_name = {e["name"]: e for e in doc["parameters"]}
    assert by_name["theta5"]["joint"] == "wrist_2_joint"
    assert by_name["theta7"]["joint"] is None and by_name["theta7"]["frame"] == "tool0"


NEXT = {
    "ur5": ["ur5"],
    "paper": ["aid", "--params", "paper"],  # design's rows reach the complete model's 25
    "plane": ["ur5", "--measure", "plane"],
    "tree": CASES["talos"],
    "tree paper": [*CASES["talos"], "--params", "paper"],  # a tree's design: complete
}


def next_step(capsys, args: list[str]) -> tuple[list[str], int, list[str]]:
    """The closing line's design command, its least K and its calibrate command."""
    last = run(capsys, ["analyze", *args]).splitlines()[-1]
    found = re.fullmatch(
        r"next: calib (design .*) --configs K --out (\S+) chooses K >= (\d+) postures.*"
        r"then calib (calibrate .*)",
        last,
    )
    assert found is not None, last
    design = [*shlex.split(found.group(1)), "--out", found.group(2)]
    return design, int(found.group(3)), shlex.split(found.group(4))


@pytest.mark.parametrize("case", NEXT)
def test_the_next_step_is_one_design_and_calibrate_take(capsys, case, tmp_path, monkeypatch):
    """design refuses one configuration fewer than the line's least K, saying that K; the
    calibrate command is one calibrate's parser takes."""
    monkeypatch.chdir(tmp_path)
    design, least, calibrate = next_step(capsys, NEXT[case])
    assert main([*design, "--configs", str(least - 1), "--quiet", "--candidates", "200"]) == 2
    assert f"choose at least {least} configurations" in capsys.readouterr().err
    build_parser().parse_args(calibrate)  # every option exists (MEASURED.csv: the user's file)


def test_the_next_step_runs_for_the_least_k(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    design, least, _ = next_step(capsys, NEXT["ur5"])
    assert main([*design, "--configs", str(least), "--quiet", "--candidates", "200"]) == 0
    assert len((tmp_path / "plan.csv").read_text().splitlines()) == least + 1  # a header


def test_a_tree_measured_in_pose_is_sent_to_its_positions(capsys, tmp_path, monkeypatch):
    """design and calibrate take a tree's positions: the line sends to their analysis, whose
    own next step design takes."""
    last = run(capsys, ["analyze", *CASES["talos"], "--measure", "pose"]).splitlines()[-1]
    found = re.search(r"calib (analyze .*--measure position) counts", last)
    assert found is not None, last
    monkeypatch.chdir(tmp_path)
    design, least, _ = next_step(capsys, shlex.split(found.group(1))[1:])
    assert main([*design, "--configs", str(least - 1), "--quiet", "--candidates", "200"]) == 2
    assert f"choose at least {least} configurations" in capsys.readouterr().err


MARKERS = {
    "ur5 3 points": ["ur5", "--markers", "3"],
    "tiago pose": ["tiago", "--markers", "2", "--measure", "pose"],  # the torso lift first
}


@pytest.mark.parametrize("case", MARKERS)
def test_markers_name_the_joint_pinocchio_puts_on_each_row(capsys, case):
    """``analyze --markers K``: each MDH parameter's joint (JSON ``identifiable``) is the one
    whose axis Pinocchio puts on its row's z axis (the rows the count leaves out named by
    analyze's own table, itself checked above); the text lists each joint's parameters."""
    args = MARKERS[case]
    doc = json.loads(run(capsys, ["show", args[0], "--json"]))
    found = json.loads(run(capsys, ["analyze", *args, "--json"]))
    entries = found["identifiable"]
    assert [e["name"] for e in entries] == found["parameters"]
    named = {e["row"]: e["joint"] for e in entries if e["joint"] is not None}
    assert len(named) >= 5
    every = json.loads(run(capsys, ["analyze", args[0], "--json"]))["parameters"]
    joints = {e["row"]: e["joint"] for e in every if e["joint"] is not None} | named
    for seed in range(3):
        check_rows_on_their_joints(doc, joints, seed)
    first, last = sorted(named)[0], sorted(named)[-1]
    with pytest.raises(AssertionError):  # a markers' name on the wrong row is seen
        check_rows_on_their_joints(doc, joints | {first: named[last], last: named[first]}, 0)
    for e in entries:
        row = re.fullmatch(r"[a-z]+(\d+)", e["name"])
        assert e["row"] == (None if row is None else int(row.group(1)))
        if e["name"].startswith("frame."):
            assert e["frame"] == "measurement"
    lines = run(capsys, ["analyze", *args]).splitlines()[1:]
    said = {}
    for line in lines:
        label, names = re.fullmatch(r"  (\S+(?: \S+)?) +(\S.*)", line).groups()
        said[label] = names.split(", ")
    for joint in set(named.values()):
        assert said[joint] == [e["name"] for e in entries if e["joint"] == joint]
    assert said["(measurement frame)"] == [n for n in found["parameters"] if n[:6] == "frame."]
