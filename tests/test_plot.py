"""--plot / result.plot(): the figure's data read back from its Axes equal the report's errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

import calib
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.entry import calibrate as calibrate_tree
from calib.calibration.entry import calibrate_contacts
from calib.cli.commands import main
from calib.kinematics.catalog import resolve_urdf
from calib.kinematics.tree import load_tree
from calib.measurements.csvfile import write_measurements
from calib.measurements.tree_campaign import simulate_tree

TALOS = "talos_full_v2.urdf"
LEFT = ("left_sole_link", "gripper_left_base_link")
RIGHT = ("right_sole_link", "gripper_right_base_link")


def lines_by_label(ax) -> dict[str, np.ndarray]:
    return {line.get_label(): np.asarray(line.get_ydata(), dtype=float) for line in ax.lines}


def rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(v**2)))


def check_errors(fig, errors: dict, part: str, label: str) -> None:
    """The plotted rows of ``label`` (fitted, held out) give the report's RMS and max [mm]."""
    lines = lines_by_label(fig.axes[0])
    for stage in ("registration", "calibrated"):
        y = lines[f"{label}: {stage}"]
        want = errors[part][stage]
        assert rms(y) == pytest.approx(want["position_rms_mm"], rel=1e-9)
        assert y.max() == pytest.approx(want["position_max_mm"], rel=1e-9)


def check_parameters(fig, doc: dict) -> None:
    """The parameters panel: each value +- std of the report, in mm or mrad, named by joint."""
    ax = fig.axes[1]
    points = ax.lines[0]
    values = np.array([1e3 * p["value"] for p in doc["parameters"]])
    np.testing.assert_allclose(points.get_xdata(), values, rtol=1e-12)
    labels = [t.get_text() for t in ax.get_yticklabels()]
    for p, text in zip(doc["parameters"], labels, strict=True):
        assert text.startswith(p["name"]) and (p["joint"] is None or p["joint"] in text)
    spans = ax.collections[0].get_segments()  # the error bars: value - std .. value + std
    stds = np.array([1e3 * p["std"] for p in doc["parameters"]])
    np.testing.assert_allclose([s[1][0] - s[0][0] for s in spans], 2 * stds, rtol=1e-9, atol=1e-12)


def test_chain_figure_holds_the_reports_errors_fitted_and_held_out():
    chain = calib.load_chain("ur5")
    campaign = calib.simulate(chain, 60, "position", marker=[0.01, 0, 0.05], noise_mm=0.05, seed=4)
    result = calib.calibrate(chain, campaign.measurements, params="complete", holdout=0.25, seed=1)
    fig = result.plot()
    doc = result.to_dict()
    check_errors(fig, doc["errors"], "train", "fitted")
    check_errors(fig, doc["errors"], "held_out", "held out")
    assert len(lines_by_label(fig.axes[0])["held out: calibrated"]) == 15  # 25 % of 60
    check_parameters(fig, doc)


def test_tree_figure_holds_the_reports_errors():
    urdf = resolve_urdf("erd:talos_data/robots/talos_reduced.urdf")
    tree = load_tree(urdf, "base_link", ("wrist_left_ft_tool_link", "wrist_right_ft_tool_link"))
    campaign = simulate_tree(tree, 30, markers=[0.05, 0.02, 0.1], noise_mm=0.05, seed=2)
    result = calibrate_tree(tree, campaign.measurements, params="complete", holdout=0.2, seed=1)
    fig = result.plot()
    doc = result.to_dict()
    for k, (term, tool) in enumerate(zip(doc["errors"]["terms"], tree.tool_frames, strict=True)):
        check_gaps(fig, term, f"{k + 1}: {tool} (position)")  # each tool's rows
    lines = lines_by_label(fig.axes[0])
    for part, name in (("train", "fitted"), ("held_out", "held out")):  # every tool's together
        for stage in ("registration", "calibrated"):
            y = np.concatenate(
                [
                    lines[f"{k + 1}: {t} (position) {name}: {stage}"]
                    for k, t in enumerate(tree.tool_frames)
                ]
            )
            want = doc["errors"][part][stage]
            assert rms(y) == pytest.approx(want["position_rms_mm"], rel=1e-9)
            assert y.max() == pytest.approx(want["position_max_mm"], rel=1e-9)
    check_parameters(fig, doc)


def test_cli_plot_written_with_the_urdf(tmp_path, capsys):
    m, out, plot = tmp_path / "m.csv", tmp_path / "c.urdf", tmp_path / "c.svg"
    chain = calib.load_chain("ur5")
    write_measurements(m, calib.simulate(chain, 40, "position", noise_mm=0.05, seed=1).measurements)
    argv = ["calibrate", "ur5", "--data", str(m), "--out", str(out), "--plot", str(plot)]
    assert main([*argv, "--report", str(tmp_path / "r.json")]) == 0
    assert plot.read_bytes().startswith(b"<?xml") and b"<svg" in plot.read_bytes()
    assert json.loads((tmp_path / "r.json").read_text())["accepted"]


@pytest.mark.parametrize(
    ("name", "fact"), [("c.txt", "--plot"), ("c", "--plot"), ("no_dir/c.png", "no_dir")]
)
def test_cli_bad_plot_path_is_one_line_before_the_fit(tmp_path, capsys, name, fact):
    m, out = tmp_path / "m.csv", tmp_path / "c.urdf"
    m.write_text("not read: the path is refused first\n")
    argv = ["calibrate", "ur5", "--data", str(m), "--out", str(out), "--plot", str(tmp_path / name)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("calib: error: ") and fact in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.csv"]


def check_gaps(fig, errors: dict, label: str) -> None:
    """The plotted touches of ``label`` give the report's weighted gap RMS [mm]."""
    lines = lines_by_label(fig.axes[0])
    for part, name in (("train", "fitted"), ("held_out", "held out")):
        for stage in ("registration", "calibrated"):
            y = lines[f"{label} {name}: {stage}".strip()]
            assert rms(y) == pytest.approx(errors[part][stage]["weighted_mm"], rel=1e-9)


def test_contacts_figure_holds_the_reports_gaps():
    chain = calib.load_chain(TALOS, *LEFT)
    data = calib.simulate_contacts(chain, 40, "plane", seed=3).data
    result = calibrate_contacts(chain, data, holdout=0.25, seed=2)
    fig = result.plot()
    doc = result.to_dict()
    check_gaps(fig, doc["errors"], "")
    check_parameters(fig, doc)


def test_several_terms_figure_holds_each_terms_errors():
    chains = [calib.load_chain(TALOS, *pair) for pair in (LEFT, RIGHT)]
    data = [calib.simulate_contacts(c, 24, "plane", seed=4 + k).data for k, c in enumerate(chains)]
    result = calibrate_contact_chains(chains, data, holdout=0.25, seed=1)
    fig = result.plot()
    doc = result.to_dict()
    for k, (term, chain) in enumerate(zip(doc["errors"]["terms"], chains, strict=True)):
        check_gaps(fig, term, f"{k + 1}: {chain.tool_frame} (plane)")
    check_parameters(fig, doc)


def test_refused_model_writes_its_report_and_plot_but_no_urdf_nor_origins(tmp_path, capsys):
    """No geometric error and 2 mm of noise: the complete tree model only overfits (refused)."""
    tree = calib.load_robot("bolt")
    camp = simulate_tree(
        tree, 20, markers=[0.01, 0, 0.02], error_mm=0, error_mrad=0, noise_mm=2, seed=0
    )
    data = tmp_path / "m.csv"
    write_measurements(data, camp.measurements)
    out, report, plot, origins = (tmp_path / n for n in ("o.urdf", "r.json", "p.png", "o.yaml"))
    argv = ["calibrate", "bolt", "--data", str(data), "--out", str(out), "--report", str(report)]
    argv += ["--plot", str(plot), "--origins", str(origins), "--holdout", "0.3", "--seed", "1"]
    assert main(argv) == 2
    assert "calibration refused" in capsys.readouterr().err
    assert plot.read_bytes().startswith(b"\x89PNG") and report.exists()
    assert not out.exists() and not origins.exists()
