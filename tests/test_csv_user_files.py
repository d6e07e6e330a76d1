"""A user's own measurement file: comment lines, millimetres written as metres.

The expected numbers are Python's ``float`` of the cells written here (the ``csv`` module
reads them), never calib's own reading of another file.
"""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from calib import Columns, DataError, load_chain, read_measurements, simulate
from calib.cli import main
from calib.cli.flags import FLAGS
from calib.design.configurations import read_configurations
from calib.identification.pinhole import Pinhole
from calib.measurements.contact_campaign import parse_contacts
from calib.measurements.csvfile import MM_HINT, measurements_csv
from calib.measurements.detection_files import read_image_joints
from calib.measurements.intrinsics import Intrinsics
from calib.measurements.pixels import parse_observations, parse_target


@pytest.fixture(scope="module")
def ur5():
    return load_chain("ur5")


def _lines(chain, m=12) -> list[str]:
    camp = simulate(chain, m, "position", (0.01, 0.02, 0.05), noise_mm=0.05, seed=3)
    return measurements_csv(camp.measurements).splitlines()


def _cells(lines: list[str]) -> np.ndarray:
    return np.array([[float(c) for c in row] for row in csv.reader(io.StringIO("\n".join(lines)))])


def test_comment_lines_are_skipped_and_rows_keep_their_editor_numbers(ur5, tmp_path):
    """Notes above the header (an instrument's export), a row commented out, a comment with
    quotes and commas: skipped; the rows are numbered as an editor numbers the file's lines."""
    lines = _lines(ur5)
    text = [
        "# UR5 SN 123, Leica AT960, 2026-11-27",
        '  # units: m, "tracker" frame, 3 SMRs',
        lines[0],
        lines[1],
        "#" + lines[2],  # a posture left out
        *lines[3:],
    ]
    path = tmp_path / "mine.csv"
    path.write_text("\n".join(text) + "\n")
    data = read_measurements(path, ur5)
    expected = _cells([lines[1], *lines[3:]])
    assert np.array_equal(data.q, expected[:, :6])
    assert np.array_equal(data.position, expected[:, 6:9])
    assert data.rows == (4, *range(6, 6 + len(lines) - 3))
    bad = [*text[:6], text[6].replace(text[6].split(",")[7], "12 mm", 1), *text[7:]]
    path.write_text("\n".join(bad) + "\n")
    with pytest.raises(DataError, match=r"row 7, column 'y'.*not a number: '12 mm'"):
        read_measurements(path, ur5)


def test_a_configurations_file_takes_comment_lines(ur5, tmp_path):
    lines = [line.split(",")[:6] for line in _lines(ur5)]
    path = tmp_path / "plan.csv"
    path.write_text("# my plan\n" + "\n".join(",".join(c) for c in lines) + "\n")
    q = read_configurations(path, ur5)
    assert np.array_equal(q, np.array([[float(c) for c in row] for row in lines[1:]]))


def test_a_header_written_as_a_comment_is_named(ur5, tmp_path):
    """numpy's ``savetxt(header=...)`` writes ``# name,...``: the first row is numbers."""
    lines = _lines(ur5)
    path = tmp_path / "np.csv"
    path.write_text("\n".join(["# " + lines[0], *lines[1:]]) + "\n")
    with pytest.raises(DataError, match=r"row 2\): the header holds numbers.*# comment"):
        read_measurements(path, ur5)


def _in_mm(lines: list[str], offset_m: float) -> list[str]:
    """The positions in millimetres, the instrument ``offset_m`` metres away along x."""
    rows = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        xyz = [(float(c) + (offset_m if k == 0 else 0.0)) * 1000 for k, c in enumerate(cells[6:])]
        rows.append(",".join([*cells[:6], *(f"{v:.4f}" for v in xyz)]))
    return rows


def test_millimetres_read_as_metres_name_units_mm(ur5, tmp_path, capsys):
    """A tracker 3 m away writes thousands of millimetres: refused, and the way out named."""
    path = tmp_path / "mm.csv"
    path.write_text("\n".join(_in_mm(_lines(ur5), 3.0)) + "\n")
    with pytest.raises(DataError, match="not a plausible measurement") as info:
        read_measurements(path, ur5)
    assert str(info.value).endswith(MM_HINT) and "Columns(units='mm')" in MM_HINT
    assert main(["calibrate", "ur5", "--data", str(path), "--out", str(tmp_path / "c.urdf")]) == 2
    err = capsys.readouterr().err
    assert "millimetres? read them with --units mm" in err and "Columns(" not in err
    assert any(key in MM_HINT for key in FLAGS)  # the table holds the library's text
    data = read_measurements(path, ur5, Columns(units="mm"))
    expected = _cells(_in_mm(_lines(ur5), 3.0)[1:])[:, 6:9] / 1000
    assert np.allclose(data.position, expected, rtol=0, atol=1e-15)


def test_coordinates_too_large_even_in_millimetres_are_not_called_millimetres(ur5, tmp_path):
    lines = _lines(ur5)
    path = tmp_path / "far.csv"
    path.write_text("\n".join(_in_mm(lines, 2.0e3)) + "\n")  # 2 km away: 2e6 mm
    with pytest.raises(DataError, match="not a plausible measurement") as info:
        read_measurements(path, ur5)
    assert "millimetres" not in str(info.value)
    path.write_text("\n".join(_in_mm(lines, 300.0)) + "\n")  # 3e5: 3 km in cm, 300 m in mm
    with pytest.raises(DataError, match="not a plausible") as info:
        read_measurements(path, ur5, Columns(units="cm"))
    assert str(info.value).endswith(MM_HINT)


CAMERAS = {"c": Intrinsics(640, 480, Pinhole(600.0, 600.0, 320.0, 240.0))}
NOTES = "# notes\n# of the campaign\n"
"""Two comment lines above the header: the header is row 3."""


def test_header_errors_name_the_header_row_below_comment_lines(ur5, tmp_path):
    """Each reader's header error names the header's row, not row 1 (a comment)."""
    joints = ",".join(ur5.joint_names[1:])  # the first joint's column missing
    with pytest.raises(DataError, match=r"row 3\).*no column for joint shoulder_pan_joint"):
        parse_contacts(f"{NOTES}plane,{joints}\n0,0,0,0,0,0\n", ur5, "plane", "t.csv")
    with pytest.raises(DataError, match=r"row 3, column 'shoulder_pan_joint'\): missing joint"):
        parse_observations(
            f"{NOTES}camera,point,u,v,{joints}\nc,1,1,1,0,0,0,0,0\n", ur5.joint_names, CAMERAS
        )
    with pytest.raises(DataError, match=r"row 3, column 'nz'\): missing column"):
        parse_target(f"{NOTES}point,x,y,z,nx,ny\n1,0,0,0,0,1\n")
    path = tmp_path / "images.csv"
    path.write_text(f"{NOTES}{joints}\n0,0,0,0,0\n")
    with pytest.raises(DataError, match=r"row 3\): no 'image' column"):
        read_image_joints(path)


def test_a_row_whose_one_point_is_written_nan_says_to_leave_it_out(ur5, tmp_path, capsys):
    """A tracker's export with its lost beam written NaN (MATLAB, NumPy): the point is not
    seen, so a row of one point measures nothing: one line saying so, exit 2, nothing
    written; the row commented out, the file is read without it."""
    lines = _lines(ur5)
    cells = lines[3].split(",")
    nan_row = ",".join([*cells[:6], "NaN", "nan", "NaN"])
    path, out = tmp_path / "tracker.csv", tmp_path / "cal.urdf"
    path.write_text("\n".join([*lines[:3], nan_row, *lines[4:]]) + "\n")
    assert main(["calibrate", "ur5", "--data", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.strip().splitlines() == [
        f"calib: error: {path} (row 4): empty cells: this row measures no point: leave the row "
        "out (start it with #)"
    ]
    assert not out.exists()
    path.write_text("\n".join([*lines[:3], "#" + nan_row, *lines[4:]]) + "\n")
    data = read_measurements(path, ur5)
    assert data.rows == (2, 3, *range(5, len(lines) + 1))
    assert np.array_equal(data.position, _cells([*lines[1:3], *lines[4:]])[:, 6:9])
