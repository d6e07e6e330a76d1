"""Stated maxima of rows, touches and objects: one line before any work, no output file."""

from __future__ import annotations

import pytest

import calib.calibration.choice as choice
import calib.calibration.entry as entry
import calib.calibration.register as register
import calib.core.checks
import calib.measurements.contact_campaign as contact_campaign
import calib.measurements.csvfile as csvfile
from calib import InvalidArgumentError, load_chain, simulate
from calib.calibration.entry import calibrate_contacts
from calib.cli.commands import main
from calib.core.checks import MAX_OBJECTS, MAX_ROWS, MAX_TOUCHES, check_size
from calib.identification.parameters import parameter_set
from calib.kinematics.mdh import from_chain
from calib.measurements.contact_campaign import contacts_csv, simulate_contacts
from calib.measurements.csvfile import measurements_csv

PEAK_ONE_PLANE = 650e6
"""Peak memory [B] of ``calib calibrate`` on 20,000 touches of one plane, params auto
(``benchmarks/bench_scale.py``)."""

PEAK_500_PLANES = 438e6
"""The same on 2,000 touches of 500 planes."""


def _one_error(capsys, argv) -> str:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if not x.startswith("calib: warning:")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("calib: error: "), err
    assert "Traceback" not in err
    return lines[0]


def test_the_stated_maxima():
    assert (MAX_ROWS, MAX_TOUCHES, MAX_OBJECTS) == (100_000, 50_000, 2_000)
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
    monkeypatch.setattr(register, "MAX_TOUCHES", 11)
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


def test_the_memory_bound_of_the_measured_cases():
    """The estimate covers the measured whole-process peaks (TALOS sole to gripper, params
    auto: 62 columns to select beside the planes' unknowns), which now run; at the stated
    maxima, 50,000 touches of one plane run and 2,000 planes of 4 touches are refused."""
    per_touch, per_column, per_object = choice.SELECTION_BYTES
    limit = calib.core.checks.MAX_WORK_BYTES
    for m, objects, peak in ((20000, 3, PEAK_ONE_PLANE), (2000, 1500, PEAK_500_PLANES)):
        need = m * (per_touch + 62 * per_column + objects * per_object)
        assert peak <= need <= 1.25 * peak and need <= limit
    assert MAX_TOUCHES * (per_touch + 62 * per_column + 3 * per_object) <= limit
    assert 8000 * (per_touch + 62 * per_column + 6000 * per_object) > limit


def test_a_contact_calibration_too_big_for_memory_is_refused_up_front(monkeypatch):
    """params 'auto' on too many touches x columns: one line naming the way out, before the
    registration (no work); at the bound, the selection runs. The objects' part refuses
    every level."""
    chain = load_chain("ur5")
    data = simulate_contacts(chain, 40, "plane", contacts=2, seed=0).data
    mdh = from_chain(chain)  # auto's candidates: the complete set's joint rows 1..n
    dense = 2 + sum(1 <= p.row <= mdh.n for p in parameter_set(mdh, "complete").parameters)
    monkeypatch.setattr(choice, "SELECTION_BYTES", (0, 2**31 // (40 * dense) + 1, 0))
    with pytest.raises(InvalidArgumentError, match="give a level") as err:
        calibrate_contacts(chain, data)
    assert f"40 touches of 2 planes (6 of their unknowns, {dense} other columns to select)" in (
        str(err.value)
    )
    assert calibrate_contacts(chain, data, params="complete").selection is None  # no selection
    monkeypatch.setattr(choice, "SELECTION_BYTES", (0, 2**31 // (40 * dense), 0))
    assert calibrate_contacts(chain, data).selection is not None  # at the bound: selected
    monkeypatch.setattr(choice, "SELECTION_BYTES", (0, 0, 2**31 // (40 * 6) + 1))
    with pytest.raises(InvalidArgumentError, match=r"GB: fewer touches or planes$"):
        calibrate_contacts(chain, data, params="complete")
