"""Chain and tree: one contract (issue 20, item 4).

One :class:`Options` for both calibrations, the same keyword-only arguments, a tree given
to ``calibrate`` calibrated as ``calibrate_tree`` does, a :class:`Robot` base class that
chains and trees share instead of class checks, and the bugs found on the way
(``MDHModel.replace`` dropping ``source``; ``--measure pose`` on position data). The
expectations come from outside the code under test: Python's ``inspect``, the catalog's
tool names, the URDF file converted with its exact angles, exit status, stderr and files.
"""

from __future__ import annotations

import contextlib
import dataclasses
import inspect
import io
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import chain_of
from test_round_off import MINIMAL  # one joint, a tool whose rpy is RPY

import calib
from calib import InvalidArgumentError, calibrate, simulate
from calib.calibration.entry import calibrate_tree
from calib.calibration.options import APPLIES, TREE_LEVELS, Options
from calib.calibration.problem import Problem, Term
from calib.cli.commands import main
from calib.kinematics.robot import Robot
from calib.kinematics.tree import load_robot, load_tree
from calib.measurements.tree_campaign import simulate_tree

CALIB = Path(calib.__file__).parent
MARKER = (0.05, 0.02, 0.1)


@pytest.fixture(scope="module")
def bolt():
    tree = load_robot("bolt")
    return tree, simulate_tree(tree, 20, markers=MARKER, seed=3).measurements


@pytest.fixture(scope="module")
def ur5():
    chain = chain_of("ur5")
    return chain, simulate(chain, configs=30, measure="position", seed=3).measurements


# --- one signature, keyword-only after (robot, data) -----------------------------------------


def test_chain_and_tree_calibrations_take_the_same_arguments():
    chain = inspect.signature(calibrate).parameters
    tree = inspect.signature(calibrate_tree).parameters
    assert list(chain)[2:] == list(tree)[2:]
    # marker, validate, known_planes (what a touch term holds: its objects), and progress (what
    # is shown, not an option of the calibration)
    assert len(chain) == len(tree) == 2 + len(dataclasses.fields(Options)) + 4
    for name in list(chain)[2:]:
        assert chain[name].kind is inspect.Parameter.KEYWORD_ONLY, name
        assert chain[name].default == tree[name].default, name
    for p in list(chain.values())[:2] + list(tree.values())[:2]:
        assert p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD
    # a tree takes the level, max_iterations, holdout and seed; the rest is for one chain
    run = {"params", "max_iterations", "holdout", "seed"}
    fields = {f.name for f in dataclasses.fields(Options)}
    assert {k for k, shapes in APPLIES.items() if "tree" not in shapes} & fields == fields - run
    # every option is a field of Options, with the same default
    options = {f.name: f.default for f in dataclasses.fields(Options)}
    for name, default in options.items():
        assert chain[name].default == default, name


@pytest.mark.parametrize(
    ("call", "says"),
    [
        (lambda c, d: calibrate(c, d, None, "complete"), "by name"),
        (lambda c, d: calibrate(c, d, level="paper"), "level is called params"),
        (lambda c, d: calibrate(c, d, levl="paper"), "unknown argument levl"),
        (lambda c, d: calibrate(chain=c, data=d), "chain is called robot"),
        (lambda c, d: calibrate(c), "missing a required argument: 'data'"),
    ],
)
def test_a_wrong_argument_is_one_line(ur5, call, says):
    with pytest.raises(InvalidArgumentError) as info:
        call(*ur5)
    assert says in str(info.value) and "\n" not in str(info.value)


def test_tree_positional_level_is_one_line(bolt):
    with pytest.raises(InvalidArgumentError, match="by name"):
        calibrate_tree(*bolt, "frames")


# --- one Options, validated once --------------------------------------------------------------


def test_options_are_checked_when_made():
    assert Options(fix="frame").fix == ("frame",)  # one name alone
    assert Options(fix=["tool", "d3"], free=iter(["c2"])).fix == ("tool", "d3")
    for bad, says in (
        ({"fix": ("d3", "d3")}, "fix names a parameter twice"),
        ({"fix": ("d3",), "free": ("d3",)}, "d3 both fixed and free"),
        ({"fix": (3,)}, "parameter names"),
        ({"params": "all"}, "unknown parameter level 'all'"),
        ({"loss": "cauchy"}, "unknown loss"),
        ({"elastic": "yes"}, "elastic is True, False or None"),
        ({"noise_mm": -1.0}, "noise must be a finite number > 0"),
        ({"max_iterations": 0}, "max_iterations must be an integer in [1, 1000000]"),
        ({"max_iterations": 3_000_000_000}, "max_iterations must be an integer in [1, 1000000]"),
        ({"seed": -1}, "seed must be an integer >= 0"),
        ({"holdout": 1.0}, "holdout fraction must be in [0, 1)"),
    ):
        with pytest.raises(InvalidArgumentError) as info:
            Options(**bad)
        assert says in str(info.value), (bad, str(info.value))
    with pytest.raises(dataclasses.FrozenInstanceError):
        Options().seed = 3  # type: ignore[misc]


def test_a_problems_options_are_its_values_under_the_same_names(ur5):
    given = {
        "fix": ("d3",),
        "free": ("c2",),
        "elastic": True,
        "loss": "huber",
        "noise_mm": 0.2,
        "orientation_weight": 0.5,
        "max_iterations": 7,
        "holdout": 0.2,
        "seed": 4,
    }
    chain = ur5[0]
    poses = simulate(chain, configs=30, measure="pose", seed=3).measurements  # angles: weighed
    problem = Problem((Term(chain, poses),), params="paper", **given)
    assert problem.options() == Options(params="paper", **given)
    assert isinstance(problem, Options) and problem.params == "paper"  # a problem's options
    assert Problem((Term(*ur5),)).options() == Options()  # a chain's level unless given
    assert Options().level == "auto" and Options(params="paper").level == "paper"


@pytest.mark.parametrize(
    "bad",
    [{"max_iterations": 0}, {"seed": -1, "holdout": 0.2}, {"holdout": 1.5}, {"loss": "x"}],
)
def test_chain_and_tree_refuse_a_bad_option_with_the_same_line(ur5, bolt, bad):
    lines = []
    for robot, data in (ur5, bolt):
        with pytest.raises(InvalidArgumentError) as info:
            calibrate(robot, data, **bad)
        lines.append(str(info.value))
    assert lines[0] == lines[1]


@pytest.mark.parametrize(
    "given",
    [
        {"fix": ("frame",)},
        {"free": ("d3",)},
        {"elastic": True},
        {"loss": "huber"},
        {"noise_mm": 0.1},
        {"orientation_weight": 0.5},
        {"params": "auto"},
        {"params": "paper"},
        {"marker": MARKER},
    ],
)
def test_tree_refuses_what_only_a_chain_honours(bolt, given):
    for function in (calibrate, calibrate_tree):
        with pytest.raises(InvalidArgumentError) as info:
            function(*bolt, **given)
        text = str(info.value)
        assert "for one chain" in text or "for a tree: choose frames, complete" in text, text


def test_calibrate_takes_a_tree_as_calibrate_tree_does(bolt):
    tree, data = bolt
    direct = calibrate_tree(tree, data, holdout=0.25, seed=1).check()
    via = calibrate(tree, data, holdout=0.25, seed=1).check()
    assert type(via) is type(direct) and via.params == "complete"
    assert via.to_dict()["parameters"] == direct.to_dict()["parameters"]
    np.testing.assert_array_equal(via.estimate, direct.estimate)
    held = [r.to_dict()["errors"]["held_out"]["calibrated"] for r in (via, direct)]
    assert held[0]["position_rms_mm"] == held[1]["position_rms_mm"]
    # the chain-only options at their defaults are accepted (given or not; elastic=False asks
    # for nothing, as on every shape: APPLIES)
    same = calibrate_tree(
        tree, data, holdout=0.25, seed=1, fix=(), loss="linear", marker=None, elastic=False
    )
    np.testing.assert_array_equal(same.estimate, direct.estimate)
    assert calibrate(tree, data, params="frames").params == "frames"
    assert set(TREE_LEVELS) == {"frames", "complete"}


# --- the Robot contract -----------------------------------------------------------------------


def test_chain_is_a_one_tool_tree_to_the_code_that_asks():
    entries = {e.name: e for e in calib.catalog()}
    chain, tree = chain_of("ur5"), load_tree("bolt")
    assert isinstance(chain, Robot) and isinstance(tree, Robot)
    assert (chain.is_tree, tree.is_tree) == (False, True)
    assert chain.tool_frames == (entries["ur5"].tool,) and chain.n_tools == 1
    assert chain.chains == (chain,) and chain.tool_ids == (chain.tool_id,)
    assert tree.tool_frames == tuple(entries["bolt"].tools) and tree.n_tools == 2
    assert tuple(c.tool_frame for c in tree.chains) == tree.tool_frames
    assert load_robot(chain) is chain and load_robot(tree) is tree
    # a one-tool tree is still a tree
    one = load_tree("bolt", tools=[entries["bolt"].tools[0]])
    assert one.is_tree and one.n_tools == 1


def test_no_chain_or_tree_dispatch_by_class():
    """Code asks the robot (is_tree, tool_frames), not its class; only argument checks of
    functions that take a tree alone test ``isinstance(..., Tree)``."""
    found = []
    for path in sorted(CALIB.rglob("*.py")):
        for no, line in enumerate(path.read_text().splitlines(), 1):
            if re.search(r"hasattr\([^)]*tool_frames", line):
                found.append(f"{path.name}:{no}: {line.strip()}")
            for match in re.finditer(r"(not )?isinstance\([^)]*\bTree\)", line):
                if match.group(1) is None:
                    found.append(f"{path.name}:{no}: {line.strip()}")
    assert not found, found


# --- bugs -------------------------------------------------------------------------------------


GEOMETRY = ("beta", "alpha", "d", "theta", "r", "y")


def test_mdh_replace_keeps_source_unless_the_geometry_changes(tmp_path):
    """``idealized`` of a renamed model is the conversion of the exact URDF (a half-turn
    rounded to 3.1416 in the file, pi in the reference); a changed row keeps its change."""
    rounded, exact = tmp_path / "rounded.urdf", tmp_path / "exact.urdf"
    rounded.write_text(MINIMAL.replace("RPY", "3.1416 0 0"))
    exact.write_text(MINIMAL.replace("RPY", "3.141592653589793 0 0"))
    model = calib.from_chain(load_robot(rounded, "base", "tool"))
    reference = calib.from_chain(load_robot(exact, "base", "tool"))
    renamed = model.replace(tool_frame="flange", base_frame="world")
    assert renamed.source is model.source is not None
    ideal = renamed.idealized()
    assert (ideal.tool_frame, ideal.base_frame) == ("flange", "world")
    for name in GEOMETRY:
        np.testing.assert_allclose(getattr(ideal, name), getattr(reference, name), atol=1e-12)
    d = model.d.copy()
    d[1] += 0.01  # 1 cm along x_0: another robot than the file's
    moved = model.replace(d=d)
    assert moved.source is None
    assert moved.idealized().d[1] == pytest.approx(reference.d[1] + 0.01, abs=1e-12)
    assert model.replace(d=d, source=model.source).source is model.source  # given: kept


def test_tree_model_replace_keeps_source_unless_the_geometry_changes():
    model = calib.from_tree(load_tree("bolt"))
    renamed = model.replace(base_frame="world")
    assert renamed.source is model.source is not None
    for name in ("gamma", "b", *GEOMETRY):
        np.testing.assert_array_equal(
            getattr(renamed.idealized(), name), getattr(model.idealized(), name)
        )
    assert model.replace(theta=model.theta + 0.01).source is None


def _run(argv) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


@pytest.mark.parametrize(("robot", "says"), [("ur5", "needs orientation"), ("bolt", "one point")])
def test_measure_pose_on_position_data_is_one_line(tmp_path, robot, says):
    data, out, report = tmp_path / "m.csv", tmp_path / "o.urdf", tmp_path / "r.json"
    sim = ["simulate", robot, "--measure", "position", "--configs", 20, "--out", data]
    assert _run(sim)[0] == 0
    assert "qw" not in data.read_text().splitlines()[0]  # position data: no quaternion
    argv = ["calibrate", robot, "--data", data, "--measure", "pose", "--out", out]
    code, stdout, err = _run([*argv, "--report", report])
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("calib: error: ") and "--measure pose" in lines[0]
    assert says in lines[0] and stdout == ""
    assert not out.exists() and not report.exists()
