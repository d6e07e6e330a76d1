"""The report lists the held-out rows it scored (``held_out.rows``), so a ``--holdout`` run can
be checked from the files alone; a pixel term's ``configs`` counts postures, ``pixels`` pixels.

The expected figures come from the written URDF through Pinocchio (and a textbook pinhole for
pixels) at the rows the report lists, and the postures from the CSV's joint columns.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pinocchio as pin
from pinref import pin_config, pin_frame
from pixel_scorer import link_points, textbook_pixels
from pixel_setups import grid

from calib.cli import main
from calib.identification.pinhole import Pinhole
from calib.measurements.intrinsics import Intrinsics, write_intrinsics
from calib.measurements.pixels import write_target

HEAD = ("xtion_optical_frame", "xtion_link")
INTRINSICS = Intrinsics(
    640, 480, Pinhole(522.0, 522.0, 319.5, 239.5, np.array([-0.1, 0.05, 0.0, 0.0, 0.0]))
)


def run(capsys, *argv) -> str:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


def _rows(path: Path) -> list[dict]:
    """The CSV's rows: ``rows[i]`` is line ``i + 2`` (the header is line 1)."""
    with path.open() as f:
        return list(csv.DictReader(f))


def test_a_head_cameras_holdout_lists_its_rows_and_counts_postures(capsys, tmp_path):
    """TIAGo's head camera seeing a tag on the hand, a fifth of the postures held out: the
    listed rows, projected through the written URDF by Pinocchio and a textbook pinhole, give
    the report's held-out reprojection RMS and max; the rows neither listed nor set aside give
    the training ones; ``configs`` is their distinct postures, ``pixels`` their count (it was
    the pixel count under ``configs``, and no row was listed)."""
    write_intrinsics(tmp_path / "intr.yaml", INTRINSICS)
    write_target(tmp_path / "tag.csv", grid(2, 2, 0.06))
    camera = ["--camera", *HEAD, tmp_path / "intr.yaml"]
    common = [*camera, "--target", tmp_path / "tag.csv", "--tool", "arm_tool_link"]
    obs = tmp_path / "obs.csv"
    noise = ["--noise-px", 0.5, "--seed", 1]
    run(
        capsys,
        "simulate",
        "tiago",
        "--measure",
        "pixels",
        *common,
        "--configs",
        800,
        *noise,
        "--out",
        obs,
    )
    urdf, report = tmp_path / "cal.urdf", tmp_path / "r.json"
    outputs = ["--out", urdf, "--report", report]
    run(
        capsys,
        "calibrate",
        "tiago",
        "--measure",
        "pixels",
        "--data",
        obs,
        *common,
        "--holdout",
        0.2,
        *outputs,
    )
    doc = json.loads(report.read_text())
    term = doc["errors"]["terms"][0]
    rows = _rows(obs)
    joints = [c for c in rows[0] if c not in ("camera", "point", "u", "v")]
    model = pin.buildModelFromUrdf(str(urdf))
    tag = {r["point"]: [float(r[k]) for k in "xyz"] for r in _rows(tmp_path / "tag.csv")}

    def errors(lines: list[int]) -> np.ndarray:
        picked = [rows[n - 2] for n in lines]
        q = np.array([[float(r[j]) for j in joints] for r in picked])
        X = np.array([tag[r["point"]] for r in picked])
        p = link_points(model, HEAD[0], "arm_tool_link", joints, q, X)
        uv = textbook_pixels(p, INTRINSICS.camera.camera_matrix, INTRINSICS.camera.distortion)
        return np.linalg.norm(uv - [[float(r["u"]), float(r["v"])] for r in picked], axis=1)

    held = term["held_out"]["rows"]
    aside = {o["row"] for o in doc["outliers"]}
    train = [n for n in range(2, len(rows) + 2) if n not in set(held) | aside]
    assert term["held_out"]["source"] == "holdout" and held == sorted(set(held))
    assert len(joints) == 9  # the head's 2 joints and the arm's 7
    for part, lines in (("train", train), ("held_out", held)):
        e = errors(lines)
        px = term[part]["pixels"]["calibrated"]
        assert np.isclose(np.sqrt(np.mean(e**2)), px["reprojection_rms_px"], rtol=1e-9, atol=0)
        assert np.isclose(np.max(e), px["reprojection_max_px"], rtol=1e-9, atol=0)
        postures = {tuple(rows[n - 2][j] for j in joints) for n in lines}
        for group in ("registration", "calibrated", "urdf"):
            assert term[part][group]["configs"] == len(postures) < len(lines), (part, group)
            assert term[part][group]["pixels"] == len(lines), (part, group)
    assert doc["terms"][0]["configs"] == term["train"]["calibrated"]["configs"]
    every = {tuple(r[j] for j in joints) for r in rows}
    assert term["held_out"]["calibrated"]["configs"] == round(0.2 * len(every))


def test_a_position_holdout_lists_the_rows_its_errors_are_of(capsys, tmp_path):
    """The README's UR5 run: the held-out rows listed, through the written URDF (Pinocchio,
    the marker link and the report's measurement frame), give the held-out RMS and max."""
    data, urdf, report = tmp_path / "meas.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    marker = ["--marker", 0.01, 0.02, 0.05]
    run(capsys, "simulate", "ur5", *marker, "--noise-mm", 0.05, "--seed", 1, "--out", data)
    run(
        capsys,
        "calibrate",
        "ur5",
        "--data",
        data,
        "--holdout",
        0.3,
        "--out",
        urdf,
        "--report",
        report,
    )
    doc = json.loads(report.read_text())
    held = doc["errors"]["held_out"]
    assert held == doc["errors"]["terms"][0]["held_out"]
    rows = _rows(data)
    joints = list(rows[0])[:6]
    model = pin.buildModelFromUrdf(str(urdf))
    kin = model.createData()
    ids = [model.getJointId(n) for n in joints]
    base, marker = pin_frame(model, "base_link"), pin_frame(model, "tool0_marker1")
    M = pin.SE3(np.array(doc["frames"]["measurement"]["matrix"]))
    e = []
    for n in held["rows"]:
        q = np.array([float(rows[n - 2][j]) for j in joints])
        pin.framesForwardKinematics(model, kin, pin_config(model, ids, q))
        seen = M.act(kin.oMf[base].actInv(kin.oMf[marker]).translation)
        e.append(np.linalg.norm(seen - [float(rows[n - 2][k]) for k in "xyz"]))
    assert len(e) == held["urdf"]["configs"] == 30
    assert np.isclose(1e3 * np.sqrt(np.mean(np.square(e))), held["urdf"]["position_rms_mm"])
    assert np.isclose(1e3 * np.max(e), held["urdf"]["position_max_mm"])


def test_held_out_rows_are_the_files_own_line_numbers(capsys, tmp_path):
    """Comment and blank lines above the header and between rows count (docs/reference/
    formats.md, ``rows``): the lines listed are the same records as without them."""
    plain, noted = tmp_path / "plain.csv", tmp_path / "noted.csv"
    run(capsys, "simulate", "ur5", "--configs", 30, "--seed", 3, "--out", plain)
    lines = plain.read_text().splitlines(keepends=True)
    notes = ["# exported by an instrument\n", "\n"]
    noted.write_text("".join([*notes, *lines[:10], "# a row left out\n", "\n", *lines[10:]]))
    listed = []
    for data in (plain, noted):
        report, urdf = (tmp_path / f"{data.stem}.{ext}" for ext in ("json", "urdf"))
        outputs = ["--out", urdf, "--report", report]
        run(capsys, "calibrate", "ur5", "--data", data, "--holdout", 0.3, *outputs)
        listed.append(json.loads(report.read_text())["errors"]["held_out"]["rows"])
    assert len(listed[0]) == 9 and min(listed[0]) >= 2
    shift = [n + 2 if n <= 10 else n + 4 for n in listed[0]]  # the lines added above each row
    assert listed[1] == shift
    text = noted.read_text().splitlines(keepends=True)
    assert [text[n - 1] for n in listed[1]] == [lines[n - 1] for n in listed[0]]
