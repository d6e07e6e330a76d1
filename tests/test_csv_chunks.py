"""The measurement reader parses rows by chunks: same numbers, same errors, little memory."""

from __future__ import annotations

import csv
import io
import tracemalloc

import numpy as np
import pytest

import calib.measurements.csvfile as csvfile
from calib import DataError, load_chain, simulate
from calib.measurements.csvfile import measurements_csv, parse_measurements


@pytest.fixture(scope="module")
def ur5():
    return load_chain("ur5")


def _text(chain, m: int, measure: str = "pose") -> str:
    camp = simulate(chain, m, measure, (0.01, 0.02, 0.05), noise_mm=0.05, seed=2)
    return measurements_csv(camp.measurements)


def test_chunks_give_python_float_of_every_cell(ur5, monkeypatch):
    text = _text(ur5, 40, "position").replace(",", " , ")  # spaces around cells too
    monkeypatch.setattr(csvfile, "CHUNK", 3)  # 40 rows: 13 chunks of 3 and one of 1
    data = parse_measurements(text, ur5)
    cells = [[float(c) for c in row] for row in list(csv.reader(io.StringIO(text)))[1:]]
    expected = np.array(cells)  # Python's float() of each cell, joints then x, y, z
    assert np.array_equal(data.q, expected[:, :6])
    assert np.array_equal(data.position, expected[:, 6:9])
    assert data.rows == tuple(range(2, 42))


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ("1e999", "f.csv (row 9, column 'z'): '1e999' is not a finite number"),
        ("0x10", "f.csv (row 9, column 'z'): not a number: '0x10'"),
        (
            "",
            "f.csv (row 9, column 'z'): empty cell: a marker not seen leaves all of x, y, z "
            "empty (or NaN), this row has 1 of them",
        ),
        ("1,2", "f.csv (row 9): expected 9 cells, found 10"),
    ],
)
def test_a_bad_cell_in_a_later_chunk_is_named(ur5, monkeypatch, bad, message):
    lines = _text(ur5, 40, "position").splitlines()
    cells = lines[8].split(",")
    lines[8] = ",".join([*cells[:-1], bad])  # row 8: line 9, the third chunk of 3
    lines[10] = lines[10].replace(",", ";", 1)  # a later error is not the one named
    monkeypatch.setattr(csvfile, "CHUNK", 3)
    with pytest.raises(DataError) as error:
        parse_measurements("\n".join(lines), ur5, "f.csv")
    assert str(error.value) == message


def test_reading_keeps_no_object_per_cell(ur5):
    """20,000 poses (5.1 MB of text): the parse's traced peak stays under three times the
    text's size (2.3 times; before: 6.2 times, io.StringIO's copy of four bytes per character
    and a float object per cell)."""
    text = _text(ur5, 20_000)
    tracemalloc.start()
    try:
        parse_measurements(text, ur5)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 3 * len(text), (peak, len(text))


@pytest.mark.parametrize(
    ("row", "message"),
    [
        ("1,2,3", "f.csv (row 4): expected 10 cells, found 3"),  # short: no tool cell
        ("0,0,0,0,0,0,0.1,0.2,0.3, ", "f.csv (row 4, column 'tool'): empty cell"),
    ],
)
def test_a_bad_row_beside_a_tool_column_is_named(ur5, monkeypatch, row, message):
    lines = [f"{line},tool0" for line in _text(ur5, 5, "position").splitlines()]
    lines[0] = lines[0].replace("tool0", "tool")
    lines[3] = row
    monkeypatch.setattr(csvfile, "CHUNK", 2)
    with pytest.raises(DataError) as error:
        parse_measurements("\n".join(lines), ur5, "f.csv")
    assert str(error.value) == message
    lines[3] = lines[2]
    assert parse_measurements("\n".join(lines), ur5).tool == ("tool0",) * 5


@pytest.mark.parametrize(("sep", "what"), [(";", "';'"), ("\t", "tabs")])
def test_a_file_of_another_separator_is_named(ur5, sep, what):
    """A semicolon- or tab-separated file is one line saying so, not a missing joint column."""
    text = _text(ur5, 5, "position").replace(",", sep)
    with pytest.raises(DataError, match=f"one column containing {what}: write the CSV comma"):
        parse_measurements(text, ur5)


@pytest.mark.parametrize("sep", [";", "\t"])
def test_every_calib_csv_names_another_separator(tmp_path, sep):
    """Touches, pixels and configurations files too: one line naming the separator."""
    from pixel_setups import INTRINSICS

    from calib.design.configurations import parse_configurations
    from calib.measurements.contact_campaign import parse_contacts
    from calib.measurements.pixels import read_observations

    ur5 = load_chain("ur5")
    joints = ",".join(ur5.joint_names)
    touches = f"plane,{joints}\nt,0.1,0.2,0.3,0.4,0.5,0.6\n".replace(",", sep)
    pixels = tmp_path / "obs.csv"
    pixels.write_text(f"{joints},camera,point,u,v\n".replace(",", sep))
    match = "one column containing .*: write the CSV comma-separated"
    with pytest.raises(DataError, match=match):
        parse_contacts(touches, ur5, "plane")
    with pytest.raises(DataError, match=match):
        parse_configurations(f"{joints}\n0,0,0,0,0,0\n".replace(",", sep), ur5)
    with pytest.raises(DataError, match=match):
        read_observations(pixels, ur5.joint_names, {"cam": INTRINSICS}, None)
