"""What a user takes home: the calibrated URDF (tool frame, marker links, world link), the
compliance file with calib.load_calibrated and `calib predict`, scored independently with
Pinocchio on the written files (pinocchio.buildModelFromUrdf + framesForwardKinematics).
"""

from __future__ import annotations

import csv
import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from test_report import TOP  # the format-3 top-level keys, in their order

from calib import InvalidArgumentError, from_chain, load_calibrated, load_chain
from calib.calibration.model import State
from calib.cli.commands import main
from calib.identification.parameters import complete_parameters

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


class PinURDF:
    """Forward kinematics of a written URDF by Pinocchio alone, joints set by name."""

    def __init__(self, path: Path):
        self.model = pin.buildModelFromUrdf(str(path))
        self.data = self.model.createData()

    def q(self, joints: dict[str, float]) -> np.ndarray:
        q = pin.neutral(self.model)
        for name, v in joints.items():
            joint = self.model.joints[self.model.getJointId(name)]
            if joint.nq == 2:
                q[joint.idx_q : joint.idx_q + 2] = (np.cos(v), np.sin(v))
            else:
                q[joint.idx_q] = v
        return q

    def placements(self, rows: list[dict[str, float]], frm: str, to: str) -> np.ndarray:
        """Pose of frame ``to`` in frame ``frm`` at each row ``(m, 4, 4)``."""
        a, b = self.model.getFrameId(frm), self.model.getFrameId(to)
        out = []
        for row in rows:
            pin.framesForwardKinematics(self.model, self.data, self.q(row))
            out.append(self.data.oMf[a].actInv(self.data.oMf[b]).homogeneous)
        return np.array(out)


def joint_rows(rows, names) -> list[dict[str, float]]:
    return [{n: float(r[n]) for n in names} for r in rows]


def points(rows, k: int = 1) -> np.ndarray:
    cols = ("x", "y", "z") if "x" in rows[0] else (f"x{k}", f"y{k}", f"z{k}")
    return np.array([[float(r[c]) for c in cols] for r in rows])


def test_pose_data_urdf_tool_frame_is_the_measured_frame(tmp_path, capsys):
    m, urdf, rep = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    args = ["--measure", "pose", "--error-mm", "1", "--error-mrad", "1", "--noise-mm", "0"]
    assert run(capsys, "simulate", "ur5", *args, "--out", str(m))[0] == 0
    code, out, _ = run(
        capsys,
        "calibrate",
        "ur5",
        "--data",
        str(m),
        "--out",
        str(urdf),
        "--report",
        str(rep),
        "--params",
        "complete",
    )
    assert code == 0, out
    report = json.loads(rep.read_text())
    rows = read_csv(m)
    chain = load_chain("ur5")
    T = np.array(report["measurement_to_base"]["matrix"])
    P = T @ PinURDF(urdf).placements(joint_rows(rows, chain.joint_names), "base_link", "tool0")
    assert np.max(np.linalg.norm(P[:, :3, 3] - points(rows), axis=1)) < 1e-6
    quat = np.array([[float(r[c]) for c in ("qx", "qy", "qz", "qw")] for r in rows])
    for (x, y, z, w), Rp in zip(quat, P[:, :3, :3], strict=True):
        Rm = pin.Quaternion(w, x, y, z).toRotationMatrix()
        assert np.linalg.norm(pin.log3(Rm @ Rp.T)) < 1e-6
    # The fitted measured frame was not the tool frame (the old URDF was 1.2 mm off), and
    # the marker link sits at the tool frame's origin.
    assert np.linalg.norm(report["measured_frame"]["xyz"]) > 1e-4
    assert report["markers"] == [[0.0, 0.0, 0.0]] and report["marker_links"] == ["tool0_marker1"]


def test_marker_links_and_world_link_give_the_measured_points(tmp_path, capsys):
    m, urdf, rep = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    sim = ["--measure", "position", "--marker", "0.01", "0.02", "0.05", "--noise-mm", "0"]
    assert run(capsys, "simulate", "ur5", *sim, "--out", str(m))[0] == 0
    cal = ["calibrate", "ur5", "--data", str(m), "--params", "complete", "--report", str(rep)]
    code, out, _ = run(capsys, *cal, "--out", str(urdf), "--world-link", "tracker")
    assert code == 0, out
    report = json.loads(rep.read_text())
    assert report["world_link"] == "tracker"
    rows = read_csv(m)
    q = joint_rows(rows, load_chain("ur5").joint_names)
    model = PinURDF(urdf)
    T = np.array(report["measurement_to_base"]["matrix"])
    mk = T @ model.placements(q, "base_link", "tool0_marker1")
    assert np.max(np.abs(mk[:, :3, 3] - points(rows))) < 1e-9
    assert np.allclose(mk[:, :3, :3], (T @ model.placements(q, "base_link", "tool0"))[:, :3, :3])
    direct = model.placements(q, "tracker", "tool0_marker1")  # from the world link, no T
    assert np.max(np.abs(direct[:, :3, 3] - points(rows))) < 1e-9
    assert np.allclose(report["markers"], [[0.01, 0.02, 0.05]], atol=5e-3)
    # The marker link is the calibrated model's prediction (Python API, same data).
    from calib import calibrate, read_measurements

    chain = load_chain("ur5")
    res = calibrate(chain, read_measurements(m, chain), params="complete")
    assert (
        np.max(np.abs(res.points(np.array([list(r.values()) for r in q]))[:, 0] - mk[:, :3, 3]))
        < 1e-9
    )

    # Loaded without --tool, the calibrated URDF has its nominal file's default tool: the
    # marker links under the tool are deeper, yet never the default.
    nominal_default = load_chain(chain.urdf_path).tool_frame
    assert nominal_default != "tool0_marker1"
    assert load_chain(urdf).tool_frame == nominal_default

    # Calibrated again, the calibrated URDF's marker link is moved, not duplicated.
    again = tmp_path / "again.urdf"
    code, out, _ = run(
        capsys,
        "calibrate",
        str(urdf),
        "--base",
        "base_link",
        "--tool",
        "tool0",
        "--data",
        str(m),
        "--params",
        "frames",
        "--out",
        str(again),
    )
    assert code == 0, out
    assert again.read_text().count('<link name="tool0_marker1"') == 1
    mk2 = PinURDF(again).placements(q, "tracker", "tool0_marker1")
    assert np.max(np.abs(mk2[:, :3, 3] - points(rows))) < 1e-9
    # A taken name is a one-line error, exit 2, no file written.
    for name in ("world", "base_link", "tool0_marker1", "world_joint"):
        out2 = tmp_path / f"clash_{name}.urdf"
        code, _, err = run(capsys, *cal, "--out", str(out2), "--world-link", name)
        assert code == 2 and err.count("\n") == 1 and "--world-link" in err, err
        assert not out2.exists()


def elastic_campaign(chain, m: int, seed: int, noise: float, error: float = 1e-3) -> np.ndarray:
    """Rows ``(m, n + 3)``: joints and a marker of a robot with geometric errors (``error``
    [m, rad]) and compliance (c2 = c3 = 1e-5 rad/(N m)) under the URDF's gravity, with
    noise [m]."""
    rng = np.random.default_rng(seed)
    nominal = from_chain(chain)
    pset = complete_parameters(nominal)
    scale = np.full(len(pset), error)
    true = pset.apply(nominal, scale * np.random.default_rng(7).standard_normal(len(pset)))
    frame = np.eye(4)
    frame[:3, 3] = (0.5, -0.2, 0.1)
    c = np.zeros(chain.n)
    c[1:3] = 1e-5
    state = State(true, frame, np.array([[0.01, 0.02, 0.05]]), None, c)
    q = chain.random_configurations(m, seed)
    pts = state.predict(q, chain.gravity_torques(q))[0][:, 0]
    return np.hstack([q, pts + noise * rng.standard_normal(pts.shape)])


def write_rows(path: Path, chain, rows: np.ndarray) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([*chain.joint_names, "x", "y", "z"])
        w.writerows([[repr(float(v)) for v in r] for r in rows])


def test_elastic_delivery_reproduces_the_whole_model(tmp_path, capsys):
    chain = load_chain("ur5")
    train, val = tmp_path / "train.csv", tmp_path / "val.csv"
    write_rows(train, chain, elastic_campaign(chain, 80, 1, 5e-5))
    held = elastic_campaign(chain, 40, 2, 5e-5)
    write_rows(val, chain, held)
    urdf, rep = tmp_path / "cal.urdf", tmp_path / "r.json"
    code, out, _ = run(
        capsys,
        "calibrate",
        "ur5",
        "--data",
        str(train),
        "--validate",
        str(val),
        "--elastic",
        "--params",
        "complete",
        "--out",
        str(urdf),
        "--report",
        str(rep),
    )
    assert code == 0, out
    report = json.loads(rep.read_text())
    comp = tmp_path / "cal.compliance.json"
    doc = json.loads(comp.read_text())
    assert doc["joints"] == list(chain.joint_names)
    assert np.allclose(doc["compliance"][1:3], 1e-5, rtol=0.05)
    errors = report["errors"]["held_out"]
    assert errors["source"] == str(val)
    whole, alone = errors["calibrated"], errors["urdf"]
    assert whole["position_rms_mm"] < 0.5 * alone["position_rms_mm"]  # compliance matters here
    # Both figures are printed (mm, 3 decimals).
    for label, st in (("calibrated", whole), ("URDF alone (no compliance)", alone)):
        line = next(x for x in out.splitlines() if x.startswith(f"held out ({val}), {label}"))
        rms = float(line.split()[-2])
        assert abs(rms - st["position_rms_mm"]) < 6e-4

    q, measured = held[:, : chain.n], held[:, chain.n :]
    # Independent of calib's model: Pinocchio's gravity torques of the nominal URDF (root -z)
    # and its forward kinematics of the written URDF at the deflected joints.
    pm, nom = PinURDF(urdf), PinURDF(chain.urdf_path)
    T = np.array(doc["measurement_to_base"])
    c = np.array(doc["compliance"])
    v = [nom.model.joints[nom.model.getJointId(n)].idx_v for n in chain.joint_names]
    expected = []
    for row in q:
        qn = nom.q(dict(zip(chain.joint_names, row, strict=True)))
        tau = pin.computeGeneralizedGravity(nom.model, nom.data, qn)[v]
        defl = dict(zip(chain.joint_names, row + c * tau, strict=True))
        P = pm.placements([defl], "base_link", "tool0_marker1")[0]
        expected.append((T @ P)[:3, 3])
    expected = np.array(expected)
    rms = np.sqrt(np.mean(np.sum((expected - measured) ** 2, axis=1)))
    assert abs(1e3 * rms - whole["position_rms_mm"]) < 1e-9
    for source in (comp, rep):  # the compliance file or the report
        model = load_calibrated(urdf, source)
        assert np.max(np.abs(model.points(q)[:, 0] - expected)) < 1e-9
        target = model.deflected(q)
        assert np.max(np.abs(model.deflected(model.command(target)) - target)) < 1e-10
        refusals = (
            ("x", "must be numbers, got 'x'"),
            (q[:, :3], rf"must have shape \(m, {chain.n}\), got \({len(q)}, 3\)"),
            (np.full_like(q, np.nan), "must be finite numbers, got NaN"),
        )
        for bad, reason in refusals:
            with pytest.raises(InvalidArgumentError, match=reason):
                model.points(bad)
    # calib predict writes the same points and deflected joints.
    configs, pred = tmp_path / "configs.csv", tmp_path / "pred.csv"
    write_rows(configs, chain, held)
    code, out, err = run(
        capsys,
        "predict",
        str(urdf),
        "--compliance",
        str(comp),
        "--configs",
        str(configs),
        "--out",
        str(pred),
    )
    assert code == 0, err
    rows = read_csv(pred)
    assert np.max(np.abs(points(rows) - expected)) < 1e-9
    defl = np.array([[float(r[f"deflected_{n}"]) for n in chain.joint_names] for r in rows])
    assert np.allclose(defl, load_calibrated(urdf, comp).deflected(q), atol=1e-12)
    # Both record the URDF written with them: the nominal URDF is refused with either.
    assert doc["urdf_sha256"] == report["model"]["urdf_sha256"]
    assert doc["urdf_sha256"] == hashlib.sha256(urdf.read_bytes()).hexdigest()
    for source in (comp, rep):
        args = ["--compliance", str(source), "--configs", str(configs), "--out", str(pred)]
        code, _, err = run(capsys, "predict", str(chain.urdf_path), *args)
        assert code == 2 and err.count("\n") == 1 and "written with another URDF" in err, err
    # Errors: one line, exit 2, no file, inputs never overwritten.
    before = configs.read_bytes()
    for argv in (
        ["--compliance", str(train), "--configs", str(configs), "--out", str(tmp_path / "p2")],
        ["--compliance", str(comp), "--configs", str(configs), "--out", str(configs)],
        ["--compliance", str(tmp_path / "no.json"), "--configs", str(configs), "--out", "p3"],
    ):
        code, _, err = run(capsys, "predict", str(urdf), *argv)
        assert code == 2 and err.count("\n") == 1, err
    assert configs.read_bytes() == before and not (tmp_path / "p2").exists()


def test_urdf_alone_worse_than_registration_is_written_with_its_compliance_and_a_warning(
    tmp_path, capsys
):
    """Nominal geometry plus compliance: the registration is the best frame and markers for
    the nominal geometry, so the URDF alone (the frame fitted with the compliance) is worse
    on the fitted data. With --elastic the delivered model is the URDF plus the compliance
    file: both are written, and a warning (printed and in the report) says the URDF alone
    must not be used without the compliance file."""
    chain = load_chain("ur5")
    train = tmp_path / "train.csv"
    write_rows(train, chain, elastic_campaign(chain, 60, 3, 0.0, error=0.0))
    urdf, rep = tmp_path / "cal.urdf", tmp_path / "r.json"
    code, out, err = run(
        capsys,
        "calibrate",
        "ur5",
        "--data",
        str(train),
        "--elastic",
        "--params",
        "frames",
        "--free",
        "c2",
        "c3",
        "--out",
        str(urdf),
        "--report",
        str(rep),
    )
    report = json.loads(rep.read_text())
    res = report["errors"]["train"]
    assert res["urdf"]["position_rms_mm"] > res["registration"]["position_rms_mm"]
    assert res["calibrated"]["position_rms_mm"] < 1e-6  # the whole model is exact
    assert code == 0, err
    assert urdf.exists() and (tmp_path / "cal.compliance.json").exists()
    assert report["accepted"] is True
    assert any("URDF alone" in w and "compliance file" in w for w in report["warnings"])
    assert "URDF alone" in out


def point1_csv(src: Path, dst: Path) -> None:
    rows = read_csv(src)
    keep = [k for k in rows[0] if not re.fullmatch(r"[xyz][234]", k)]
    with open(dst, "w", newline="") as f:
        w = csv.DictWriter(f, keep, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def test_tiago_written_urdf_reproduces_the_printed_held_out_figures(tmp_path, capsys):
    tiago = REAL / "tiago"
    train, test = tmp_path / "train.csv", tmp_path / "test.csv"
    point1_csv(tiago / "qualisys_2021-11-30_static_postures.csv", train)
    point1_csv(tiago / "qualisys_2021-11-26_static_postures.csv", test)
    urdf, rep = tmp_path / "tiago_cal.urdf", tmp_path / "r.json"
    # Default options (compliance is opt-in: the URDF holds the whole model).
    code, out, err = run(
        capsys,
        "calibrate",
        str(tiago / "tiago_48_schunk.urdf"),
        "--base",
        "base_footprint",
        "--tool",
        "wrist_ft_tool_link",
        "--data",
        str(train),
        "--validate",
        str(test),
        "--out",
        str(urdf),
        "--report",
        str(rep),
    )
    assert code == 0, err
    report = json.loads(rep.read_text())
    rows = read_csv(test)
    names = [k for k in rows[0] if k.endswith("_joint")]
    assert len(names) == 8
    T = np.array(report["measurement_to_base"]["matrix"])
    P = T @ PinURDF(urdf).placements(
        joint_rows(rows, names), "base_footprint", "wrist_ft_tool_link_marker1"
    )
    err_mm = 1e3 * np.linalg.norm(P[:, :3, 3] - points(rows), axis=1)
    rms, worst = np.sqrt(np.mean(err_mm**2)), np.max(err_mm)
    # Issue 18's targets, on the written URDF: below FIGAROH's full geometric model.
    assert rms < 3.22 and worst <= 12.2
    line = next(x for x in out.splitlines() if x.startswith(f"held out ({test}), calibrated"))
    printed = [float(v) for v in line.split()[-2:]]
    assert abs(printed[0] - rms) < 0.01 and abs(printed[1] - worst) < 0.01
    held = report["validation"]["calibrated"]
    assert abs(1e3 * held["position_rms"] - rms) < 1e-6
    assert abs(1e3 * held["position_max"] - worst) < 1e-6
    assert report["validation"]["urdf"] == held
    assert not any(report["compliance"].values())


def key_paths(doc, prefix: str = "", leaves: tuple[str, ...] = ()) -> set[str]:
    """Every key of a JSON report, nested as ``a.b`` and ``a[].b`` (first item of a list)."""
    out: set[str] = set()
    if isinstance(doc, dict):
        for k, v in doc.items():
            path = f"{prefix}.{k}" if prefix else k
            out.add(path)
            if path not in leaves:
                out |= key_paths(v, path, leaves)
    elif isinstance(doc, list) and doc and isinstance(doc[0], dict):
        out |= key_paths(doc[0], prefix + "[]", leaves)
    return out


STATS = ("configs", "position_rms", "position_max", "orientation_rms", "orientation_max")
STATS_MM = (
    "configs",
    "position_rms_mm",
    "position_max_mm",
    "orientation_rms_deg",
    "orientation_max_deg",
)
POSE = ("xyz", "rpy", "matrix")
MDH = ("name", "joint", "sigma", "sign", "beta", "alpha", "d", "theta", "r", "y")
GROUPS = ("registration", "calibrated", "urdf")

FORMAT3_KEYS = set(TOP)
"""Every report's top-level keys (format 3), whatever the shape and kind."""

CHAIN_REPORT_KEYS = {
    *FORMAT3_KEYS,
    *(f"terms[].{k}" for k in ("base", "tool", "kind", "data", "configs", "objects")),
    *(f"parameters[].{k}" for k in ("name", "joint", "value", "std", "unit", "prior_weight")),
    *(f"errors.{p}" for p in ("train", "held_out", "terms")),
    "errors.held_out.source",
    "errors.held_out.predicted_std_mm",
    "errors.terms[].train",
    "errors.terms[].held_out",
    "errors.terms[].held_out.source",
    "errors.terms[].held_out.predicted_std_mm",
    "errors.held_out.rows",
    "errors.terms[].held_out.rows",
    *(
        f"{p}.{g}"
        for p in (
            "errors.train",
            "errors.held_out",
            "errors.terms[].train",
            "errors.terms[].held_out",
        )
        for g in GROUPS
    ),
    *(
        f"{p}.{g}.{k}"
        for p in (
            "errors.train",
            "errors.held_out",
            "errors.terms[].train",
            "errors.terms[].held_out",
        )
        for g in GROUPS
        for k in STATS_MM
    ),
    *(
        f"frames.{k}"
        for k in (
            "measurement",
            "measured",
            "markers",
            "contacts",
            "world_link",
            "tool_link",
            "on_robot",
            "cameras",
        )
    ),
    *(f"frames.{f}.{k}" for f in ("measurement", "measured") for k in POSE),
    *(f"fit.{k}" for k in ("sigma", "condition_number", "predicted_std_mm", "orientation_weight")),
    "model_choice.kept",
    "model_choice.steps",
    "model_choice.steps[].name",
    "model_choice.steps[].loo_mm",
    "model_choice.prior_strength",
    "model_choice.cv_registration_mm",
    "model_choice.cv_selection_mm",
    "model_choice.guarded",
    "model_choice.cv_complete_mm",
    "model_choice.winner",
    *(f"outliers[].{k}" for k in ("term", "row", "kind", "error_mm", "median_mm")),
    "model.mdh_nominal",
    "model.mdh_calibrated",
    "model.gravity",
    "model.gravity.frame",
    "model.joint_origins",
    "model.shared_joints",  # one engine: a chain's joint origins too
    "model.gravity.vector",
    *(f"model.mdh_{w}[].{k}" for w in ("nominal", "calibrated") for k in MDH),
    *(f"timings_ms.{k}" for k in ("registration", "selection", "fit", "validation")),
}
"""The chain report's format 3 keys (``deprecated`` ones aside): a change here is a change
of format_version."""

CHAIN_DEPRECATED = {
    "data",
    "base_frame",
    "tool_frame",
    "measure",
    "markers",
    "marker_links",
    "measured_frame",
    "world_link",
    "configs",
    "orientation_weight",
    "residuals",
    "validation",
    "selection",
    "sigma",
    "condition_number",
    "predicted_std",
    "gravity",
    "measurement_to_base",
    "mdh_nominal",
    "mdh_calibrated",
}
"""Format 2's keys a chain report still writes (until format 4)."""

TREE_DEPRECATED = {
    "data",
    "base_frame",
    "tools",
    "measure",
    "rows",
    "residuals",
    "per_tool",
    "validation",
    "markers",
    "marker_links",
    "measurement_to_base",
}


def format3_paths(report: dict, leaves: tuple[str, ...]) -> set[str]:
    """The key paths of a report without its deprecated (format 2) keys."""
    kept = {k: v for k, v in report.items() if k not in report["deprecated"]}
    return key_paths(kept, leaves=leaves)


def readme_report_table() -> tuple[set[str], set[str]]:
    """Keys in the first column of the "Report JSON" table (docs/reference/formats.md), and every
    name in it."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "reference" / "formats.md").read_text()
    table = text[text.index("**Report JSON**") :].split("\n\n")[1]
    lines = table.splitlines()[2:]
    first = {k for line in lines for k in re.findall(r"`([a-z_]+)`", line.split("|")[1])}
    return first, set(re.findall(r"`([a-z_]+)`", table))


def test_report_keys_are_pinned_and_documented(tmp_path, capsys):
    from calib import calibrate, read_measurements

    chain = load_chain("ur5")
    rows = elastic_campaign(chain, 40, 5, 1e-4)
    rows[7, chain.n :] += 0.05  # an outlier row
    data = tmp_path / "m.csv"
    write_rows(data, chain, rows)
    res = calibrate(chain, read_measurements(data, chain), holdout=0.25)
    report = json.loads(json.dumps(res.to_dict()))
    assert report["outliers"] and report["model_choice"] is not None
    assert report["errors"]["held_out"] is not None
    leaves = ("deprecated", "compliance", "frames.markers", "frames.contacts", "objects")
    leaves += ("model.joint_origins",)  # joint -> pose (``frames.markers``: link -> point)
    assert format3_paths(report, leaves) == CHAIN_REPORT_KEYS
    assert report["format_version"] == "3"
    assert set(report["deprecated"]) == CHAIN_DEPRECATED
    assert "marker" not in report  # written until format 3, as format 2 said
    assert next(iter(report["frames"]["markers"].values())) == report["markers"][0]
    assert set(report["compliance"]) == set(chain.joint_names)
    # The tree report (written by `calib calibrate` with several tools).
    m, rep = tmp_path / "t.csv", tmp_path / "t.json"
    tools = ["--tool", "wrist_left_ft_tool_link", "--tool", "wrist_right_ft_tool_link"]
    base = ["talos", "--base", "base_link", *tools]
    assert run(capsys, "simulate", *base, "--measure", "position", "--out", str(m))[0] == 0
    code, out, _ = run(
        capsys,
        "calibrate",
        *base,
        "--data",
        str(m),
        "--holdout",
        "0.25",
        "--out",
        str(tmp_path / "t.urdf"),
        "--report",
        str(rep),
    )
    assert code == 0, out
    tree = json.loads(rep.read_text())
    assert set(tree) - set(tree["deprecated"]) == FORMAT3_KEYS
    assert tree["format_version"] == "3" and set(tree["deprecated"]) == TREE_DEPRECATED
    assert [t["tool"] for t in tree["terms"]] == tools[1::2]
    # Every key is documented in the reference's table (format 3 and the deprecated ones).
    rows, names = readme_report_table()
    assert rows >= FORMAT3_KEYS, FORMAT3_KEYS - rows
    nested = {k.split(".")[-1].split("[")[0] for k in CHAIN_REPORT_KEYS if "." in k}
    assert nested <= names, nested - names
    assert names >= (CHAIN_DEPRECATED | TREE_DEPRECATED)


def test_tree_marker_links_give_the_measured_points(tmp_path, capsys):
    m, urdf, rep = tmp_path / "t.csv", tmp_path / "t.urdf", tmp_path / "t.json"
    tools = ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    base = ["talos", "--base", "base_link", *(a for t in tools for a in ("--tool", t))]
    sim = ["--measure", "position", "--marker", "0.05", "0.02", "0.1", "--noise-mm", "0"]
    assert run(capsys, "simulate", *base, *sim, "--out", str(m))[0] == 0
    cal = ["calibrate", *base, "--data", str(m), "--report", str(rep)]
    assert run(capsys, *cal, "--out", str(urdf))[0] == 0
    report = json.loads(rep.read_text())
    assert report["marker_links"] == {t: f"{t}_marker1" for t in tools}
    T = np.array(report["measurement_to_base"]["matrix"])
    rows = read_csv(m)
    names = [k for k in rows[0] if k not in ("tool", "x", "y", "z", "x1", "y1", "z1")]
    model = PinURDF(urdf)
    for tool in tools:
        mine = [r for r in rows if r["tool"] == tool]
        P = T @ model.placements(joint_rows(mine, names), "base_link", f"{tool}_marker1")
        assert np.max(np.abs(P[:, :3, 3] - points(mine))) < 1e-8
    # --world-link is for one chain: a one-line error, no file.
    code, _, err = run(capsys, *cal, "--out", str(tmp_path / "w.urdf"), "--world-link", "w")
    assert code == 2 and err.count("\n") == 1 and "--world-link" in err
    assert not (tmp_path / "w.urdf").exists()


def test_compliance_file_never_overwrites_an_input(tmp_path, capsys):
    chain = load_chain("ur5")
    data = tmp_path / "cal.compliance.json"  # an input named as the compliance file would be
    write_rows(data, chain, elastic_campaign(chain, 30, 6, 0.0))
    before = data.read_bytes()
    code, _, err = run(
        capsys, "calibrate", "ur5", "--data", str(data), "--out", str(tmp_path / "cal.urdf")
    )
    assert code == 2 and err.count("\n") == 1 and "compliance file" in err, err
    assert data.read_bytes() == before and not (tmp_path / "cal.urdf").exists()
    code, _, err = run(capsys, "calibrate", "ur5", "--data", str(data), "--out", "-", "--elastic")
    assert code == 2 and err.count("\n") == 1 and "no regular file" in err, err


def test_tiago_elastic_files_reproduce_the_whole_model(tmp_path, capsys):
    """--elastic on the TIAGo: both figures are printed (whole model, URDF alone); the URDF
    alone is worse than the registration, so a warning says to use it with its compliance
    file; the files `calibrate` writes reproduce the whole model's held-out figure."""
    import warnings

    from calib import DataWarning, calibrate, read_measurements

    tiago = REAL / "tiago"
    train, test = tmp_path / "train.csv", tmp_path / "test.csv"
    point1_csv(tiago / "qualisys_2021-11-30_static_postures.csv", train)
    point1_csv(tiago / "qualisys_2021-11-26_static_postures.csv", test)
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        tr, te = read_measurements(train, chain), read_measurements(test, chain)
        res = calibrate(chain, tr, validate=te, elastic=True)
    assert res.elastic and res.accepted
    assert any("URDF alone" in w for w in res.warnings)
    urdf, comp = tmp_path / "cal.urdf", tmp_path / "cal.compliance.json"
    code, out, err = run(
        capsys,
        "calibrate",
        str(tiago / "tiago_48_schunk.urdf"),
        "--base",
        "base_footprint",
        "--tool",
        "wrist_ft_tool_link",
        "--data",
        str(train),
        "--validate",
        str(test),
        "--elastic",
        "--world-link",
        "mocap",
        "--out",
        str(urdf),
    )
    assert code == 0, err
    assert f"held out ({test}), calibrated" in out
    assert f"held out ({test}), URDF alone (no compliance)" in out
    model = load_calibrated(urdf, comp)
    e = np.linalg.norm(model.points(te.q)[:, 0] - te.points[:, 0], axis=1)
    held = res.to_dict()["errors"]["held_out"]
    assert held["source"] == te.source
    assert abs(1e3 * np.sqrt(np.mean(e**2)) - held["calibrated"]["position_rms_mm"]) < 1e-9
    assert abs(1e3 * np.max(e) - held["calibrated"]["position_max_mm"]) < 1e-9
    # The URDF alone, scored by Pinocchio from the world link: the printed "URDF alone" figure.
    rows = read_csv(test)
    names = list(chain.joint_names)
    P = PinURDF(urdf).placements(joint_rows(rows, names), "mocap", "wrist_ft_tool_link_marker1")
    e = np.linalg.norm(P[:, :3, 3] - points(rows), axis=1)
    assert abs(1e3 * np.sqrt(np.mean(e**2)) - held["urdf"]["position_rms_mm"]) < 1e-9


def test_write_urdf_refuses_what_is_not_a_path_for_every_shape():
    """A tree's ``write_urdf(3)`` is one InvalidArgumentError, as a chain touching's is (it was
    a TypeError from the output checks: only the moved-origins URDF checked the path)."""
    from calib import calibrate
    from calib.kinematics.tree import load_tree
    from calib.measurements.tree_campaign import simulate_tree

    tree = load_tree("bolt")
    result = calibrate(tree, simulate_tree(tree, 30, seed=1).measurements)
    with pytest.raises(InvalidArgumentError, match="path must be a file path"):
        result.write_urdf(3)


def test_a_report_reads_only_with_the_urdf_written_with_it(tmp_path, capsys):
    """A report records the digest of the URDF written with it (``model.urdf_sha256``, by
    ``Result.write`` and ``calib calibrate``): ``load_calibrated`` and ``calib predict`` refuse
    the nominal URDF, another calibration's or an edited copy in one line naming both files
    (they predicted other points with exit 0). A report without the digest (written alone,
    older) is read as before."""
    from calib import DataError, calibrate, read_measurements, simulate

    chain = load_chain("ur5")
    runs = [calibrate(chain, simulate(chain, 30, seed=s).measurements) for s in (1, 2)]
    files = [(tmp_path / f"c{k}.urdf", tmp_path / f"c{k}.json") for k in (1, 2)]
    for r, (urdf, report) in zip(runs, files, strict=True):
        r.write(urdf, report)
    (urdf, report), (other, _) = files
    assert load_calibrated(urdf, report).chain.tool_frame == "tool0"
    edited = tmp_path / "edited.urdf"
    edited.write_bytes(urdf.read_bytes().replace(b"<robot", b"<robot ", 1))
    for wrong in (chain.urdf_path, "ur5", other, edited):
        with pytest.raises(DataError, match="written with another URDF") as info:
            load_calibrated(wrong, report)
        assert "\n" not in str(info.value) and f"{report}: " in str(info.value)
        assert f"than {wrong} " in str(info.value)
    configs, pred = tmp_path / "q.csv", tmp_path / "p.csv"
    assert run(capsys, "simulate", "ur5", "--configs", "3", "--out", str(configs))[0] == 0
    args = ["--compliance", str(report), "--configs", str(configs), "--out", str(pred)]
    code, _, err = run(capsys, "predict", str(other), *args)
    assert code == 2 and err.count("\n") == 1 and "written with another URDF" in err, err
    assert not pred.exists()
    assert run(capsys, "predict", str(urdf), *args)[0] == 0
    # calib calibrate records it too; a report without it is read with any URDF.
    data, cli, cli_report = tmp_path / "m.csv", tmp_path / "cli.urdf", tmp_path / "cli.json"
    assert run(capsys, "simulate", "ur5", "--configs", "30", "--out", str(data))[0] == 0
    cal = ["calibrate", "ur5", "--data", str(data), "--out", str(cli), "--report", str(cli_report)]
    assert run(capsys, *cal)[0] == 0
    with pytest.raises(DataError, match="written with another URDF"):
        load_calibrated(urdf, cli_report)
    assert load_calibrated(cli, cli_report).chain.tool_frame == "tool0"
    alone = tmp_path / "alone.json"
    alone.write_text(json.dumps(runs[0].to_dict()))
    assert "urdf_sha256" not in runs[0].to_dict()["model"]
    assert load_calibrated(other, alone).chain.tool_frame == "tool0"
    # A compliance file records it too (``urdf_sha256``).
    data = tmp_path / "e.csv"
    write_rows(data, chain, elastic_campaign(chain, 40, 1, 5e-5))
    stiff, comp = tmp_path / "e.urdf", tmp_path / "e.compliance.json"
    calibrate(chain, read_measurements(data, chain), elastic=True).write(stiff)
    digest = json.loads(comp.read_text())["urdf_sha256"]
    assert digest == hashlib.sha256(stiff.read_bytes()).hexdigest()
    assert load_calibrated(stiff, comp).chain.tool_frame == "tool0"
    with pytest.raises(DataError, match=r"written with another URDF .*\(urdf_sha256 differs"):
        load_calibrated(urdf, comp)


def test_write_never_overwrites_an_input_read_by_a_relative_name(tmp_path, monkeypatch):
    """The inputs ``Result.write`` protects are the files read, not their names: after
    ``os.chdir`` the data and the validation data read by relative names are refused given
    by their new names (they were overwritten), and those names now name other files, which
    are written (they were refused). Touches the same way. (The URDF is given by its full
    name: writing reads it again.)"""
    import shutil

    from calib import calibrate, read_contacts, read_measurements, simulate, write_measurements
    from calib.measurements.contact_campaign import simulate_contacts, write_contacts

    here, elsewhere = tmp_path / "in", tmp_path / "elsewhere"
    here.mkdir()
    elsewhere.mkdir()
    shutil.copy(load_chain("ur5").urdf_path, here / "robot.urdf")
    monkeypatch.chdir(here)
    chain = load_chain(here / "robot.urdf")
    rows = simulate(chain, 60, seed=1).measurements
    write_measurements("m.csv", rows.subset(np.arange(40)))
    write_measurements("v.csv", rows.subset(np.arange(40, 60)))
    write_contacts("t.csv", simulate_contacts(chain, 30, "plane", seed=3).data)
    data, check = read_measurements("m.csv", chain), read_measurements("v.csv", chain)
    results = {
        "m.csv": calibrate(chain, data, validate=check),
        "t.csv": calibrate(chain, read_contacts("t.csv", chain, "plane")),
    }
    names = ("robot.urdf", "m.csv", "v.csv", "t.csv")
    before = {name: (here / name).read_bytes() for name in names}
    monkeypatch.chdir(elsewhere)
    for read, r in results.items():
        assert r.accepted, r.refusal
        inputs = ("robot.urdf", read, "v.csv") if read == "m.csv" else ("robot.urdf", read)
        for name in inputs:
            with pytest.raises(InvalidArgumentError, match="would overwrite"):
                r.write(here / name)
            with pytest.raises(InvalidArgumentError, match="would overwrite"):
                r.write(elsewhere / "cal.urdf", report=here / name)
        r.write("robot.urdf", report=read)  # other files of the same names
        assert (elsewhere / "robot.urdf").read_bytes() == r.urdf()
    assert {name: (here / name).read_bytes() for name in names} == before


def test_a_robot_loaded_by_a_relative_name_reads_that_file_after_chdir(tmp_path, monkeypatch):
    """A chain or tree loaded from a relative URDF name keeps the file it read
    (``urdf_resolved``): after ``os.chdir`` it calibrates, and its result's ``urdf()``,
    ``origins()``, compliance file and ``write`` read that file, never the file the name
    now names (here: the calibrated URDF just written under it). ``write`` refuses the
    nominal URDF by its new name. The report keeps the name given."""
    import shutil

    from calib import calibrate, read_measurements
    from calib.kinematics.tree import load_tree
    from calib.measurements.tree_campaign import simulate_tree

    here, elsewhere = tmp_path / "in", tmp_path / "elsewhere"
    here.mkdir()
    elsewhere.mkdir()
    shutil.copy(load_chain("ur5").urdf_path, here / "robot.urdf")
    shutil.copy(load_tree("bolt").urdf_path, here / "bolt.urdf")
    monkeypatch.chdir(here)
    chain = load_chain("robot.urdf", "base_link", "tool0")
    tree = load_tree("bolt.urdf", "base_link", ["FL_FOOT", "FR_FOOT"])
    assert (chain.urdf_path, tree.urdf_path) == (Path("robot.urdf"), Path("bolt.urdf"))
    assert chain.urdf_resolved == (here / "robot.urdf").resolve()
    assert tree.urdf_resolved == (here / "bolt.urdf").resolve()
    write_rows(here / "e.csv", chain, elastic_campaign(chain, 40, 1, 5e-5))
    data = read_measurements(here / "e.csv", chain)
    monkeypatch.chdir(elsewhere)
    results = {
        "robot.urdf": calibrate(chain, data, elastic=True),
        "bolt.urdf": calibrate(tree, simulate_tree(tree, 40, seed=2).measurements),
    }
    for name, r in results.items():
        assert r.accepted, r.refusal
        assert r.to_dict()["urdf"] == name
        urdf, origins = r.urdf(), r.origins()
        assert origins["joints"]
        with pytest.raises(InvalidArgumentError, match="would overwrite the nominal URDF"):
            r.write(here / name)
        r.write(name, report=f"{name}.json")  # another file of that name
        assert (elsewhere / name).read_bytes() == urdf
        assert (r.urdf(), r.origins()) == (urdf, origins)
    comp = json.loads((elsewhere / "robot.compliance.json").read_text())
    assert comp["nominal_origins"]
    monkeypatch.chdir(here)
    for r in results.values():
        assert r.urdf() == (elsewhere / r.to_dict()["urdf"]).read_bytes()


def test_term_is_an_index_and_out_a_path(tmp_path):
    """``load_calibrated(term=)`` takes a Python or NumPy integer (an index from
    ``np.argmax``); a bool, text or a float is a bad argument (InvalidArgumentError naming
    ``term``), on a report as on a compliance file (``term=False`` read a compliance file as
    term 0, ``np.int64(0)`` was 'no term 0'). ``write(None, report=)`` is the same one-line
    InvalidArgumentError as ``write(3)`` (it was a TypeError), and writes nothing."""
    from calib import calibrate, read_measurements, simulate

    chain = load_chain("ur5")
    r = calibrate(chain, simulate(chain, 30, seed=1).measurements)
    urdf, report = tmp_path / "c.urdf", tmp_path / "c.json"
    with pytest.raises(InvalidArgumentError, match="out must be a file path, got None"):
        r.write(None, report=report)
    assert not report.exists()
    r.write(urdf, report)
    assert load_calibrated(urdf, report, term=np.int64(0)).chain.tool_frame == "tool0"
    data = tmp_path / "e.csv"
    write_rows(data, chain, elastic_campaign(chain, 40, 1, 5e-5))
    stiff = tmp_path / "e.urdf"
    calibrate(chain, read_measurements(data, chain), elastic=True).write(stiff)
    comp = tmp_path / "e.compliance.json"
    assert load_calibrated(stiff, comp, term=np.int64(0)).chain.tool_frame == "tool0"
    for source, model in ((report, urdf), (comp, stiff)):
        for bad in (True, False, "0", 0.0):
            with pytest.raises(InvalidArgumentError, match=r"term must be a term's index"):
                load_calibrated(model, source, term=bad)


def test_write_takes_any_path_like_as_write_urdf_does(tmp_path):
    """``write`` checks its paths as ``write_urdf`` does (one check): any ``os.PathLike`` is a
    file path (``write`` took ``str`` and ``Path`` only, ``write_urdf`` any path)."""
    from calib import calibrate, simulate

    class Where:  # a path that is no Path
        def __init__(self, path: Path) -> None:
            self.path = path

        def __fspath__(self) -> str:
            return str(self.path)

    chain = load_chain("ur5")
    r = calibrate(chain, simulate(chain, 30, seed=1).measurements)
    r.write(Where(tmp_path / "c.urdf"), report=Where(tmp_path / "c.json"))
    assert (tmp_path / "c.urdf").read_bytes() == r.urdf()
    assert json.loads((tmp_path / "c.json").read_text())["accepted"]


def test_write_urdf_refuses_the_files_write_refuses(tmp_path):
    """``write_urdf`` and ``write`` protect the same files (one rule): the files the result
    read, else (a result that records none) those its report names: the nominal URDF and the
    data (``write_urdf`` then protected the nominal URDF alone, and wrote over the data)."""
    import dataclasses

    from calib import calibrate, read_measurements, simulate, write_measurements

    chain = load_chain("ur5")
    write_measurements(tmp_path / "m.csv", simulate(chain, 30, seed=1).measurements)
    r = calibrate(chain, read_measurements(tmp_path / "m.csv", chain))
    before = (tmp_path / "m.csv").read_bytes()
    for result in (r, dataclasses.replace(r, inputs=())):
        for path in (tmp_path / "m.csv", chain.urdf_path):
            with pytest.raises(InvalidArgumentError, match="would overwrite"):
                result.write_urdf(path)
    assert (tmp_path / "m.csv").read_bytes() == before
    r.write_urdf(tmp_path / "cal.urdf")
    assert (tmp_path / "cal.urdf").read_bytes() == r.urdf()
