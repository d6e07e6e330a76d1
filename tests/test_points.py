"""``--points`` / ``Columns(points=...)``: which measured points of a file are fitted.

The independent route: the same file cut by hand (the csv module keeps the chosen columns)
and read as it is.
"""

from __future__ import annotations

import csv
import json
import warnings
from pathlib import Path

import numpy as np
import pytest
from pinfit import PinChainFit, PinMdhFit, csv_rows
from pinref import instrument_points

from calib import CalibError, Columns, DataWarning, load_chain, read_measurements
from calib.cli.commands import main

TIAGO = Path(__file__).resolve().parents[1] / "data" / "realdata" / "tiago"
TRAIN = TIAGO / "qualisys_2021-11-30_static_postures.csv"
TEST = TIAGO / "qualisys_2021-11-26_static_postures.csv"
CHAIN = ["--base", "base_footprint", "--tool", "wrist_ft_tool_link"]
URDF = str(TIAGO / "tiago_48_schunk.urdf")


def cut(src: Path, dst: Path, points: tuple[int, ...]) -> Path:
    """The file with only the chosen points' columns, renumbered 1.. in the order given."""
    with src.open(newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    coords = {f"{a}{k}" for k in range(1, 5) for a in "xyz"}
    keep = [j for j, name in enumerate(header) if name not in coords]
    chosen = [header.index(f"{a}{p}") for p in points for a in "xyz"]
    names = [f"{a}{i + 1}" for i in range(len(points)) for a in "xyz"]
    with dst.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow([header[j] for j in keep] + names)
        for row in rows[1:]:
            writer.writerow([row[j] for j in keep] + [row[j] for j in chosen])
    return dst


def run_report(tmp_path: Path, name: str, argv: list[str]) -> dict:
    report = tmp_path / f"{name}.json"
    out = tmp_path / f"{name}.urdf"
    code = main(["calibrate", URDF, *CHAIN, *argv, "--out", str(out), "--report", str(report)])
    assert code == 0 and out.exists()
    return json.loads(report.read_text())


@pytest.mark.filterwarnings("ignore::calib.DataWarning")
def test_points_1_is_the_hand_cut_file(tmp_path, capsys):
    """``--points 1`` on the TIAGo's sessions (data and --validate) fits what the files cut to
    x1, y1, z1 by hand fit: 2.963 / 8.962 mm held out (the written URDF read by Pinocchio on
    the other session's rows) against the registration's 4.875 / 12.202. Both are independent
    fits (tests/pinfit.py): a base frame and a marker; and those with the MDH parameters auto
    kept, under its prior (the chain pipeline, gone, gave 2.983 / 9.291)."""
    chosen = run_report(
        tmp_path, "chosen", ["--data", str(TRAIN), "--validate", str(TEST), "--points", "1"]
    )
    train, test = cut(TRAIN, tmp_path / "train.csv", (1,)), cut(TEST, tmp_path / "test.csv", (1,))
    by_hand = run_report(tmp_path, "hand", ["--data", str(train), "--validate", str(test)])
    assert chosen["parameters"] == by_hand["parameters"]
    for part in ("train", "held_out"):
        for model in ("registration", "calibrated"):
            a, b = chosen["errors"][part][model], by_hand["errors"][part][model]
            assert a["position_rms_mm"] == b["position_rms_mm"]
            assert a["position_max_mm"] == b["position_max_mm"]
    held = chosen["errors"]["held_out"]
    got = [
        held[m][k]
        for m in ("calibrated", "registration")
        for k in ("position_rms_mm", "position_max_mm")
    ]
    # the registration's: a base frame and a marker fitted by Pinocchio and scipy alone
    reference = PinChainFit(URDF, *CHAIN[1::2])
    seen, unseen = (csv_rows(path, reference.names) for path in (TRAIN, TEST))
    assert got[2:] == pytest.approx(reference.held_out_mm("frames", seen, unseen), abs=1e-3)
    chain = load_chain(URDF, "base_footprint", "wrist_ft_tool_link")
    rows = read_measurements(test, chain)
    assert held["calibrated"]["configs"] == rows.m  # no held-out row set aside
    urdf = tmp_path / "chosen.urdf"
    points = instrument_points(urdf, chosen, *CHAIN[1::2], chain.joint_names, rows.q)
    e = 1e3 * np.linalg.norm(points - rows.points[:, 0], axis=1)  # [mm]
    assert np.allclose(got[:2], [np.sqrt(np.mean(e**2)), e.max()], rtol=0, atol=1e-9)
    # auto's: its choice (the parameters kept, its prior) fitted by Pinocchio and scipy alone
    choice = chosen["model_choice"]
    named = PinMdhFit(URDF, *CHAIN[1::2])
    independent = named.held_out_named_mm(choice["kept"], seen, unseen, choice["prior_strength"])
    assert got[:2] == pytest.approx(independent, abs=1e-3)


def test_points_are_read_in_the_order_given(tmp_path):
    """Columns(points=(3, 1)): the file's point 3 then point 1, as the hand-cut file reads."""
    chain = load_chain(URDF, "base_footprint", "wrist_ft_tool_link")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        chosen = read_measurements(TRAIN, chain, Columns(points=(3, 1)))
        by_hand = read_measurements(cut(TRAIN, tmp_path / "c.csv", (3, 1)), chain)
    assert chosen.n_markers == 2
    assert np.array_equal(chosen.position, by_hand.position)
    assert np.array_equal(chosen.q, by_hand.q) and chosen.rows == by_hand.rows


def test_points_not_chosen_are_not_read_nor_warned_about(tmp_path):
    """A point left out may have empty cells (an occluded marker); no "ignored" warning."""
    path = tmp_path / "m.csv"
    chain = load_chain("ur5")
    header = ",".join(chain.joint_names) + ",x1,y1,z1,x2,y2,z2\n"
    rows = ["0.1,0.2,0.3,0.4,0.5,0.6,0.5,0.1,0.2,,,\n", "0.2,0.2,0.3,0.4,0.5,0.6,0.4,0.2,0.1,,,\n"]
    path.write_text(header + "".join(rows))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        data = read_measurements(path, chain, Columns(points=(1,)))
    assert data.position.tolist() == [[0.5, 0.1, 0.2], [0.4, 0.2, 0.1]]
    with pytest.raises(CalibError, match="no row sees marker 2"):
        read_measurements(path, chain)


def test_a_marker_not_seen_is_read_or_says_how_to_leave_it_out(tmp_path, capsys):
    """A fitted point's 3 empty cells (an occluded marker) are that marker not seen in the row
    (tests/test_partial_markers.py); a point seen in no row says the way out: the other points
    chosen; a row that sees no point: the row commented out."""
    path = tmp_path / "m.csv"
    chain = load_chain("ur5")
    header = ",".join(chain.joint_names) + ",x1,y1,z1,x2,y2,z2\n"
    seen = "0.1,0.2,0.3,0.4,0.5,0.6,0.5,0.1,0.2,0.6,0.1,0.2\n"
    unseen = "0.2,0.2,0.3,0.4,0.5,0.6,0.4,0.2,0.1,,,\n"
    path.write_text(header + seen + unseen)
    assert read_measurements(path, chain).seen.tolist() == [[True, True], [True, False]]
    path.write_text(header + unseen)
    with pytest.raises(CalibError) as error:
        read_measurements(path, chain)
    assert str(error.value).endswith(
        "(column 'x2'): no row sees marker 2 (its cells are all empty): fit the other points "
        "only (Columns' points)"
    )
    assert main(["calibrate", "ur5", "--data", str(path), "--out", str(tmp_path / "c.urdf")]) == 2
    assert capsys.readouterr().err.rstrip().endswith("fit the other points only (--points)")
    assert read_measurements(path, chain, Columns(points=(1,))).m == 1
    path.write_text(header.replace(",x2,y2,z2", "") + "0.1,0.2,0.3,0.4,0.5,0.6,,,\n")
    with pytest.raises(CalibError, match=r"\(row 2\): empty cells: .* \(start it with #\)$"):
        read_measurements(path, chain)  # one point: no other to fit


@pytest.mark.parametrize(
    ("points", "message"),
    [
        ((5,), "point 5 is not in the file"),
        ((0,), "numbered from 1"),
        ((1.0,), "numbered from 1"),
        ((True,), "numbered from 1"),
        ((1, 2, 1), "point 1 is chosen twice"),
        ((), "at least one point"),
        ("1", "a sequence of point numbers"),
        (1, "a sequence of point numbers"),
    ],
)
def test_bad_points_in_the_api_are_one_line_errors(points, message):
    chain = load_chain(URDF, "base_footprint", "wrist_ft_tool_link")
    with pytest.raises(CalibError, match=message) as info:
        read_measurements(TRAIN, chain, Columns(points=points))
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("5", "point 5 is not in the file (its header has x1, y1, z1 to x4, y4, z4: 4 points)"),
        ("0", "numbered from 1"),
        ("1.5", "expected point numbers separated by commas"),
        ("1,x", "expected point numbers separated by commas"),
        ("1,1", "point 1 is chosen twice"),
        ("", "expected point numbers separated by commas"),
    ],
)
def test_bad_points_on_the_command_line(tmp_path, capsys, value, message):
    """One ``calib: error:`` line, exit 2, no output written."""
    out = tmp_path / "c.urdf"
    argv = ["calibrate", URDF, *CHAIN, "--data", str(TRAIN), "--points", value, "--out", str(out)]
    assert main(argv) == 2
    errors = [
        line for line in capsys.readouterr().err.splitlines() if line.startswith("calib: error:")
    ]
    assert len(errors) == 1 and message in errors[0], errors
    assert not out.exists() and not list(tmp_path.iterdir())


def test_points_chosen_for_the_marker_set_pose(tmp_path):
    """``--orientation markers`` reads the chosen points as the rigid set (3 needed)."""
    chain = load_chain(URDF, "base_footprint", "wrist_ft_tool_link")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        chosen = read_measurements(TRAIN, chain, Columns("markers", points=(2, 3, 4)))
        by_hand = read_measurements(
            cut(TRAIN, tmp_path / "c.csv", (2, 3, 4)), chain, Columns("markers")
        )
        assert np.array_equal(chosen.position, by_hand.position)
        assert np.array_equal(chosen.quaternion, by_hand.quaternion)
        with pytest.raises(CalibError, match=r"needs x1\.\.z3 or more points"):
            read_measurements(TRAIN, chain, Columns("markers", points=(1, 2)))


def test_points_is_refused_where_no_point_is_read(tmp_path, capsys):
    """Contacts record joints alone: ``--points`` there is a one-line error."""
    out = tmp_path / "c.urdf"
    argv = ["calibrate", "ur5", "--measure", "plane", "--data", "d.csv", "--points", "1"]
    assert main([*argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "calib: error: --points is for one chain measured by an instrument" in err, err
