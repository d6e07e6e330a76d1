"""One default instrument and parameter set across analyze, sweep, simulate and design.

A point measured (position), the complete set: the one ``calibrate --params auto`` chooses
from. ``calib analyze ur5`` then ``calib design ur5`` assume the same campaign.
"""

from __future__ import annotations

import argparse
import csv
import json

import pytest

from calib.cli.commands import build_parser, main


def defaults(command: str, *argv: str) -> argparse.Namespace:
    return build_parser().parse_args([command, *argv])


@pytest.mark.parametrize(
    "argv",
    [
        ["analyze", "ur5"],
        ["sweep"],
        ["simulate", "ur5", "--out", "m.csv"],
        ["design", "ur5", "--configs", "5"],
    ],
    ids=lambda a: a[0],
)
def test_every_command_assumes_a_point_and_the_complete_set(argv):
    args = defaults(*argv)
    assert args.measure == "position"
    # analyze: None, resolved to complete; sweep's verdict judges the paper set (the complete
    # set always reaches the rank: its verdict would say nothing), both counts in its table
    assert (args.params or "complete") == ("paper" if argv[0] == "sweep" else "complete")


def test_analyze_by_default_is_analyze_position_complete(capsys):
    """The report's header says which instrument and set it shows; the counts are those of
    the explicit options (and the point's count 4R + 2P + 3 - 2 of a tool on the last axis)."""
    assert main(["analyze", "ur5", "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    argv = ["analyze", "ur5", "--json", "--measure", "position", "--params", "complete"]
    assert main(argv) == 0
    explicit = json.loads(capsys.readouterr().out)
    del plain["timings_ms"], explicit["timings_ms"]
    assert explicit == plain
    assert plain["measure"] == "position" and plain["params"] == "complete"
    assert main(["analyze", "ur5"]) == 0
    assert "measure position, complete set" in capsys.readouterr().out.splitlines()[0]


def test_simulate_by_default_writes_points_design_counts_them(tmp_path, capsys):
    """simulate's CSV has no orientation; design's parameter count is analyze's."""
    out = tmp_path / "m.csv"
    assert main(["simulate", "ur5", "--configs", "12", "--out", str(out)]) == 0
    with out.open() as f:
        header = next(csv.reader(f))
    assert {"x", "y", "z"} <= set(header) and not {"qx", "qw"} & set(header)
    capsys.readouterr()
    assert main(["analyze", "ur5", "--json"]) == 0
    n_base = json.loads(capsys.readouterr().out)["n_base"]
    assert main(["design", "ur5", "--configs", "12", "--candidates", "60", "--json"]) == 0
    design = json.loads(capsys.readouterr().out)
    assert len(design["parameters"]) == design["design"]["rank"] == n_base


@pytest.mark.parametrize("robot", ["ur5", "panda", "aid", "talos_left_arm"])
def test_python_and_command_line_defaults_print_the_same_counts(robot, capsys):
    """``calib.analyze(robot)`` and ``calib analyze ROBOT`` assume one instrument and one set:
    the same report (JSON, timings aside) and the same printed text (the command line's
    closing ``next:`` line, its commands, aside)."""
    import calib
    from calib.identification.report import analysis_text

    res = calib.analyze(robot)
    assert main(["analyze", robot, "--json"]) == 0
    cli = json.loads(capsys.readouterr().out)
    mine = res.to_dict()
    del cli["timings_ms"], mine["timings_ms"]
    assert mine == json.loads(json.dumps(mine)) and mine["n_base"] == cli["n_base"]
    assert mine == cli
    assert main(["analyze", robot]) == 0
    *text, last = capsys.readouterr().out.rstrip("\n").splitlines()
    assert last.startswith(f"next: calib design {robot} ")
    assert "\n".join(text) == analysis_text(res).rstrip("\n")


def test_python_simulate_and_design_default_to_the_command_lines_instrument():
    """A simulated campaign is points (no orientation), and a design counts the set
    ``calib.analyze`` counts by default."""
    import calib

    chain = calib.load_chain("ur5")
    data = calib.simulate(chain, 12, seed=0).measurements
    assert data.quaternion is None and data.position.shape[1] == 3
    design = calib.design(chain, 12, candidates=60, seed=0)
    assert design.indices.rank == len(design.model.names) == calib.analyze(chain).n_base
