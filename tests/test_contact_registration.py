"""Contact registration: planes, fixed points and poses recovered; bad geometry refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from contact_scorer import plane_gaps, read_joints, relative_placements
from scipy.spatial.transform import Rotation

from calib.calibration.contact_checks import register_contacts
from calib.exceptions import CalibError, ContactGeometryError
from calib.identification.contacts import FixedPointContact, FixedPoseContact, PlaneContact
from calib.kinematics.catalog import resolve_urdf

TALOS = resolve_urdf("erd:talos_data/robots/talos_full_v2.urdf")
REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"


def _pose(rotvec, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rotation.from_rotvec(rotvec).as_matrix(), t
    return T


def _flush_touches(plane: np.ndarray, contact: np.ndarray, m: int, seed: int, yaw=0.8):
    """Tool placements whose contact frame lies flush on the plane (spots, yaws at random)."""
    rng = np.random.default_rng(seed)
    R, p = [], []
    for _ in range(m):
        on = _pose([0, 0, rng.uniform(-yaw, yaw)], [*rng.uniform(-0.3, 0.3, 2), 0.0])
        T = plane @ on @ np.linalg.inv(contact)
        R.append(T[:3, :3])
        p.append(T[:3, 3])
    return np.array(R), np.array(p)


PLANES = {
    "table": _pose([0.05, -0.03, 0.4], [0.6, 0.1, 0.9]),
    "wall": _pose([1.4, 0.2, -0.3], [0.9, -0.4, 1.2]),
}
CONTACT = _pose([0.08, -0.12, 0.5], [0.01, -0.015, -0.13])
GUESS = _pose([0.0, 0.0, 0.2], [0.0, 0.0, -0.12])


def register_planes(R, p, ids, guess, weight=1.0):
    return register_contacts(PlaneContact(), R, p, ids, guess, weight)


def register_points(R, p, ids, guess):
    return register_contacts(FixedPointContact(), R, p, ids, guess)


def register_poses(R, p, ids, contact):
    return register_contacts(FixedPoseContact(), R, p, ids, contact)


def _plane(reg, name: str) -> np.ndarray:
    return reg.objects[reg.ids.index(name)]


def _gaps(reg, R, p, ids) -> np.ndarray:
    return reg.gaps(R, p, reg.index(ids))


def _two_planes(seed: int = 0):
    Ra, pa = _flush_touches(PLANES["table"], CONTACT, 12, seed)
    Rb, pb = _flush_touches(PLANES["wall"], CONTACT, 9, seed + 1)
    ids = ["table"] * 12 + ["wall"] * 9
    return np.concatenate([Ra, Rb]), np.concatenate([pa, pb]), ids


def test_noise_free_planes_and_contact_normal_recovered():
    R, p, ids = _two_planes()
    reg = register_planes(R, p, ids, GUESS)
    assert reg.ids == ("table", "wall")
    a = CONTACT[:3, 2]
    np.testing.assert_allclose(reg.contact[:3, 2], a, atol=1e-9)
    # the gauge: the contact keeps its guessed origin, tilted about its own x and y only
    np.testing.assert_array_equal(reg.contact[:3, 3], GUESS[:3, 3])
    tilt = Rotation.from_matrix(GUESS[:3, :3].T @ reg.contact[:3, :3]).as_rotvec()
    assert abs(tilt[2]) < 1e-12
    for name, truth in PLANES.items():
        fitted = _plane(reg, name)
        n = truth[:3, 2]
        np.testing.assert_allclose(fitted[:3, 2], n, atol=1e-9)
        # the contact's offset along its normal regroups with the plane's height
        expected = n @ truth[:3, 3] + a @ (GUESS[:3, 3] - CONTACT[:3, 3])
        assert abs(fitted[:3, 2] @ fitted[:3, 3] - expected) < 1e-9
        np.testing.assert_allclose(fitted[:3, :3].T @ fitted[:3, :3], np.eye(3), atol=1e-12)
    assert np.max(np.abs(_gaps(reg, R, p, ids))) < 1e-9


def _cost(R, p, ids, contact, planes: dict, weight: float) -> float:
    """Weighted sum of squares, scored with Pinocchio's rpy (not calib's residual code)."""
    total = 0.0
    for Rt, pt, name in zip(R, p, ids, strict=True):
        rel = pin.SE3(planes[name]).actInv(pin.SE3(Rt, pt) * pin.SE3(contact))
        roll, pitch, _ = pin.rpy.matrixToRpy(rel.rotation)
        total += rel.translation[2] ** 2 + weight**2 * (roll**2 + pitch**2)
    return total


def test_noisy_plane_fit_is_a_least_squares_minimum():
    R, p, ids = _two_planes(seed=3)
    rng = np.random.default_rng(7)
    p = p + rng.normal(0, 2e-3, p.shape)
    R = R @ Rotation.from_rotvec(rng.normal(0, 5e-3, (len(R), 3))).as_matrix()
    weight = 0.5
    reg = register_planes(R, p, ids, GUESS, weight=weight)
    planes = {k: _plane(reg, k) for k in reg.ids}
    best = _cost(R, p, ids, reg.contact, planes, weight)
    r = _gaps(reg, R, p, ids)
    assert best == pytest.approx(np.sum(r[:, 0] ** 2) + weight**2 * np.sum(r[:, 1:] ** 2))
    # every free direction (plane tilts and heights, contact tilt) raises the cost
    h = 1e-5
    for k in reg.ids:
        for axis in range(3):
            for sign in (-1, 1):
                moved = dict(planes)
                moved[k] = planes[k] @ _pose(sign * h * np.eye(3)[axis] * (axis < 2), [0, 0, 0])
                if axis == 2:
                    moved[k] = planes[k] @ _pose([0, 0, 0], [0, 0, sign * h])
                assert _cost(R, p, ids, reg.contact, moved, weight) > best
    for axis in range(2):
        for sign in (-1, 1):
            C = reg.contact @ _pose(sign * h * np.eye(3)[axis], [0, 0, 0])
            assert _cost(R, p, ids, C, planes, weight) > best


def test_plane_geometry_that_fixes_nothing_is_refused():
    R, p, ids = _two_planes()
    with pytest.raises(ContactGeometryError, match="at least 3"):
        register_planes(R[:14], p[:14], ids[:14], GUESS)
    # one orientation and spots on a line: the plane's tilt about that line is free
    same = np.repeat(R[:1], 8, axis=0)
    line = p[0] + np.outer(np.linspace(0, 0.3, 8), R[0][:, 0])
    with pytest.raises(ContactGeometryError, match="do not fix"):
        register_planes(same, line, ["t"] * 8, GUESS)
    assert issubclass(ContactGeometryError, CalibError)
    with pytest.raises(ContactGeometryError) as caught:
        register_planes(same, line, ["t"] * 8, GUESS)
    assert "\n" not in str(caught.value)


def test_fixed_points_recovered_and_one_orientation_refused():
    rng = np.random.default_rng(1)
    tip = np.array([0.02, -0.01, 0.15])
    points = {"cup": np.array([0.5, 0.2, 0.3]), "cone": np.array([0.4, -0.3, 0.1])}
    R = Rotation.from_rotvec(rng.normal(0, 0.6, (16, 3))).as_matrix()
    ids = ["cup"] * 9 + ["cone"] * 7
    p = np.array([points[k] - Rt @ tip for Rt, k in zip(R, ids, strict=True)])
    reg = register_points(R, p, ids, GUESS)
    np.testing.assert_allclose(reg.contact[:3, 3], tip, atol=1e-9)
    np.testing.assert_array_equal(reg.contact[:3, :3], GUESS[:3, :3])
    for k, y in points.items():
        np.testing.assert_allclose(reg.objects[reg.ids.index(k), :3, 3], y, atol=1e-9)
    assert np.max(np.abs(_gaps(reg, R, p, ids))) < 1e-9
    with pytest.raises(ContactGeometryError, match="tip"):
        register_points(np.repeat(R[:1], 5, axis=0), p[:5], ["cup"] * 5, GUESS)
    about_z = Rotation.from_rotvec(np.outer(np.linspace(0, 2, 6), [0, 0, 1])).as_matrix()
    with pytest.raises(ContactGeometryError, match="tip"):
        register_points(about_z, p[:6], ["cup"] * 6, GUESS)


def test_fixed_pose_is_the_geodesic_mean():
    rng = np.random.default_rng(2)
    F = _pose([0.3, -0.2, 1.0], [0.1, 0.2, 0.0])
    noise = [_pose(rng.normal(0, 0.05, 3), rng.normal(0, 0.01, 3)) for _ in range(10)]
    T = np.array([F @ E @ np.linalg.inv(CONTACT) for E in noise])
    reg = register_poses(T[:, :3, :3], T[:, :3, 3], ["feet"] * 10, CONTACT)
    np.testing.assert_array_equal(reg.contact, CONTACT)

    # stationary: the cost of the rotation residuals rises in every direction
    def cost(Rf):
        return sum(
            np.sum(Rotation.from_matrix(Rf.T @ Tt[:3, :3] @ CONTACT[:3, :3]).as_rotvec() ** 2)
            for Tt in T
        )

    Rf = reg.objects[0][:3, :3]
    best = cost(Rf)
    for axis in range(3):
        for sign in (-1, 1):
            assert cost(Rf @ Rotation.from_rotvec(sign * 1e-5 * np.eye(3)[axis]).as_matrix()) > best
    x = T[:, :3, 3] + T[:, :3, :3] @ CONTACT[:3, 3]
    np.testing.assert_allclose(reg.objects[0][:3, 3], x.mean(axis=0), atol=1e-12)
    exact = np.array([F @ np.linalg.inv(CONTACT)] * 4)
    again = register_poses(exact[:, :3, :3], exact[:, :3, 3], ["f"] * 4, CONTACT)
    np.testing.assert_allclose(again.objects[0], F, atol=1e-9)


def test_independent_scorer_agrees_with_the_registration_on_talos():
    ids, joints = read_joints(REAL / "left_train.csv")
    T = relative_placements(TALOS, "left_sole_link", "gripper_left_base_link", joints)
    R = np.array([t.rotation for t in T])
    p = np.array([t.translation for t in T])
    reg = register_planes(R, p, ids, _pose([0, 0, 0], [0, 0, -0.12]))
    gaps = plane_gaps(
        TALOS, "left_sole_link", "gripper_left_base_link", reg.contact, _plane(reg, "table"), joints
    )
    np.testing.assert_allclose(gaps, _gaps(reg, R, p, ids), atol=1e-12)
    assert np.sqrt(np.mean(gaps[:, 0] ** 2)) > 1e-4  # real data: the nominal model misfits


def test_scorer_reads_a_known_gap():
    _, joints = read_joints(REAL / "left_train.csv")
    one = {k: v[:1] for k, v in joints.items()}
    T = relative_placements(TALOS, "left_sole_link", "gripper_left_base_link", one)[0]
    C = _pose([0.1, 0.2, 0.3], [0.0, 0.0, -0.12])
    E = _pose([0.02, 0.0, 0.0], [0.0, 0.0, 0.01])  # 10 mm up, rolled 0.02 rad
    plane = T.homogeneous @ C @ np.linalg.inv(E)
    gaps = plane_gaps(TALOS, "left_sole_link", "gripper_left_base_link", C, plane, one)
    np.testing.assert_allclose(gaps[0], [0.01, 0.02, 0.0], atol=1e-12)
