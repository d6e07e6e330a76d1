"""``calib analyze`` ends with a next step for every kind that has one, and that command runs:
``--term`` problems (one term: calibrate's ``--base``/``--tool``/``--data``; several: the same
``--term``), ``calib demo`` (its UR5 in pose, checked against design's own refusal), and a
contact's row 0 is named for the object it places (the plane, the point), not a base frame.
(``--measure pixels``: tests/test_pixel_count_draws.py.)
"""

from __future__ import annotations

import json
import re
import shlex

import pytest

import calib
from calib.cli.commands import main
from calib.measurements.contact_campaign import write_contacts

URDF = "talos_full_v2.urdf"
ARMS = (
    ("left_sole_link", "gripper_left_base_link"),
    ("right_sole_link", "gripper_right_base_link"),
)


def run(capsys, *argv) -> str:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


def calibrate_words(last: str) -> list[str]:
    found = re.fullmatch(r"next: calib (calibrate .*) fits what the data determine", last)
    assert found is not None, last
    return shlex.split(found.group(1))


def test_one_term_is_calibrated_as_one_chain(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    run(capsys, "simulate", "ur5", "--configs", "30", "--out", "meas.csv")
    last = run(capsys, "analyze", "ur5", "--term", "position", "base_link", "tool0", "meas.csv")
    words = calibrate_words(last.splitlines()[-1])
    one_term = ["calibrate", "ur5", "--term", "position", "base_link", "tool0", "meas.csv"]
    assert main([*one_term, "--out", "a.urdf"]) == 2
    assert "two terms or more" in capsys.readouterr().err  # why one term is not --term
    assert "accepted" in run(capsys, *words)
    assert (tmp_path / "calibrated.urdf").exists()


def test_several_terms_are_calibrated_together(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv = ["analyze", URDF]
    for k, pair in enumerate(ARMS):
        chain = calib.load_robot(URDF, *pair)
        data = calib.simulate_contacts(chain, 24, "plane", seed=1 + k).data
        write_contacts(tmp_path / f"arm{k}.csv", data)
        argv += ["--term", "plane", *pair, f"arm{k}.csv"]
    words = calibrate_words(run(capsys, *argv).splitlines()[-1])
    assert words[:2] == ["calibrate", URDF] and words.count("--term") == 2
    run(capsys, *words)
    assert (tmp_path / "calibrated.urdf").exists()


def test_the_demo_ends_with_the_ur5s_next_step(capsys, tmp_path, monkeypatch):
    """design refuses one configuration fewer than the line's least K, saying that K."""
    monkeypatch.chdir(tmp_path)
    last = run(capsys, "demo").splitlines()[-1]
    found = re.fullmatch(
        r"next: calib (design .*) --configs K --out (\S+) chooses K >= (\d+) postures.*"
        r"then calib (calibrate .*)",
        last,
    )
    assert found is not None, last
    design, least = [*shlex.split(found.group(1)), "--out", found.group(2)], int(found.group(3))
    assert design[:2] == ["design", "ur5"] and "pose" in design
    assert main([*design, "--configs", str(least - 1), "--quiet", "--candidates", "200"]) == 2
    assert f"choose at least {least} configurations" in capsys.readouterr().err
    assert main([*design, "--configs", str(least), "--quiet", "--candidates", "200"]) == 0


@pytest.mark.parametrize(("measure", "label"), [("plane", "plane"), ("fixed-point", "point")])
def test_a_contacts_row_0_is_its_objects(capsys, measure, label):
    """Row 0 places the contact's object (frame -1, the analysis' base frame: ``plane``,
    ``fixed-point``), as the contact's own lines say (``frame -1``); a measured chain's row 0
    stays the base frame."""
    doc = json.loads(run(capsys, "analyze", "ur5", "--measure", measure, "--json"))
    assert doc["base_frame"] == measure and doc["unseen"][0].count("frame -1") == 1
    row0 = [e for e in doc["parameters"] if e["row"] == 0]
    assert row0 and all(e["frame"] == measure and e["joint"] is None for e in row0)
    text = run(capsys, "analyze", "ur5", "--measure", measure)
    assert re.search(rf"^0  \({label} frame\)  +", text, re.M)
    assert f"r0 ({label} frame)" in text and "(base frame)" not in text
    assert re.search(r"^0  \(base frame\)  +", run(capsys, "analyze", "ur5"), re.M)
