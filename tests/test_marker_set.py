"""Rigid marker sets read as poses, and the orientation weight estimated from the data."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import chain_of
from scipy.spatial.transform import Rotation

from calib import Columns, DataError, DataWarning, calibrate, simulate
from calib.calibration.weighting import estimate_weight, pose_angles, variance_ratio
from calib.cli.commands import main
from calib.measurements.csvfile import measurements_csv, parse_measurements
from calib.measurements.marker_set import marker_set_pose

PLATE = np.array([[0.0, 0.0, 0.0], [0.15, 0.0, 0.0], [0.15, 0.1, 0.01], [0.0, 0.1, 0.0]])


def _moved(plate: np.ndarray, m: int, seed: int):
    rot = Rotation.random(m, random_state=seed)
    t = np.random.default_rng(seed).normal(size=(m, 3))
    return rot.as_matrix(), np.einsum("mij,kj->mki", rot.as_matrix(), plate) + t[:, None]


def test_orientation_of_a_rigid_set_follows_its_motion():
    R, points = _moved(PLATE, 20, 1)
    pose = marker_set_pose(points)
    offset = np.swapaxes(R, 1, 2) @ pose.rotations  # the set's frame on the plate: constant
    assert np.allclose(offset, offset[0], atol=1e-12)
    assert pose.spread < 1e-12
    flat = PLATE * [1, 1, 0]  # a flat plate: x from marker 1 to 2, z = x cross (marker 4 - 1)
    R, points = _moved(flat, 5, 6)
    assert np.allclose(np.swapaxes(R, 1, 2) @ marker_set_pose(points).rotations, np.eye(3))


def test_the_frame_is_named_by_the_markers_not_by_the_first_row():
    """Two files of the same plate (other postures, other order) give the same frame."""
    R, points = _moved(PLATE, 30, 2)
    a = marker_set_pose(points[:15])
    b = marker_set_pose(points[15:][::-1])
    off_a = R[0].T @ a.rotations[0]
    off_b = R[-1].T @ b.rotations[0]
    assert np.allclose(off_a, off_b, atol=1e-12)


def test_collinear_markers_are_an_error_and_a_loose_set_a_warning():
    chain = chain_of("ur5")
    data = simulate(chain, configs=8, measure="position", seed=0).measurements
    names = ",".join(chain.joint_names)

    def csv(points):
        cells = [f"x{k},y{k},z{k}" for k in range(1, 4)]
        rows = [
            ",".join(str(float(v)) for v in [*q, *p.ravel()])
            for q, p in zip(data.q, points, strict=True)
        ]
        return "\n".join([names + "," + ",".join(cells), *rows])

    line = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]], dtype=float)
    _, on_line = _moved(line, 8, 3)
    with pytest.raises(DataError, match="on a line"):
        parse_measurements(csv(on_line), chain, columns=Columns("markers"))
    _, loose = _moved(PLATE[:3], 8, 4)
    loose[0, 2] += 0.005  # 5 mm off the rigid set
    with pytest.warns(DataWarning, match="not one rigid set"):
        parse_measurements(csv(loose), chain, columns=Columns("markers"))
    with pytest.raises(DataError, match=r"x1\.\.z3 or more points"):
        parse_measurements(measurements_csv(data), chain, columns=Columns("markers"))


def test_a_loose_set_names_the_row_and_marker_farthest_off_it():
    """One marker 5 mm off the plate in one row (an outlier, two labels swapped): the warning
    names that row (as an editor numbers it, comments counted) and that marker."""
    chain = chain_of("ur5")
    q = chain.random_configurations(8, seed=0)
    _, points = _moved(PLATE, 8, 4)
    points[5, 1] += [0.003, -0.004, 0.0]  # configuration 5, marker 2
    header = ",".join([*chain.joint_names, *(f"{a}{k}" for k in range(1, 5) for a in "xyz")])
    rows = [
        ",".join(str(float(v)) for v in [*qi, *p.ravel()]) for qi, p in zip(q, points, strict=True)
    ]
    text = "\n".join(["# a note", header, *rows])  # configuration 5 is row 8
    with pytest.warns(
        DataWarning, match=r"up to \S+ mm relative to each other \(row 8, marker 2\)"
    ):
        parse_measurements(text, chain, columns=Columns("markers"))


def test_variance_ratio_is_the_simulated_noise_ratio():
    """Pose data with 0.1 mm and 2 mrad noise: sigma_p / sigma_o = 0.05 m/rad."""
    chain = chain_of("ur5")
    rng = np.random.default_rng(5)
    m = 4000
    residuals = np.hstack([rng.normal(0, 1e-4, (m, 3)), rng.normal(0, 2e-3, (m, 3))])
    assert variance_ratio(residuals, pose_angles(1)) == pytest.approx(0.05, rel=0.03)
    assert (
        variance_ratio(np.zeros((5, 6)), pose_angles(1)) is None
    )  # noise-free: the default weight
    data = simulate(chain, 300, "pose", noise_mm=0.1, noise_mrad=2.0, error_mm=0, error_mrad=0)
    res = calibrate(chain, data.measurements, params="frames")
    assert res.orientation_weight == pytest.approx(0.05, rel=0.1)


def test_the_weight_iteration_stops_where_the_ratio_settles():
    calls = []

    def residuals_at(w):
        calls.append(w)  # a fit whose orientation error shrinks as its weight grows
        return np.hstack([np.full((4, 3), 1e-3), np.full((4, 3), 1e-3 / (1 + w))])

    w = estimate_weight(residuals_at, pose_angles(1))
    # no fixed point (the ratio is 1 + w): each fit moves w by 1 from 1, until the 10 fits run out
    assert calls == pytest.approx(list(range(1, 11))) and w == pytest.approx(11)
    calls.clear()

    def settling(w):  # the ratio is 3 sqrt(w): its fixed point 9, reached at half the gap a fit
        calls.append(w)
        return np.hstack([np.full((4, 3), 1e-3), np.full((4, 3), 1e-3 / (3 * np.sqrt(w)))])

    w = estimate_weight(settling, pose_angles(1))
    assert w == pytest.approx(9, rel=0.02) and len(calls) < 10  # stopped where it settles
    fixed = estimate_weight(
        lambda w: np.hstack([np.ones((2, 3)), np.full((2, 3), 4.0)]), pose_angles(1)
    )
    assert fixed == pytest.approx(0.25)


def test_cli_orientation_weight_takes_auto_or_a_number(tmp_path, capsys):
    chain = chain_of("ur5")
    data = simulate(chain, 40, "pose", noise_mm=0.05, seed=2).measurements
    csv = tmp_path / "d.csv"
    csv.write_text(measurements_csv(data))
    base = ["calibrate", "ur5", "--data", str(csv), "--params", "frames"]
    for weight, expect in (("auto", None), ("0.5", 0.5)):
        out = tmp_path / f"{weight}.urdf"
        report = tmp_path / f"{weight}.json"
        code = main(
            [*base, "--out", str(out), "--report", str(report), "--orientation-weight", weight]
        )
        assert code == 0
        if expect is not None:
            assert f'"orientation_weight": {expect}' in report.read_text()
    assert main([*base, "--out", str(tmp_path / "x.urdf"), "--orientation-weight", "heavy"]) != 0
    assert "expected a number or auto" in capsys.readouterr().err
