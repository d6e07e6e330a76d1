"""Stated maxima of rows, touches and objects: one line before any work, no output file."""

from __future__ import annotations

import pytest

import calib.calibration.contact_pipeline as contact_pipeline
import calib.calibration.entry as entry
import calib.core.checks
import calib.measurements.contact_campaign as contact_campaign
import calib.measurements.csvfile as csvfile
from calib import InvalidArgumentError, load_chain, simulate
from calib.calibration.contact_pipeline import calibrate_contacts
from calib.cli.commands import main
from calib.core.checks import MAX_OBJECTS, MAX_ROWS, MAX_TOUCHES, check_size
from calib.kinematics.mdh import from_chain
from calib.measurements.contact_campaign import contacts_csv, simulate_contacts
from calib.measurements.csvfile import measurements_csv


def _one_error(capsys, argv) -> str:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if not x.startswith("calib: warning:")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("calib: error: "), err
    assert "Traceback" not in err
    return lines[0]


def test_the_stated_maxima():
    assert (MAX_ROWS, MAX_TOUCHES, MAX_OBJECTS) == (50_000, 50_000, 2_000)
    check_size(MAX_TOUCHES, MAX_TOUCHES, "touches")  # at the limit: accepted
    with pytest.raises(InvalidArgumentError, match="50001 touches: calib handles at most 50000"):
        check_size(MAX_TOUCHES + 1, MAX_TOUCHES, "touches")


def test_too_many_touches_or_planes_in_a_file_is_one_line(tmp_path, capsys, monkeypatch):
    chain = load_chain("ur5")
    data = simulate_contacts(chain, 12, "plane", contacts=4, seed=0).data
    path = tmp_path / "touches.csv"
    path.write_text(contacts_csv(data))
    argv = ["calibrate", "ur5", "--measure", "plane", "--data", path, "--out", tmp_path / "o"]
    monkeypatch.setattr(contact_campaign, "MAX_TOUCHES", 11)
    assert "12 touches: calib handles at most 11" in _one_error(capsys, argv)
    monkeypatch.setattr(contact_campaign, "MAX_TOUCHES", 12)
    monkeypatch.setattr(contact_campaign, "MAX_OBJECTS", 3)
    assert "4 planes: calib handles at most 3" in _one_error(capsys, argv)
    assert not (tmp_path / "o").exists()
    with pytest.raises(InvalidArgumentError, match="4 planes"):
        simulate_contacts(chain, 12, "plane", contacts=4)
    monkeypatch.setattr(contact_pipeline, "MAX_TOUCHES", 11)
    with pytest.raises(InvalidArgumentError, match="12 touches"):
        calibrate_contacts(chain, data)  # data made by the API are held to the same maxima


def test_too_many_rows_is_one_line(tmp_path, capsys, monkeypatch):
    chain = load_chain("ur5")
    data = simulate(chain, 30, "position", seed=0).measurements
    path = tmp_path / "data.csv"
    path.write_text(measurements_csv(data))
    monkeypatch.setattr(csvfile, "MAX_ROWS", 29)
    argv = ["calibrate", "ur5", "--data", path, "--out", tmp_path / "o"]
    assert "30 rows: calib handles at most 29" in _one_error(capsys, argv)
    assert not (tmp_path / "o").exists()
    monkeypatch.setattr(entry, "MAX_ROWS", 29)
    with pytest.raises(InvalidArgumentError, match="30 rows"):
        calib.calibrate(chain, data)


def test_the_selection_bound_of_the_measured_cases():
    """The estimate covers the measured peaks (and refuses them: each is above 2 GB)."""
    per_touch, per_column = contact_pipeline.SELECTION_BYTES
    for m, columns, peak in ((20000, 65, 2.48e9), (1200, 1262, 2.19e9), (2000, 1562, 4.07e9)):
        need = m * (per_touch + columns * per_column)
        assert peak <= need <= 1.25 * peak and need > calib.core.checks.MAX_WORK_BYTES


def test_a_contact_selection_too_big_for_memory_is_refused_up_front(monkeypatch):
    """params 'auto' on too many touches x columns: one line naming the way out, before the
    registration (no work); at the bound, the selection runs."""
    chain = load_chain("ur5")
    data = simulate_contacts(chain, 40, "plane", contacts=2, seed=0).data
    columns = 2 * 3 + 2 + len(contact_pipeline._candidates(from_chain(chain), "auto"))
    monkeypatch.setattr(contact_pipeline, "SELECTION_BYTES", (0, 2**31 // (40 * columns) + 1))
    with pytest.raises(InvalidArgumentError, match="give a level") as err:
        calibrate_contacts(chain, data)
    assert f"{columns} columns (8 of the plane(s) and the contact) on 40 touches" in str(err.value)
    monkeypatch.setattr(contact_pipeline, "SELECTION_BYTES", (0, 2**31 // (40 * columns)))
    assert calibrate_contacts(chain, data).selection is not None  # at the bound: selected
