"""Several markers end to end (markers48): what a file measures, counts side by side, a tree.

``calib design --evaluate`` of a K-point file scores K points (the user says where, the file
does not); ``calib sweep --markers K`` counts what ``calib analyze --markers K`` counts; a
tree given another number of ``--marker`` than one or one per tool names the flag. The
expected counts are the theory (4R + 2P + 3K, + 3 for a pose) from the robots' joint types,
the expected point counts those the test writes.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import calib
from calib import InvalidArgumentError
from calib.cli.commands import main
from calib.kinematics.tree import load_tree
from calib.measurements.tree_campaign import simulate_tree
from calib.outputs.sweep import sweep

MARKERS = [[0.05, 0.0, 0.1], [-0.03, 0.04, 0.1], [-0.03, -0.04, 0.12]]
"""Three markers on the tool [m] (a cluster on a hand)."""

JOINTS = {"ur5": (6, 0), "panda": (7, 0), "stanford": (5, 1)}
"""Revolute and prismatic joints R, P of each chain (the robots' definitions)."""


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    return code, out, err


def one_error(capsys, *argv) -> str:
    code, out, err = run(capsys, *argv)
    lines = [x for x in err.splitlines() if not x.startswith("calib: warning:")]
    assert code == 2 and len(lines) == 1 and lines[0].startswith("calib: error: "), (out, err)
    return lines[0]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """A UR5 campaign of 3 markers, one of 1 point, and their configurations alone."""
    chain = calib.load_chain("ur5")
    d = tmp_path_factory.mktemp("markers")
    three = calib.simulate(chain, 12, measure="position", marker=MARKERS, seed=1).measurements
    one = calib.simulate(chain, 12, measure="position", seed=1).measurements
    calib.write_measurements(d / "three.csv", three)
    calib.write_measurements(d / "one.csv", one)
    names = ",".join(chain.joint_names)
    rows = "\n".join(",".join(f"{v:.6f}" for v in q) for q in one.q)
    (d / "configs.csv").write_text(f"{names}\n{rows}\n")
    return d


def _markers(k: int) -> list[str]:
    return [a for m in MARKERS[:k] for a in ("--marker", *map(str, m))]


def test_evaluate_scores_the_points_the_file_measures(capsys, files):
    """A 3-point file scored as one point at the tool origin (no --marker) is refused, with
    the way out; 3 --marker score it; a 1-point file with 2 --marker is refused too."""
    three = files / "three.csv"
    line = one_error(capsys, "design", "ur5", "--evaluate", three)
    assert f"{three} measures 3 points" in line and "--marker X Y Z 3 times" in line, line
    line = one_error(capsys, "design", "ur5", "--evaluate", three, *_markers(1))
    assert "measures 3 points, the score would be of 1 point" in line, line
    code, out, err = run(capsys, "design", "ur5", "--evaluate", three, *_markers(3))
    assert code == 0 and "predicted RMS position error" in out, err
    line = one_error(capsys, "design", "ur5", "--evaluate", files / "one.csv", *_markers(2))
    assert "measures 1 point, the score would be of 2 points" in line and "once" in line
    for path, markers in ((files / "one.csv", 0), (files / "configs.csv", 2)):
        code, out, err = run(capsys, "design", "ur5", "--evaluate", path, *_markers(markers))
        assert code == 0, err  # a configurations file says nothing of the points
    code, out, err = run(capsys, "design", "ur5", "--evaluate", three, "--measure", "pose")
    assert code == 0, err  # a pose: the markers read as one frame (--orientation markers)


@pytest.mark.parametrize("measure", ["position", "pose"])
def test_sweep_markers_counts_what_analyze_markers_counts(capsys, measure):
    """Each chain's count is the theory (each marker adds 3 to 4R + 2P, a pose 3 more) and
    ``analyze --markers K``'s, side by side."""
    k, extra = 2, 3 if measure == "pose" else 0
    argv = ["sweep", "--robots", *JOINTS, "--markers", k, "--measure", measure]
    code, out, err = run(capsys, *argv, "--json")
    assert code == 0, err
    rows = {r["robot"]: r for r in json.loads(out)["rows"]}
    for robot, (r, p) in JOINTS.items():
        theory = 4 * r + 2 * p + 3 * k + extra
        row = rows[robot]
        assert (row["n_base_complete"], row["n_theory"], row["verdict"]) == (
            theory,
            theory,
            "complete",
        )
        assert row["n_base_paper"] is None and row["error"] is None
        code, out, err = run(
            capsys, "analyze", robot, "--markers", k, "--measure", measure, "--json"
        )
        assert code == 0 and json.loads(out)["n_identifiable"] == theory, err
        assert json.loads(out)["n_theory"] == theory
    code, out, err = run(capsys, *argv)
    assert code == 0 and "as analyze --markers 2" in out, err
    ur5 = next(line.split() for line in out.splitlines() if line.startswith("ur5 "))
    n = str(4 * 6 + 3 * k + extra)  # R P T std paper complete model theory verdict
    assert ur5[ur5.index("tool0") + 1 :][:9] == ["6", "0", "1", "-", "-", n, "-", n, "complete"]


def test_sweep_markers_rows_without_theory_and_refusals(capsys):
    """A tree is a row with its reason; a planar 2R chain (its first marker's x held) has no
    theory; what --markers would ignore is refused before any work."""
    rows = sweep(robots=["twodof", "bolt"], markers=2)
    assert rows[0].n_theory is None and rows[0].verdict == "-" and "held" in rows[0].note
    assert rows[1].error is not None and "one chain" in rows[1].error
    for extra, said in (
        (["--marker", "0", "0", "0.1"], "--marker is not for --markers"),
        (["--params", "paper"], "--params paper is not for --markers"),
        (["--measure", "plane"], "--markers takes --measure position or pose"),
    ):
        line = one_error(capsys, "sweep", "--robots", "ur5", "--markers", "3", *extra)
        assert said in line, line
    with pytest.raises(InvalidArgumentError, match="position or pose"):
        sweep(robots=["ur5"], measure="plane", markers=2)
    with pytest.raises(InvalidArgumentError, match="give no marker"):
        sweep(robots=["ur5"], marker=[0, 0, 0.1], markers=2)


@pytest.mark.parametrize("command", ["simulate", "design"])
def test_a_tree_given_another_number_of_markers_names_the_flag(capsys, tmp_path, command):
    """bolt has 2 feet: 3 --marker are neither one for both nor one per foot."""
    argv = [command, "bolt", "--configs", 5, *_markers(3), "--out", tmp_path / "o.csv"]
    if command == "design":
        argv += ["--candidates", 40]
    line = one_error(capsys, *argv)
    assert "takes --marker once for all its tools or once per tool" in line, line
    assert "got 3" in line and "markers must be" not in line


def test_simulate_tree_says_the_count_in_python():
    """The library's words (no flag) for the same mistake, and its shape message otherwise."""
    tree = load_tree("bolt")
    with pytest.raises(InvalidArgumentError, match="2 tools takes one marker for all or one"):
        simulate_tree(tree, 5, np.array(MARKERS))
    with pytest.raises(InvalidArgumentError, match="finite numbers"):
        simulate_tree(tree, 5, [0.0, np.nan, 0.1])


def test_the_counts_plot_of_markers_has_no_paper_bar(capsys, tmp_path):
    """The figure of ``sweep --markers K`` names the markers' formula and has no paper set
    (its rows have no paper count); one point's keeps both."""
    from calib.outputs.plots import counts_figure

    rows = sweep(robots=["ur5"], markers=2)
    labels = [t.get_text() for t in counts_figure(rows, theory="4R+2P+3K").axes[0].legend_.texts]
    assert labels == ["theory (4R+2P+3K)", "complete set"]
    labels = [t.get_text() for t in counts_figure(sweep(robots=["ur5"])).axes[0].legend_.texts]
    assert labels == ["theory (4R+2P+6 or +3)", "paper set", "complete set"]
    code, _, err = run(
        capsys, "sweep", "--robots", "ur5", "--markers", 2, "--plot", tmp_path / "p.png"
    )
    assert code == 0 and (tmp_path / "p.png").stat().st_size > 0, err
