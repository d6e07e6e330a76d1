"""The joint engine's result of one measured chain read as a chain's result (issue 28).

``urdf``/``to_dict`` take ``world_link`` and ``on_robot``,
``residual_stats``, ``load_calibrated`` and ``calib predict`` take the result and its report.
Every number is checked against Pinocchio on the written URDF, simulated rows without noise
(the truth) or Pinocchio-scored held-out data.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import re
from pathlib import Path

import numpy as np
import pytest
from pinref import PinTree

import calib
from calib import InvalidArgumentError, calibrate, load_calibrated, load_chain
from calib.calibration import residual_stats
from calib.calibration.validation import stats as state_stats
from calib.cli.commands import main
from calib.measurements.tree_campaign import simulate_tree

MARKER = (0.05, 0.02, 0.1)


def simulated(chain, measure: str = "position"):
    """40 noise-free rows to fit, 15 unseen noise-free rows (the truth)."""
    seen = calib.simulate(chain, 40, measure, marker=MARKER, seed=4).measurements
    q = calib.simulate(chain, 15, seed=9).measurements.q
    return seen, calib.simulate(chain, q, measure, marker=MARKER, seed=4).measurements


@pytest.fixture(scope="module")
def ur5_fit():
    chain = load_chain("ur5")
    seen, truth = simulated(chain)
    return chain, calibrate(chain, seen, params="complete"), truth


def marker_in(urdf: Path, base: str, chain, q) -> np.ndarray:
    """Pinocchio alone: marker 1 of the written URDF in ``base`` ``(m, 3)`` [m]."""
    tree = PinTree.of_file(urdf, base, [f"{chain.tool_frame}_marker1"])
    return tree.poses(chain.joint_names, q)[:, 0, :3, 3]


def test_world_link_gives_measured_coordinates(ur5_fit, tmp_path):
    """Failed before: urdf() and to_dict() took no world_link (TypeError)."""
    chain, result, truth = ur5_fit
    assert result.shape == "chain" and result.accepted
    path = tmp_path / "cal.urdf"
    path.write_bytes(result.urdf(world_link="tracker"))
    got = marker_in(path, "tracker", chain, truth.q)
    assert np.abs(got - truth.position[:, :3]).max() < 1e-9
    frames = result.to_dict(world_link="tracker")["frames"]
    assert frames["world_link"] == "tracker" and not frames["on_robot"]
    # measurement_to_base places the URDF's base frame in the instrument's frame.
    T = result.measurement_to_base
    base = marker_in(path, chain.base_frame, chain, truth.q)
    assert np.abs(base @ T[:3, :3].T + T[:3, 3] - truth.position[:, :3]).max() < 1e-9


def test_load_calibrated_and_residual_stats_read_the_engine_result(ur5_fit, tmp_path):
    """Failed before: load_calibrated refused the report ("its joints () are not ...")."""
    _, result, truth = ur5_fit
    urdf, report = tmp_path / "cal.urdf", tmp_path / "cal.json"
    urdf.write_bytes(result.urdf())
    report.write_text(json.dumps(result.to_dict()))
    model = load_calibrated(urdf, report)
    assert np.abs(model.points(truth.q)[:, 0] - truth.position[:, :3]).max() < 1e-9
    stats = residual_stats(result, truth)
    assert stats.configs == truth.m and stats.position_max < 1e-9


def test_a_calibrated_model_refuses_degrees_as_calib_predict_does(ur5_fit, tmp_path):
    """Failed before: load_calibrated(...).points(q) predicted at q in degrees (far past a
    joint limit) where ``calib predict --configs`` refuses them; a little past is accepted."""
    _, result, truth = ur5_fit
    urdf, report = tmp_path / "cal.urdf", tmp_path / "cal.json"
    urdf.write_bytes(result.urdf())
    report.write_text(json.dumps(result.to_dict()))
    model = load_calibrated(urdf, report)
    shown = repr(model)  # failed before: 21 lines of arrays
    assert shown.endswith(": base_link -> tool0, 6 joints, 0 compliant, 1 marker>"), shown
    assert shown.startswith("<ElasticModel ") and "\n" not in shown, shown
    degrees = np.degrees(truth.q)
    for call in (
        model.points,
        model.deflected,
        model.torques,
        model.tool_placements,
        model.command,
    ):
        with pytest.raises(calib.DataError, match=r"degrees for radians\?"):
            call(degrees)
    q = truth.q.copy()
    q[0, 1] = model.chain.upper[1] + 0.05  # within the margin a reading may have
    assert model.points(q).shape == (truth.m, 1, 3)


def test_a_results_methods_name_an_unknown_keyword(ur5_fit, tmp_path):
    """Failed before: ``result.urdf(foo=1)`` raised Python's bare TypeError where
    ``calibrate`` names an unknown keyword in an InvalidArgumentError."""
    _, result, _ = ur5_fit
    out = tmp_path / "cal.urdf"
    calls = {
        "urdf: unknown argument foo (it takes world_link, on_robot)": lambda: result.urdf(foo=1),
        "to_dict: unknown argument world (it takes world_link": lambda: result.to_dict(
            world="tracker"
        ),
        "summary: unknown argument verbose (it takes no argument)": lambda: result.summary(
            verbose=True
        ),
        "write: unknown argument reprot (it takes out, report)": lambda: result.write(
            out, reprot=tmp_path / "cal.json"
        ),
        "write: too many positional arguments": lambda: result.write(out, out, out),
        "origins: unknown argument foo": lambda: result.origins(foo=1),
    }
    for said, call in calls.items():
        with pytest.raises(InvalidArgumentError, match=re.escape(said)):
            call()
    assert not out.exists()


def test_attributes_of_a_chain(ur5_fit):
    chain, result, truth = ur5_fit
    # points: the calibrated model's prediction of unseen noise-free rows (the truth).
    assert np.abs(result.points(truth.q)[:, 0] - truth.position[:, :3]).max() < 1e-9
    assert result.chain is chain
    assert result.nominal.rows() == calib.from_chain(chain).rows()
    # The registration: nominal robot, its residual the perturbation's (mm), not the truth.
    assert np.abs(result.registration.predict(truth.q)[0][:, 0] - truth.position).max() > 1e-4
    assert result.warnings == result.notes and isinstance(result.message, str)
    own = ("frame.rx", "frame.ry", "frame.rz", "frame.x", "frame.y", "frame.z")
    own += ("marker1.x", "marker1.y", "marker1.z")  # the frame's and the marker's, then fitted
    assert result.names == (*own, *result.fitted) and len(result.fitted) > 0
    assert result.iterations == result.solver[2] > 0 and result.converged
    assert result.outliers == ()
    assert result.marker_links == ("tool0_marker1",)
    report = result.to_dict()
    # Failed before: the report named them instrument.frame.rx ... term1.marker1.z.
    assert [p["name"] for p in report["parameters"]] == list(result.names)
    assert list(report["frames"]["markers"]) == ["tool0_marker1"]
    assert report["compliance"] == dict.fromkeys(load_chain("ur5").joint_names, 0.0)


def test_residual_stats_on_measured_held_out_rows(tmp_path):
    """TIAGo, 2021-11-26 held out (4 markers): the statistics equal Pinocchio's on the URDF."""
    real = Path(__file__).resolve().parents[1] / "data" / "realdata" / "tiago"
    chain = load_chain(real / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    train, test = (
        calib.read_measurements(real / f"qualisys_2021-11-{d}_static_postures.csv", chain)
        for d in (30, 26)
    )
    result = calibrate(chain, train, params="frames")
    stats = residual_stats(result, test)
    path = tmp_path / "cal.urdf"
    path.write_bytes(result.urdf())
    T = np.array(result.to_dict()["frames"]["measurement"]["matrix"])
    tools = [f"{chain.tool_frame}_marker{k + 1}" for k in range(test.n_markers)]
    p = PinTree.of_file(path, chain.base_frame, tools).poses(chain.joint_names, test.q)
    measured = test.position.reshape(test.m, test.n_markers, 3)
    norms = np.linalg.norm(measured - (p[..., :3, 3] @ T[:3, :3].T + T[:3, 3]), axis=2)
    assert test.n_markers == 4 and stats.configs == test.m
    assert stats.position_rms == pytest.approx(np.sqrt(np.mean(norms**2)), rel=1e-9)
    assert stats.position_max == pytest.approx(norms.max(), rel=1e-9)


def test_world_link_and_on_robot_are_for_one_chain(ur5_fit):
    """A tree refuses world_link, on_robot and measurement_to_base in one line; a chain
    refuses on_robot with world_link, and on_robot where it hangs from its base frame
    (UR5's base_link, fixed to world: moving that joint moves the whole arm; a head camera
    measuring the arm is written: tests/test_on_robot.py)."""
    tree = calib.load_robot("talos", tool=["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"])
    data = simulate_tree(tree, 20, seed=2, error_mm=0.0, error_mrad=0.0).measurements
    result = calibrate(tree, data)
    assert result.shape == "tree"
    for call in (result.urdf, result.to_dict):
        for option, value in (("world_link", "w"), ("on_robot", True)):
            with pytest.raises(InvalidArgumentError, match=f"{option} is for one chain measured"):
                call(**{option: value})
        with pytest.raises(InvalidArgumentError, match="on the robot or in the world"):
            getattr(ur5_fit[1], call.__name__)(world_link="w", on_robot=True)
    with pytest.raises(calib.CalibError, match="on_robot: the chain hangs from the base frame"):
        ur5_fit[1].urdf(on_robot=True)
    with pytest.raises(InvalidArgumentError, match="a chain measured by an instrument"):
        result.measurement_to_base  # noqa: B018


def write_configs(path: Path, names, q) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(names)
        w.writerows(q.tolist())


def test_cli_calibrate_world_link_and_predict(tmp_path, capsys):
    """calib calibrate --world-link, then calib predict with its report, under the switch."""
    data, urdf, rep = tmp_path / "m.csv", tmp_path / "cal.urdf", tmp_path / "r.json"
    sim = ["--measure", "position", "--marker", *map(str, MARKER), "--noise-mm", "0"]
    assert main(["simulate", "ur5", *sim, "--out", str(data)]) == 0
    cal = ["calibrate", "ur5", "--data", str(data), "--params", "complete"]
    code = main([*cal, "--report", str(rep), "--out", str(urdf), "--world-link", "tracker"])
    out = capsys.readouterr().out
    assert code == 0, out
    report = json.loads(rep.read_text())
    assert report["shape"] == "chain" and report["frames"]["world_link"] == "tracker"
    chain = load_chain("ur5")
    truth = calib.read_measurements(data, chain)  # noise-free: the truth
    assert np.abs(marker_in(urdf, "tracker", chain, truth.q) - truth.position).max() < 1e-9
    configs, pred = tmp_path / "q.csv", tmp_path / "p.csv"
    write_configs(configs, chain.joint_names, truth.q)
    code = main(
        [
            "predict",
            str(urdf),
            "--compliance",
            str(rep),
            "--configs",
            str(configs),
            "--out",
            str(pred),
        ]
    )
    assert code == 0, capsys.readouterr().err
    with pred.open() as f:
        rows = list(csv.DictReader(f))
    got = np.array([[float(r[c]) for c in ("x1", "y1", "z1")] for r in rows])
    assert np.abs(got - truth.position[:, :3]).max() < 1e-9


@pytest.mark.filterwarnings("ignore::calib.DataWarning")
def test_a_chains_errors_are_its_states_residuals_at_its_rows():
    """``before``, ``after``, ``urdf_after`` and ``validation`` read the term's one set of
    statistics (the rows its ``stats`` keep): the numbers of its states' residuals at the same
    rows, fitted and held out, with compliance fitted (the URDF alone: compliance zero)."""
    chain = load_chain("ur5")
    seen = calib.simulate(chain, 40, "pose", marker=MARKER, seed=1, error_mm=0.05).measurements
    result = calibrate(chain, seen, params="complete", elastic=True, holdout=0.3, seed=0)
    held = result.validation
    assert held is not None and np.any(result.state.compliance)
    alone = dataclasses.replace(result.state, compliance=np.zeros_like(result.state.compliance))
    for rows, got in (
        (result.data, (result.before, result.after, result.urdf_after)),
        (held.rows, (held.registration, held.calibrated, held.urdf)),
    ):
        want = (
            state_stats(result.registration, rows, None),
            residual_stats(result, rows),  # the joints deflected by gravity
            state_stats(alone, rows, None),
        )
        assert got == want
