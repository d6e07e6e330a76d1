"""Experiment design: indices, low-rank updates, designed vs random sets, filters, CLI."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from conftest import chain_of
from hypothesis import given, settings
from hypothesis import strategies as st
from pinref import pair_collides

from calib import InvalidArgumentError, calibrate, load_chain, simulate
from calib.calibration import residual_stats
from calib.cli.commands import main
from calib.design.blocks import solve_blocks
from calib.design.configurations import configurations_csv, parse_configurations
from calib.design.constraints import Constraints, filter_candidates
from calib.design.design import candidate_configurations, design, evaluate, least_i
from calib.design.exchange import ExchangeState, optimal_subset
from calib.design.observability import indices_of, observation_model, reference
from calib.exceptions import DataError
from calib.kinematics.catalog import erd_robots_dir


@pytest.fixture(scope="module")
def panda_problem():
    chain = chain_of("panda")
    model = observation_model(chain, "position")
    q = candidate_configurations(chain, 600, seed=1)
    ref = reference(model, candidate_configurations(chain, 100, seed=2))
    return chain, model, q, model.jacobian(q), ref


# --- indices --------------------------------------------------------------------------


def test_indices_against_their_definitions(panda_problem):
    """Each index from the singular values, recomputed from M = W^T W by other routines."""
    _, model, _, J, ref = panda_problem
    ind = indices_of(J[:40], ref)
    W = J[:40].reshape(-1, model.b)
    M = W.T @ W
    eig = np.linalg.eigvalsh(M)  # s_i^2
    assert ind.rank == model.b
    assert ind.cond == pytest.approx(math.sqrt(eig[-1] / eig[0]), rel=1e-9)
    assert ind.d == pytest.approx(np.linalg.slogdet(M)[1], rel=1e-12)
    assert ind.a == pytest.approx(np.trace(np.linalg.inv(M)), rel=1e-9)
    assert ind.o1 == pytest.approx(np.prod(np.sqrt(eig)) ** (1 / model.b) / math.sqrt(40), 1e-9)
    assert ind.o3 == pytest.approx(math.sqrt(eig[0]), rel=1e-9)
    assert ind.o4 == pytest.approx(eig[0] / math.sqrt(eig[-1]), rel=1e-9)
    var = [np.trace(P @ np.linalg.solve(M, P.T)) for P in ref.points]
    assert ind.i == pytest.approx(math.sqrt(np.mean(var)), rel=1e-9)
    assert ind.g == pytest.approx(math.sqrt(np.max(var)), rel=1e-9)


def test_predicted_error_is_the_monte_carlo_error(panda_problem):
    """I x noise is the RMS error of a linear least-squares fit with that noise."""
    _, model, _, J, ref = panda_problem
    W = J[:40].reshape(-1, model.b)
    rng = np.random.default_rng(0)
    noise = rng.standard_normal((2000, W.shape[0]))
    x = np.linalg.lstsq(W, noise.T, rcond=None)[0]  # estimation errors, true x = 0
    err = np.einsum("prb,bt->tpr", ref.points, x)
    rms = math.sqrt(np.mean(np.sum(err**2, axis=2)))
    assert rms == pytest.approx(indices_of(J[:40], ref).i, rel=0.05)


def test_rank_deficient_set_has_infinite_indices(panda_problem):
    _, _, _, J, ref = panda_problem
    ind = indices_of(J[:5], ref)  # 15 rows for 29 parameters
    assert ind.rank < ind.parameters and math.isinf(ind.cond) and ind.d == -math.inf
    assert ind.to_dict()["cond"] is None and ind.to_dict()["I"] is None


def test_scaling_moves_angles_only():
    """Angle columns are divided by L; L is the summed MDH lengths (UR5 by hand)."""
    chain = chain_of("ur5")
    model = observation_model(chain, "position", markers=(0.0, 0.0, 0.1))
    # UR5's MDH table (`calib show ur5`): r1, d3, (d4, r4), r5, tool r; marker 0.1.
    lengths = [0.089159, 0.425, math.hypot(0.39225, 0.10915), 0.09465, 0.0823]
    assert model.length == pytest.approx(sum(lengths) + 0.1, rel=1e-9)
    assert set(np.array(model.names)[model.angular]) >= {"frame.rx", "frame.ry", "frame.rz"}
    assert not any(
        n.startswith(("d", "r", "marker", "frame.x")) for n in np.array(model.names)[model.angular]
    )


# --- low-rank updates -----------------------------------------------------------------


def _fresh(J, design, L):
    ind = indices_of(J[design], None)
    return (
        -ind.d
        if L is None
        else float(
            np.trace(
                L
                @ np.linalg.inv(
                    J[design].reshape(-1, J.shape[2]).T @ J[design].reshape(-1, J.shape[2])
                )
            )
        )
    )


@pytest.mark.parametrize("criterion", ["D", "A", "I"])
def test_low_rank_update_equals_fresh_computation(panda_problem, criterion):
    """Predicted change and updated state agree with a new SVD / inverse to 1e-9 relative."""
    _, model, _, J, ref = panda_problem
    L = {"D": None, "A": np.eye(model.b), "I": ref.mean}[criterion]
    design_ = list(range(0, 80, 2))
    state = ExchangeState(J, design_, L, 0.0)
    before = _fresh(J, design_, L)
    assert state.value() == pytest.approx(before, rel=1e-9)
    for remove, add in ((design_[3], 101), (design_[17], 333), (None, 555)):
        gains = state.gains(remove)
        new = [c for c in state.design if c != remove] + [add]
        after = _fresh(J, new, L)
        if L is None:  # log det: compare det ratios
            assert math.exp(gains[add] - (before - after)) == pytest.approx(1.0, abs=1e-9)
        else:
            assert gains[add] == pytest.approx(before - after, rel=1e-9, abs=1e-12 * before)
        state.apply(add, remove)
        assert state.value() == pytest.approx(after, rel=1e-9)
        if L is not None:  # the trace criterion is I^2 for the reference weight
            ref_i = indices_of(J[new], ref).i
            assert criterion != "I" or state.value() == pytest.approx(ref_i**2, rel=1e-9)
        before = after


def test_bounds_never_below_gains(panda_problem):
    _, model, _, J, ref = panda_problem
    for L in (None, np.eye(model.b), ref.mean):
        state = ExchangeState(J, list(range(40)), L, 0.0)
        for j in state.design[:6]:
            assert np.all(state.bounds(j) >= state.gains(j) - 1e-9)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(1, 6), st.integers(0, 2**31 - 1))
def test_small_block_solver(r, seed):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((5, r, r))
    X = A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(r)
    E = rng.standard_normal((5, r, 2))
    logdet, Y, ok = solve_blocks(X.transpose(1, 2, 0), E.transpose(1, 2, 0))
    assert np.all(ok)
    np.testing.assert_allclose(logdet, np.linalg.slogdet(X)[1], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(Y.transpose(2, 0, 1), np.linalg.solve(X, E), rtol=1e-7, atol=1e-9)


def test_exchange_never_worse_than_greedy_and_reaches_a_local_optimum(panda_problem):
    """No single swap of the result improves it (checked by brute force on a fresh SVD)."""
    J = panda_problem[3]
    res = optimal_subset(J[:150], 12, "D")
    final = indices_of(J[list(res.design)]).d
    assert final >= indices_of(J[list(res.greedy)]).d - 1e-9
    rng = np.random.default_rng(3)
    for j in rng.choice(res.design, 3, replace=False):
        for c in rng.choice(150, 20, replace=False):
            if c in res.design:
                continue
            swapped = [c if d == j else d for d in res.design]
            assert indices_of(J[swapped]).d <= final + 1e-7


def test_least_i_bounds_every_subset_and_is_tight():
    """The certified bound of I against every subset of a small instance (brute force)."""
    rng = np.random.default_rng(8)
    J = rng.standard_normal((11, 3, 5)) * rng.uniform(0.2, 2.0, (11, 1, 1))
    C = rng.standard_normal((5, 5))
    L = C @ C.T
    k = 4

    def i_of(rows):
        W = J[list(rows)].reshape(-1, 5)
        return math.sqrt(np.trace(L @ np.linalg.inv(W.T @ W)))

    exact = min(i_of(s) for s in itertools.combinations(range(11), k))
    bound = least_i(J, k, L, tolerance=1e-6, iterations=20000)
    # below every subset; the relaxation (fractional weights) gap is 11 % on 4 of 11
    assert 0.85 * exact < bound <= exact * (1.0 + 1e-12)
    # the exchange finds the best subset here (never below the bound)
    assert i_of(optimal_subset(J, k, "I", L).design) == pytest.approx(exact, rel=1e-9)
    with pytest.raises(InvalidArgumentError, match=r"number of configurations .* got 0"):
        least_i(J, 0, L)
    with pytest.raises(InvalidArgumentError, match="must have shape"):
        least_i(J, k, L[:4, :4])
    with pytest.raises(InvalidArgumentError, match="identify"):
        least_i(np.zeros((11, 3, 5)), k, L)


# --- designed vs random ---------------------------------------------------------------


@pytest.mark.parametrize("criterion", ["D", "A", "I"])
def test_design_beats_random_sets(criterion):
    d = design(
        chain_of("panda"),
        30,
        candidates=1000,
        criterion=criterion,
        seed=4,
        constraints=Constraints(collision=False),
    )
    for name in ("D", "A", "I", "cond"):
        worse = [d.indices.better(r, name) for r in d.random]
        assert np.mean(worse) >= 0.9, name  # better than 90 % of the random sets
    assert d.indices.better(d.greedy, criterion) or d.exchanges == 0


def _heldout_rms(chain, q, q_ref, seed):
    data = simulate(chain, q, "position", noise_mm=0.05, seed=seed).measurements
    truth = simulate(chain, q_ref, "position", noise_mm=0.0, seed=seed).measurements
    result = calibrate(chain, data, params="complete")
    return residual_stats(result, truth).position_rms


def test_designed_set_calibrates_better_than_random_sets():
    """Median over seeds of the held-out error (true, noise-free points) after calibration."""
    chain = chain_of("ur5")
    k = 30
    q_ref = candidate_configurations(chain, 200, seed=99)
    designed, randoms = [], []
    for seed in range(5):
        d = design(
            chain,
            k,
            candidates=1000,
            seed=seed,
            random_sets=1,
            constraints=Constraints(collision=False),
        )
        q_rand = candidate_configurations(chain, k, seed=100 + seed)
        designed.append(_heldout_rms(chain, d.q, q_ref, seed))
        randoms.append(_heldout_rms(chain, q_rand, q_ref, seed))
    assert np.median(designed) < np.median(randoms)


# --- filters --------------------------------------------------------------------------

COLLIDING = {  # hand-made: the forearm folded onto the shoulder, the hand onto link 1, ...
    "ur5": ([0.0, -1.57, 2.9, 0.0, 0.0, 0.0], ("shoulder_link", "forearm_link")),
    "panda": ([0.0, 0.0, 0.0, -3.0, 0.0, 0.2, 0.0], ("panda_link1", "panda_hand")),
    "tiago": ([0.0, 0.07, -1.5, -3.4, 0.2, 0.0, 0.0, 0.0], ("base_link", "arm_5_link")),
}
FREE = {  # and a pose of the same pair apart (Franka's "ready" pose for the Panda)
    "ur5": [0.0] * 6,
    "panda": [0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785],
    "tiago": [0.0] * 8,
}


def _pinocchio_pair_collides(chain, q, links) -> bool:
    package = str(erd_robots_dir().parent.parent)
    return pair_collides(chain.urdf_path, package, chain.joint_names, q, links)


@pytest.mark.parametrize("robot", sorted(COLLIDING))
def test_collision_filter_rejects_a_known_colliding_configuration(robot):
    chain = chain_of(robot)
    q, links = COLLIDING[robot]
    assert _pinocchio_pair_collides(chain, q, links)
    free = np.array(FREE[robot])
    assert not _pinocchio_pair_collides(chain, free, links)
    keep, report = filter_candidates(chain, np.array([q, free]), np.zeros((1, 3)), Constraints())
    assert keep.tolist() == [False, True]
    assert dict(report.rejected)["collision"] == 1


def test_collision_filter_reads_the_urdf_loaded_by_a_relative_name(tmp_path, monkeypatch):
    """A chain loaded by a relative URDF name reads that file's collision geometry after
    ``os.chdir`` (the file it loaded, not the name's)."""
    import shutil

    (tmp_path / "elsewhere").mkdir()
    shutil.copy(chain_of("ur5").urdf_path, tmp_path / "robot.urdf")
    monkeypatch.chdir(tmp_path)
    chain = load_chain("robot.urdf", "base_link", "tool0")
    monkeypatch.chdir(tmp_path / "elsewhere")
    q = np.array([COLLIDING["ur5"][0], FREE["ur5"]])
    keep, report = filter_candidates(chain, q, np.zeros((1, 3)), Constraints())
    assert keep.tolist() == [False, True]
    assert dict(report.rejected)["collision"] == 1


def test_urdf_without_collision_geometry_is_accepted_with_a_note():
    chain = chain_of("aid")
    q = candidate_configurations(chain, 50, seed=0)
    keep, report = filter_candidates(chain, q, np.zeros((1, 3)), Constraints())
    assert keep.all() and "no collision geometry" in report.notes[0]


def test_workspace_and_margin_filters_against_pinocchio():
    chain = chain_of("ur5")
    q = candidate_configurations(chain, 300, seed=5)
    box = (-0.5, -0.5, 0.0, 0.5, 0.5, 0.8)
    keep, _ = filter_candidates(
        chain, q, np.zeros((1, 3)), Constraints(workspace=box, collision=False)
    )
    tool = chain.tool_placements(q)[:, :3, 3]  # Pinocchio's forward kinematics
    inside = np.all((tool >= box[:3]) & (tool <= box[3:]), axis=1)
    assert keep.tolist() == inside.tolist() and 0 < inside.sum() < len(q)
    keep, _ = filter_candidates(
        chain, q, np.zeros((1, 3)), Constraints(margin=1.0, collision=False)
    )
    near = np.any((q < chain.lower + 1.0) | (q > chain.upper - 1.0), axis=1)
    assert keep.tolist() == (~near).tolist()


def test_line_of_sight_blocked_by_a_wall():
    chain = chain_of("panda")
    q = candidate_configurations(chain, 40, seed=6)
    eye = (2.0, 0.0, 0.5)
    wall = (1.2, -3.0, -3.0, 1.3, 3.0, 3.0)  # out of the Panda's reach, between it and eye
    free, _ = filter_candidates(chain, q, np.zeros((1, 3)), Constraints(line_of_sight=eye))
    walled, report = filter_candidates(
        chain, q, np.zeros((1, 3)), Constraints(line_of_sight=eye, obstacles=(wall,))
    )
    assert free.sum() > 0 and walled.sum() == 0
    assert (
        dict(report.rejected)["collision"]
        == dict(filter_candidates(chain, q, np.zeros((1, 3)), Constraints())[1].rejected)[
            "collision"
        ]
    )


# --- files and CLI --------------------------------------------------------------------


def test_configurations_csv_round_trip_and_errors():
    chain = chain_of("ur5")
    q = candidate_configurations(chain, 5, seed=0)
    text = configurations_csv(chain, q)
    np.testing.assert_array_equal(parse_configurations(text, chain), q)
    shuffled = (
        "x,"
        + ",".join(reversed(chain.joint_names))
        + "\n"
        + "\n".join("1.0," + ",".join(repr(float(v)) for v in row[::-1]) for row in q)
    )
    np.testing.assert_array_equal(parse_configurations(shuffled, chain), q)
    with pytest.raises(DataError, match=r"column 'shoulder_pan_joint'.*missing joint column"):
        parse_configurations(",".join(chain.joint_names[1:]) + "\n" + "0," * 4 + "0\n", chain)
    # none of the chain's joints: another robot's file, its columns shown
    with pytest.raises(
        DataError, match=r"row 1\): no joint column of ur5 .*columns: a, b: a file of another"
    ):
        parse_configurations("a,b\n1,2\n", chain)
    bad = text.replace(repr(float(q[2, 1])), "1_0")
    with pytest.raises(DataError, match=r"row 4.*not a number"):
        parse_configurations(bad, chain)


def test_cli_design_simulate_evaluate(tmp_path, capsys):
    out = tmp_path / "configs.csv"
    assert main(["design", "ur5", "--configs", "30", "--candidates", "500", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "random (median of 20)" in text and f"wrote {out}" in text
    chain = chain_of("ur5")
    q = parse_configurations(out.read_text(), chain)
    assert q.shape == (30, 6)
    meas = tmp_path / "meas.csv"
    assert (
        main(
            [
                "simulate",
                "ur5",
                "--configs-file",
                str(out),
                "--out",
                str(meas),
                "--measure",
                "position",
            ]
        )
        == 0
    )
    lines = meas.read_text().splitlines()
    assert len(lines) == 31 and lines[1].startswith(repr(float(q[0, 0])))
    capsys.readouterr()
    assert main(["design", "ur5", "--evaluate", str(out), "--json"]) == 0
    import json

    got = json.loads(capsys.readouterr().out)
    assert got["D"] == pytest.approx(evaluate(chain, q).d, rel=1e-12)


def test_cli_evaluate_predicts_the_error_at_the_instruments_noise(tmp_path, capsys):
    """``--evaluate --noise-mm``: the predicted error of a given set, as a design prints its
    own (it refused --noise-mm, leaving I per unit noise to multiply by hand)."""
    q = candidate_configurations(chain_of("ur5"), 23, 4)
    out = tmp_path / "configs.csv"
    out.write_text(configurations_csv(chain_of("ur5"), q))
    assert main(["design", "ur5", "--evaluate", str(out), "--noise-mm", "0.03"]) == 0
    i = evaluate(chain_of("ur5"), q).i
    line = capsys.readouterr().out.splitlines()[-1]
    assert (
        line
        == f"predicted RMS position error after calibration at 0.03 mm noise: {0.03 * i:.4g} mm"
    )


def test_the_noise_of_a_design_is_its_summarys_as_the_command_lines(tmp_path, capsys):
    """``calib design --noise-mm`` scales the printed prediction alone (the configurations do
    not depend on it); in Python the same number is ``summary(noise_mm=)``: the same line,
    noise x I."""
    argv = ["design", "ur5", "--configs", "10", "--candidates", "300", "--no-collision"]
    printed, written = {}, {}
    for noise in ("0.03", "0.1"):
        out = tmp_path / f"plan{noise}.csv"
        assert main([*argv, "--noise-mm", noise, "--out", str(out)]) == 0
        printed[noise] = capsys.readouterr().out.splitlines()
        written[noise] = out.read_text()
    assert written["0.03"] == written["0.1"]
    constraints = Constraints(collision=False)
    plan = design("ur5", 10, candidates=300, constraints=constraints)
    for noise in ("0.03", "0.1"):
        summary = plan.summary(noise_mm=float(noise)).splitlines()
        assert summary == printed[noise][: len(summary)]
        figure = float(summary[-1].split(": design ")[1].split()[0])
        assert figure == pytest.approx(float(noise) * plan.indices.i, rel=1e-3)


def test_cli_design_errors_leave_no_output(tmp_path, capsys):
    out = tmp_path / "configs.csv"
    assert main(["design", "ur5", "--configs", "3", "--out", str(out)]) == 2
    assert "choose at least" in capsys.readouterr().err and not out.exists()
    cand = tmp_path / "cand.csv"
    cand.write_text(configurations_csv(chain_of("ur5"), np.zeros((40, 6))))
    before = cand.read_text()
    assert (
        main(
            ["design", "ur5", "--configs", "10", "--candidates-file", str(cand), "--out", str(cand)]
        )
        == 2
    )
    assert "would overwrite" in capsys.readouterr().err and cand.read_text() == before
    assert main(["design", "ur5", "--configs", "10", "--candidates-file", str(cand)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "do not identify" in err  # 40 copies of one pose
    assert "too few distinct candidates?" in err
    assert (
        main(
            [
                "design",
                "ur5",
                "--configs",
                "30",
                "--workspace",
                "5",
                "5",
                "5",
                "6",
                "6",
                "6",
                "--out",
                str(out),
            ]
        )
        == 2
    )
    assert "workspace rejects 2000" in capsys.readouterr().err and not out.exists()


def test_design_refuses_bad_arguments():
    chain = chain_of("ur5")
    with pytest.raises(InvalidArgumentError, match="criterion"):
        design(chain, 30, criterion="E")
    with pytest.raises(InvalidArgumentError, match="measure"):
        design(chain, 30, measure="orientation")
    with pytest.raises(InvalidArgumentError, match="margin"):
        design(chain, 30, constraints=Constraints(margin=4.0))


@pytest.mark.parametrize("measure", ["pose", "position"])
def test_frames_and_offsets_levels_on_the_tiago(measure):
    """``frames``: the instrument's unknowns alone (frame 6, marker 3, tool rotation 3 for
    poses). ``offsets``: the joint offsets neither they nor the other offsets carry. On the
    TIAGo (a prismatic torso along z, then 7 revolute joints) the torso's r1 is the frame's z,
    theta2 (the vertical arm_1, after a translation only) the frame's rotation about z, and
    theta8 the tool's rotation (poses) or a turn of the tool origin about its own axis (a
    point that does not move): theta3 to theta7 are left."""
    chain = load_chain("tiago")
    own = observation_model(chain, measure, params="frames").names
    assert len(own) == (12 if measure == "pose" else 9)
    assert all(n.startswith(("frame.", "marker1.", "tool.")) for n in own)
    offsets = observation_model(chain, measure, params="offsets").names
    assert offsets == own + tuple(f"theta{k}" for k in range(3, 8))


def test_every_function_takes_the_measured_point_as_marker():
    """calibrate, simulate, analyze and design name the measured point alike (newuser48)."""
    import inspect

    import calib

    for f in (calib.calibrate, calib.simulate, calib.analyze, calib.design, evaluate):
        assert "marker" in inspect.signature(f).parameters, f.__name__
    chain = chain_of("ur5")
    marker = (0.05, 0.02, 0.3)
    plan = design(chain, 12, candidates=200, marker=marker, random_sets=2, seed=3)
    assert plan.indices.d == pytest.approx(evaluate(chain, plan.q, marker=marker).d, rel=1e-12)
    assert plan.indices.d != pytest.approx(evaluate(chain, plan.q).d, rel=1e-6)


def test_cli_evaluate_of_too_few_configurations_says_why_no_prediction(tmp_path, capsys):
    # 2 configurations of a point give 6 rows: rank 6 of the UR5's 25 (4R + 2P + 3 - 2, the
    # flange's origin on the last axis); the missing 19 directions are said, no prediction
    path = tmp_path / "two.csv"
    path.write_text(
        configurations_csv(chain_of("ur5"), candidate_configurations(chain_of("ur5"), 2, 0))
    )
    assert main(["design", "ur5", "--evaluate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "25 parameters, rank 6" in out and "predicted RMS" not in out
    assert (
        "rank 6 of 25 parameters: these configurations leave 19 parameter directions unseen" in out
    )


@pytest.mark.parametrize(
    ("extra", "fact"),
    [
        (["--workspace", "5", "5", "5", "6", "6", "6"], "workspace rejects 500"),  # out of reach
        (["--workspace", "1", "1", "1", "0", "0", "0"], "with min < max"),
        (["--workspace", "nan", "0", "0", "1", "1", "1"], "box must be finite numbers, got NaN"),
        (["--obstacle", "1", "1", "1", "0", "0", "0"], "an obstacle box is xmin"),
        (["--configs", "0"], "integer >= 1, got 0"),
        (["--configs", "3"], "choose at least 9 configurations"),  # 9 rows for 25 parameters
        (["--tool", "tool00"], "no frame named 'tool00'"),
        (["--marker", "0", "0", "0.1", "--marker", "0", "0", "0.1"], "markers 1 and 2 are at one"),
        (["--candidates", "10000000"], "use at most"),
        (["--candidates", "20"], "20 of 20 candidates pass the filters"),
    ],
)
def test_cli_design_refuses_a_planners_bad_input_in_one_line_and_writes_nothing(
    tmp_path, capsys, extra, fact
):
    out = tmp_path / "configs.csv"
    defaults = {"--configs": "30", "--candidates": "500"}  # an option is given once
    given = [a for k, v in defaults.items() if k not in extra for a in (k, v)]
    argv = ["design", "ur5", *given, *extra, "--out", str(out)]
    assert main(argv) == 2
    std, err = capsys.readouterr()
    assert std == "" and err.count("\n") == 1 and err.startswith("calib: error: ")
    assert fact in err, err
    assert list(tmp_path.iterdir()) == []


# --- evaluate over the design's reference postures (evaluate49) ------------------------

UR10_BOX = (-0.2, -1.2, 0.05, 1.3, 1.2, 1.6)
UR10_MARKER = (0.03, 0.0, 0.05)


def test_evaluate_within_the_designs_limits_predicts_the_designs_error():
    """The same plan, the same limits: evaluate's I is the design's (both average over the
    same reference postures), not the whole joint space's (planner49 #7)."""
    chain = chain_of("ur10")
    limits = Constraints(workspace=UR10_BOX, line_of_sight=(2.5, 0.0, 0.8))
    plan = design(
        chain, 30, candidates=600, marker=UR10_MARKER, constraints=limits, random_sets=2, seed=2
    )
    kept = evaluate(chain, plan.q, marker=UR10_MARKER, seed=2, candidates=600, constraints=limits)
    assert kept.i == pytest.approx(plan.indices.i, rel=1e-9)
    assert kept.d == pytest.approx(plan.indices.d, rel=1e-9)  # the same set, whatever the ref
    anywhere = evaluate(chain, plan.q, marker=UR10_MARKER, seed=2)
    assert anywhere.d == pytest.approx(plan.indices.d, rel=1e-9)
    assert anywhere.i != pytest.approx(plan.indices.i, rel=1e-3)


def test_cli_evaluate_takes_the_workspace_of_the_design(tmp_path, capsys):
    """``--evaluate plan.csv --workspace ...`` prints the figure ``--configs 30 --workspace``
    printed for that plan; a box no posture reaches is one line saying so."""
    plan = tmp_path / "plan.csv"
    box = [str(v) for v in UR10_BOX]
    limits = ["--marker", *map(str, UR10_MARKER), "--workspace", *box, "--candidates", "600"]
    argv = ["design", "ur10", "--configs", "30", *limits, "--seed", "2", "--quiet"]
    assert main([*argv, "--out", str(plan), "--json"]) == 0
    designed = json.loads(capsys.readouterr().out)["design"]["I"]
    assert main(["design", "ur10", "--evaluate", str(plan), *limits, "--seed", "2", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["I"] == pytest.approx(designed, rel=1e-9)
    far = ["--workspace", "5", "5", "5", "6", "6", "6"]
    assert main(["design", "ur10", "--evaluate", str(plan), "--marker", "0", "0", "0", *far]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "no reference posture" in err and "workspace rejects 2000" in err


def test_design_and_evaluate_take_a_robot_name_as_analyze_does():
    """``calib.design("ur10", ...)`` is the design of ``load_chain("ur10")`` (the catalog's
    base and tool), as ``calib.analyze("ur10")`` loads it (planner49 #8)."""
    import calib

    chain = load_chain("ur10")
    named = calib.design("ur10", 10, candidates=150, random_sets=2, seed=4)
    loaded = calib.design(chain, 10, candidates=150, random_sets=2, seed=4)
    assert np.array_equal(named.q, loaded.q) and named.indices.i == loaded.indices.i
    assert named.tools == (chain.tool_frame,) and named.robot == chain.name
    assert evaluate("ur10", loaded.q).i == evaluate(chain, loaded.q).i
    path = chain.urdf_path
    assert calib.design(path, 10, candidates=150, random_sets=2, seed=4).tools == (
        load_chain(path).tool_frame,
    )
