"""The hedged plurals (words48): ``1 outlier row(s)``, ``1 term(s)``, ``2 plane(s)``,
``camera(s) cam``, ``1 marker(s)``, ``unknown argument(s)`` said the count of one in the
singular and several in the plural.

The counts expected come from outside the texts: the outliers, terms, markers, cameras and
arguments given here, the distinct ids in the touches' own column.
"""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from calib import Problem, Term, analyze, calibrate, load_chain, simulate, simulate_contacts
from calib.calibration.outliers import Outlier, set_aside_note
from calib.core.words import counted, noun
from calib.exceptions import DataError, InvalidArgumentError
from calib.measurements.pixels import PixelObservations

CHAIN = load_chain("ur5")


def test_noun_is_the_singular_for_one_only():
    assert [noun(n, "cameras") for n in (0, 1, 2)] == ["cameras", "camera", "cameras"]
    assert noun(1, "touches") == "touch" and noun(1, "see", "sees") == "sees"
    assert noun(3, "see", "sees") == "see" and counted(1, "marker guesses") == "1 marker guess"


@pytest.mark.parametrize(
    ("rows", "unit", "said"),
    [
        ((4,), "rows", "1 outlier row set aside"),
        ((4, 9), "rows", "2 outlier rows set aside"),
        ((4,), "touches", "1 outlier touch set aside"),
    ],
)
def test_the_outliers_set_aside_are_counted(rows, unit, said):
    dropped = [Outlier(r, 5e-3, 1e-3) for r in rows]
    note = set_aside_note(dropped, unit)
    assert note.startswith(said + " ("), note
    assert "(s)" not in note and "(es)" not in note


def test_a_problem_of_one_term_and_of_two():
    one = simulate_contacts(CHAIN, 20, "plane", seed=0).data
    wrist = load_chain("ur5", tool="wrist_3_link")
    two = (Term(CHAIN, one), Term(wrist, simulate_contacts(wrist, 20, "plane", seed=1).data))
    for terms in ((Term(CHAIN, one),), two):
        analysis = analyze(Problem(terms))
        words = "1 term" if len(terms) == 1 else f"{len(terms)} terms"
        assert analysis.summary().splitlines()[0].startswith(f"ur5: {words}, "), analysis
        assert f", {words}, " in repr(analysis) and "(s)" not in repr(analysis)


@pytest.mark.parametrize("contacts", [1, 2])
def test_touches_of_one_plane_and_of_two(contacts):
    data = simulate_contacts(CHAIN, 12, "plane", contacts=contacts, seed=0).data
    planes = len(set(data.contacts))
    assert planes == contacts
    said = "1 plane" if planes == 1 else f"{planes} planes"
    assert repr(data).endswith(f"touches of {said}, 6 joints>"), repr(data)


@pytest.mark.parametrize("markers", [1, 2])
def test_measurements_of_one_marker_and_of_two(markers):
    marker = np.array([[0.05, 0.02, 0.1], [0.0, 0.1, 0.1]])[:markers]
    data = simulate(CHAIN, 12, "position", marker=marker, seed=1).measurements
    said = "1 marker" if markers == 1 else f"{markers} markers"
    assert repr(data).endswith(f", position, {said}>"), repr(data)


@pytest.mark.parametrize("cameras", [("cam",) * 4, ("cam", "top") * 2])
def test_pixels_of_one_camera_and_of_two(cameras):
    obs = PixelObservations(
        CHAIN.joint_names, np.zeros((4, 6)), cameras, ("a",) * 4, np.ones((4, 2))
    )
    names = ", ".join(dict.fromkeys(cameras))
    said = "camera" if len(set(cameras)) == 1 else "cameras"
    assert f", {said} {names}, 6 joints>" in repr(obs), repr(obs)


def test_one_unknown_argument_and_two():
    data = simulate(CHAIN, 12, "position", seed=1).measurements
    with pytest.raises(InvalidArgumentError, match="unknown argument levl"):
        calibrate(CHAIN, data, levl="paper")
    with pytest.raises(InvalidArgumentError, match="unknown arguments levl, noize"):
        calibrate(CHAIN, data, levl="paper", noize=1)


@pytest.mark.parametrize("still", [(1,), (1, 2)])
def test_one_joint_column_not_logged_and_two(still):
    data = simulate(CHAIN, 30, "position", marker=(0.05, 0.02, 0.1), seed=2).measurements
    q = data.q.copy()
    q[:, list(still)] = 0.3
    names = ", ".join(CHAIN.joint_names[j] for j in still)
    said = (
        f"joint column {names} holds one value in every row: was that joint logged?"
        if len(still) == 1
        else f"joint columns {names} hold one value in every row: were those joints logged?"
    )
    with pytest.raises(DataError, match=re.escape(said)):
        calibrate(CHAIN, dataclasses.replace(data, q=q))
