"""An accepted fit that held nothing out says so, one text for every kind (checks48).

Its held-out figures are null in the report: nothing was checked on unseen postures. The note
says it and names the ways out; with a holdout or K folds (every row held out once) it is not
there. Whether anything was held out is read from the report (each term's held-out errors).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import chain_of
from pixel_setups import INTRINSICS, calibrated, setup

from calib import Problem, Term, calibrate, cross_validate, load_chain, simulate, simulate_contacts
from calib.calibration.engine import NOTHING_HELD
from calib.calibration.pixel_chain import PixelCamera
from calib.cli.flags import in_flags
from calib.measurements.pixel_simulation import simulate_pixels

MARKER = (0.05, 0.02, 0.1)


def _measured(**options):
    chain = chain_of("ur5")
    data = simulate(chain, 30, "position", marker=MARKER, noise_mm=0.05, seed=1).measurements
    return calibrate(chain, data, marker=MARKER, **options)


def _touches(**options):
    chain = chain_of("ur5")
    data = simulate_contacts(chain, 40, "plane", seed=1).data
    return calibrate(chain, data, **options)


def _pixels(tmp_path, **options):
    s = setup("ur5", tmp_path, postures=30)
    obs = simulate_pixels(s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q, seed=1)
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    return calibrated(s.nominal, camera, s.target, obs, **options)


def _held_out(result) -> list:
    """Each term's held-out errors in the report (None: none)."""
    return [t["held_out"] for t in result.to_dict()["errors"]["terms"]]


@pytest.mark.parametrize("kind", ["measured", "touches", "pixels"])
def test_every_kind_says_when_nothing_is_held_out(kind, tmp_path):
    fit = {"measured": _measured, "touches": _touches}.get(kind) or (
        lambda **o: _pixels(tmp_path, **o)
    )
    alone, held = fit(), fit(holdout=0.25)
    assert alone.accepted and held.accepted, (alone.refusal, held.refusal)
    assert _held_out(alone) == [None] and _held_out(held) != [None]
    ways = "holdout or validate)" if kind == "pixels" else "holdout, validate or folds)"
    note = "nothing held out: not checked on unseen postures (hold some out: " + ways
    assert note in alone.notes and not any(n.startswith(NOTHING_HELD) for n in held.notes)
    assert f"note: {note}" in alone.summary()
    assert note in alone.to_dict()["warnings"]


def test_folds_hold_every_row_out_once_so_no_note():
    chain = chain_of("ur5")
    data = simulate(chain, 30, "position", marker=MARKER, noise_mm=0.05, seed=1).measurements
    folded = cross_validate(chain, data, folds=5, marker=MARKER)
    assert _held_out(folded) != [None]
    assert not any(n.startswith(NOTHING_HELD) for n in folded.notes)


def test_a_term_with_nothing_held_out_beside_one_with_validation_is_named():
    """Two terms, the first with validation rows, the second (touches) with none: accepted, and
    the note names the second (before: no note). The same terms with no validation at all keep
    the one note of every term."""
    arm = chain_of("ur5")
    rows = simulate(arm, 55, "position", marker=MARKER, noise_mm=0.05, seed=1).measurements
    first = np.arange(rows.m) < 40
    wrist = load_chain("ur5", "base_link", "wrist_2_link")
    touches = simulate_contacts(wrist, 40, "plane", seed=1).data
    some = calibrate(
        Problem((Term(arm, rows.subset(first), rows.subset(~first)), Term(wrist, touches)))
    )
    none = calibrate(Problem((Term(arm, rows.subset(first)), Term(wrist, touches))))
    assert some.accepted and none.accepted, (some.refusal, none.refusal)
    assert [h is None for h in _held_out(some)] == [False, True]
    term = "term 2 (base_link -> wrist_2_link, plane): "
    note = term + "nothing held out: not checked on unseen postures (hold some out: a term's "
    note += "validate, as the other terms)"
    assert note in some.notes and f"note: {note}" in some.summary()
    assert not any(n.startswith(NOTHING_HELD) for n in some.notes)
    assert NOTHING_HELD + "holdout, validate or folds)" in none.notes
    assert not any(n.startswith("term ") for n in none.notes)


@pytest.mark.parametrize(
    ("ways", "flags"),
    [
        ("holdout, validate or folds)", "--holdout, --validate or --folds)"),
        ("holdout or validate)", "--holdout or --validate)"),
        (
            "a term's validate, as the other terms)",
            "a --term's VALIDATION file, as the other terms)",
        ),
    ],
)
def test_the_command_line_names_its_flags(ways, flags):
    said = in_flags(NOTHING_HELD + ways)
    assert said.endswith(f"(hold some out: {flags}"), said
