"""Contact kinds on chains from a foot up the leg backwards (TALOS foot to hand, foot to foot).

Independent routes: Pinocchio alone on the URDF file (tests/pinref.py ``PathRef``: the
relative placement ``oMf[base]^-1 oMf[tool]``) gives each touch's gap, written here from the
kind's definition, and the finite-difference rank of a generic 6-DOF error on every joint
placement of the path, the base and tool frames and the plane, point or pose; the closed
forms are written here in R and P. A simulated campaign is checked on the true robot's URDF.
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest
from pinref import PathRef
from test_contacts import pin_gap

import calib
from calib import analyze, from_chain, load_chain
from calib.cli.commands import main
from calib.identification.contact_postures import contact_configurations, joint_jacobian
from calib.identification.contacts import contact_kind
from calib.kinematics.urdf_export import calibrated_urdf, measurement_to_base
from calib.measurements.contact_campaign import read_contacts, simulate_contacts

KINDS = ("plane", "plane-point", "fixed-point", "fixed-pose")
PAIRS = (
    pytest.param("left_sole_link", "gripper_left_base_link", id="foot-hand"),
    pytest.param("left_sole_link", "right_sole_link", id="foot-foot"),
)


def closed_form(kind: str, revolute: int, prismatic: int) -> int:
    """The counts of docs/method.md section 6, written out (no joint axis through the contact)."""
    base = 4 * revolute + 2 * prismatic
    if kind == "plane":
        return base - (1 if prismatic else 2)
    return base - (0 if prismatic else 1)


def postures(chain, kind: str, m: int, seed: int = 0) -> np.ndarray:
    """calib's postures on the contact, drawn as :func:`calib.analyze` draws them."""
    mdh = from_chain(chain).idealized()
    _, q = contact_configurations(
        mdh, contact_kind(kind), lambda c, r: chain.random_configurations(c, seed + r), m
    )
    return q


def contact_frame(chain, ref: PathRef, seed: int = 0) -> np.ndarray:
    """Inverse of the reference touch's placement (Pinocchio): the plane, point or pose."""
    q0 = chain.random_configurations(1, seed)
    return np.linalg.inv(ref.placements(chain.joint_names, q0)[0])


def contact_rank(chain, ref: PathRef, kind: str, q: np.ndarray, h: float = 1e-6) -> int:
    """Rank of the gaps' central differences under 6-DOF errors of every joint placement of
    the path, the base and tool frames, and the plane, point or pose (Pinocchio only)."""
    P0 = contact_frame(chain, ref)
    qps = [ref.config(chain.joint_names, qi) for qi in q]

    def gaps(P: np.ndarray) -> np.ndarray:
        return np.concatenate([pin_gap(kind, P @ ref.relative(qp).homogeneous) for qp in qps])

    places = ref.nominal_places()
    cols = []
    for a in range(6):
        d = np.zeros(6)
        d[a] = h
        for what, i, nominal in places:
            ref.place(what, i, nominal * pin.exp6(pin.Motion(d)))
            plus = gaps(P0)
            ref.place(what, i, nominal * pin.exp6(pin.Motion(-d)))
            minus = gaps(P0)
            ref.place(what, i, nominal)
            cols.append((plus - minus) / (2 * h))
        plus = gaps(pin.exp6(pin.Motion(d)).homogeneous @ P0)
        minus = gaps(pin.exp6(pin.Motion(-d)).homogeneous @ P0)
        cols.append((plus - minus) / (2 * h))
    s = np.linalg.svd(np.array(cols).T, compute_uv=False)
    return int(np.sum(s > 1e-7 * s[0]))


def true_placements(chain, true_mdh, q: np.ndarray, tmp_path) -> np.ndarray:
    """The true tool in the true base frame: Pinocchio on the true robot's URDF (calib's
    export; the base frame's own error is the documented measurement_to_base)."""
    path = tmp_path / "true.urdf"
    nominal = from_chain(chain)
    path.write_bytes(calibrated_urdf(chain, nominal, true_mdh))
    written = PathRef(path, chain.base_frame, chain.tool_frame)
    return measurement_to_base(nominal, true_mdh) @ written.placements(chain.joint_names, q)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize(("base", "tool"), PAIRS)
def test_postures_hold_the_contact_in_pinocchio(base, tool, kind):
    chain = load_chain("talos", base, tool)
    assert -1 in from_chain(chain).sign  # the leg is traversed backwards
    ref = PathRef(chain.urdf_path, base, tool)
    q = postures(chain, kind, 25)
    P = contact_frame(chain, ref)
    T = P @ ref.placements(chain.joint_names, q)
    assert len(q) == 25
    assert np.abs([pin_gap(kind, t) for t in T]).max() < 1e-9
    if kind == "plane":  # flush, not upside down
        assert (T[:, 2, 2] > 0.99).all()


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize(("base", "tool"), PAIRS)
def test_count_is_the_closed_form_and_the_pinocchio_rank(base, tool, kind):
    chain = load_chain("talos", base, tool)
    m = 120 if kind == "plane-point" else 40  # one row per touch: more touches than unknowns
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        res = analyze("talos", base, tool, kind, params="complete", configs=m)
    expected = closed_form(kind, chain.n_revolute, chain.n_prismatic)
    assert res.n_theory == expected
    assert res.n_base == res.n_complete == expected
    ref = PathRef(chain.urdf_path, base, tool)
    assert contact_rank(chain, ref, kind, postures(chain, kind, m)) == expected


def test_the_cli_lists_what_a_plane_cannot_see_from_the_foot(capsys):
    argv = ["analyze", "talos", "--base", "left_sole_link", "--tool", "gripper_left_base_link"]
    assert main([*argv, "--measure", "plane"]) == 0
    out = capsys.readouterr().out
    assert "15R 0P" in out and "theory 58" in out and "base 58" in out
    assert "a plane contact can never identify" in out
    assert "the plane's height along its normal" in out and "the scale" in out


def test_simulated_touches_from_the_foot_hold_on_the_true_robot(tmp_path, capsys):
    """calib simulate --measure plane on the foot-to-hand chain: Pinocchio on the true URDF."""
    base, tool = "left_sole_link", "gripper_left_base_link"
    chain = load_chain("talos", base, tool)
    camp = simulate_contacts(chain, 10, "plane", contacts=2, seed=5)
    data, truth = camp.data, camp.truth
    T = true_placements(chain, truth.true_mdh, data.q, tmp_path)
    for i, name in enumerate(data.ids):
        assert np.abs(pin_gap("plane", np.linalg.inv(truth.frames[name]) @ T[i])).max() < 1e-9
    assert np.all((data.q >= chain.lower - 1e-12) & (data.q <= chain.upper + 1e-12))
    out = tmp_path / "touches.csv"
    argv = ["simulate", "talos", "--base", base, "--tool", tool, "--measure", "plane"]
    assert main([*argv, "--configs", "12", "--seed", "2", "--out", str(out)]) == 0
    capsys.readouterr()
    back = read_contacts(out, chain, "plane")
    again = simulate_contacts(chain, 12, "plane", seed=2)
    np.testing.assert_allclose(back.q, again.data.q, atol=1e-12)
    T = true_placements(chain, again.truth.true_mdh, back.q, tmp_path)
    frame = np.linalg.inv(again.truth.frames[back.ids[0]])
    assert np.abs([pin_gap("plane", frame @ t) for t in T]).max() < 1e-9


@pytest.mark.parametrize(("base", "tool"), PAIRS)
def test_joint_jacobian_is_pinocchios_relative_frame_jacobian(base, tool):
    """The Newton step's d(tool pose)/dq, signs included, against Pinocchio's frame Jacobians."""
    chain = load_chain("talos", base, tool)
    mdh = from_chain(chain)
    q = chain.random_configurations(6, 7)
    W6 = joint_jacobian(mdh, mdh.kinematics(q))
    ref = PathRef(chain.urdf_path, base, tool).relative_jacobian(chain.joint_names, q)
    np.testing.assert_allclose(W6.reshape(-1, chain.n), ref, atol=1e-10)


def test_plane_newton_system_is_its_own_derivative_and_vanishes_on_one_side_only():
    """The plane's Newton residual: its rows are its central differences, and a frame
    upside down on the plane is far from its zero (and from the gap's: roll pi)."""
    chain = load_chain("talos", "left_sole_link", "gripper_left_base_link")
    mdh = from_chain(chain)
    kind = contact_kind("plane")
    q = chain.random_configurations(4, 9)

    def system(qq):
        kin = mdh.kinematics(qq)
        return kind.newton_system(joint_jacobian(mdh, kin), kin.R[:, -1], kin.p[:, -1])

    _, J = system(q)
    h = 1e-6
    for j in range(chain.n):
        e = np.zeros(chain.n)
        e[j] = h
        num = (system(q + e)[0] - system(q - e)[0]) / (2 * h)
        np.testing.assert_allclose(J[:, :, j], num, atol=1e-7)
    tilt = pin.exp3(np.array([1e-3, 0.0, 0.0]))
    for R, far in ((tilt, False), (np.diag([1.0, -1.0, -1.0]) @ tilt, True)):
        gap = kind.residual(R[None], np.zeros((1, 3)))
        newton, _ = kind.newton_system(np.zeros((1, 6, 1)), R[None], np.zeros((1, 3)))
        assert abs(abs(gap[0, 1]) - (np.pi if far else 0.0)) < 2e-3  # roll: pi upside down
        assert (np.abs(newton).max() > 1e3) if far else (np.abs(newton).max() < 1e-3)


SILENT = {  # where the closed form says nothing, and why (docs/howto/identifiable.md table)
    ("tiago", "plane"),  # a prismatic first joint
    ("tiago", "plane-point"),  # likewise
    ("ur5", "fixed-pose"),  # a 6-joint loop cannot move
}


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("robot", ["ur5", "panda", "tiago"])
def test_forward_chains_counts_are_the_closed_form_where_it_speaks(robot, kind):
    chain = load_chain(robot)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        res = analyze(robot, measure=kind, params="complete")
    if (robot, kind) in SILENT:
        assert res.n_theory is None
        return
    on_axis = 2 if res.on_axes and kind in ("plane-point", "fixed-point") else 0
    flange = 2 if kind == "plane" and robot in ("ur5", "panda") else 0  # last axis = normal
    expected = closed_form(kind, chain.n_revolute, chain.n_prismatic) - on_axis - flange
    assert res.n_theory == res.n_base == res.n_complete == expected
