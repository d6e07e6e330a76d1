"""One calibration problem: terms of one robot, one entry (``calibrate(problem)``), one table
of the options that apply to each shape.

The fits themselves are checked by independent routes elsewhere (Pinocchio on the written
URDFs); here: a problem of several terms, built by hand, is the noise-free truth again on
the written URDF (simulated touches on a URDF whose joint origins were moved, Pinocchio's
gaps), and every shape refuses, in one line, what does not apply to it.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from contact_scorer import plane_gaps

import calib
from calib import InvalidArgumentError, Problem, Term, calibrate, load_robot, simulate
from calib.calibration.options import APPLIES
from calib.calibration.placements import Placements
from calib.kinematics.placement_export import moved_origins_urdf
from calib.measurements.contact_campaign import simulate_contacts

URDF = "talos_full_v2.urdf"
PAIRS = (
    ("left_sole_link", "gripper_left_base_link"),
    ("right_sole_link", "gripper_right_base_link"),
)


@pytest.fixture(scope="module")
def shapes():
    """One problem's terms of every shape (data small: no fit runs)."""
    ur5 = load_robot("ur5")
    measured = simulate(ur5, 12, "position", seed=0).measurements
    arms = [load_robot(URDF, b, t) for b, t in PAIRS]
    touches = [simulate_contacts(c, 12, "plane", seed=1).data for c in arms]
    touches[1] = dataclasses.replace(touches[1], ids=("table2",) * 12)  # one table per base
    tree = load_robot("ur5", tool=("wrist_2_link", "tool0"))
    return {
        "chain": (Term(ur5, simulate(ur5, 12, "pose", seed=0).measurements),),
        "tree": (Term(tree, measured),),
        "contacts": (Term(arms[0], touches[0]),),
        "chains": tuple(Term(c, d) for c, d in zip(arms, touches, strict=True)),
    }


VALUES = {
    "fix": ("frame",),
    "free": ("theta2",),
    "loss": "huber",
    "noise_mm": 0.1,
    "elastic": True,
    "orientation_weight": 0.5,
    "pose_weight": 2.0,
    "shared_planes": True,
    "known_planes": {"table1": (0.0, 0.0, 0.0, 0.0, 0.0, 1.0)},
}


def test_each_problem_has_the_shape_of_its_terms(shapes):
    assert {name: Problem(terms).shape for name, terms in shapes.items()} == {
        name: name for name in shapes
    }


@pytest.fixture(scope="module")
def loop(shapes):
    """Several terms, one of them fixed-pose (a closed loop): what ``pose_weight`` weighs."""
    arm = shapes["chains"][1].robot
    return (shapes["chains"][0], Term(arm, simulate_contacts(arm, 12, "fixed-pose", seed=2).data))


@pytest.mark.parametrize("option", sorted(APPLIES))
@pytest.mark.parametrize("shape", ["chain", "tree", "contacts", "chains"])
def test_an_option_applies_where_the_table_says_and_is_refused_elsewhere(
    shapes, loop, option, shape
):
    assert set(VALUES) == set(APPLIES)  # every option of the table is tried
    if shape in APPLIES[option]:
        terms = loop if option == "pose_weight" else shapes[shape]
        assert Problem(terms, **{option: VALUES[option]}).shape == shape
        return
    with pytest.raises(InvalidArgumentError) as info:
        Problem(shapes[shape], **{option: VALUES[option]})
    message = str(info.value)
    assert message.startswith(f"{option} is for ") and "\n" not in message


def test_an_orientation_weight_without_angle_rows_is_refused():
    """It weighs orientation or tilt rows: positions, fixed-point touches and image points
    have none (it was recorded in the report and used nowhere)."""
    ur5 = load_robot("ur5")
    positions = simulate(ur5, 12, "position", seed=0).measurements
    points = simulate_contacts(ur5, 12, "fixed-point", seed=1).data
    for terms in ((Term(ur5, positions),), (Term(ur5, points),)):
        with pytest.raises(InvalidArgumentError, match="no term has any") as info:
            Problem(terms, orientation_weight=0.5)
        assert "\n" not in str(info.value)
    from calib.calibration.engine import calibrate_contact_chains
    from calib.calibration.entry import calibrate_contacts

    with pytest.raises(InvalidArgumentError, match="no term has any"):  # the engine's entries
        calibrate_contact_chains([ur5], [positions], orientation_weight=0.5)
    with pytest.raises(InvalidArgumentError, match="no term has any"):
        calibrate_contacts(ur5, points, orientation_weight=0.5)
    planes = simulate_contacts(ur5, 12, "plane", seed=1).data  # a touch's tilts: weighed
    mixed = (Term(ur5, positions), Term(ur5, planes))
    assert Problem(mixed, orientation_weight=0.5).shape == "chains"


def test_a_pose_weight_without_a_fixed_pose_term_is_refused(shapes):
    """It weighs the rows of closed loops: several plane terms have none (it weighed nothing,
    where the command line's --pose-weight without --loop was refused)."""
    from calib.calibration.engine import calibrate_contact_chains

    with pytest.raises(InvalidArgumentError, match="no term is one") as info:
        Problem(shapes["chains"], pose_weight=2.0)
    assert "\n" not in str(info.value)
    arms, touches = zip(*((t.robot, t.data) for t in shapes["chains"]), strict=True)
    with pytest.raises(InvalidArgumentError, match="no term is one"):  # the engine's entry
        calibrate_contact_chains(list(arms), list(touches), pose_weight=2.0)


def test_a_default_value_given_is_not_refused(shapes):
    problem = Problem(shapes["tree"], loss="linear", elastic=False, fix=(), pose_weight=1.0)
    assert problem.shape == "tree"


def _guessed(terms, heights):
    """The terms, each with a contact frame guess ``(0, 0, height)``."""
    pairs = zip(terms, heights, strict=True)
    return tuple(Term(t.robot, t.data, guess=(0, 0, h)) for t, h in pairs)


@pytest.mark.parametrize(
    ("build", "says"),
    [
        (lambda s: Problem(()), "at least one Term"),
        (lambda s: Problem(("x",)), "must be Term"),
        (lambda s: Problem((*s["chains"], *s["chain"])), "one URDF"),
        (lambda s: Term("ur5", s["chain"][0].data), "must be a Chain or a Tree"),
        (
            lambda s: Term(s["chain"][0].robot, np.zeros((3, 6))),
            "Measurements, ContactData or PixelData",
        ),
        (lambda s: Term(s["chain"][0].robot, s["chain"][0].data, s["contacts"][0].data), "like"),
        (lambda s: Problem(s["chain"], loss="x"), "unknown loss"),
        (lambda s: Problem(s["chains"], holdout=1.5), "holdout"),
        (lambda s: Problem(_guessed(s["chains"], (0.1, 0.2))), "one contact frame guess"),
        (lambda s: calibrate(Problem(s["chain"]), s["chain"][0].data), "the problem alone"),
        (lambda s: calibrate(Problem(s["chain"]), params="complete"), "the problem alone"),
    ],
)
def test_a_bad_problem_is_one_line(shapes, build, says):
    with pytest.raises(InvalidArgumentError) as info:
        build(shapes)
    assert says in str(info.value) and "\n" not in str(info.value)


def test_the_terms_and_problem_are_public_and_listed():
    assert {"Problem", "Term", "calibrate"} <= set(calib.__all__)
    assert {"Problem", "Term", "calibrate"} <= set(dir(calib))


def test_a_problem_of_two_terms_finds_the_truth_on_the_written_urdf(tmp_path):
    """Both arms' touches of a TALOS whose joint origins were moved (~1 mm, 1 mrad), and
    touches of other postures to validate on: one problem, one URDF; Pinocchio sees every
    validation touch flush on the written URDF (the report's planes and contact frames)."""
    nominal = [load_robot(URDF, b, t) for b, t in PAIRS]
    pl = Placements.of(tuple(nominal))
    truth = pl.shifted(1e-3 * np.random.default_rng(3).standard_normal(pl.y.size))
    true_urdf = tmp_path / "true.urdf"
    true_urdf.write_bytes(moved_origins_urdf(nominal[0], truth.errors()))
    true_chains = [load_robot(true_urdf, b, t) for b, t in PAIRS]

    def split(c, k):  # the first k touches to fit, the others to validate on
        d = simulate_contacts(c, 150, "plane", error_mm=0, error_mrad=0, seed=5).data
        return [dataclasses.replace(d, q=d.q[s], ids=d.ids[s]) for s in (slice(k), slice(k, None))]

    terms = [Term(c, *split(t, 120)) for c, t in zip(nominal, true_chains, strict=True)]
    problem = Problem(tuple(terms), params="complete")
    result = calibrate(problem)
    assert result.accepted and result.to_dict()["shape"] == "chains"
    out = tmp_path / "cal.urdf"
    result.write(out)
    for term, part in zip(problem.terms, result.chains, strict=True):
        v, chain = term.validate, term.robot
        joints = {name: v.q[:, k] for k, name in enumerate(chain.joint_names)}
        g = plane_gaps(out, chain.base_frame, chain.tool_frame, part.contact, part.plane, joints)
        assert np.abs(g[:, 0]).max() < 1e-9 and np.abs(g[:, 1:]).max() < 1e-9  # [m], [rad]
        assert part.stats["held_out_registration"].height_rms_mm > 1.0  # something to fix


def test_a_noise_free_fit_of_the_nominal_robot_is_not_refused_on_round_off():
    """Touches of the nominal TALOS itself: nothing to fix, every error round-off (1e-13 mm);
    the model is accepted, not refused as '0.000 > 0.000 mm' worse than its registration."""
    arms = [load_robot(URDF, b, t) for b, t in PAIRS]
    data = [simulate_contacts(c, 60, "plane", error_mm=0, error_mrad=0, seed=8).data for c in arms]
    result = calibrate(
        Problem(
            tuple(Term(c, d) for c, d in zip(arms, data, strict=True)),
            params="complete",
            holdout=0.25,
        )
    )
    assert result.accepted, result.refusal
    for part in result.chains:
        assert part.stats["held_out"].weighted_mm < 1e-6


def test_two_measured_terms_of_one_camera_are_refused_in_one_line():
    """Each term would fit its own correction of the camera, and the URDF holds one."""
    camera = "rgbd_optical_frame"
    hands = [
        load_robot(URDF, camera, t) for t in ("gripper_left_base_link", "gripper_right_base_link")
    ]
    data = [simulate(h, 20, "position", seed=k).measurements for k, h in enumerate(hands)]
    with pytest.raises(InvalidArgumentError) as info:
        calibrate(Problem(tuple(Term(h, d) for h, d in zip(hands, data, strict=True))))
    assert f"two measured terms measure from '{camera}'" in str(info.value)
    assert "\n" not in str(info.value)


def test_one_urdf_is_one_file_whatever_its_name(tmp_path, monkeypatch):
    """Terms of one file named two ways are one URDF; two files of one name are two."""
    text = load_robot("ur5").urdf_path.read_bytes()
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "robot.urdf").write_bytes(text)
    monkeypatch.chdir(tmp_path / "a")
    first = load_robot("robot.urdf", "base_link", "wrist_3_link")
    again = load_robot("./robot.urdf", "base_link", "forearm_link")
    data = simulate(first, 12, "position", seed=0).measurements
    other_data = simulate(again, 12, "position", seed=1).measurements
    assert len(Problem((Term(first, data), Term(again, other_data))).terms) == 2
    monkeypatch.chdir(tmp_path / "b")
    other = load_robot("robot.urdf", "base_link", "forearm_link")
    with pytest.raises(InvalidArgumentError, match="one URDF, got 2"):
        Problem((Term(first, data), Term(other, other_data)))


def test_a_results_shape_is_its_problems_and_other_shapes_attributes_are_missing():
    """One chain touching is shape ``contacts`` for the problem, the result and its report
    alike (the result said ``chains``); a measured chain's attributes on it are missing as
    Python means it (``hasattr`` False) with a CalibError that says where its errors are."""
    chain = load_robot("ur5")
    touches = simulate_contacts(chain, 30, "plane", seed=2).data
    problem = Problem((Term(chain, touches),))
    result = calibrate(problem)
    assert problem.shape == result.shape == result.to_dict()["shape"] == "contacts"
    wrist = load_robot("ur5", chain.base_frame, "wrist_3_link")
    other = simulate_contacts(wrist, 30, "plane", seed=3).data
    two = Problem((Term(chain, touches), Term(wrist, other)))
    assert two.shape == calibrate(two).shape == "chains"
    assert not hasattr(result, "validation") and not hasattr(result, "robot")
    for error in (calib.InvalidArgumentError, AttributeError):
        with pytest.raises(error, match=r"^only a chain measured .* result.chains \(its errors: "):
            result.points(touches.q[:1])


@pytest.mark.parametrize(
    ("make", "said"),
    [
        (
            lambda t, c, d: Term(c, d, marker=(0, 0, 0.1)),
            "unknown argument marker; a term's guess=",
        ),
        (lambda t, c, d: Problem((t,), "auto"), "its options by name"),
        (lambda t, c, d: Problem(t, t), "by position, as one tuple"),
        (lambda t, c, d: Problem((t,), folds=5), "unknown argument folds; K folds: calib.cross"),
    ],
)
def test_wrong_arguments_of_a_term_or_problem_are_one_line_errors(make, said):
    """calibrate's keyword for a term's guess, an option by position, terms not in one tuple,
    cross_validate's folds: one line naming the way, not Python's TypeError."""
    chain = load_robot("ur5")
    touches = simulate_contacts(chain, 12, "plane", seed=2).data
    with pytest.raises(calib.InvalidArgumentError, match=said) as info:
        make(Term(chain, touches), chain, touches)
    assert "\n" not in str(info.value)
