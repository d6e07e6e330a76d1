"""Identifiable (base) parameters: the paper's 23 for the AID robot, completeness counts
4R + 2P + 6 / + 3 / + 1 on catalog chains against an independent Pinocchio reference,
the regrouping identity, invariances, zero columns, warnings and bad input.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from conftest import ANALYSABLE, INDEPENDENT, chain_of, mdh_of
from pinref import own_random_q, pin_config, pin_frame, rigid_error_columns

import calib
from calib import InvalidArgumentError, Measurement, RankWarning, analyze
from calib.identification.identifiability import (
    analyze_model,
    checked_selection,
    independent_columns,
    select_by_rank,
)
from calib.identification.jacobian import identification_jacobian
from calib.identification.parameters import Kind, Parameter, ParameterSet, paper_parameters
from calib.kinematics.mdh import from_lines

MARKER = (0.011, 0.023, 0.037)


# --------------------------------------------------------------------------------------
# Independent references
# --------------------------------------------------------------------------------------


def pin_complete_rank(chain, q, rows=(0, 1, 2, 3, 4, 5), marker=(0.0, 0.0, 0.0)) -> int:
    """Rank of a generic 6-DOF rigid error on the base and on every chain link, built from
    Pinocchio's joint frames (a complete model that knows nothing about DH)."""
    model = chain.model
    data = model.createData()
    base, tool = pin_frame(model, chain.base_frame), pin_frame(model, chain.tool_frame)
    joints = [model.getJointId(name) for name in chain.joint_names]
    blocks = []
    for qi in q:
        pin.framesForwardKinematics(model, data, pin_config(model, joints, qi))
        oMb = data.oMf[base]
        T = oMb.inverse() * data.oMf[tool]
        E = T.translation + T.rotation @ np.asarray(marker, dtype=float)
        frames = [pin.SE3.Identity()] + [oMb.inverse() * data.oMi[j] for j in joints]
        blocks.append(rigid_error_columns(frames, E)[list(rows)])
    s = np.linalg.svd(np.vstack(blocks), compute_uv=False)
    return int(np.sum(s > 1e-8 * s[0]))


def pin_lines(chain):
    """(points, directions) of the chain axes at q = 0 in the base frame, from Pinocchio."""
    model = chain.model
    data = model.createData()
    base = pin_frame(model, chain.base_frame)
    joints = [model.getJointId(name) for name in chain.joint_names]
    q0 = pin_config(model, joints, np.zeros(chain.n))
    pin.computeJointJacobians(model, data, q0)
    pin.framesForwardKinematics(model, data, q0)
    oMb = data.oMf[base]
    pts, dirs = [], []
    for jid, s in zip(joints, chain.sigma, strict=True):
        Jj = np.asarray(pin.getJointJacobian(model, data, jid, pin.LOCAL_WORLD_ALIGNED))
        col = Jj.reshape(6, model.nv)[:, model.joints[jid].idx_v]
        u = col[:3] if s == 1 else col[3:]
        pts.append(oMb.rotation.T @ (data.oMi[jid].translation - oMb.translation))
        dirs.append(oMb.rotation.T @ u / np.linalg.norm(u))
    tool = (oMb.inverse() * data.oMf[pin_frame(model, chain.tool_frame)]).homogeneous
    return np.array(pts), np.array(dirs), tool


def distance_to_line(x, p, u) -> float:
    v = x - p
    return float(np.linalg.norm(v - np.dot(v, u) * u))


def own_rank(W: np.ndarray) -> int:
    """docs/method.md section 3: pivoted QR, b = #{|R_ii| > tau}, tau = r eps |R_11|."""
    R = scipy.linalg.qr(W, mode="r", pivoting=True)[0]
    d = np.abs(np.diag(R))
    return int(np.sum(d > W.shape[0] * np.finfo(float).eps * d[0]))


def counts(chain) -> tuple[int, int]:
    return int(np.sum(chain.sigma == 0)), int(np.sum(chain.sigma == 1))


def quiet_analyze(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RankWarning)
        return analyze(*args, **kwargs)


# --------------------------------------------------------------------------------------
# The paper's result
# --------------------------------------------------------------------------------------


def test_aid_paper_position_gives_23():
    res = analyze("aid", measure="position", params="paper")
    assert res.n_standard == 4 * (6 + 2) - 2 == 30
    assert res.n_base == 23  # Khalil & Gautier 1991, eq. 29
    assert len(res.base) + len(res.others) == 30
    assert set(res.base) | set(res.others) == set(res.params.names)
    assert res.B.shape == (23, 7)


def test_aid_base_set_is_stable_over_seeds_and_sizes():
    sets = set()
    for seed in range(5):
        for m in (60, 100, 500):
            res = analyze("aid", measure="position", params="paper", configs=m, seed=seed)
            assert res.n_base == 23
            sets.add(frozenset(res.base))
    assert len(sets) == 1


def test_aid_zero_columns_are_the_rotations_about_the_line_of_the_point():
    """The measured point is on z6 and z7, so theta6 and theta7 cannot move it."""
    res = analyze("aid", measure="position", params="paper")
    assert set(res.zero) == {"theta6", "theta7"}
    assert res.status("theta6") == "zero"
    assert res.status("d3") == "identifiable"


def test_aid_beta1_would_give_24_and_the_complete_set_25():
    chain, mdh = chain_of("aid"), mdh_of("aid")
    q = own_random_q(chain.sigma, 100, seed=0)
    meas = Measurement.of("position")
    paper = paper_parameters(mdh)
    with_beta1 = ParameterSet("paper+beta1", (*paper.parameters, Parameter(1, Kind.BETA)))
    assert analyze_model(mdh, with_beta1, meas, q).n_base == 24  # docs/method.md section 4
    res = analyze("aid", measure="position", params="paper")
    assert res.n_complete == 4 * 6 + 3 - 2 == 25  # point on the last axis: 2 fewer
    assert res.n_complete == pin_complete_rank(chain, q, rows=(0, 1, 2))
    assert len(res.missing) == 2
    assert sorted(m.split(":", 1)[0] for m in res.missing) == ["beta1", "y1"]
    full = analyze("aid", measure="position", params="complete")
    assert full.n_base == full.n_complete == 25
    assert full.missing == ()


# --------------------------------------------------------------------------------------
# Completeness on every catalog chain
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", INDEPENDENT)
def test_complete_set_pose_reaches_4r_2p_6(name):
    chain = chain_of(name)
    R, P = counts(chain)
    res = quiet_analyze(chain, measure="pose", params="complete", configs=40, seed=1)
    q = chain.random_configurations(40, seed=1)
    assert pin_complete_rank(chain, q) == 4 * R + 2 * P + 6
    assert res.n_base == res.n_complete == 4 * R + 2 * P + 6
    assert res.n_theory == 4 * R + 2 * P + 6
    assert res.missing == ()


@pytest.mark.parametrize("name", INDEPENDENT)
def test_complete_set_position_off_axis_marker_reaches_4r_2p_3(name):
    chain = chain_of(name)
    R, P = counts(chain)
    res = quiet_analyze(chain, measure="position", marker=MARKER, params="complete", configs=40)
    q = chain.random_configurations(40, seed=0)
    assert pin_complete_rank(chain, q, rows=(0, 1, 2), marker=MARKER) == 4 * R + 2 * P + 3
    assert res.n_base == res.n_complete == 4 * R + 2 * P + 3
    assert not res.on_last_axis


def _on_last_axis_chains():
    out = []
    for name in INDEPENDENT:
        chain = chain_of(name)
        if chain.sigma[-1] != 0:
            continue
        pts, dirs, tool = pin_lines(chain)
        if distance_to_line(tool[:3, 3], pts[-1], dirs[-1]) < 1e-12:
            out.append(name)
    return out


ON_LAST_AXIS = _on_last_axis_chains()


def test_on_last_axis_chains_include_the_papers_and_ur5():
    assert {"aid", "ur5"} <= set(ON_LAST_AXIS)


@pytest.mark.parametrize("name", ON_LAST_AXIS)
def test_point_on_last_axis_loses_two(name):
    chain = chain_of(name)
    R, P = counts(chain)
    pts, dirs, tool = pin_lines(chain)
    res = quiet_analyze(chain, measure="position", params="complete", configs=60, seed=2)
    q = chain.random_configurations(60, seed=2)
    ref = pin_complete_rank(chain, q, rows=(0, 1, 2))
    assert res.on_last_axis
    assert res.n_complete == ref
    assert res.n_base == ref
    if chain.n >= 2 and distance_to_line(tool[:3, 3], pts[-2], dirs[-2]) > 1e-6:
        # only the last axis goes through the point (no wrist centre there): 4R + 2P + 1
        assert ref == 4 * R + 2 * P + 1
        assert res.n_theory == ref


@pytest.mark.parametrize("name", ANALYSABLE)
@pytest.mark.parametrize("params", ["paper", "complete"])
@pytest.mark.parametrize("measure", ["pose", "position"])
def test_base_count_is_the_numerical_rank(name, params, measure):
    """n_base is the rank b of W (docs/method.md section 3), however the columns are chosen."""
    chain, mdh = chain_of(name), mdh_of(name)
    q = own_random_q(chain.sigma, 60, seed=8)
    meas = Measurement.of(measure)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RankWarning)
        res = analyze_model(mdh, params, meas, q)
    W = identification_jacobian(mdh, res.params, q, meas)
    assert res.n_base == own_rank(W)
    assert res.n_base <= res.n_complete


# --------------------------------------------------------------------------------------
# Regrouping, zero columns
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "measure", "params"),
    [
        ("aid", "position", "paper"),
        ("aid", "pose", "complete"),
        ("stanford", "position", "paper"),
        ("tiago", "pose", "paper"),
        ("panda", "position", "complete"),
        ("so100", "pose", "paper"),
    ],
)
def test_regrouping_identity(name, measure, params):
    chain, mdh = chain_of(name), mdh_of(name)
    q = own_random_q(chain.sigma, 50, seed=3)
    meas = Measurement.of(measure)
    res = analyze_model(mdh, params, meas, q)
    W = identification_jacobian(mdh, res.params, q, meas)
    names = list(res.params.names)
    i1 = [names.index(n) for n in res.base]
    i2 = [names.index(n) for n in res.others]
    assert sorted(i1 + i2) == list(range(len(names)))
    rng = np.random.default_rng(4)
    for _ in range(5):
        dX = rng.normal(size=len(names)) * 1e-3
        lhs = W @ dX
        rhs = W[:, i1] @ (dX[i1] + res.B @ dX[i2])
        assert np.abs(lhs - rhs).max() <= 1e-9 * np.abs(W).max() * np.abs(dX).max() * len(names)
    # the kept columns are independent, as many as the rank of W
    assert own_rank(W[:, i1]) == len(i1) == own_rank(W)


def test_regrouping_identity_through_analyze():
    res = analyze("stanford", measure="pose", params="complete", configs=30, seed=9)
    q = chain_of("stanford").random_configurations(30, seed=9)
    W = identification_jacobian(res.mdh, res.params, q, res.measurement)
    names = list(res.params.names)
    i1 = [names.index(n) for n in res.base]
    i2 = [names.index(n) for n in res.others]
    dX = np.random.default_rng(10).normal(size=len(names))
    assert np.allclose(W @ dX, W[:, i1] @ (dX[i1] + res.B @ dX[i2]), atol=1e-9, rtol=0)


def test_exact_urdf_round_off_is_flagged_and_analyze_removes_it():
    # UR5's tool0 rpy "-1.57079632679" leaves the tool 4e-13 m off the last axis: on the
    # exact model the two directions this creates sit just above tau, and calib says so.
    q = own_random_q(chain_of("ur5").sigma, 40, seed=5)
    with pytest.warns(calib.RankWarning, match="weak rank gap"):
        analyze_model(mdh_of("ur5"), "paper", Measurement.of("position"), q)
    with warnings.catch_warnings():
        warnings.simplefilter("error", calib.RankWarning)
        res = calib.analyze("ur5", measure="position", params="complete")
    assert res.n_base == res.n_complete == 4 * 6 + 3 - 2  # point on the last axis
    assert any(s.startswith("alpha7:") for s in res.snapped)


def test_an_analysis_says_its_text_as_every_result_does(capsys):
    """Result, ProblemAnalysis and Design have ``summary()``; an Identifiability had none (the
    CLI's text was ``calib.identification.report.analysis_text``, outside ``calib.__all__``)."""
    from calib.cli.commands import main

    assert main(["analyze", "ur5", "--measure", "pose"]) == 0
    out = capsys.readouterr().out  # the summary, then the command line's next step
    text = calib.analyze("ur5", measure="pose").summary() + "\n"
    assert out.startswith(text) and out[len(text) :].startswith("next: calib design ur5")
    assert out.count("\n") == text.count("\n") + 1


def test_a_round_off_seven_digits_hide_is_listed_with_its_change():
    """TIAGo's ``alpha3: -1.570796 rad -> -1.570796`` said nothing: the change is given too
    where the two values print alike (a value snapped to 0 keeps its line)."""
    snapped = calib.analyze("tiago").snapped
    alpha3 = next(s for s in snapped if s.startswith("alpha3:"))
    assert alpha3 == "alpha3: -1.570796 rad (was +4.9e-12 rad off)", alpha3
    assert "theta4: 4.896583e-12 rad -> 0" in snapped


def test_a_round_off_seven_digits_hide_reads_as_round_off():
    """The SCARA's tool0 ``rpy="3.1416 0 0"`` snapped to pi moves r5 (0.33 m before the
    flip) by 0.33 (1 - cos(3.1416 - pi)) = 8.9e-12 m: printed as ``-0.33 -> -0.33
    (-8.9e-12 m)``, a change a user reads as none; now the value once, and how far off."""
    snapped = calib.analyze(Path(__file__).parent / "data" / "scara.urdf").snapped
    off = 0.33 * (1 - math.cos(3.1416 - math.pi))
    assert f"beta5: {math.pi - 3.1416:.6g} rad -> 0" in snapped, snapped
    assert f"r5: -0.33 m (was {off:+.2g} m off)" in snapped, snapped
    assert not any("-0.33 m -> -0.33" in s for s in snapped), snapped


def test_the_scale_is_unseen_by_a_contact_only_without_a_prismatic_joint():
    """A prismatic joint's reading fixes the scale (docs/method.md: one fewer only without
    one): TIAGo's plane analysis listed "without a prismatic joint, the scale" anyway."""
    scale = "without a prismatic joint, the scale"
    ur5, tiago = (calib.analyze(r, measure="plane") for r in ("ur5", "tiago"))
    assert any(u.startswith(scale) for u in ur5.unseen) and len(tiago.unseen) == 3
    assert not any(u.startswith(scale) for u in tiago.to_dict()["unseen"])
    from calib.identification.report import analysis_text

    assert scale not in analysis_text(tiago)


@pytest.mark.filterwarnings("ignore::calib.RankWarning")  # exact UR5: see the test above
@pytest.mark.parametrize("name", ["aid", "stanford", "ur5", "tiago", "twodof"])
@pytest.mark.parametrize("measure", ["position", "pose"])
def test_zero_columns_are_zero_and_only_those(name, measure):
    chain, mdh = chain_of(name), mdh_of(name)
    q = own_random_q(chain.sigma, 40, seed=5)
    meas = Measurement.of(measure)
    res = analyze_model(mdh, "paper", meas, q)
    W = identification_jacobian(mdh, res.params, q, meas)
    norms = dict(zip(res.params.names, np.linalg.norm(W, axis=0), strict=True))
    scale = max(norms.values())
    for name_ in res.zero:
        assert norms[name_] <= 1e-12 * scale, name_
    for name_, v in norms.items():
        if v <= 1e-14 * scale:
            assert name_ in res.zero, name_


# --------------------------------------------------------------------------------------
# Invariances
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["aid", "ur5", "tiago", "stanford"])
def test_rank_does_not_depend_on_seed_or_m(name):
    chain = chain_of(name)
    R, P = counts(chain)
    minimum = math.ceil((4 * R + 2 * P + 6) / 6)
    ranks = {
        quiet_analyze(chain, measure="pose", params="complete", configs=m, seed=seed).n_base
        for seed in (0, 1, 2)
        for m in (minimum + 10, 3 * minimum + 10, 80)
    }
    assert ranks == {4 * R + 2 * P + 6}


def random_world(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    Q, Rr = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(Rr)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    T = np.eye(4)
    T[:3, :3] = Q
    T[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return T


def in_world(chain, T):
    pts, dirs, tool = pin_lines(chain)
    return from_lines(
        pts @ T[:3, :3].T + T[:3, 3], dirs @ T[:3, :3].T, chain.sigma, T @ tool, chain.joint_names
    )


@pytest.mark.parametrize("name", ["aid", "ur5", "tiago", "stanford", "panda"])
@pytest.mark.parametrize("world_seed", [0, 1])
def test_complete_rank_does_not_depend_on_the_world_frame(name, world_seed):
    chain = chain_of(name)
    q = own_random_q(chain.sigma, 50, seed=6)
    T = random_world(world_seed)
    moved = in_world(chain, T)
    # the re-expressed chain is the same robot: FK in the new world = T @ FK in the old one
    assert np.abs(moved.forward(q) - T @ mdh_of(name).forward(q)).max() <= 1e-10
    for measure, marker in (("pose", None), ("position", MARKER)):
        meas = Measurement.of(measure, marker)
        rows = meas.rows
        before = analyze_model(mdh_of(name), "complete", meas, q)
        after = analyze_model(moved, "complete", meas, q)
        ref = pin_complete_rank(chain, q, rows=rows, marker=meas.marker)
        assert before.n_base == after.n_base == ref
        assert after.n_complete == ref


def test_paper_rank_changes_with_a_tilted_world_and_then_is_complete():
    """The paper's set has no beta1: with the base z parallel to axis 1 (Table 1) it misses
    the rotation about y0 (and, as the lines coincide, the translation along y0), 23 < 25.
    Re-expressed in a world frame whose z is not parallel to axis 1, row 1 is an ordinary MDH
    row and the same 30 parameters reach the complete rank."""
    chain = chain_of("aid")
    q = own_random_q(chain.sigma, 80, seed=7)
    meas = Measurement.of("position")
    ref = pin_complete_rank(chain, q, rows=(0, 1, 2))
    assert ref == 25
    tilted = in_world(chain, random_world(3))
    assert not tilted.parallel[1]
    res = analyze_model(tilted, "paper", meas, q)
    assert res.n_standard == 30
    assert res.n_base == res.n_complete == ref
    assert res.missing == ()


# --------------------------------------------------------------------------------------
# Warnings and bad input
# --------------------------------------------------------------------------------------


def test_too_few_configurations_warn():
    with pytest.warns(RankWarning):
        res = analyze("aid", measure="pose", params="paper", configs=1)
    assert res.n_base <= 6


def test_enough_configurations_do_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error", RankWarning)
        analyze("aid", measure="position", params="paper", configs=100)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"measure": "orientation"},
        {"measure": "x,q"},
        {"marker": (0.1, 0.2)},
        {"marker": (0.1, 0.2, 0.3, 0.4)},
        {"marker": "abc"},
        {"marker": (0.1, float("nan"), 0.3)},
        {"configs": 0},
        {"configs": -5},
        {"configs": 2.5},
        {"params": "full"},
    ],
)
def test_bad_arguments(kwargs):
    with pytest.raises(InvalidArgumentError) as info:
        analyze("aid", **kwargs)
    assert "\n" not in str(info.value)
    (bad,) = kwargs.values()
    assert repr(bad) in str(info.value)  # refused for this argument, not for another
    assert isinstance(info.value, calib.CalibError)


def test_status_of_unknown_parameter():
    res = analyze("aid", measure="position", params="paper", configs=30)
    with pytest.raises(InvalidArgumentError, match="'beta1' is not a parameter of the paper set"):
        res.status("beta1")


def test_to_dict_is_consistent():
    res = analyze("aid", measure="position", params="paper")
    d = res.to_dict()
    assert d["n_base"] == len(d["base_parameters"]) == 23
    assert d["n_standard"] == len(d["standard_parameters"]) == 30
    assert set(d["nonidentifiable"]) | set(d["regrouped"]) | set(d["base_parameters"]) == set(
        d["standard_parameters"]
    )
    assert d["joints"] == {"revolute": 6, "prismatic": 0}


def test_values_are_read_only_and_configs_are_required():
    chain, mdh = chain_of("ur5"), mdh_of("ur5")
    with pytest.raises(ValueError):
        mdh.theta[1] = 1.0
    with pytest.raises(ValueError):
        chain.sigma[0] = 1
    with pytest.raises(calib.InvalidArgumentError):
        analyze_model(mdh)
    with pytest.raises(calib.InvalidArgumentError):
        analyze_model(mdh, "paper", Measurement.of("pose"), np.full((3, 6), np.nan))
    for seed in (None, -1, 1.5, True):
        with pytest.raises(calib.InvalidArgumentError):
            chain.random_configurations(10, seed)


def test_regrouping_coefficients_are_the_rows_of_b():
    res = quiet_analyze("aid", measure="position", params="paper")
    coef = res.regrouping_coefficients()
    assert set(coef) == set(res.base)
    for i, name in enumerate(res.base):
        for j, other in enumerate(res.others):
            assert coef[name].get(other, 0.0) == pytest.approx(
                res.B[i, j] if abs(res.B[i, j]) > 1e-8 else 0.0
            )
    assert coef["theta5"]["d6"] == pytest.approx(-1 / 0.21)  # Table 1: r7 = 0.21 m


def _planted(seed: int, n_cols: int = 24, rank: int = 15):
    """A tall matrix whose columns beyond ``rank`` are exact combinations of a few others,
    columns shuffled, and a random order of preference."""
    rng = np.random.default_rng(seed)
    W = rng.normal(size=(120, n_cols))
    for j in range(rank, n_cols):
        picks = rng.choice(rank, size=rng.integers(1, 4), replace=False)
        W[:, j] = W[:, picks] @ rng.normal(size=len(picks))
    W = W[:, rng.permutation(n_cols)]
    return W, [int(i) for i in rng.permutation(n_cols)]


@pytest.mark.parametrize("seed", range(12))
def test_base_walk_proved_by_one_qr_matches_the_rank_definition(seed):
    """The selection (first-QR guess proved by one QR, else the restarting walk) keeps the
    same columns as the definition: a column is kept when it raises the pivoted-QR rank
    (select_by_rank, an independent route)."""
    W, order = _planted(seed)
    _, tau, kept, R = independent_columns(W, order)
    assert len(kept) == 15
    assert kept == select_by_rank(R, order, tau)


def test_checked_selection_refuses_a_wrong_guess():
    """The one-QR check proves only the walk's own result: a kept column dropped, or a
    dependent one added, is refused (None)."""
    W, order = _planted(3)
    _, _, kept, R = independent_columns(W, order)
    threshold = 1e-6  # inside the gap: the planted columns are dependent to round-off
    assert checked_selection(R, order, kept, threshold) is not None
    dependent = next(i for i in order if i not in kept)
    assert checked_selection(R, order, kept[:-1], threshold) is None
    assert checked_selection(R, order, [*kept, dependent], threshold) is None


def _pinocchio_rank(urdf, tool: str, points, m: int = 60, seed: int = 7) -> int:
    """Rank of the points' positions against every joint placement, the base and the tool
    frame (6 each, finite differences on Pinocchio's model alone): the identifiable count."""
    model0 = pin.buildModelFromUrdf(str(urdf))
    rng = np.random.default_rng(seed)
    lo, hi = model0.lowerPositionLimit, model0.upperPositionLimit
    qs = lo + (hi - lo) * rng.random((m, model0.nq))
    fid, n = model0.getFrameId(tool), 6 * (model0.njoints + 1)

    def positions(delta):
        model = model0.copy()
        for j in range(1, model0.njoints):
            move = pin.exp6(pin.Motion(delta[6 * j : 6 * j + 6]))
            model.jointPlacements[j] = model.jointPlacements[j] * move
        frame = model.frames[fid]
        frame.placement = frame.placement * pin.exp6(pin.Motion(delta[6 * model0.njoints :]))
        model.frames[fid] = frame
        data, base = model.createData(), pin.exp6(pin.Motion(delta[:6]))
        out = []
        for q in qs:
            pin.framesForwardKinematics(model, data, q)
            out += [(base * data.oMf[fid]).act(np.asarray(p, float)) for p in points]
        return np.concatenate(out)

    p0, eps = positions(np.zeros(n)), 1e-6
    J = np.column_stack([(positions(eps * e) - p0) / eps for e in np.eye(n)])
    s = np.linalg.svd(J, compute_uv=False)
    return int(np.sum(s > 1e-6 * s[0]))


def test_a_hand_written_scara_counts_as_pinocchio_alone_does():
    """tests/data/scara.urdf (parallel revolute axes, a prismatic quill, rounded numbers):
    4R + 2P + 3 = 17 from a point off the last axis, 2 fewer on it, 4R + 2P + 6 = 20 from
    the pose (three points), each the rank of Pinocchio's own finite differences."""
    urdf = Path(__file__).parent / "data" / "scara.urdf"
    chain = calib.load_chain(urdf, "base_link", "tool0")
    marker = (0.03, 0.02, 0.01)
    cases = [
        (calib.analyze(chain).n_base, [(0, 0, 0)], 15),
        (calib.analyze(chain, marker=marker).n_base, [marker], 17),
        (calib.analyze(chain, measure="pose").n_base, [(0, 0, 0), (0.1, 0, 0), (0, 0.1, 0)], 20),
    ]
    for n_base, points, theory in cases:
        assert n_base == _pinocchio_rank(urdf, "tool0", points) == theory
