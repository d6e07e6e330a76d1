"""Calibration from every contact kind, several objects per file.

Independent routes: the truth the simulation used (the true robot and objects, compared
through what no gauge changes), Pinocchio (tests/contact_scorer.py) on the written URDF and
the report's matrices, and the exit status, stderr and files of the command line.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from contact_scorer import contact_gaps, read_joints

from calib import load_robot
from calib.calibration import choice
from calib.calibration.contact_checks import registration, split_contacts
from calib.calibration.entry import calibrate_contacts
from calib.cli.commands import main
from calib.exceptions import DataError
from calib.kinematics.mdh import from_chain
from calib.measurements.contact_campaign import simulate_contacts, write_contacts

KINDS = ("plane", "plane-point", "fixed-point", "fixed-pose")
CHAINS = {
    "ur5": ("ur5", None, None),
    "panda": ("panda", None, None),
    "talos": ("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link"),
}
ROUND_TRIPS = [
    (robot, kind)
    for robot in CHAINS
    for kind in KINDS
    if (robot, kind) != ("ur5", "fixed-pose")  # a 6-joint loop cannot move
]


def _placements(mdh, contact: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The contact frame in the base frame ``(m, 4, 4)`` at postures q."""
    return mdh.forward(q) @ contact


def _scale_fit(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Scale s with a = s b (least squares) and the largest residual."""
    s = float(a.ravel() @ b.ravel() / (b.ravel() @ b.ravel()))
    return s, float(np.max(np.abs(a - s * b)))


def _similarity_fit(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Scale s and rotation Q with a = s Q b (Procrustes, rows are vectors); largest residual."""
    U, S, Vt = np.linalg.svd(a.T @ b)
    Q = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    s = float(np.trace(np.diag(S) @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)])) / np.sum(b**2))
    return s, float(np.max(np.abs(a - s * b @ Q.T)))


def _invariants(kind: str, T: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What no gauge changes, at contact placements T ``(m, 4, 4)`` off their object F.

    Returns (exact, scaled): quantities equal for the truth and any calibration that fits,
    and quantities equal up to one scale (revolute robots: the robot and the objects scaled
    together touch at the same joint positions), vectors up to a rotation too.
    """
    rel = np.linalg.inv(F) @ T
    if kind == "plane":  # the contact's tilt off the plane (its yaw, spot and scale free)
        return np.arccos(np.clip(rel[:, 2, 2], -1, 1)), np.zeros((0, 3))
    if kind == "plane-point":  # the tip's height over the plane (its side free: a sign)
        return np.zeros(0), rel[:, 2:3, 3]
    if kind == "fixed-point":  # the tip's offset from the point (the point's axes are free)
        return np.zeros(0), T[:, :3, 3] - F[:3, 3]
    # fixed-pose: F and the contact frame only by their relative placement (a conjugation):
    # the rotation angle and the translation along the screw axis are invariant
    rotvec = np.array([_log3(R) for R in rel[:, :3, :3]])
    angle = np.linalg.norm(rotvec, axis=1)
    along = np.einsum("mi,mi->m", rotvec / angle[:, None], rel[:, :3, 3])
    return angle, along[:, None]


def test_rank_postures_are_flush_on_the_joint_frames(monkeypatch):
    """The structural rank is taken at postures flush in the geometry it differentiates: the
    joint frames, not only the MDH model (the UR5's differ by 4e-13 m, which made dependent
    directions independent at 1e-12 and dropped two of the fixed point's 26 columns)."""
    seen = []
    structural = choice.structural

    def spy(wide, start, flush, *rest):
        seen.append((start, flush))
        return structural(wide, start, flush, *rest)

    monkeypatch.setattr(choice, "structural", spy)
    chain = load_robot(*CHAINS["ur5"])
    camp = simulate_contacts(chain, 80, "fixed-point", contacts=2, seed=3)
    calibrate_contacts(chain, camp.data, params="complete", holdout=0.3, seed=1)
    start, flush = seen[0]
    assert np.max(np.abs(start.residuals(flush))) < 1e-14


def _log3(R: np.ndarray) -> np.ndarray:
    import pinocchio as pin

    return pin.log3(R)


@pytest.mark.parametrize(("robot", "kind"), ROUND_TRIPS)
def test_noise_free_round_trip_recovers_the_truth(robot, kind):
    """Two objects: held-out gaps vanish, and the calibration agrees with the truth off contact."""
    chain = load_robot(*CHAINS[robot])
    touches = 160 if kind == "plane-point" else 80  # one row each: the 56 unknowns of TALOS
    camp = simulate_contacts(chain, touches, kind, contacts=2, seed=3)
    r = calibrate_contacts(chain, camp.data, params="complete", holdout=0.3, seed=1)
    assert r.accepted, r.refusal
    held, reg = r.stats["held_out"], r.stats["held_out_registration"]
    objects = r.chains[0].objects()
    assert held.m >= 20 and set(objects) == set(camp.truth.frames) and len(objects) == 2
    top = np.array(held.max) * np.where(held.angular, math.radians(1.0), 1e-3)  # [m, rad]
    assert np.max(top) < 1e-9
    assert reg.weighted_mm > 1e-3  # there was something to fix
    q = chain.random_configurations(40, 7)  # postures where no contact holds
    true_T = _placements(camp.truth.true_mdh, np.eye(4), q)
    got_T = _placements(r.chains[0].calibrated, r.chains[0].contact, q)
    for name, F_true in camp.truth.frames.items():
        exact_t, scaled_t = _invariants(kind, true_T, F_true)
        exact_g, scaled_g = _invariants(kind, got_T, objects[name])
        assert np.max(np.abs(exact_g - exact_t), initial=0.0) < 1e-8
        if not scaled_t.size:
            continue
        fit = _similarity_fit if kind == "fixed-point" else _scale_fit
        s, residual = fit(scaled_g, scaled_t)
        assert residual < 1e-8 and abs(abs(s) - 1) < 0.1


def _cli(capsys, *argv: str) -> tuple[int, str]:
    code = main(list(argv))
    return code, capsys.readouterr().err


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(
    ("robot", "kind"),
    [("panda", k) for k in KINDS] + [("talos", "fixed-point"), ("talos", "fixed-pose")],
)
def test_written_urdf_scored_by_pinocchio_reproduces_the_report(capsys, tmp_path, robot, kind):
    """Noisy touches of two objects through the command line: Pinocchio, reading the URDF and
    the report's matrices, gives the report's held-out and training gaps row by row."""
    chain = load_robot(*CHAINS[robot])
    base, tool = chain.base_frame, chain.tool_frame
    where = [CHAINS[robot][0]] + (["--base", base, "--tool", tool] if robot == "talos" else [])
    camp = simulate_contacts(chain, 70, kind, contacts=2, seed=5, noise_mrad=0.3)
    csv, out, rep = tmp_path / "t.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    write_contacts(csv, camp.data)
    guess = ["0", "0", "0.01"] + (["0.01", "-0.02", "0.03"] if kind == "plane-point" else [])
    code, err = _cli(
        capsys,
        "calibrate",
        *where,
        "--data",
        str(csv),
        "--measure",
        kind,
        "--contact",
        *guess,
        "--out",
        str(out),
        "--report",
        str(rep),
        "--holdout",
        "0.3",
        "--seed",
        "2",
    )
    assert code == 0, err
    report = json.loads(rep.read_text())
    group = {"plane": "planes", "plane-point": "planes", "fixed-point": "points"}.get(kind, "poses")
    objects = report["contact"][group]
    assert set(report["contact"]) == {group, "frames"} and set(objects) == set(camp.truth.frames)
    assert all(o["frame"] == base for o in objects.values())
    C = np.array(report["contact"]["frames"][tool]["matrix"])
    data = dataclasses.replace(camp.data, rows=tuple(range(2, camp.data.m + 2)))
    train, held = split_contacts(data, 0.3, 2)
    ids, joints = read_joints(csv)
    for label, part in (("held_out", held), ("train", train)):
        rows = [i - 2 for i in part.rows]
        g = contact_gaps(
            kind,
            out,
            base,
            tool,
            C,
            [np.array(objects[ids[i]]["matrix"]) for i in rows],
            {k: v[rows] for k, v in joints.items()},
        )
        stats = report["gaps"][label]
        assert stats["m"] == len(rows)
        names = camp.data.kind.row_names
        for j, (name, angle) in enumerate(zip(names, camp.data.kind.angular, strict=True)):
            unit, scale = ("deg", math.degrees(1.0)) if angle else ("mm", 1e3)
            assert abs(scale * np.sqrt(np.mean(g[:, j] ** 2)) - stats[f"{name}_rms_{unit}"]) < 1e-6
            assert abs(scale * np.max(np.abs(g[:, j])) - stats[f"{name}_max_{unit}"]) < 1e-6
    assert (
        report["gaps"]["held_out"]["weighted_mm"]
        < report["gaps"]["held_out_registration"]["weighted_mm"]
    )


def test_report_keys_of_each_kind():
    """The report's groups, matrices and per-row gap keys (docs: formats.md, report keys)."""
    chain = load_robot("panda")
    want = {
        "plane": ("planes", ["height", "roll", "pitch"], ["mm", "deg", "deg"]),
        "plane-point": ("planes", ["height"], ["mm"]),
        "fixed-point": ("points", ["x", "y", "z"], ["mm"] * 3),
        "fixed-pose": ("poses", ["x", "y", "z", "rx", "ry", "rz"], ["mm"] * 3 + ["deg"] * 3),
    }
    for kind, (group, rows, units) in want.items():
        data = simulate_contacts(chain, 40, kind, contacts=2, seed=1).data
        d = calibrate_contacts(chain, data, params="offsets", holdout=0.25).to_dict()
        assert d["measure"] == kind
        assert sorted(d["contact"]) == sorted([group, "frames"])
        for obj in d["contact"][group].values():
            T = np.array(obj["matrix"])
            assert obj["frame"] == "panda_link0" and T.shape == (4, 4)
            assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3)) and np.allclose(
                T[3], [0, 0, 0, 1]
            )
            if group == "points":  # the point as origin, the base frame's axes
                assert np.allclose(T[:3, :3], np.eye(3))
        assert list(d["contact"]["frames"]) == ["panda_hand"]
        keys = [f"{r}_{s}_{u}" for r, u in zip(rows, units, strict=True) for s in ("rms", "max")]
        for part in ("train", "train_registration", "held_out", "held_out_registration"):
            assert list(d["gaps"][part]) == ["m", *keys, "weighted_mm"]
        assert (d["tilt_weight"] is None) == (kind in ("plane-point", "fixed-point"))


def test_summary_names_each_kind_of_object_and_its_own_rows():
    """Planes, points and poses counted by their kind; each chain's line gives its rows' units."""
    chain = load_robot("panda")
    want = {
        "plane": ("2 planes", "plane 'table1', 'table2' (gaps: height [mm], roll [deg], pitch"),
        "plane-point": ("2 planes", "plane 'table1', 'table2' (gaps: height [mm]):"),
        "fixed-point": ("2 points", "point 'point1', 'point2' (gaps: x [mm], y [mm], z [mm]):"),
        "fixed-pose": ("2 poses", "pose 'point1', 'point2' (gaps: x [mm], y [mm], z [mm], rx"),
    }
    for kind, (objects, heading) in want.items():
        data = simulate_contacts(chain, 40, kind, contacts=2, seed=1).data
        lines = calibrate_contacts(chain, data, params="offsets").summary().splitlines()
        assert lines[0].startswith(f"panda: 1 chain, {objects}, "), lines[0]
        assert lines[1].startswith(f"panda_link0 -> panda_hand, {heading}"), lines[1]
        assert not any(line.startswith("gaps (RMS)") for line in lines)


def test_usual_mistakes_and_outliers_in_touches():
    """Swapped joint columns and degrees are named; a wild touch is set aside and listed."""
    chain = load_robot("panda")
    data = simulate_contacts(chain, 60, "fixed-point", contacts=2, seed=4).data
    q = data.q.copy()
    q[:, [1, 3]] = q[:, [3, 1]]
    with pytest.raises(DataError, match="panda_joint2 and panda_joint4 swapped"):
        calibrate_contacts(chain, dataclasses.replace(data, q=q))
    with pytest.raises(DataError, match="degrees"):
        calibrate_contacts(chain, dataclasses.replace(data, q=np.degrees(data.q)))
    q = data.q.copy()
    q[7, 2] += 0.05  # a bad reading: centimetres off its point
    rows = tuple(range(2, data.m + 2))
    r = calibrate_contacts(chain, dataclasses.replace(data, q=q, rows=rows), params="offsets")
    assert [o.row for o in r.chains[0].outliers] == [9]
    assert r.stats["train"].m == data.m - 1
    assert r.to_dict()["outliers"][0]["row"] == 9


def test_a_tilted_touch_is_set_aside_as_an_orientation_outlier():
    """A touch tilted 0.1 rad at its height is named by its tilt gap, as the rule found it.

    The outlier's record is the one rule's (:func:`calib.calibration.outliers.records`): the
    touch's angle gap and their median, not its length gap (no outlier by itself).
    """
    chain = load_robot("panda")
    data = simulate_contacts(chain, 60, "plane", contacts=2, seed=4).data
    state = registration(from_chain(chain), data, np.eye(4), 1.0)
    q = data.q.copy()

    def gap(qi):
        return state.gaps(qi[None], [data.ids[7]])[0]

    target = gap(q[7]) + np.array([0.0, 0.1, 0.0])  # the height kept, rolled by 0.1 rad
    for _ in range(5):
        J = np.stack([(gap(q[7] + h) - gap(q[7] - h)) / 2e-6 for h in 1e-6 * np.eye(chain.n)], 1)
        q[7] += np.linalg.lstsq(J, target - gap(q[7]), rcond=None)[0]
    r = calibrate_contacts(chain, dataclasses.replace(data, q=q), params="offsets")
    (out,) = r.chains[0].outliers
    assert (out.row, out.kind) == (8, "orientation")
    assert out.error > 0.09 and out.error > 6 * out.median
    assert any("row 8 (orientation 5.9 deg)" in n for n in r.notes)


def test_validation_touches_of_an_unfitted_object_are_refused():
    chain = load_robot("panda")
    camp = simulate_contacts(chain, 40, "plane", contacts=2, seed=1)
    held = simulate_contacts(chain, 40, "plane", contacts=2, seed=2).data  # other touches
    one = dataclasses.replace(held, ids=tuple("other" if i == "table2" else i for i in held.ids))
    with pytest.raises(DataError, match="'other'"):
        calibrate_contacts(chain, camp.data, validate=one, params="offsets")


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--measure", "fixed-pose"], "'point' column"),
        (["--measure", "fixed-point", "--contact", "0", "0", "0", "1"], "3 or 6 numbers"),
        (["--measure", "fixed-point", "--holdout", "0.9", "--params", "complete"], "equations"),
    ],
)
def test_bad_input_one_line_exit_2_no_output(capsys, tmp_path, extra, message):
    chain = load_robot("ur5")
    csv = tmp_path / "points.csv"
    kind = "plane-point" if "fixed-pose" in extra else "fixed-point"
    write_contacts(csv, simulate_contacts(chain, 30, kind, seed=0).data)
    out, rep = tmp_path / "cal.urdf", tmp_path / "r.json"
    code, err = _cli(
        capsys,
        "calibrate",
        "ur5",
        "--data",
        str(csv),
        "--out",
        str(out),
        "--report",
        str(rep),
        *extra,
    )
    assert code == 2 and message in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists() and not rep.exists()


def test_an_object_of_too_few_touches_names_the_file(capsys, tmp_path):
    """Two touches of one point: the one-line error names the file, like every data error."""
    data = simulate_contacts(load_robot("ur5"), 30, "fixed-point", seed=0).data
    ids = tuple("t2" if k < 2 else i for k, i in enumerate(data.ids))
    csv = tmp_path / "points.csv"
    write_contacts(csv, dataclasses.replace(data, ids=ids))
    out = tmp_path / "cal.urdf"
    argv = ("calibrate", "ur5", "--data", str(csv), "--measure", "fixed-point", "--out", str(out))
    code, err = _cli(capsys, *argv)
    assert code == 2 and f"{csv}: 't2' has 2 touches: at least 3 are needed" in err
    assert not out.exists()


def test_validation_file_of_few_touches_scores_the_fit():
    """A validation campaign of two touches per object is scored, not registered on its own."""
    chain = load_robot("panda")
    camp = simulate_contacts(chain, 64, "fixed-point", contacts=2, seed=2)
    ids = np.array(camp.data.ids)
    few = np.concatenate([np.flatnonzero(ids == k)[:2] for k in camp.data.contacts])
    rest = np.setdiff1d(np.arange(camp.data.m), few)

    def take(rows):
        return dataclasses.replace(
            camp.data, q=camp.data.q[rows], ids=tuple(camp.data.ids[i] for i in rows)
        )

    r = calibrate_contacts(chain, take(rest), validate=take(few), params="complete")
    assert r.accepted and r.stats["held_out"].m == 4
    assert max(r.stats["held_out"].max) < 1e-6  # mm: noise-free


def _distinct(q: np.ndarray, tol: float = 0.01) -> list[int]:
    """Cluster label of each configuration: joints within ``tol`` rad modulo a turn."""
    labels: list[int] = []
    for i, row in enumerate(q):
        near = [j for j in range(i) if np.max(np.abs(np.angle(np.exp(1j * (q[j] - row))))) < tol]
        labels.append(labels[near[0]] if near else i)
    return labels


def test_a_six_joint_arm_holding_a_fixed_pose_is_noted_not_silent():
    """A UR5 (6 joints) holding a fixed pose (6 conditions) cannot move: the touches repeat
    its inverse-kinematics branches; a note says how many and that the held-out ones repeat."""
    chain = load_robot("ur5")
    data = simulate_contacts(chain, 20, "fixed-pose", seed=2, noise_mrad=0.1).data
    result = calibrate_contacts(chain, data, holdout=0.25, seed=0)
    train, held = split_contacts(data, 0.25, 0)
    labels = _distinct(np.vstack([train.q, held.q]))
    fitted = set(labels[: train.m])
    repeats = sum(label in fitted for label in labels[train.m :])
    note = [n for n in result.notes if "finitely many postures" in n]
    assert len(set(labels)) <= 8  # a UR5 has at most 8 inverse-kinematics branches
    assert note == [  # the engine's notes name their term
        f"base_link -> tool0: a 6-joint chain holding a fixed-pose contact (6 conditions) has "
        f"finitely many postures: the touches sit at {len(set(labels))} distinct postures, "
        f"and {repeats} of the {held.m} held-out touches repeat a fitted one: the model is "
        f"checked at those postures only"
    ]
    panda = load_robot("panda")
    moving = simulate_contacts(panda, 20, "fixed-pose", seed=2, noise_mrad=0.1).data
    notes = calibrate_contacts(panda, moving, holdout=0.25, seed=0).notes
    assert not any("finitely many postures" in n for n in notes)
