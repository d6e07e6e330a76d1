"""The pixel kind on three set-ups: counts, noise-free round trips, 0.5 px noise.

Checked by routes that share nothing with the fit: the rank of central differences of
Pinocchio's placements projected by a textbook pinhole (tests/pixel_scorer.py), and the
written URDF loaded by Pinocchio, whose camera link sees the observed pixels.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from pixel_scorer import link_points, moved_model, numerical_rank, seen_pixels
from pixel_setups import INTRINSICS, SETUPS, calibrated, pixels, setup

from calib.calibration.pixel_chain import PixelCamera, Unknowns, pixel_rows
from calib.measurements.pixel_simulation import simulate_pixels
from calib.measurements.pixels import Target

K, DIST = INTRINSICS.camera.camera_matrix, INTRINSICS.camera.distortion
# 4 per revolute joint + 6 (Everett) with the target's mounting unknown; 4 fewer without it
# (the mounting's components across the last joint's axis are in no joint placement), but
# the Panda's target is on the root link: panda_joint1's origin in it is its mounting
EXPECTED = {"ur5": (26, 30), "panda": (34, 34), "tiago": (38, 42)}
TRAIN, HELD = slice(0, 150), slice(150, 250)


@pytest.fixture(scope="module", params=sorted(SETUPS))
def case(request, tmp_path_factory):
    s = setup(request.param, tmp_path_factory.mktemp(request.param), postures=250)
    obs = simulate_pixels(s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q[TRAIN])
    held = simulate_pixels(s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q[HELD])
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    fits = [
        calibrated(s.nominal, camera, s.target, obs, validate=held, what=Unknowns(mount))
        for mount in (False, True)
    ]
    return s, obs, held, fits


def _fd_rank(s, rows, mount, h=1e-6):
    """Rank of central differences over the camera's 6, every chain joint's 6 and (with
    ``mount``) the target mounting's 6 (Pinocchio + numpy; the placements moved by the test)."""
    chain = s.nominal
    model = chain.model
    X = s.target.position[rows.point]

    def px(C=s.placement, model=model, X=X):
        return seen_pixels(
            model, chain.base_frame, chain.tool_frame, chain.joint_names, rows.q, X, C, K, DIST
        ).ravel()

    cols = []
    for e in h * np.eye(6):
        up, down = np.eye(4), np.eye(4)
        up[:3, :3], up[:3, 3] = pin.exp3(e[3:]), e[:3]
        down[:3, :3], down[:3, 3] = pin.exp3(-e[3:]), -e[:3]
        cols.append((px(C=s.placement @ up) - px(C=s.placement @ down)) / (2 * h))
    for name in chain.joint_names:
        for e in h * np.eye(6):
            cols.append(
                (
                    px(model=moved_model(model, name, np.eye(3), e))
                    - px(model=moved_model(model, name, np.eye(3), -e))
                )
                / (2 * h)
            )
    for e in h * np.eye(6) if mount else ():
        cols.append(
            (px(X=X @ pin.exp3(e[3:]).T + e[:3]) - px(X=X @ pin.exp3(-e[3:]).T - e[:3])) / (2 * h)
        )
    return numerical_rank(np.column_stack(cols))


def test_count_equals_an_independent_finite_difference_rank(case):
    s, obs, _, fits = case
    rows = pixel_rows(s.nominal, obs, s.target, s.camera)
    some = rows.subset(np.arange(rows.m) % max(1, rows.m // 150) == 0)
    assert _fd_rank(s, some, False) == fits[0].identifiable == EXPECTED[s.name][0]
    assert _fd_rank(s, some, True) == fits[1].identifiable == EXPECTED[s.name][1]
    # every unknown determined is fitted (the Panda's board on its root: panda_joint1's origin)
    assert (fits[0].unknowns, fits[1].unknowns) == EXPECTED[s.name]


def test_noise_free_round_trip_on_the_written_urdf(case, tmp_path):
    """Pinocchio loads the written URDF: its camera link sees every observed pixel (training
    and held out) of the target file's points, or of the fitted target when its mounting
    was an unknown."""
    s, obs, held, fits = case
    for result in fits:
        path = tmp_path / "cal.urdf"
        path.write_bytes(result.urdf())
        model = pin.buildModelFromUrdf(str(path))
        for data in (obs, held):
            rows = pixel_rows(s.nominal, data, s.target, s.camera)
            X = result.chains[0].state.target[rows.point]
            seen = seen_pixels(
                model,
                s.camera,
                s.nominal.tool_frame,
                s.nominal.joint_names,
                rows.q,
                X,
                np.eye(4),
                K,
                DIST,
            )
            assert np.max(np.abs(seen - rows.pixels)) < 1e-9
        assert pixels(result, "train_registration")["reprojection_rms_px"] > 0.3
    assert np.array_equal(fits[0].chains[0].state.target, s.target.position)


def test_half_a_pixel_of_noise_held_out_position_at_the_target(case, capsys, tmp_path):
    """0.5 px noise: the calibrated model places the held-out target points in the camera
    closer to the truth than the nominal robot with the camera registered (printed)."""
    s, _, _, _ = case
    obs = simulate_pixels(
        s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q[TRAIN], noise_px=0.5, seed=7
    )
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    result = calibrated(s.nominal, camera, s.target, obs, holdout=0.2, seed=1)
    q = np.repeat(s.q[HELD], len(s.target.point), axis=0)
    X = np.tile(s.target.position, (len(s.q[HELD]), 1))
    chain = s.nominal

    def in_camera(model, C):
        p = link_points(model, chain.base_frame, chain.tool_frame, chain.joint_names, q, X)
        return (p - C[:3, 3]) @ C[:3, :3]

    truth = in_camera(s.truth.model, s.true_placement)
    path = tmp_path / "cal.urdf"
    path.write_bytes(result.urdf())
    model = pin.buildModelFromUrdf(str(path))
    fitted = in_camera(model, result.chains[0].state.camera)
    start = in_camera(chain.model, result.chains[0].registered.camera)
    err = 1e3 * np.linalg.norm(fitted - truth, axis=1)
    err0 = 1e3 * np.linalg.norm(start - truth, axis=1)
    with capsys.disabled():
        rms, rms0 = np.sqrt(np.mean(err**2)), np.sqrt(np.mean(err0**2))
        print(f"\n{s.name}: held-out position at the target, rms {rms:.3f} mm (camera registered")
        print(f"  on the nominal robot: {rms0:.3f} mm)")
    assert np.sqrt(np.mean(err**2)) < 0.5 * np.sqrt(np.mean(err0**2))
    assert not any("reprojection error is" in n for n in result.notes)  # 0.5 px: no warning
    assert not any("fitting its intrinsics" in n for n in result.notes)  # the right ones


def test_refine_targets_recovers_the_points_after_the_first_three(tmp_path):
    """A target file with its points after the first three off by ~2 mm: --refine-targets
    fits them back (noise-free, the truth's points to 1e-9 m), the first three stay as given."""
    s = setup("ur5", tmp_path, postures=120)
    obs = simulate_pixels(s.truth, s.camera, s.true_placement, INTRINSICS, s.target, s.q)
    wrong = s.target.position.copy()
    wrong[3:] += 2e-3 * np.random.default_rng(5).standard_normal(wrong[3:].shape)
    target = Target(s.target.point, wrong)
    camera = PixelCamera(s.camera, s.link, INTRINSICS, s.placement)
    result = calibrated(s.nominal, camera, target, obs, what=Unknowns(targets=True))
    fitted = result.chains[0].state.target
    assert np.array_equal(fitted[:3], wrong[:3])
    assert np.max(np.abs(fitted - s.target.position)) < 1e-9
    assert pixels(result)["reprojection_max_px"] < 1e-9
    plain = calibrated(s.nominal, camera, target, obs)
    assert pixels(plain)["reprojection_rms_px"] > 0.1
