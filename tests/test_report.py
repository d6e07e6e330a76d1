"""One report for every calibration (format 3): the same top-level keys for every shape and
kind, every parameter named with its URDF joint, errors in mm and degrees.

The expected layout is written out here (not imported from calib), the joints are checked
against ``calib show --json`` (the conversion's own record of each row's joint, computed
without the calibration), and the errors against the format 2 figures in metres.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from pixel_setups import INTRINSICS, grid, look_at

from calib import (
    DataWarning,
    PixelCamera,
    PixelData,
    Problem,
    Term,
    calibrate,
    load_chain,
    load_robot,
    read_measurements,
    simulate,
    simulate_pixels,
)
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.entry import calibrate_contacts
from calib.cli.commands import main
from calib.measurements.contact_campaign import simulate_contacts
from calib.measurements.tree_campaign import simulate_tree

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata"

TOP = [
    "format_version",
    "deprecated",
    "robot",
    "urdf",
    "shape",
    "terms",
    "params",
    "accepted",
    "refusal",
    "converged",
    "message",
    "iterations",
    "parameters",
    "errors",
    "frames",
    "objects",
    "fit",
    "model_choice",
    "outliers",
    "compliance",
    "model",
    "warnings",
    "timings_ms",
]
"""Format 3's top-level keys, in order, for every shape and kind."""

PARAMETER = {"name", "joint", "value", "std", "unit", "prior_weight"}
TERM = {"base", "tool", "kind", "data", "configs", "objects"}
FRAMES = {"measurement", "measured", "markers", "contacts", "world_link", "tool_link"}
FRAMES |= {"on_robot", "cameras"}
FIT = {"sigma", "condition_number", "predicted_std_mm", "orientation_weight"}
UNITS = {"m", "rad", "rad/(N m)", "m/N"}


def _chain_report():
    chain = load_chain("ur5")
    camp = simulate(chain, 40, noise_mm=0.05, seed=1, measure="pose")
    q = camp.measurements
    position = q.position.copy()
    position[7] += 0.05  # a gross outlier: set aside
    data = dataclasses.replace(q, position=position)
    return calibrate(chain, data, holdout=0.25, seed=0).to_dict()


def _tree_report():
    tree = load_robot("talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"])
    camp = simulate_tree(tree, 40, noise_mm=0.05, seed=2)
    return calibrate(tree, camp.measurements, holdout=0.25).to_dict()


def _contact_report(kind: str):
    chain = load_robot("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
    data = simulate_contacts(chain, 60, kind, seed=2).data
    return calibrate_contacts(chain, data, holdout=0.25, seed=1).to_dict()


def _chains_report():
    pairs = (
        ("left_sole_link", "gripper_left_base_link"),
        ("right_sole_link", "gripper_right_base_link"),
    )
    chains = [load_robot("talos_full_v2.urdf", b, t) for b, t in pairs]
    data = [simulate_contacts(c, 40, "plane", seed=4).data for c in chains]
    return calibrate_contact_chains(chains, data, params="offsets", holdout=0.25).to_dict()


def _pixel_report():
    chain = load_robot("ur5", "world", "tool0")
    board, camera = grid(4, 3, 0.03), PixelCamera("cam", "world", INTRINSICS, None)
    seen = look_at(np.array([1.6, 0.3, 0.8]), [0, 0, 0.3])
    q = chain.random_configurations(300, 1)
    obs = simulate_pixels(chain, "cam", seen, INTRINSICS, board, q, noise_px=0.3, seed=1)
    terms = (Term(chain, PixelData(camera, board, obs)),)
    return calibrate(Problem(terms, params="complete", holdout=0.25)).to_dict()


SHAPES = {
    "chain": _chain_report,
    "chains-pixels": _pixel_report,
    "tree": _tree_report,
    "contacts-plane": lambda: _contact_report("plane"),
    "contacts-fixed-point": lambda: _contact_report("fixed-point"),
    "chains": _chains_report,
}


@pytest.fixture(scope="module")
def reports():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {name: json.loads(json.dumps(make())) for name, make in SHAPES.items()}


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_every_shape_has_format_3_keys(reports, shape):
    """The same top-level keys in the same order (format 2's, listed in ``deprecated``,
    after them), the same keys inside ``terms``, ``parameters``, ``frames`` and ``fit``."""
    r = reports[shape]
    assert r["format_version"] == "3"
    assert list(r)[: len(TOP)] == TOP
    assert set(r) - set(TOP) == set(r["deprecated"])
    assert all("format 3 moved it to" in why for why in r["deprecated"].values())
    assert "marker" not in r  # format 2 announced its end at format 3
    assert r["terms"] and all(set(t) == TERM for t in r["terms"])
    assert r["parameters"] and all(set(p) == PARAMETER for p in r["parameters"])
    assert {p["unit"] for p in r["parameters"]} <= UNITS
    assert set(r["frames"]) == FRAMES and set(r["fit"]) == FIT
    assert isinstance(r["warnings"], list)
    assert len(r["errors"]["terms"]) == len(r["terms"])


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_errors_are_in_mm_and_degrees_with_the_unit_in_the_key(reports, shape):
    keys = set()
    for part in reports[shape]["errors"]["terms"]:
        for group in (part["train"], part["held_out"] or {}):
            for key, stats in group.items():
                if key == "pixels":  # a camera's reprojection errors, by model [px]
                    keys |= {k for model in stats.values() for k in model}
                elif isinstance(stats, dict):
                    keys |= set(stats)
    assert keys
    assert all(re.fullmatch(r"configs|pixels|\w+_(mm|deg|px)", k) for k in keys), keys


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_every_held_out_entry_lists_the_rows_it_scored(reports, shape):
    """``held_out.rows``: the rows scored by their line (no file: row i is i + 1), sorted,
    as many as the entry counts (a camera's: its pixels), none a training outlier; a
    tree's pooled entry lists every tool's."""
    errors = reports[shape]["errors"]
    terms = [t["held_out"] for t in errors["terms"]]
    for held in [*terms, errors["held_out"] or terms[0]]:
        rows, counted = held["rows"], held["calibrated"]
        assert rows == sorted(set(rows)) and min(rows) >= 1, shape
        assert len(rows) == counted.get("pixels", counted["configs"]), shape
    if errors["held_out"] is not None and len(terms) > 1:
        assert errors["held_out"]["rows"] == sorted(n for t in terms for n in t["rows"])
    aside = {(o["term"], o["row"]) for o in reports[shape]["outliers"]}
    assert not aside & {(k, n) for k, t in enumerate(terms) for n in t["rows"]}


def test_chain_errors_are_the_format_2_figures_in_mm(reports):
    r = reports["chain"]
    for new, old in (
        (r["errors"]["train"], r["residuals"]),
        (r["errors"]["held_out"], r["validation"]),
    ):
        for group in ("registration", "calibrated", "urdf"):
            a, b = new[group], old[group]
            assert a["configs"] == b["configs"]
            assert math.isclose(a["position_rms_mm"], 1e3 * b["position_rms"], rel_tol=1e-12)
            assert math.isclose(a["orientation_max_deg"], math.degrees(b["orientation_max"]))
    assert r["outliers"] and r["outliers"][0]["row"] == 7 + 1  # rows count from 1 (no file)
    assert r["outliers"][0]["error_mm"] > 10 * r["outliers"][0]["median_mm"]
    assert r["model_choice"]["kept"] == r["selection"]["kept"]


def test_contact_errors_are_the_gaps(reports):
    r = reports["contacts-plane"]
    gaps = r["gaps"]
    assert r["errors"]["train"]["calibrated"]["height_rms_mm"] == gaps["train"]["height_rms_mm"]
    held = r["errors"]["held_out"]
    assert held["source"] == "holdout"
    assert held["registration"]["roll_max_deg"] == gaps["held_out_registration"]["roll_max_deg"]
    assert held["calibrated"]["configs"] == gaps["held_out"]["m"]


def test_a_trees_held_out_rows_are_labelled_holdout_or_their_file(reports, tmp_path):
    """Rows held out of a tree's data are 'holdout'; a validation file's, its name."""
    for term in reports["tree"]["errors"]["terms"]:
        assert term["held_out"]["source"] == "holdout"
    tree = load_robot("talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"])
    data, check = (simulate_tree(tree, 30, noise_mm=0.05, seed=s).measurements for s in (2, 3))
    check = dataclasses.replace(check, source="check.csv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        report = calibrate(tree, data, validate=check).to_dict()
    assert [t["held_out"]["source"] for t in report["errors"]["terms"]] == ["check.csv"] * 2


@pytest.mark.parametrize("shape", sorted(SHAPES))
def test_parameters_name_their_joint(reports, shape):
    """A joint parameter names a joint of the URDF; frames, markers and objects name none."""
    r = reports[shape]
    for p in r["parameters"]:
        frame = p["name"].startswith(("frame.", "marker", "tool.")) or "." in p["name"]
        assert (p["joint"] is None) == frame, p
    chains_fit = shape == "chains"
    if chains_fit:  # joint placement components: <joint>:<component>
        assert all(p["joint"] == p["name"].split(":")[0] for p in r["parameters"])


def test_tiago_report_names_each_rows_joint_as_calib_show(tmp_path, capsys):
    """On the TIAGo data: every MDH row parameter's joint is its row's in ``calib show``."""
    tiago = REAL / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        data = read_measurements(tiago / "qualisys_2021-11-30_static_postures.csv", chain)
    point1 = tmp_path / "train.csv"
    cols = [*chain.joint_names, "x1", "y1", "z1"]
    q, x = data.q, data.position[:, :3]
    rows = [",".join(cols)] + [
        ",".join(repr(float(v)) for v in (*a, *b)) for a, b in zip(q, x, strict=True)
    ]
    point1.write_text("\n".join(rows) + "\n")
    urdf = str(tiago / "tiago_48_schunk.urdf")
    frames = ["--base", "base_footprint", "--tool", "wrist_ft_tool_link"]
    report = tmp_path / "r.json"
    code = main(
        [
            "calibrate",
            urdf,
            *frames,
            "--data",
            str(point1),
            "--out",
            str(tmp_path / "c.urdf"),
            "--report",
            str(report),
        ]
    )
    assert code == 0
    printed = capsys.readouterr().out  # the printed table names the joint too
    assert re.search(r"arm_5_joint:theta6\s+=", printed), printed
    assert main(["show", urdf, *frames, "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)["frames"]
    params = json.loads(report.read_text())["parameters"]
    # The joint engine names an MDH row's direction <joint>:<parameter><row>.
    rows = [(p, re.fullmatch(r"(\w+):[a-z]+(\d+)", p["name"])) for p in params]
    rows = [(p, m) for p, m in rows if m is not None]
    assert rows
    for p, m in rows:
        assert p["joint"] == shown[int(m.group(2))]["joint"] == m.group(1), p
    names = {p["name"]: p["joint"] for p, _ in rows}
    assert names.get("arm_5_joint:theta6") == "arm_5_joint"


def test_values_and_units_match_the_calibrated_model(reports):
    """A contact fit's MDH directions (``<joint>:<MDH parameter>``, the joint engine's): each
    names a joint the calibration moved (``model.joint_origins``), in the unit of its MDH
    parameter, with the size of the simulated errors (1 mm, 1 mrad: a unit mistake is a
    factor 57 or 1000). (The perturbed robot's MDH rows may take the other sense of a line
    or another representation, so they are not the values' reference.)"""
    r = reports["contacts-plane"]
    moved = set(r["model"]["joint_origins"])
    checked = 0
    for p in r["parameters"]:
        m = re.fullmatch(r"(\w+):(alpha|d|theta|r|beta)(\d+)", p["name"])
        if m is None:
            continue
        joint, kind, _ = m.groups()
        assert p["joint"] == joint and joint in moved, p
        assert p["unit"] == ("rad" if kind in ("alpha", "theta", "beta") else "m")
        assert 1e-7 < abs(p["value"]) < 2e-2, p  # [m or rad]
        assert p["std"] is None or p["std"] > 0
        checked += 1
    assert checked
    assert np.isfinite([p["value"] for p in r["parameters"]]).all()


# --- reading every kind's report back: load_calibrated and calib predict ----------------


def _pin_tool(urdf: Path, base: str, tool: str, names, q: np.ndarray) -> np.ndarray:
    """``oMf[base]^-1 oMf[tool]`` of the written URDF by Pinocchio alone ``(m, 4, 4)``."""
    import pinocchio as pin

    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    out = []
    for row in q:
        x = pin.neutral(model)
        for name, v in zip(names, row, strict=True):
            joint = model.joints[model.getJointId(name)]
            x[joint.idx_q] = v
        pin.framesForwardKinematics(model, data, x)
        oMb, oMt = (data.oMf[model.getFrameId(f)] for f in (base, tool))
        out.append((oMb.inverse() * oMt).homogeneous)
    return np.array(out)


def test_load_calibrated_reads_a_chain_report_of_format_3_and_2(tmp_path):
    """The points predicted from the report are Pinocchio's on the written URDF (the
    measurement frame and markers from the report); a format 2 view gives the same."""
    from calib import DataError, load_calibrated

    chain = load_chain("ur5")
    camp = simulate(chain, 30, noise_mm=0.05, seed=3, measure="pose")
    res = calibrate(chain, camp.measurements).check()
    urdf, report = tmp_path / "c.urdf", tmp_path / "r.json"
    urdf.write_bytes(res.urdf())
    doc = res.to_dict()
    report.write_text(json.dumps(doc))
    q = chain.random_configurations(5, 7)
    model = load_calibrated(urdf, report)
    T = _pin_tool(urdf, chain.base_frame, chain.tool_frame, chain.joint_names, q)
    M = np.array(doc["frames"]["measurement"]["matrix"])
    marker = np.array(next(iter(doc["frames"]["markers"].values())))
    expected = (M @ T)[:, :3, 3] + np.einsum("mij,j->mi", (M @ T)[:, :3, :3], marker)
    assert np.allclose(model.points(q)[:, 0], expected, atol=1e-9)
    old = {k: v for k, v in doc.items() if k in doc["deprecated"] or k not in TOP}
    old.update(format_version="2", compliance=doc["compliance"], urdf=doc["urdf"])
    two = tmp_path / "r2.json"
    two.write_text(json.dumps(old))
    assert np.allclose(load_calibrated(urdf, two).points(q), model.points(q), atol=1e-12)
    for path in (two, report):  # one chain's file: the tool named must be its tool
        assert load_calibrated(urdf, path, chain.tool_frame).chain.tool_frame == chain.tool_frame
        with pytest.raises(DataError, match="tool"):
            load_calibrated(urdf, path, "wrist_1_link")


def test_load_calibrated_and_predict_read_a_contact_report(tmp_path, capsys):
    """A contact calibration's report (format 3) is read: the contact's placement in its
    plane is Pinocchio's on the written URDF with the report's contact frame and plane."""
    from calib import load_calibrated
    from calib.measurements.contact_campaign import write_contacts

    urdf = "talos_full_v2.urdf"
    base, tool = "left_sole_link", "gripper_left_base_link"
    chain = load_robot(urdf, base, tool)
    camp = simulate_contacts(chain, 40, "plane", seed=2)
    data = tmp_path / "touch.csv"
    write_contacts(data, camp.data)
    out, report = tmp_path / "c.urdf", tmp_path / "r.json"
    code = main(
        [
            "calibrate",
            urdf,
            "--base",
            base,
            "--tool",
            tool,
            "--measure",
            "plane",
            "--data",
            str(data),
            "--out",
            str(out),
            "--report",
            str(report),
        ]
    )
    assert code == 0
    doc = json.loads(report.read_text())
    model = load_calibrated(out, report)
    q = camp.data.q[:6]
    T = _pin_tool(out, base, tool, chain.joint_names, q)
    C = np.array(doc["frames"]["contacts"][tool]["matrix"])
    P = np.array(next(iter(doc["objects"]["planes"].values()))["matrix"])
    expected = np.linalg.inv(P) @ T @ C
    assert np.allclose(model.contact_placements(q), expected, atol=1e-9)
    assert np.max(np.abs(expected[:, 2, 3])) < 5e-3  # flush: within the touches' noise
    configs = tmp_path / "q.csv"
    configs.write_text(
        ",".join(chain.joint_names)
        + "\n"
        + "\n".join(",".join(repr(float(v)) for v in row) for row in q)
        + "\n"
    )
    capsys.readouterr()
    code = main(
        [
            "predict",
            str(out),
            "--compliance",
            str(report),
            "--configs",
            str(configs),
            "--out",
            str(tmp_path / "p.csv"),
        ]
    )
    assert code == 0 and (tmp_path / "p.csv").exists()


def test_load_calibrated_and_predict_read_each_tool_of_a_tree_report(tmp_path, capsys):
    """Issue 28: every kind's report is read; a tree's (or several terms') by the tool of one
    term. Each tool's points are Pinocchio's on the written URDF with the report's frames,
    and they are the measured points (0.05 mm noise); without a tool, one line lists them."""
    from calib import DataError, load_calibrated
    from calib.measurements.tree_campaign import simulate_tree

    tools = ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    tree = load_robot("talos", "base_link", tools)
    data = simulate_tree(tree, 40, markers=(0.01, 0.02, 0.05), noise_mm=0.05, seed=2)
    data = data.measurements
    urdf, report = tmp_path / "t.urdf", tmp_path / "t.json"
    calibrate(tree, data).write(urdf, report=report)
    doc = json.loads(report.read_text())
    M = np.array(doc["frames"]["measurement"]["base_link"]["matrix"])
    for tool in tools:
        model = load_calibrated(urdf, report, tool)
        rows = np.array([t == tool for t in data.tool])
        q = data.q[rows][:, [tree.joint_names.index(j) for j in model.chain.joint_names]]
        T = M @ _pin_tool(urdf, "base_link", tool, model.chain.joint_names, q)
        marker = np.array(doc["frames"]["markers"][tool][0])
        expected = T[:, :3, 3] + T[:, :3, :3] @ marker
        assert np.allclose(model.points(q)[:, 0], expected, atol=1e-9)
        assert np.sqrt(np.mean(np.sum((expected - data.position[rows]) ** 2, 1))) < 0.2e-3
    with pytest.raises(DataError, match="a report of 2 terms: name the tool of one") as info:
        load_calibrated(urdf, report)
    assert "\n" not in str(info.value) and all(t in str(info.value) for t in tools)
    configs = tmp_path / "q.csv"
    configs.write_text(",".join(model.chain.joint_names) + "\n" + ",".join(["0.1"] * 9) + "\n")
    argv = ["predict", str(urdf), "--compliance", str(report), "--configs", str(configs)]
    assert main([*argv, "--tool", tools[1], "--out", str(tmp_path / "p.csv")]) == 0
    assert main([*argv, "--out", str(tmp_path / "p2.csv")]) == 2
    assert not (tmp_path / "p2.csv").exists()


def test_load_calibrated_reads_each_touching_term_on_its_own_table_of_one_id(tmp_path):
    """Both TALOS arms touching a table each (both ids ``table1``, planes not shared: their
    bases differ): two planes are fitted, each in its arm's base frame. The report kept one
    (the other term was refused, "not in its base's frame"); each is now ``table1@<tool>``,
    and each term's contact is flush on its own (Pinocchio's placements on the written URDF,
    within the touches' noise)."""
    from calib import Problem, Term, load_calibrated

    arms = [
        load_robot("talos_full_v2.urdf", f"{s}_sole_link", f"gripper_{s}_base_link")
        for s in ("left", "right")
    ]
    data = [simulate_contacts(c, 40, "plane", seed=2 + i).data for i, c in enumerate(arms)]
    result = calibrate(Problem(tuple(Term(c, d) for c, d in zip(arms, data, strict=True))))
    assert result.planes == 2
    urdf, report = tmp_path / "c.urdf", tmp_path / "c.json"
    result.write(urdf, report=report)
    doc = json.loads(report.read_text())
    for k, (arm, touches) in enumerate(zip(arms, data, strict=True)):
        name = f"table1@{arm.tool_frame}"
        assert doc["terms"][k]["objects"] == [name]
        table = doc["objects"]["planes"][name]
        assert table["frame"] == arm.base_frame
        model = load_calibrated(urdf, report, arm.tool_frame)
        T = _pin_tool(urdf, arm.base_frame, arm.tool_frame, arm.joint_names, touches.q)
        C = np.array(doc["frames"]["contacts"][arm.tool_frame]["matrix"])
        expected = np.linalg.inv(np.array(table["matrix"])) @ T @ C
        assert np.allclose(model.contact_placements(touches.q), expected, atol=1e-9)
        assert np.max(np.abs(expected[:, 2, 3])) < 5e-3


def test_each_touching_term_is_read_against_the_table_it_touched(tmp_path):
    """Both TALOS arms from ``base_link``, each touching its own table: both tables are in the
    one base frame; each term's touches are flush on its own (the report's ``terms[k].
    objects``), not on the first table of the base (the other arm's: 352 mm off)."""
    import dataclasses

    from calib import Problem, Term, load_calibrated

    arms = [
        load_robot("talos_full_v2.urdf", "base_link", f"gripper_{s}_base_link")
        for s in ("left", "right")
    ]
    data = [simulate_contacts(c, 40, "plane", seed=2 + i).data for i, c in enumerate(arms)]
    data[1] = dataclasses.replace(data[1], ids=tuple("right_" + i for i in data[1].ids))
    urdf, report = tmp_path / "c.urdf", tmp_path / "c.json"
    calibrate(Problem(tuple(Term(c, d) for c, d in zip(arms, data, strict=True)))).write(
        urdf, report=report
    )
    doc = json.loads(report.read_text())
    assert [t["objects"] for t in doc["terms"]] == [["table1"], ["right_table1"]]
    for arm, touches, table in zip(arms, data, ("table1", "right_table1"), strict=True):
        model = load_calibrated(urdf, report, arm.tool_frame)
        T = _pin_tool(urdf, arm.base_frame, arm.tool_frame, arm.joint_names, touches.q)
        C = np.array(doc["frames"]["contacts"][arm.tool_frame]["matrix"])
        P = np.array(doc["objects"]["planes"][table]["matrix"])
        expected = np.linalg.inv(P) @ T @ C
        assert np.allclose(model.contact_placements(touches.q), expected, atol=1e-9)
        assert np.max(np.abs(expected[:, 2, 3])) < 5e-3


def test_a_refused_calibrations_report_is_not_read(tmp_path, reports):
    """A refused fit writes its report and no URDF: predict read its frames with any URDF."""
    from calib import DataError, load_calibrated

    report = tmp_path / "r.json"
    report.write_text(json.dumps({**reports["chain"], "accepted": False, "refusal": "worse"}))
    with pytest.raises(DataError, match=r"a refused calibration \(worse\)"):
        load_calibrated(load_chain("ur5").urdf_path, report)


def test_a_report_of_a_newer_format_is_refused_in_one_line(tmp_path, reports):
    from calib import DataError, load_calibrated

    report = tmp_path / "r.json"
    model = {**reports["chain"].get("model", {}), "urdf_sha256": "0" * 64}  # another URDF's
    for doc in ({}, {"model": model}):  # its format is said first, with a digest or without
        report.write_text(json.dumps({**reports["chain"], "format_version": "4", **doc}))
        with pytest.raises(DataError, match="format_version '4' is not one this calib reads"):
            load_calibrated(load_chain("ur5").urdf_path, report)


# --- one interface: summary, urdf, write, repr -------------------------------------------


def _results():
    """One result of every shape (the fixtures' fits, as objects)."""
    chain = load_chain("ur5")
    tree = load_robot("talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"])
    left = load_robot("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
    right = load_robot("talos_full_v2.urdf", "right_sole_link", "gripper_right_base_link")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {
            "chain": calibrate(
                chain, simulate(chain, 30, noise_mm=0.05, seed=1, measure="pose").measurements
            ),
            "tree": calibrate(tree, simulate_tree(tree, 30, noise_mm=0.05, seed=2).measurements),
            "contacts": calibrate_contacts(left, simulate_contacts(left, 40, "plane", seed=2).data),
            "chains": calibrate_contact_chains(
                [left, right],
                [simulate_contacts(c, 30, "plane", seed=4).data for c in (left, right)],
                params="offsets",
            ),
        }


@pytest.fixture(scope="module")
def results():
    return _results()


@pytest.mark.parametrize("shape", ["chain", "tree", "contacts", "chains"])
def test_every_result_writes_its_urdf_and_report_the_same_way(results, shape, tmp_path):
    """``write(out, report=)`` writes what ``urdf()`` and ``to_dict()`` give, the report with
    the URDF's SHA-256 in ``model.urdf_sha256``; the summary ends on the verdict; the repr is
    one short line naming the shape."""
    r = results[shape]
    assert r.accepted, r.refusal
    out, report = tmp_path / "cal.urdf", tmp_path / "r.json"
    r.write(out, report=report)
    assert out.read_bytes() == r.urdf()
    expected = json.loads(json.dumps(r.to_dict()))
    expected["model"]["urdf_sha256"] = hashlib.sha256(out.read_bytes()).hexdigest()
    assert json.loads(report.read_text()) == expected
    pin_model = __import__("pinocchio").buildModelFromUrdf(str(out))  # a URDF Pinocchio reads
    assert pin_model.nq > 0
    assert r.summary().splitlines()[-1] == "accepted"
    text = repr(r)
    assert "\n" not in text and len(text) < 300 and f" {r.to_dict()['shape']}: " in text


def test_write_never_overwrites_the_nominal_urdf_and_refuses_a_refused_model(results, tmp_path):
    from calib import CalibrationRefusedError, InvalidArgumentError

    r = results["contacts"]
    nominal = Path(r.to_dict()["urdf"])
    before = nominal.read_bytes()
    with pytest.raises(InvalidArgumentError, match="would overwrite"):
        r.write(nominal)
    assert nominal.read_bytes() == before
    refused = dataclasses.replace(r, refusal="a test refusal")
    out, report = tmp_path / "cal.urdf", tmp_path / "r.json"
    with pytest.raises(CalibrationRefusedError, match="a test refusal"):
        refused.write(out, report=report)
    assert not out.exists() and json.loads(report.read_text())["accepted"] is False


def test_real_talos_joint_fit_names_each_direction_by_its_joint_and_unit():
    """Both arms' real touches, ``auto``: the fit offers each chain's MDH rows as directions of
    joint placement errors (``<joint>:alpha15``). Each names its joint, a joint of the chains
    (Pinocchio's model); angles are in rad, lengths in m (before: no joint, and 'mm' for
    angles in the printed table)."""
    import pinocchio as pin

    from calib import Problem, Term, load_robot, read_contacts

    urdf = "talos_full_v2.urdf"
    real = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
    base = "left_sole_link"
    pairs = ((base, "gripper_left_base_link"), (base, "gripper_right_base_link"))
    chains = [load_robot(urdf, *p) for p in pairs]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        files = ("left_train.csv", "right_train.csv")
        terms = [
            Term(c, read_contacts(real / f, c, "plane"), guess=(0, 0, -0.12))
            for c, f in zip(chains, files, strict=True)
        ]
        result = calibrate(Problem(tuple(terms), holdout=0.25))
    model = pin.buildModelFromUrdf(str(chains[0].urdf_path))
    on_chains = {str(model.names[j]) for c in chains for j in c.joint_ids}
    directions = [p for p in result.to_dict()["parameters"] if ":" in p["name"]]
    assert any(re.search(r":(alpha|theta)\d+$", p["name"]) for p in directions)
    for p in directions:
        joint, what = p["name"].split(":")
        assert p["joint"] == joint and joint in on_chains, p
        angle = what in ("rx", "ry", "rz") or re.fullmatch(r"(alpha|beta|theta)\d+", what)
        assert p["unit"] == ("rad" if angle else "m"), p
    for line in result.summary().splitlines():  # the printed table names each joint once
        named = [j for j in on_chains if f"{j}:" in line]
        assert all(line.count(j) == 1 for j in named), line


def test_compliance_fields_takes_a_terms_index_as_load_calibrated_does(reports):
    """The term's index is checked where it is used (``report_view.compliance_fields``), not
    only by ``load_calibrated``: ``term=True`` was read as "no term True"."""
    from calib import InvalidArgumentError
    from calib.kinematics.report_view import compliance_fields

    doc = reports["chain"]
    assert compliance_fields(doc, "r.json", term=np.int64(0))["tool_frame"] == "tool0"
    for bad in (True, "0", 0.0):
        with pytest.raises(InvalidArgumentError, match="term must be a term's index"):
            compliance_fields(doc, "r.json", term=bad)
