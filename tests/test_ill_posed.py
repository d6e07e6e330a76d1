"""Issue 29, item 5: unknowns the data cannot separate are named, never delivered.

A ceiling-drilling robot whose tool always points up, measured by a total station: the
prism's offset along the tool axis and the instrument frame's height are one sum."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import chain_of
from scipy.optimize import least_squares

from calib import calibrate, simulate
from calib.kinematics.mdh import from_chain

PRISM = (0.0, 0.0, 0.15)


def _tool_up(chain, m: int, seed: int) -> np.ndarray:
    """UR5 configurations whose nominal tool z axis points straight up (wrist solved)."""
    nominal = from_chain(chain)
    rng = np.random.default_rng(seed)
    out: list[np.ndarray] = []
    while len(out) < m:
        q = chain.random_configurations(1, int(rng.integers(2**31)))[0]

        def off(x, q=q):
            q = q.copy()
            q[3:5] = x
            return nominal.forward(q[None])[0, :3, 2] - [0.0, 0.0, 1.0]

        sol = least_squares(off, q[3:5], xtol=1e-15, ftol=1e-15, gtol=1e-15)
        q[3:5] = sol.x
        if np.linalg.norm(sol.fun) < 1e-10 and np.all((q >= chain.lower) & (q <= chain.upper)):
            out.append(q)
    return np.array(out)


def _true_points(campaign, q) -> np.ndarray:
    T = campaign.truth.true_mdh.forward(q)
    return T[:, :3, :3] @ np.asarray(PRISM) + T[:, :3, 3]


@pytest.mark.parametrize("params", [None, "frames"])
def test_prism_offset_and_frame_height_are_named_not_delivered(params):
    """Before: accepted with frame.z +40 mm and marker1.z -40 mm (std 14 mm each)."""
    chain = chain_of("ur5")
    up = _tool_up(chain, 40, 1)
    campaign = simulate(chain, up, "position", marker=PRISM, seed=1, noise_mm=0.05)
    res = calibrate(chain, campaign.measurements, params=params, marker=PRISM)
    assert not res.accepted
    assert "cannot separate frame.z and marker1.z" in res.refusal
    assert "postures such as" in res.refusal  # the data's weakness: the robot's tool turns,
    assert not any("held at its given value" in w for w in res.warnings)  # so nothing is held
    if params is None:  # auto: Everett's 4R + 3 = 27 at generic configurations, the pair one
        everett = 4 * chain.n_revolute + 3
        assert any(
            f"determine {everett - 1} of the {everett} parameters" in w for w in res.warnings
        )
    # The evidence: the reported standard deviations and the condition.
    std = {p["name"]: np.inf if p["std"] is None else p["std"] for p in res.to_dict()["parameters"]}
    assert std["frame.z"] > 1e-3 and std["marker1.z"] > 1e-3  # named as in the refusal
    assert res.condition > 1e3  # determined.ILL_CONDITION
    if params == "frames":
        return
    # What the delivered URDF would have done: with the tool turned over, the fitted prism is
    # centimetres from the true one (the sum is right only with the tool up).
    over = chain.random_configurations(30, 4)
    err = np.linalg.norm(res.points(over)[:, 0] - _true_points(campaign, over), axis=1)
    assert np.sqrt(np.mean(err**2)) > 5e-3


def test_turned_postures_separate_them_and_match_the_truth():
    """The same robot with ten postures that turn the tool: accepted, the truth recovered."""
    chain = chain_of("ur5")
    up = _tool_up(chain, 40, 1)
    turned = np.vstack([up, chain.random_configurations(10, 3)])
    campaign = simulate(chain, turned, "position", marker=PRISM, seed=1, noise_mm=0.05)
    res = calibrate(chain, campaign.measurements, marker=PRISM).check()
    over = chain.random_configurations(30, 4)
    err = np.linalg.norm(res.points(over)[:, 0] - _true_points(campaign, over), axis=1)
    assert np.sqrt(np.mean(err**2)) < 0.3e-3


def test_ill_posed_names_a_pair_of_equal_columns():
    from calib.calibration.determined import ill_posed

    rng = np.random.default_rng(0)
    J = rng.normal(size=(30, 4))
    J[:, 3] = 2.0 * J[:, 1] + 1e-9 * rng.normal(size=30)
    found = ill_posed(J, ("a", "b", "c", "d"))
    assert [d.names for d in found] == [("b", "d")]
    assert abs(abs(found[0].weights[0]) - np.sqrt(0.5)) < 1e-6
    assert found[0].weights[0] * found[0].weights[1] < 0  # b - d is what the data miss
    assert ill_posed(rng.normal(size=(30, 4)), ("a", "b", "c", "d")) == []


def test_ill_posed_finds_a_weak_direction_either_side_of_the_threshold():
    """The singular values alone skip the vectors only when none can be weak."""
    from calib.calibration.determined import ILL_CONDITION, ill_posed

    rng = np.random.default_rng(2)
    u, _ = np.linalg.qr(rng.normal(size=(30, 4)))
    v, _ = np.linalg.qr(rng.normal(size=(4, 4)))
    seen = set()
    for ratio in (0.5, 0.7, 0.703, 0.7035, 0.705, 0.71, 2.0):  # the columns' scale: x1.42
        J = u @ np.diag([1.0, 0.8, 0.5, ratio / ILL_CONDITION]) @ v.T
        norms = np.linalg.norm(J, axis=0)
        s = np.linalg.svd(J / norms, full_matrices=False)[1]
        weak = int(np.sum(s < s[0] / ILL_CONDITION))
        assert len(ill_posed(J, ("a", "b", "c", "d"))) == weak
        seen.add(weak)
    assert seen == {0, 1}


def test_a_ceiling_touched_with_the_tool_up_names_the_tip_and_the_height():
    """Contacts: a drill tip on a ceiling (plane-point), the tool always pointing up: the tip's
    offset along the tool and the ceiling's height are one sum (and the tip's x, y unseen)."""
    from calib.calibration.contact_checks import register_contacts
    from calib.exceptions import ContactGeometryError
    from calib.identification.contacts import PlanePointContact

    rng = np.random.default_rng(0)
    m = 20
    R = np.tile(np.eye(3), (m, 1, 1))
    p = np.column_stack([rng.uniform(-0.5, 0.5, (m, 2)), np.full(m, 2.0)])
    guess = np.eye(4)
    guess[2, 3] = 0.1
    with pytest.raises(ContactGeometryError) as info:
        register_contacts(PlanePointContact(), R, p, ["ceiling"] * m, guess)
    assert "cannot separate plane_ceiling_z, contact_x, contact_y, contact_z" in str(info.value)


def test_a_level_the_rows_cannot_determine_names_what_they_cannot_separate():
    """`complete` on the tool-up campaign is refused before the fit: it names the pair."""
    from calib import DataError

    chain = chain_of("ur5")
    campaign = simulate(chain, _tool_up(chain, 40, 1), "position", marker=PRISM, seed=1)
    with pytest.raises(DataError, match=r"cannot separate frame\.z, marker1\.z"):
        calibrate(chain, campaign.measurements, params="complete", marker=PRISM)


@pytest.mark.parametrize(
    ("axes", "still"),
    [(None, (0, 1, 2)), ([[0.2, -0.3, 0.93]], (2,)), ([[0.9, 0.1, 0.2]], (0,)), (3, ())],
)
def test_the_tool_directions_that_never_turn_are_the_robots(axes, still):
    """``still_axes`` of the tool's rotations (scipy's): a tool that never turns hides all
    three coordinates of a marker; one turning about a fixed axis, the one along it the most;
    one turning about any axis, none."""
    from scipy.spatial.transform import Rotation

    from calib.calibration.determined import still_axes

    rng = np.random.default_rng(0)
    R0 = Rotation.from_rotvec([0.3, -0.1, 0.2])
    if axes is None:  # a gantry
        turns = Rotation.identity(20)
    elif axes == 3:
        turns = Rotation.from_rotvec(rng.uniform(-1.0, 1.0, (20, 3)))
    else:  # about one axis, by any angle
        axis = np.asarray(axes[0]) / np.linalg.norm(axes[0])
        turns = Rotation.from_rotvec(np.outer(rng.uniform(-2.0, 2.0, 20), axis))
    assert still_axes(R0.as_matrix() @ turns.as_matrix()) == still


def test_a_tool_turning_about_two_axes_holds_nothing_without_the_random_postures():
    """``held_markers`` skips the random postures where two revolute axes turn the tool about
    two directions: the same coordinates held as the postures' ``still_axes`` on every
    catalog chain (a planar chain's, e.g. the double pendulum's, still found by them)."""
    from conftest import ANALYSABLE

    from calib.calibration.chain_registration import STRUCTURE_CONFIGS, held_markers
    from calib.calibration.determined import still_axes

    for name in ANALYSABLE:
        chain = chain_of(name)
        nominal = from_chain(chain)
        q = chain.random_configurations(STRUCTURE_CONFIGS, 0)
        assert held_markers(chain, nominal) == still_axes(nominal.kinematics(q).R[:, -1]), name
