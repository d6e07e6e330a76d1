"""A warning points at the user's line (the call into calib), not at calib's own code.

Before, each ``warnings.warn`` guessed its ``stacklevel``; reached through another public
function (``calibrate`` reading rows, ``simulate``), the guess landed inside calib, so
``python -W error`` tracebacks and the ``once`` filter named calib's line.
"""

from __future__ import annotations

import warnings

import pytest

import calib


def _warned(call) -> list[warnings.WarningMessage]:
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        call()
    return [w for w in got if issubclass(w.category, calib.DataWarning)]


def test_a_data_warning_of_read_measurements_points_at_the_callers_line(tmp_path):
    chain = calib.load_chain("ur5")
    data = calib.simulate(chain, 6, seed=1).measurements
    path = tmp_path / "m.csv"
    calib.write_measurements(path, data)
    text = path.read_text().splitlines()
    text = [text[0] + ",comment"] + [line + ",x" for line in text[1:]]
    path.write_text("\n".join(text) + "\n")
    got = _warned(lambda: calib.read_measurements(path, chain))
    assert got, "no DataWarning for an ignored column"
    assert all(w.filename == __file__ for w in got), [(w.filename, w.lineno) for w in got]


def test_a_rank_warning_points_at_the_callers_line():
    chain = calib.load_chain("ur5")
    with warnings.catch_warnings(record=True) as got:
        warnings.simplefilter("always")
        calib.analyze(chain, configs=3)
    ranks = [w for w in got if issubclass(w.category, calib.RankWarning)]
    if not ranks:
        pytest.fail("3 configurations of a UR5 should warn that they determine too little")
    assert all(w.filename == __file__ for w in ranks)
