"""Partial marker rows: a marker not seen in some rows (its x, y, z cells empty) still counts.

A row contributes the markers it has, 3 equations each; a marker not seen there none. The
independent routes: Pinocchio's forward kinematics of the URDF (the closed-form registration's
exact points), the written URDF read by Pinocchio alone (held-out points of a noise-free round
trip), and the full-row fit (the path every complete file takes) of the same data completed at
the partial fit's optimum, whose optimum it must be too, with as many more equations as values
were completed (the noise estimate's count of equations).
"""

from __future__ import annotations

import csv
import json
import re
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from pinref import PinTree

from calib import CalibError, Columns, calibrate, from_chain, load_chain, read_measurements
from calib.calibration.registration import register
from calib.cli.commands import main
from calib.design.configurations import markers_seen
from calib.design.design import evaluate
from calib.measurements.data import Measurements

MARKERS = ((0.05, 0.0, 0.1), (-0.04, 0.03, 0.08), (0.0, -0.05, 0.12))


def simulate(path: Path, configs: int, seed: int, noise: float, measure: str = "position") -> Path:
    """``calib simulate ur5`` of the 3 markers (``noise`` [mm])."""
    marks = [a for m in MARKERS for a in ("--marker", *map(str, m))]
    argv = ["simulate", "ur5", "--out", str(path), "--configs", str(configs), "--seed", str(seed)]
    assert main([*argv, *marks, "--noise-mm", str(noise), "--measure", measure]) == 0
    return path


def blank(src: Path, dst: Path, seed: int, rows: int | None = None) -> np.ndarray:
    """``src`` with one marker's 3 cells emptied in most rows (seeded), the first ``rows``.

    Returns which marker each row sees ``(m, 3)``.
    """
    with src.open(newline="") as f:
        table = list(csv.reader(f))
    head, body = table[0], table[1:]
    rng = np.random.default_rng(seed)
    seen = np.ones((len(body), 3), dtype=bool)
    for i, row in enumerate(body[:rows]):
        k = int(rng.integers(0, 4))  # 3: every marker seen
        if k < 3:
            seen[i, k] = False
            for a in "xyz":
                row[head.index(f"{a}{k + 1}")] = ""
    with dst.open("w", newline="") as f:
        csv.writer(f).writerows([head, *body])
    return seen


def test_empty_cells_of_a_marker_are_that_marker_not_seen(tmp_path, capsys):
    full = simulate(tmp_path / "m.csv", 12, 1, 0.0)
    seen = blank(full, tmp_path / "b.csv", 2)
    chain = load_chain("ur5")
    data, every = read_measurements(tmp_path / "b.csv", chain), read_measurements(full, chain)
    assert np.array_equal(data.seen, seen) and not seen.all()
    assert np.array_equal(np.isnan(data.points[..., 0]), ~seen)
    assert np.array_equal(data.points[seen], every.points[seen])
    assert data.partial and not every.partial and every.seen_rows(9) is None
    assert np.array_equal(markers_seen(tmp_path / "b.csv", chain), seen)
    assert markers_seen(full, chain) is None


def test_a_marker_written_nan_is_that_marker_not_seen(tmp_path):
    """MATLAB, NumPy and spreadsheets write a lost reading NaN (or #N/A): read as empty cells,
    by the reader and by ``design``'s file reading alike."""
    full = simulate(tmp_path / "m.csv", 12, 1, 0.0)
    seen = blank(full, tmp_path / "b.csv", 2)
    text = (tmp_path / "b.csv").read_text()
    nans = iter(["NaN", "nan", "#N/A", "-NaN"] * len(text))
    (tmp_path / "n.csv").write_text(
        "\n".join(",".join(c or next(nans) for c in r.split(",")) for r in text.splitlines())
    )
    assert (
        "NaN" in (tmp_path / "n.csv").read_text() and ",," not in (tmp_path / "n.csv").read_text()
    )
    chain = load_chain("ur5")
    data, empty = (
        read_measurements(tmp_path / "n.csv", chain),
        read_measurements(tmp_path / "b.csv", chain),
    )
    assert np.array_equal(data.seen, seen) and not seen.all()
    assert np.array_equal(data.position, empty.position, equal_nan=True)
    assert np.array_equal(markers_seen(tmp_path / "n.csv", chain), seen)


@pytest.mark.parametrize(
    ("cells", "column", "count"), [(("x2",), "x2", 1), (("y2", "z2"), "y2", 2)]
)
def test_one_or_two_empty_cells_of_a_marker_are_an_error(tmp_path, cells, column, count):
    full = simulate(tmp_path / "m.csv", 6, 1, 0.0)
    with full.open(newline="") as f:
        table = list(csv.reader(f))
    for c in cells:
        table[4][table[0].index(c)] = ""
    with (tmp_path / "b.csv").open("w", newline="") as f:
        csv.writer(f).writerows(table)
    with pytest.raises(CalibError) as error:
        read_measurements(tmp_path / "b.csv", load_chain("ur5"))
    assert str(error.value).endswith(
        f"b.csv (row 5, column '{column}'): empty cell: a marker not seen leaves all of "
        f"x2, y2, z2 empty (or NaN), this row has {count} of them"
    )


def test_a_row_that_sees_no_marker_and_a_marker_no_row_sees_are_errors(tmp_path):
    full = simulate(tmp_path / "m.csv", 6, 1, 0.0)
    with full.open(newline="") as f:
        table = list(csv.reader(f))
    head = table[0]
    points = [j for j, c in enumerate(head) if c[0] in "xyz" and c[1:].isdigit()]
    none = [r.copy() for r in table]
    for j in points:
        none[3][j] = ""
    never = [r.copy() for r in table]
    for row in never[1:]:
        for a in "xyz":
            row[head.index(f"{a}3")] = ""
    chain = load_chain("ur5")
    for rows, message in (
        (none, "b.csv (row 4): empty cells: this row measures no marker"),
        (never, "b.csv (column 'x3'): no row sees marker 3 (its cells are all empty)"),
    ):
        with (tmp_path / "b.csv").open("w", newline="") as f:
            csv.writer(f).writerows(rows)
        with pytest.raises(CalibError, match=re.escape(message)):
            read_measurements(tmp_path / "b.csv", chain)
    assert read_measurements(tmp_path / "b.csv", chain, Columns(points=(1, 2))).m == 6
    seen = blank(full, tmp_path / "b.csv", 3)
    row, k = next((i, int(np.argmin(s))) for i, s in enumerate(seen) if not s.all())
    at = re.escape(f"(row {row + 2}, column 'x{k + 1}'): empty cell: orientation 'markers' needs")
    with pytest.raises(CalibError, match=at):
        read_measurements(tmp_path / "b.csv", chain, Columns("markers"))


def test_the_registration_of_partial_rows_is_exact(tmp_path):
    """The closed form over the points seen: Pinocchio's points of a chosen frame, markers."""
    chain = load_chain("ur5")
    q = chain.random_configurations(30, 5)
    model = PinTree.of_file(chain.urdf_path, chain.base_frame, [chain.tool_frame])
    tool = model.poses(chain.joint_names, q)[:, 0]
    frame = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 1.1), np.array([1.5, -0.4, 0.7])).homogeneous
    markers = np.array(MARKERS)
    base = np.einsum("mij,kj->mki", tool[:, :3, :3], markers) + tool[:, None, :3, 3]
    points = base @ frame[:3, :3].T + frame[:3, 3]
    seen = np.random.default_rng(6).random((30, 3)) > 0.4
    seen[np.arange(30), np.arange(30) % 3] = True  # every row sees a marker
    points[~seen] = np.nan
    state = register(from_chain(chain), q, points)
    assert np.max(np.abs(state.frame - frame)) < 1e-9
    assert np.max(np.abs(state.markers - markers)) < 1e-9


def test_a_noise_free_round_trip_predicts_held_out_points_through_the_urdf(tmp_path):
    """Partial rows calibrated (complete), the written URDF by Pinocchio alone at unseen rows."""
    full = simulate(tmp_path / "m.csv", 70, 7, 0.0)
    seen = blank(full, tmp_path / "b.csv", 8, rows=55)
    lines = (tmp_path / "b.csv").read_text().splitlines()
    train, held = lines[:56], [lines[0], *lines[56:]]
    (tmp_path / "t.csv").write_text("\n".join([*train, *("# " + s for s in held[1:])]) + "\n")
    urdf = tmp_path / "c.urdf"
    argv = ["calibrate", "ur5", "--data", str(tmp_path / "t.csv"), "--params", "complete"]
    assert main([*argv, "--out", str(urdf), "--world-link", "tracker"]) == 0
    assert not seen[:55].all()
    rows = list(csv.DictReader(held))
    chain = load_chain("ur5")
    q = np.array([[float(r[n]) for n in chain.joint_names] for r in rows])
    links = [f"tool0_marker{k + 1}" for k in range(3)]
    got = PinTree.of_file(urdf, "tracker", links).poses(chain.joint_names, q)[..., :3, 3]
    want = np.array([[[float(r[f"{a}{k + 1}"]) for a in "xyz"] for k in range(3)] for r in rows])
    assert np.max(np.abs(got - want)) < 1e-9


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_the_partial_fit_is_the_full_fit_of_its_completed_data(tmp_path, measure):
    """Completed by the partial fit's own predictions, the full-row fit stays there; its noise
    estimate counts the completed values as equations, the partial fit's does not."""
    full = simulate(tmp_path / "m.csv", 40, 9, 0.05, measure)
    seen = blank(full, tmp_path / "b.csv", 10)
    chain = load_chain("ur5")
    data = read_measurements(tmp_path / "b.csv", chain)
    weight = {"orientation_weight": 1.0} if measure == "pose" else {}  # not from the residuals
    part = calibrate(chain, data, params="complete", **weight)
    position = data.position.copy()
    position[np.isnan(position)] = part.points(data.q).reshape(data.m, -1)[np.isnan(position)]
    filled = type(data)(data.joint_names, data.q, position, data.quaternion)
    whole = calibrate(chain, filled, params="complete", **weight)
    q = chain.random_configurations(20, 11)
    assert np.max(np.abs(whole.points(q) - part.points(q))) < 1e-9
    p = len(part.covariance)
    pose = 3 * data.m if measure == "pose" else 0
    r_part, r_full = 3 * int(seen.sum()) + pose, 9 * data.m + pose
    assert part.sigma**2 * (r_part - p) == pytest.approx(whole.sigma**2 * (r_full - p), rel=1e-6)


def test_design_evaluate_scores_the_markers_measured(tmp_path, capsys):
    """A marker not seen gives no information: the rows left out, the indices of those kept."""
    full = simulate(tmp_path / "m.csv", 40, 12, 0.0)
    seen = blank(full, tmp_path / "b.csv", 13)
    chain = load_chain("ur5")
    q = read_measurements(full, chain).q
    partial = evaluate(chain, q, "position", MARKERS, seen=seen)
    every = evaluate(chain, q, "position", MARKERS)
    assert partial.d < every.d and partial.a > every.a
    argv = ["design", "ur5", "--evaluate", str(tmp_path / "b.csv"), "--json"]
    assert main([*argv, *(a for m in MARKERS for a in ("--marker", *map(str, m)))]) == 0
    assert f'"D": {partial.d!r}' in capsys.readouterr().out.replace("\n", "")


def test_a_marker_seen_in_one_row_left_to_fit_is_refused(tmp_path):
    """One row places a marker and says nothing more (the selection's folds without that row
    could not place it): a marker fitted needs 2 rows, held-out rows and outliers aside."""
    chain = load_chain("ur5")
    data = read_measurements(simulate(tmp_path / "m.csv", 30, 14, 0.05), chain)
    position = data.position.copy()
    position[2:, 6:] = np.nan  # marker 3: rows 2 and 3 of the file only
    two = Measurements(data.joint_names, data.q, position, source="two")
    assert calibrate(chain, two, params="complete").after.position_rms < 2e-4
    position[1, 6:] = np.nan
    one = Measurements(data.joint_names, data.q, position, source="one")
    with pytest.raises(CalibError, match=r"^one: marker 3 is seen in 1 row of those fitted"):
        calibrate(chain, one)


def test_validation_rows_that_see_a_marker_once_are_scored_not_refused(tmp_path):
    """Held-out rows are not registered on their own when a marker is seen in fewer rows than
    a fit needs (2): seen once there, they are scored (noise-free: exactly), not refused."""
    chain = load_chain("ur5")
    data = read_measurements(simulate(tmp_path / "m.csv", 50, 15, 0.0), chain)
    held = data.subset(np.arange(40, 50))
    position = held.position.copy()
    position[1:, 6:] = np.nan  # marker 3: the first held-out row only
    once = Measurements(held.joint_names, held.q, position, source="once")
    result = calibrate(chain, data.subset(np.arange(40)), validate=once, params="complete")
    assert result.accepted
    assert result.validation.calibrated.position_rms < 1e-9


def test_folds_whose_held_out_rows_miss_a_marker_report_it_null(tmp_path):
    """Folds none of whose held-out rows sees marker 3: its figures null (strict JSON), no
    NumPy warning; the other markers' figures are numbers."""
    full = simulate(tmp_path / "m.csv", 40, 16, 0.05)
    with full.open(newline="") as f:
        table = list(csv.reader(f))
    at = table[0].index("x3")
    for row in table[21:]:  # marker 3 seen in the first two folds (rows 2-21 of the file) only
        row[at : at + 3] = ["", "", ""]
    with (tmp_path / "b.csv").open("w", newline="") as f:
        csv.writer(f).writerows(table)
    report = tmp_path / "r.json"
    argv = ["calibrate", "ur5", "--data", str(tmp_path / "b.csv"), "--folds", "4"]
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert main([*argv, "--out", str(tmp_path / "c.urdf"), "--report", str(report)]) == 0
    folds = json.loads(report.read_text())["errors"]["held_out"]["folds"]
    for k, fold in enumerate(folds):
        figures = fold["calibrated"]
        assert all(isinstance(figures[f"{a}1_rms_mm"], float) for a in "xyz")
        nulls = [figures[f"{a}3_{s}_mm"] is None for a in "xyz" for s in ("rms", "max")]
        assert nulls == [k >= 2] * 6


def _equations(message: str) -> tuple[int, int]:
    """The equations and unknowns an equation-count refusal says."""
    found = re.search(r"give (\d+) equations \(the points seen\) for the (\d+) ", message)
    assert found, message
    return int(found[1]), int(found[2])


def test_too_few_points_seen_for_the_frame_are_refused_before_the_fit(tmp_path):
    """2 rows of 3 markers count 18 equations for the frame and markers' 15 unknowns (6 + 9),
    but 2 points seen in each give 12: refused by the count, as 2 full rows of 1 marker are."""
    chain = load_chain("ur5")
    data = read_measurements(simulate(tmp_path / "m.csv", 2, 3, 0.05), chain)
    position = data.position.copy()
    position[0, 6:], position[1, :3] = np.nan, np.nan  # row 1 sees markers 1, 2; row 2: 2, 3
    seen = 3 * int(np.isfinite(position[:, ::3]).sum())
    rows = Measurements(data.joint_names, data.q, position, source="seen")
    with pytest.raises(CalibError, match=r"^seen: 2 configurations to fit give") as info:
        calibrate(chain, rows, params="frames")
    assert _equations(str(info.value)) == (seen, 6 + 3 * 3)
    assert seen == 12 <= 15 < 2 * 9


def test_too_few_points_seen_for_a_level_are_refused_by_their_count(tmp_path):
    """A level's equations are the points seen at distinct postures: one marker blanked in a
    few rows takes the count under the level's unknowns where the full rows were over it."""
    chain = load_chain("ur5")
    data = read_measurements(simulate(tmp_path / "m.csv", 5, 4, 0.05), chain)
    position = data.position.copy()
    position[:2, 3:6] = np.nan  # marker 2 not seen in rows 1 and 2, marker 3 in rows 3 and 4
    position[2:4, 6:] = np.nan
    seen = 3 * int(np.isfinite(position[:, ::3]).sum())
    rows = Measurements(data.joint_names, data.q, position, source="seen")
    with pytest.raises(CalibError, match=r"^seen: 5 configurations to fit give") as info:
        calibrate(chain, rows, params="complete")
    equations, unknowns = _equations(str(info.value))
    assert equations == seen == 33
    assert seen <= unknowns < 5 * 9  # refused by the points seen, not by the rows


def _pinocchio_fewest(chain, configs: int = 12) -> tuple[int, int]:
    """The 3 markers' generic rank (every joint placement, the base and tool frames moved by
    Pinocchio, finite differences; each marker's own 3 columns) and the fewest random
    configurations that reach it."""
    ref = PinTree.of_file(chain.urdf_path, chain.base_frame, [chain.tool_frame])
    q = np.random.default_rng(5).uniform(-np.pi, np.pi, (configs, chain.n))
    R = ref.poses(chain.joint_names, q)[:, 0, :3, :3]
    blocks = []
    for k, marker in enumerate(MARKERS):
        W = ref.placement_jacobian(chain.joint_names, q, marker).reshape(configs, 6, -1)[:, :3]
        own = np.zeros((configs, 3, 3 * len(MARKERS)))
        own[:, :, 3 * k : 3 * k + 3] = R
        blocks.append(np.concatenate([W, own], axis=2))
    J = np.stack(blocks, axis=1).reshape(configs, 3 * len(MARKERS), -1)
    ranks = []
    for k in range(1, configs + 1):
        s = np.linalg.svd(J[:k].reshape(-1, J.shape[-1]), compute_uv=False)
        ranks.append(int(np.sum(s > 1e-7 * s[0])))
    return ranks[-1], ranks.index(ranks[-1]) + 1


def test_the_rank_refusal_asks_for_the_configurations_that_determine_the_level(tmp_path):
    """3 markers, ``complete``: each configuration past the first adds 6 directions (the
    tool's twist), so more than ``unknowns / 9`` are needed; the refusal asks for Pinocchio's
    fewest, and with that many given (a marker unseen once), for more, not for fewer."""
    chain = load_chain("ur5")
    generic, fewest = _pinocchio_fewest(chain)
    data = read_measurements(simulate(tmp_path / "m.csv", fewest, 4, 0.05), chain)
    few = data.subset(np.arange(fewest - 1))
    with pytest.raises(CalibError, match="rank of the identification Jacobian") as info:
        calibrate(chain, few, params="complete")
    message = str(info.value)
    assert "parameters of params 'complete'" in message and f" of the {generic} " in message
    assert f"measure at least {fewest} configurations that move every joint," in message
    assert (fewest - 1) * 9 > generic  # the count alone (more equations) let them through
    position = data.position.copy()
    position[0, :3] = np.nan  # marker 1 unseen in the first row: 3 fewer equations
    rows = Measurements(data.joint_names, data.q, position, source="seen")
    with pytest.raises(CalibError, match="rank of the identification Jacobian") as info:
        calibrate(chain, rows, params="complete")
    message = str(info.value)
    assert "measure at least" not in message
    more = "measure more configurations that move every joint and see every marker"
    assert f"{more} ({fewest} at generic postures are enough)," in message
