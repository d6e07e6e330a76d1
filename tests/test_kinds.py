"""Measurement kinds: one object per kind, names read in one place (kind_of)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import calib
from calib import InvalidArgumentError, load_chain
from calib.identification import jacobian, measures
from calib.identification.contacts import (
    FixedPointContact,
    FixedPoseContact,
    PlaneContact,
    PlanePointContact,
)
from calib.identification.kinds import campaign_kind, kind_of
from calib.measurements import simulation as simulate_module


def test_measurement_is_one_class_everywhere():
    assert calib.Measurement is measures.Measurement is jacobian.Measurement
    assert calib.Measurement.of("pose") == measures.POSE


@pytest.mark.parametrize(
    ("name", "rows"),
    [("pose", (0, 1, 2, 3, 4, 5)), ("position", (0, 1, 2)), ("rz, x", (0, 5))],
)
def test_kind_of_instrument_names(name, rows):
    kind = kind_of(name, (0.1, 0.0, 0.0))
    assert isinstance(kind, calib.Measurement) and kind.rows == rows
    assert kind.marker == (0.1, 0.0, 0.0) and not kind.is_contact
    assert kind_of(kind) is kind  # a kind passes through


@pytest.mark.parametrize(
    ("name", "cls", "rows", "constants"),
    [
        ("plane", PlaneContact, ("height", "roll", "pitch"), 3),
        ("plane-point", PlanePointContact, ("height",), 3),
        ("fixed-point", FixedPointContact, ("x", "y", "z"), 3),
        ("fixed-pose", FixedPoseContact, ("x", "y", "z", "rx", "ry", "rz"), 6),
    ],
)
def test_kind_of_contacts(name, cls, rows, constants):
    kind = kind_of(name)
    assert type(kind) is cls and kind.is_contact and kind.label == name
    assert kind.row_names == rows and kind.n_rows == len(rows)
    assert kind.unknown_constants() == constants
    assert isinstance(kind, measures.MeasureKind)


def test_unknown_constants_of_instruments():
    # the measurement frame 6, 3 per marker, and the measured frame's rotation for a pose
    assert kind_of("position").unknown_constants(4) == 6 + 12
    assert kind_of("pose").unknown_constants(1) == 6 + 3 + 3


@pytest.mark.parametrize("bad", ["planes", "", "x,q", 3])
def test_bad_names(bad):
    with pytest.raises(InvalidArgumentError) as info:
        kind_of(bad)
    assert repr(bad) in str(info.value)


def test_campaign_kind_refuses_rows_and_contacts():
    with pytest.raises(InvalidArgumentError, match="unknown measure 'x,y'"):
        campaign_kind("x,y")
    with pytest.raises(InvalidArgumentError, match=r"^a plane contact is not a measured campaign"):
        campaign_kind("plane")  # a kind calib knows: not "unknown"
    assert campaign_kind("pose").is_pose


def test_simulate_has_its_own_module_and_takes_a_kind():
    assert calib.simulate is simulate_module.simulate
    from calib.measurements.csvfile import simulate  # still found where it was

    assert simulate is simulate_module.simulate
    chain = load_chain("ur5")
    by_name = calib.simulate(chain, 20, "position", seed=3)
    by_kind = calib.simulate(chain, 20, kind_of("position"), seed=3)
    np.testing.assert_array_equal(by_name.measurements.position, by_kind.measurements.position)
    with pytest.raises(
        InvalidArgumentError, match=r"contact .*\(touches: calib.simulate_contacts\)"
    ):
        calib.simulate(chain, 5, "plane")


def test_reading_a_csv_does_not_import_the_analysis():
    code = (
        "import sys, calib.measurements.csvfile as c; "
        "print('calib.identification.identifiability' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
