"""One chain measured by an instrument, fitted by the joint engine (issue 28: its only route).

Every number is scored on what calib writes: the calibrated URDF read by Pinocchio, its marker
link placed in the instrument's frame by the report's measurement frame, against measured or
simulated rows the fit never saw.
"""

from __future__ import annotations

import dataclasses
import functools
from pathlib import Path

import numpy as np
import pytest
from pinfit import PinChainFit, PinMdhFit, csv_rows
from pinref import instrument_points

import calib
import calib.calibration.entry as entry
from calib import InvalidArgumentError, calibrate, from_chain, load_chain, read_measurements
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.model import State
from calib.identification.parameters import complete_parameters
from calib.measurements.data import Measurements

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata"


def measured_by_pinocchio(result, chain, q, tmp_path) -> np.ndarray:
    """The written URDF's marker 1 in the instrument frame ``(m, 3)`` [m], Pinocchio alone."""
    path = tmp_path / "cal.urdf"
    path.write_bytes(result.urdf())
    report = result.to_dict()
    return instrument_points(path, report, chain.base_frame, chain.tool_frame, chain.joint_names, q)


def rms_max_mm(error: np.ndarray) -> tuple[float, float]:
    norms = 1e3 * np.linalg.norm(error, axis=1)
    return float(np.sqrt(np.mean(norms**2))), float(norms.max())


@pytest.fixture(scope="module")
def tiago():
    tiago = REAL / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    files = [tiago / f"qualisys_2021-11-{d}_static_postures.csv" for d in (30, 26)]
    train, test = (read_measurements(f, chain) for f in files)
    one = [dataclasses.replace(d, position=d.position[:, :3]) for d in (train, test)]
    return chain, one[0], one[1]


@functools.cache
def independent_held_out(level: str) -> tuple[float, float]:
    """Held-out errors [mm, RMS / max] on the 2021-11-26 session of a fit of the 2021-11-30
    one at a level, by Pinocchio and scipy alone (tests/pinfit.py). They are the figures of
    docs/explanation/validation.md (4.87 / 12.20, 4.23 / 11.95, 4.17 / 21.08)."""
    tiago = REAL / "tiago"
    fit = PinChainFit(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    files = [tiago / f"qualisys_2021-11-{d}_static_postures.csv" for d in (30, 26)]
    sessions = [csv_rows(path, fit.names) for path in files]
    return fit.held_out_mm(level, *sessions)


@pytest.mark.parametrize("level", ["complete", "frames", "offsets"])
def test_tiago_levels_match_an_independent_fit_on_held_out_data(tiago, tmp_path, level):
    chain, train, test = tiago
    result = calibrate(chain, train, validate=test, params=level)
    assert result.accepted and result.shape == "chain"
    got = rms_max_mm(measured_by_pinocchio(result, chain, test.q, tmp_path) - test.position)
    assert got == pytest.approx(independent_held_out(level), abs=1e-3)


def independent_choice_held_out(names, strength) -> tuple[float, float]:
    """Held-out errors [mm] of the frames and the MDH parameters ``names`` fitted on the
    2021-11-30 session under a prior of ``strength`` (tests/pinfit.py's PinMdhFit)."""
    tiago = REAL / "tiago"
    fit = PinMdhFit(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    files = [tiago / f"qualisys_2021-11-{d}_static_postures.csv" for d in (30, 26)]
    sessions = [csv_rows(path, fit.names) for path in files]
    return fit.held_out_named_mm(names, *sessions, strength)


def test_tiago_default_matches_an_independent_fit_of_its_choice(tiago, tmp_path):
    """auto: the parameters it keeps and its prior's strength are its choice (the question);
    the held-out errors of that choice are Pinocchio's and scipy's fit of it (2.963 / 8.962
    mm, below the MDH pipeline's 2.98 / 9.29 that issue 28 removed)."""
    chain, train, test = tiago
    result = calibrate(chain, train, validate=test)
    got = rms_max_mm(measured_by_pinocchio(result, chain, test.q, tmp_path) - test.position)
    choice = result.selection
    assert len(choice.kept) > 0 and choice.winner == "selection"
    independent = independent_choice_held_out(choice.kept, choice.strength)
    assert got == pytest.approx(independent, abs=1e-3)
    assert independent[0] < independent_held_out("frames")[0]  # better than the registration


def test_a_tool_link_on_a_revolute_joint_is_written(tmp_path):
    """The UR10 data's tool wrist_3_link is carried by wrist_3_joint: its marker hangs from it.

    Failed before (marker_urdf refused a tool not carried by a fixed joint); the pipeline
    writes this URDF too. Pinocchio on the written file reproduces the 5 rows held out.
    """
    chain = load_chain(REAL / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link")
    data = read_measurements(REAL / "ur10" / "calibration.csv", chain).position_only()
    held = np.zeros(data.m, dtype=bool)
    held[:5] = True
    result = calibrate(chain, data.subset(~held), params="complete")
    test = data.subset(held)
    got = measured_by_pinocchio(result, chain, test.q, tmp_path)
    (part,) = result.chains
    expected = part.state.inner.predict(np.asarray(test.q))[0][:, 0]
    assert np.abs(got - expected).max() < 1e-9


@pytest.mark.parametrize(("robot", "measure"), [("ur5", "position"), ("panda", "pose")])
def test_noise_free_round_trip_is_exact(tmp_path, robot, measure):
    """Simulated rows without noise: the written URDF predicts unseen rows to 1e-6 mm."""
    chain = load_chain(robot)
    seen = calib.simulate(chain, 40, measure, marker=(0.05, 0.02, 0.1), seed=4).measurements
    q = calib.simulate(chain, 20, seed=9).measurements.q
    truth = calib.simulate(chain, q, measure, marker=(0.05, 0.02, 0.1), seed=4).measurements
    result = calibrate(chain, seen, params="complete")
    got = measured_by_pinocchio(result, chain, truth.q, tmp_path)
    assert rms_max_mm(got - truth.position[:, :3])[1] < 1e-6


def offset_campaign(chain, m: int, seed: int, joint: int, error: float) -> Measurements:
    """Noise-free rows of a robot whose only error is joint ``joint``'s offset [rad]."""
    nominal = from_chain(chain)
    pset = complete_parameters(nominal)
    dx = np.zeros(len(pset))
    dx[pset.names.index(f"theta{joint}")] = error
    frame = np.eye(4)
    frame[:3, 3] = (0.5, -0.2, 0.1)
    state = State(
        pset.apply(nominal, dx), frame, np.array([[0.01, 0.02, 0.05]]), None, np.zeros(chain.n)
    )
    q = chain.random_configurations(m, seed)
    points = state.predict(q)[0][:, 0]
    return Measurements(chain.joint_names, q, points, source="theta2 only"), state


def test_free_and_fix_name_the_charts_parameters():
    """``free theta2`` at ``frames`` fits that offset alone: the truth, to round-off; fixed
    at ``offsets``, the offset is held (the others cannot carry it: 1e-4 m off)."""
    chain = load_chain("ur5")
    data, truth = offset_campaign(chain, 40, 3, 2, 2e-3)
    q = chain.random_configurations(30, 8)
    expected = truth.predict(q)[0][:, 0]
    for name in ("theta2", "shoulder_lift_joint:theta2"):
        res = calibrate(chain, data, params="frames", free=(name,)).check()
        assert res.fitted == ("shoulder_lift_joint:theta2",)  # beside the frame, marker
        assert np.max(np.abs(res.points(q)[:, 0] - expected)) < 1e-9
    assert np.max(np.abs(calibrate(chain, data, params="frames").points(q)[:, 0] - expected)) > 1e-4
    free = calibrate(chain, data, params="offsets")
    assert "shoulder_lift_joint:theta2" in free.names
    assert np.max(np.abs(free.points(q)[:, 0] - expected)) < 1e-9
    held = calibrate(chain, data, params="offsets", fix=("theta2",))
    assert set(held.names) == set(free.names) - {"shoulder_lift_joint:theta2"}
    assert np.max(np.abs(held.points(q)[:, 0] - expected)) > 1e-5


def test_a_joint_offset_has_one_name_at_every_level():
    """``offsets`` names joint 2's offset as ``paper`` does, ``shoulder_lift_joint:theta2``
    (it printed the placement component ``shoulder_lift_joint:rz``), in the table and the
    report, with the same value on noise-free rows; the component's name stays accepted by
    ``fix`` and ``free`` at both levels, and ``free theta2`` at ``offsets`` is that column,
    not a second one along it."""
    chain = load_chain("ur5")
    data, _ = offset_campaign(chain, 40, 3, 2, 2e-3)
    name, rz = "shoulder_lift_joint:theta2", "shoulder_lift_joint:rz"
    values = {}
    for level in ("offsets", "paper"):
        res = calibrate(chain, data, params=level)
        assert name in res.names and rz not in res.names and name in res.summary()
        (values[level],) = [p["value"] for p in res.to_dict()["parameters"] if p["name"] == name]
        for option in ("fix", "free"):
            named = calibrate(chain, data, params=level, **{option: (rz,)}).names
            assert (name in named) == (option == "free") and rz not in named
    assert values["offsets"] == pytest.approx(values["paper"], abs=1e-9)
    assert values["offsets"] == pytest.approx(2e-3, abs=1e-9)
    forced = calibrate(chain, data, params="offsets", free=("theta2",)).names
    assert forced == calibrate(chain, data, params="offsets").names


@pytest.mark.parametrize(
    ("option", "words"),
    [
        ({"fix": ("nope",)}, "unknown parameter 'nope'"),
        ({"fix": ("frame",)}, r"fix frame: the joint engine fits .* \(a gantry's first marker\)"),
        ({"fix": ("markers",)}, "fix markers: the joint engine fits .* holding at its given"),
        ({"free": ("d1",)}, "free d1 cannot be fitted: the measurement frame"),
    ],
)
def test_bad_fix_and_free_are_one_line_errors(option, words):
    chain = load_chain("ur5")
    data, _ = offset_campaign(chain, 40, 3, 2, 2e-3)
    with pytest.raises(InvalidArgumentError, match=words) as info:
        calibrate(chain, data, **option)
    assert "\n" not in str(info.value)


def test_the_marker_guess_starts_the_measured_terms_registration(tiago, monkeypatch, tmp_path):
    """``marker=``: the engine's measured term registers from it (it was refused before).

    Every registration of the term (the checks', the diagnosis', the held-out rows') starts
    at the guess; the fit lands where it does from zeros: the held-out errors of an
    independent fit at ``frames`` (4.87 / 12.20 mm, Pinocchio on the written URDF).
    """
    import calib.calibration.chain_registration as chain_registration

    starts = []
    register = chain_registration.register

    def spy(mdh, q, points, rotations=None, markers=None, kin=None, held=()):
        starts.append(None if markers is None else np.array(markers))
        return register(mdh, q, points, rotations, markers, kin, held)

    monkeypatch.setattr(chain_registration, "register", spy)
    chain, train, test = tiago
    result = calibrate(chain, train, validate=test, params="frames", marker=(0.3, -0.2, 0.4))
    assert starts and all(np.array_equal(m, [[0.3, -0.2, 0.4]]) for m in starts)
    got = rms_max_mm(measured_by_pinocchio(result, chain, test.q, tmp_path) - test.position)
    assert got == pytest.approx(independent_held_out("frames"), abs=1e-3)


@pytest.mark.parametrize(
    ("marker", "message"),
    [
        ((0.1, 0.2), "a marker is 3 numbers"),
        ((0.0, 0.0, 0.1, 0.0, 0.0, 0.2), "2 marker guesses for 1 measured point$"),
        ((0.0, 0.0, np.inf), "3 finite numbers"),
    ],
)
def test_a_bad_marker_guess_is_one_line(tiago, marker, message):
    chain, train, _ = tiago
    with pytest.raises(InvalidArgumentError, match=message):
        calibrate(chain, train, marker=marker)


def test_a_marker_guess_without_a_measured_term_is_refused():
    """Touches only: no term has markers; the guess is an error, not ignored."""
    chain = load_chain("ur5")
    touches = calib.simulate_contacts(chain, 12, "plane", seed=0).data
    with pytest.raises(InvalidArgumentError, match="marker is for measured terms"):
        calibrate_contact_chains([chain], [touches], marker=(0.0, 0.0, 0.1))


def test_the_noise_reaches_the_outlier_rule():
    """A row 20 mm off: an outlier for 0.05 mm of noise, not for 5 mm (the rule's bar is
    6 x the noise when given: 30 mm), as the chain pipeline's rule says."""
    chain = load_chain("ur5")
    marker = (0.01, 0.02, 0.05)
    data = calib.simulate(chain, 40, "position", marker, noise_mm=0.05, seed=5).measurements
    position = data.position.copy()
    position[7, 0] += 0.02
    bad = dataclasses.replace(data, position=position)
    rows = {
        noise: [o.row for o in calibrate(chain, bad, marker=marker, noise_mm=noise).outliers]
        for noise in (0.05, 5.0)
    }
    assert rows == {0.05: [8], 5.0: []}


def test_complete_with_a_parameter_named_fits_the_charts_directions():
    """At ``complete``: free d3 keeps the fit exact on noise-free rows (the truth to 1e-9 m),
    fix d3 holds the true robot's d3 error out of it (0.1 mm off at least)."""
    chain = load_chain("ur5")
    marker = (0.01, 0.02, 0.05)
    data = calib.simulate(chain, 60, "position", marker, noise_mm=0.0, seed=5).measurements
    q = chain.random_configurations(30, 8)
    truth = calib.simulate(chain, q, "position", marker, seed=5).measurements.position
    free = calibrate(chain, data, params="complete", marker=marker, free=("d3",)).check()
    assert "elbow_joint:d3" in free.names
    assert np.max(np.abs(free.points(q)[:, 0] - truth)) < 1e-9
    held = calibrate(chain, data, params="complete", marker=marker, fix=("d3",)).check()
    assert "elbow_joint:d3" not in held.names
    assert np.max(np.abs(held.points(q)[:, 0] - truth)) > 1e-4


def test_proposed_outliers_are_set_aside_before_any_fit(monkeypatch):
    """Two rows 20 mm off among 40: the robust proposals find them on the registration of
    every row, so the one fit made is of the 38 others (no fit of all 40 made and thrown
    away), and it is the fit of those 38 rows given alone (the same points to the last bit)."""
    chain = load_chain("ur5")
    marker = (0.01, 0.02, 0.05)
    data = calib.simulate(chain, 40, "position", marker, noise_mm=0.05, seed=5).measurements
    position = data.position.copy()
    position[7, 0] += 0.02
    position[21, 1] -= 0.02
    bad = dataclasses.replace(data, position=position)
    fitted_rows: list[int] = []
    inner = entry.fit_registered

    def counting(registered):
        fitted_rows.append(registered.train[0].m)
        return inner(registered)

    monkeypatch.setattr(entry, "fit_registered", counting)
    result = calibrate(chain, bad, marker=marker, noise_mm=0.05)
    assert fitted_rows == [38]
    assert [o.row for o in result.outliers] == [8, 22]
    keep = ~np.isin(np.arange(40), [7, 21])
    alone = calibrate(chain, bad.subset(keep), marker=marker, noise_mm=0.05)
    assert not alone.outliers
    np.testing.assert_array_equal(result.points(data.q), alone.points(data.q))


def test_the_choice_differentiates_the_measured_rows_once(monkeypatch):
    """The rank test and the selection of ``auto`` read one Jacobian at the measured rows
    (the same rows at the registration), not one each; the generic configurations' own."""
    import calib.calibration.engine as engine
    from calib.calibration.engine_model import ChainsModel

    chain = load_chain("ur5")
    data = calib.simulate(chain, 40, "position", (0.01, 0.02, 0.05), noise_mm=0.05, seed=5)
    rows: list[int] = []
    inner, choose = ChainsModel.jacobian, engine.choose
    choosing = [False]

    def counting(self, start, x, d, *args, **kwargs):
        if choosing[0]:
            rows.append(d.parts[0].m)
        return inner(self, start, x, d, *args, **kwargs)

    def counted(*args, **kwargs):
        choosing[0] = True
        try:
            return choose(*args, **kwargs)
        finally:
            choosing[0] = False

    monkeypatch.setattr(ChainsModel, "jacobian", counting)
    monkeypatch.setattr(engine, "choose", counted)
    result = calibrate(chain, data.measurements, marker=(0.01, 0.02, 0.05))
    assert result.selection is not None
    assert rows.count(40) == 1
    assert len(rows) == 2
