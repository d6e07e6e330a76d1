"""``cross_validate(..., seed=S)`` and ``calibrate --folds K --seed S``: random folds.

A seed given shuffles the postures before they are cut; not given, the folds stay contiguous
(tests/test_folds.py). The expected folds are drawn here with NumPy alone, and the expected
figures come from explicit ``validate=`` fits of those folds, pooled here, and from the
documented TALOS table (docs/howto/contacts.md, `benchmarks/talos_contact_calibration.py`: its
own folds, ``numpy.random.default_rng(0).permutation`` of the touches cut in 5).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from calib import InvalidArgumentError, Problem, Term, calibrate, cross_validate, load_chain
from calib.cli.commands import main
from calib.design.folds import fold_of_rows
from calib.measurements.contact_campaign import read_contacts, simulate_contacts

pytestmark = [  # the real TALOS file's other joints, said; any NumPy warning fails
    pytest.mark.filterwarnings("ignore:.*columns not on the chain:calib.DataWarning"),
    pytest.mark.filterwarnings("error::RuntimeWarning"),
]

TALOS = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
LEFT = ("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
CONTACT = (0.0, 0.0, -0.12)


def test_a_seed_draws_the_folds_a_permutation_cuts():
    """Each object's touches permuted by the seed, then cut in K runs; a repeat stays whole."""
    chain = load_chain("ur5")
    data = simulate_contacts(chain, 30, contacts=2, seed=3).data
    order = np.r_[np.arange(data.m), [4, 4]]  # touch 4 repeated at the end
    repeated = data.subset(order)
    labels = fold_of_rows(repeated, 3, seed=7)
    rng = np.random.default_rng(7)
    ids = np.array(data.ids)
    for name in dict.fromkeys(data.ids):  # objects in order of first appearance
        rows = np.flatnonzero(ids == name)
        for k, part in enumerate(np.array_split(rng.permutation(rows), 3)):
            assert np.all(labels[part] == k), (name, k)
    assert labels[-1] == labels[-2] == labels[4]
    assert np.array_equal(fold_of_rows(repeated, 3, seed=7), labels)  # seeded: the same draw
    assert not np.array_equal(fold_of_rows(repeated, 3, seed=8), labels)
    assert np.array_equal(fold_of_rows(repeated, 3), fold_of_rows(repeated, 3, seed=None))


def _talos():
    chain = load_chain(*LEFT)
    return chain, read_contacts(TALOS / "left_train.csv", chain, "plane")


def test_seeded_folds_are_the_explicit_fits_of_the_permuted_folds():
    """The pooled held-out gaps of ``seed=0``: those of 5 ``validate=`` fits of the folds a
    permutation cuts; and the documented TALOS figures (left, ``auto``, and the baseline)."""
    chain, data = _talos()
    parts = np.array_split(np.random.default_rng(0).permutation(data.m), 5)
    runs = []
    for part in parts:
        held = np.isin(np.arange(data.m), part)
        fit = calibrate(chain, data.subset(~held), validate=data.subset(held), marker=CONTACT)
        runs.append(fit.chains[0].stats)
    folded = cross_validate(chain, data, folds=5, seed=0, marker=CONTACT)
    stats = folded.chains[0].stats
    for what in ("held_out", "held_out_registration"):
        own = [r[what] for r in runs]
        for i in range(3):  # height, roll, pitch
            expected = math.sqrt(sum(s.m * s.rms[i] ** 2 for s in own) / data.m)
            assert stats[what].rms[i] == pytest.approx(expected, rel=1e-8)
    shown = [round(v, 2) for v in (*stats["held_out"].rms, *stats["held_out_registration"].rms)]
    assert shown == [4.92, 0.68, 0.61, 13.62, 1.17, 0.95]  # docs/howto/contacts.md's table
    assert folded.chains[0].held_source == "5 folds, seed 0"
    contiguous = cross_validate(chain, data, folds=5, marker=CONTACT).chains[0]
    assert contiguous.held_source == "5 folds"
    assert abs(contiguous.stats["held_out"].rms[0] - stats["held_out"].rms[0]) > 1.0  # mm


def test_a_problems_folds_take_the_seed_too():
    """``cross_validate(problem, seed=S)``: the problem's folds shuffled, its own seed kept."""
    chain, data = _talos()
    problem = Problem((Term(chain, data, None, CONTACT),))
    by_problem = cross_validate(problem, folds=5, seed=0).chains[0].stats["held_out"]
    by_chain = cross_validate(chain, data, folds=5, seed=0, marker=CONTACT)
    assert by_problem.rms == by_chain.chains[0].stats["held_out"].rms


@pytest.mark.parametrize("seed", [-1, 1.5, True, "0"])
def test_a_bad_seed_is_a_one_line_error(seed):
    chain, data = _talos()
    with pytest.raises(InvalidArgumentError, match="the seed must be an integer >= 0"):
        cross_validate(Problem((Term(chain, data, None, CONTACT),)), folds=5, seed=seed)


def test_the_command_lines_seed_shuffles_its_folds(tmp_path, capsys):
    """``--folds 5 --seed 0``: the Python figures; ``--folds 5`` alone: contiguous folds."""
    chain, data = _talos()
    args = ["calibrate", *LEFT[:1], "--base", LEFT[1], "--tool", LEFT[2], "--measure", "plane"]
    args += ["--data", str(TALOS / "left_train.csv"), "--contact", "0", "0", "-0.12"]
    sources = {}
    for extra, seed in (([], None), (["--seed", "0"], 0)):
        report = tmp_path / f"r{seed}.json"
        outputs = ["--out", str(tmp_path / "c.urdf"), "--report", str(report)]
        code = main([*args, "--folds", "5", *extra, *outputs])
        capsys.readouterr()
        assert code == 0
        held = json.loads(report.read_text())["errors"]["held_out"]
        sources[seed] = held["source"]
        expected = cross_validate(chain, data, folds=5, seed=seed, marker=CONTACT)
        height = expected.chains[0].stats["held_out"].rms[0]  # mm, as printed
        assert held["calibrated"]["height_rms_mm"] == pytest.approx(height, rel=1e-9)
    assert sources == {None: "5 folds", 0: "5 folds, seed 0"}
