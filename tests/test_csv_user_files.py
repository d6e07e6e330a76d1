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
from calib.measurements.csvfile import MM_HINT, measurements_csv


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
