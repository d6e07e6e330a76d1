"""Calibration from flush contacts: simulated round trips, the independent scorer, refusal."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from contact_scorer import plane_gaps, read_joints

from calib import load_robot
from calib.calibration.choice import touching_postures
from calib.calibration.contact_blocks import dense
from calib.calibration.contact_model import ContactFrames, ContactState
from calib.calibration.entry import calibrate_contacts
from calib.exceptions import CalibrationRefusedError, InvalidArgumentError
from calib.identification.contacts import PlaneContact
from calib.kinematics.mdh import from_chain
from calib.kinematics.so3 import rotation_matrix
from calib.measurements.contact_campaign import read_contacts, simulate_contacts

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
CHAINS = {
    "ur5": ("ur5", None, None),
    "panda": ("panda", None, None),
    "talos": ("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link"),
}


def _tilt_angle(mdh, contact: np.ndarray, normal: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Angle [rad] between the contact frame's z axis and the plane's normal (gauge-free)."""
    kin = mdh.kinematics(q)
    z = (kin.R[:, -1] @ contact[:3, :3])[:, :, 2]
    return np.arccos(np.clip(z @ normal, -1.0, 1.0))


@pytest.mark.parametrize("name", sorted(CHAINS))
def test_noise_free_round_trip(name):
    """Held-out gaps vanish and the tilt of the contact at any posture is the truth's."""
    chain = load_robot(*CHAINS[name])
    camp = simulate_contacts(chain, 90, "plane", seed=3)
    r = calibrate_contacts(chain, camp.data, params="complete", holdout=0.3, seed=1)
    assert r.accepted
    held = r.stats["held_out"]
    assert held.m >= 25
    assert held.height_max_mm < 1e-6  # 1e-9 m
    assert max(held.roll_max_deg, held.pitch_max_deg) < math.degrees(1e-9)
    assert r.stats["held_out_registration"].height_rms_mm > 1e-3  # there was something to fix
    # identifiable combination: the contact's tilt off the plane at random postures (no
    # contact there) is the true robot's, whatever the gauge (contact yaw, scale, ...)
    q = chain.random_configurations(50, 7)
    truth = camp.truth
    (plane,) = truth.frames.values()
    want = _tilt_angle(truth.true_mdh, np.eye(4), plane[:3, 2], q)
    (part,) = r.chains
    got = _tilt_angle(part.calibrated, part.contact, part.plane[:3, 2], q)
    assert np.max(np.abs(got - want)) < 1e-8


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_identifiable_count_is_theory(name):
    """Plane, contact and robot columns kept: 4R - 2 (no prismatic joint)."""
    chain = load_robot(*CHAINS[name])
    camp = simulate_contacts(chain, 60, "plane", seed=2)
    r = calibrate_contacts(chain, camp.data, params="complete")
    assert 5 + len(r.free) == 4 * chain.n - 2


@pytest.mark.parametrize("kind", ["plane", "plane-point", "fixed-point", "fixed-pose"])
def test_jacobian_matches_central_differences(kind):
    """Every kind, two objects, away from x = 0: the model's Jacobian is d(residual)/dx."""
    chain = load_robot("panda")
    mdh = from_chain(chain)
    C = np.eye(4)
    C[:3, :3], C[:3, 3] = rotation_matrix(np.array([0.1, 0.2, 0.3])), [0.01, 0.02, 0.1]
    data = simulate_contacts(chain, 8, kind, contacts=2, seed=0).data
    objects = np.array(
        [_pose([0.1, -0.2, 0.3], [0.3, 0.1, 0.5]), _pose([1.2, 0.1, 0], [0, 0.4, 0.2])]
    )
    frames = ContactFrames(data.kind, C, objects, data.contacts)
    start = ContactState(mdh, frames, 0.7)
    x = 0.05 * np.random.default_rng(0).standard_normal(frames.size)
    J = dense(*start.blocks(x, data), 2)

    def f(v):
        return -start.moved(v).residuals(data)

    h = 1e-6
    num = np.stack([(f(x + h * e) - f(x - h * e)) / (2 * h) for e in np.eye(frames.size)], -1)
    assert J.shape == (8, data.kind.n_rows, frames.size)
    assert np.max(np.abs(J - num)) < 1e-7


def _pose(rotvec, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = rotation_matrix(np.array(rotvec, dtype=float)), t
    return T


def test_flush_postures_hold_the_contact():
    chain = load_robot(*CHAINS["talos"])
    data = read_contacts(REAL / "left_train.csv", chain, "plane")
    (r,) = calibrate_contacts(chain, data, contact=[0, 0, -0.12], params="frames").chains
    frames = ContactFrames(PlaneContact(), r.contact, r.plane[None], (r.plane_id,))
    state = ContactState(r.nominal, frames, 1.0)
    qf, reached = touching_postures(state, data.q, [r.plane_id] * data.m)
    assert reached.all() and len(qf) == data.m
    assert np.max(np.abs(state.gaps(qf))) < 1e-10
    kin = r.nominal.kinematics(qf)
    z = (kin.R[:, -1] @ r.contact[:3, :3])[:, :, 2]
    assert PlaneContact().same_side(kin.R[:, -1]).shape == (data.m,)
    assert np.allclose(z @ r.plane[:3, 2], 1.0)


@pytest.mark.filterwarnings("ignore")
def test_written_urdf_scored_by_pinocchio(tmp_path):
    """The calibrated URDF, the plane and the contact reproduce the held-out figures."""
    chain = load_robot(*CHAINS["talos"])
    data = read_contacts(REAL / "left_train.csv", chain, "plane")
    r = calibrate_contacts(chain, data, contact=[0, 0, -0.12], holdout=0.25, seed=0)
    assert r.accepted
    out = tmp_path / "cal.urdf"
    r.write_urdf(out)
    _ids, joints = read_joints(REAL / "left_train.csv")
    held = r.stats["held_out"]
    rows = [i for i in range(data.m) if not any(np.allclose(data.q[i], t) for t in _train(r, data))]
    g = plane_gaps(
        out,
        chain.base_frame,
        chain.tool_frame,
        r.chains[0].contact,
        r.chains[0].plane,
        {k: v[rows] for k, v in joints.items()},
    )
    rms = np.sqrt(np.mean(g**2, axis=0))
    assert len(rows) == held.m
    assert abs(1e3 * rms[0] - held.height_rms_mm) < 1e-6
    assert abs(math.degrees(rms[1]) - held.roll_rms_deg) < 1e-6
    assert abs(math.degrees(rms[2]) - held.pitch_rms_deg) < 1e-6
    assert held.height_rms_mm < r.stats["held_out_registration"].height_rms_mm


def _train(r, data):
    from calib.calibration.contact_checks import split_contacts

    return split_contacts(data, 0.25, 0)[0].q


def test_worse_model_refused(tmp_path):
    """Few noisy touches, every parameter: worse on other touches than the registration."""
    chain = load_robot("ur5")
    few = simulate_contacts(
        chain, 14, "plane", seed=5, noise_mrad=3.0, error_mm=0.0, error_mrad=0.0
    ).data
    r = calibrate_contacts(chain, few, params="complete", holdout=0.4, seed=0)
    assert not r.accepted
    assert r.stats["held_out"].weighted_mm > r.stats["held_out_registration"].weighted_mm
    with pytest.raises(CalibrationRefusedError):
        r.write_urdf(tmp_path / "x.urdf")
    assert not (tmp_path / "x.urdf").exists()


def test_bad_arguments():
    chain = load_robot("ur5")
    data = simulate_contacts(chain, 20, "plane", seed=0).data
    with pytest.raises(InvalidArgumentError, match="the contact frame takes X Y Z"):
        calibrate_contacts(chain, data, contact=[1, 2])
    with pytest.raises(InvalidArgumentError, match="unknown parameter level 'wild'"):
        calibrate_contacts(chain, data, params="wild")
    point = simulate_contacts(chain, 20, "fixed-point", seed=0).data
    with pytest.raises(InvalidArgumentError, match="kind 'fixed-point' for 'plane'"):
        calibrate_contacts(chain, data, validate=point)
    with pytest.raises(InvalidArgumentError, match="holdout"):
        calibrate_contacts(chain, data, holdout=1.5)


@pytest.mark.parametrize(
    "contact, words",
    [
        ([0, 0, -120], "X Y Z are metres: 120 m from the tool frame"),
        ([0, 0, 0.1, 0, 180, 0], "RX RY RZ are radians: 180 is more than a turn"),
        ([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 120], [0, 0, 0, 1]], "are metres: 120 m"),
    ],
)
def test_a_contact_guess_in_millimetres_or_degrees_is_refused_by_the_library(contact, words):
    """The command line refused ``--contact 0 0 -120``; the library fitted a contact frame
    120 m off the tool and accepted it with a note (a review's case)."""
    chain = load_robot("ur5")
    data = simulate_contacts(chain, 20, "plane", seed=0).data
    with pytest.raises(InvalidArgumentError, match=words):
        calibrate_contacts(chain, data, contact=contact)


def test_contact_model_keeps_reversed_joints():
    """The model in a contact's frame moves as the chain does (TALOS: reversed leg joints)."""
    from calib.identification.contact_postures import contact_model

    chain = load_robot(*CHAINS["talos"])
    mdh = from_chain(chain)
    q = chain.random_configurations(6, 4)
    model = contact_model(mdh, q[0])
    want = np.linalg.inv(mdh.forward(q[:1])[0]) @ mdh.forward(q)
    assert np.allclose(model.forward(q), want, atol=1e-10)


def test_talos_simulation_is_near_the_nominal():
    """Touches simulated with 1 mm / 1 mrad errors are mm from flush on the nominal robot."""
    chain = load_robot(*CHAINS["talos"])
    data = simulate_contacts(chain, 30, "plane", seed=3).data
    r = calibrate_contacts(chain, data, params="frames")
    assert r.stats["train_registration"].height_max_mm < 20


def test_calibrate_dispatches_contact_data():
    from calib.calibration import calibrate

    chain = load_robot("panda")
    data = simulate_contacts(chain, 40, "plane", seed=4).data
    guess = [0.0, 0.0, 0.05]
    a = calibrate(chain, data, marker=guess, params="offsets", holdout=0.25)
    b = calibrate_contacts(chain, data, contact=guess, params="offsets", holdout=0.25)
    # calibrate and the single chain's name: the joint engine's one fit, joint offsets
    (part,) = a.chains
    assert np.allclose(part.contact, b.chains[0].contact, atol=1e-9) and a.free == b.free
    assert {n.split(":")[0] for n in a.free} <= set(chain.joint_names)
    assert {n.split(":")[1][:5] for n in a.free} == {"theta"}  # as paper names them
    held, other = part.stats["held_out"], b.stats["held_out"]
    assert held.m == other.m and np.allclose(held.rms, other.rms, rtol=1e-6, atol=1e-9)
    fixed = calibrate(chain, data, marker=guess, params="offsets", holdout=0.25, fix=("theta2",))
    assert "panda_joint2:theta2" in a.free and "panda_joint2:theta2" not in fixed.free
    assert set(fixed.free) == set(a.free) - {"panda_joint2:theta2"}
    with pytest.raises(InvalidArgumentError, match="touches have no instrument frame"):
        calibrate(chain, data, fix=("frame",))
