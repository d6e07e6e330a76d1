"""The pinhole camera with OpenCV's distortion (calib.identification.pinhole), by other routes.

- its pixels are ``cv2.projectPoints``' for 4, 5, 8, 12 and 14 coefficients (OpenCV is a test
  extra: this file runs in CI);
- its derivatives are central differences of its pixels (numpy alone), and OpenCV's own
  Jacobian (translation and intrinsic columns);
- without distortion, the pixel is the textbook ``fx X / Z + cx``;
- a point at or behind the camera has no pixel: flagged, or refused.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib.exceptions import InvalidArgumentError
from calib.identification.pinhole import DISTORTION_COUNTS, MIN_DEPTH, Pinhole

# A real lens's order of magnitude: barrel distortion, a small rational part, thin prism and a
# sensor tilted by about a degree.
LENS = np.array(
    [
        -0.28,
        0.07,
        1.2e-3,
        -8e-4,
        0.012,
        0.09,
        -0.015,
        0.004,
        1.5e-3,
        -4e-4,
        -1e-3,
        3e-4,
        0.02,
        -0.015,
    ]
)


def camera(k: int) -> Pinhole:
    return Pinhole(612.5, 608.25, 321.7, 238.4, LENS[:k])


def points(m: int = 40, seed: int = 0) -> np.ndarray:
    """Points in the camera frame within a 90 degree field of view, 0.3 to 2 m deep."""
    rng = np.random.default_rng(seed)
    z = rng.uniform(0.3, 2.0, m)
    xy = rng.uniform(-0.45, 0.45, (m, 2)) * z[:, None]
    return np.column_stack([xy, z])


def opencv(cam: Pinhole, p: np.ndarray):
    """OpenCV's pixels ``(m, 2)`` and Jacobian ``(m, 2, 10 + k)`` of points in the camera frame."""
    pixels, jac = cv2.projectPoints(p, np.zeros(3), np.zeros(3), cam.camera_matrix, cam.distortion)
    return pixels.reshape(-1, 2), jac.reshape(len(p), 2, -1)


@pytest.mark.parametrize("k", DISTORTION_COUNTS)
def test_pixels_are_opencvs(k):
    cam, p = camera(k), points()
    want, _ = opencv(cam, p)
    got = cam.project(p)
    assert got.shape == (len(p), 2)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    # the distortion matters here: without it the pixels move by pixels, not round-off
    assert np.max(np.abs(Pinhole(cam.fx, cam.fy, cam.cx, cam.cy).project(p) - want)) > 1.0


def central(f, x: np.ndarray, h: float) -> np.ndarray:
    """Central differences of ``f`` (pixels ``(m, 2)``) by each entry of ``x``: ``(m, 2, n)``."""
    cols = []
    for j in range(len(x)):
        step = np.zeros_like(x)
        step[j] = h
        cols.append((f(x + step) - f(x - step)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("k", DISTORTION_COUNTS)
def test_point_derivative_is_central_differences(k):
    cam, p = camera(k), points(12, seed=1)
    got = cam.projection(p, derivatives=True).d_point
    for i, point in enumerate(p):
        num = central(lambda x: cam.project(x[None]), point, 1e-6)[0]
        np.testing.assert_allclose(got[i], num, rtol=1e-6, atol=1e-5)


@pytest.mark.parametrize("k", DISTORTION_COUNTS)
def test_intrinsic_derivative_is_central_differences(k):
    cam, p = camera(k), points(12, seed=2)
    got = cam.projection(p, derivatives=True).d_parameters
    assert got.shape == (len(p), 2, 4 + k) and len(cam.parameter_names) == 4 + k
    num = central(lambda x: cam.with_parameters(x).project(p), cam.parameters, 1e-7)
    np.testing.assert_allclose(got, num, rtol=1e-6, atol=1e-5)
    assert np.all(np.abs(got[:, :, 4:]).max(axis=(0, 1)) > 1e-3)  # every coefficient moves a pixel


@pytest.mark.parametrize("k", DISTORTION_COUNTS)
def test_derivatives_are_opencvs_jacobian(k):
    # OpenCV's columns: rotation (3), translation (3), f (2), c (2), distortion (k); with no
    # rotation, a translation moves the point in the camera frame
    cam, p = camera(k), points(30, seed=3)
    _, jac = opencv(cam, p)
    seen = cam.projection(p, derivatives=True)
    np.testing.assert_allclose(seen.d_point, jac[:, :, 3:6], rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(seen.d_parameters, jac[:, :, 6:], rtol=1e-9, atol=1e-9)


def test_without_distortion_the_pixel_is_the_textbook_one():
    cam = Pinhole(500.0, 400.0, 320.0, 240.0)
    p = np.array([[0.1, -0.2, 2.0], [0.0, 0.0, 1.0], [-1.0, 0.5, 0.5]])
    want = np.column_stack([500 * p[:, 0] / p[:, 2] + 320, 400 * p[:, 1] / p[:, 2] + 240])
    np.testing.assert_allclose(cam.project(p), want, rtol=0, atol=1e-12)
    d = cam.projection(p, derivatives=True).d_point
    np.testing.assert_allclose(d[0], [[250, 0, -12.5], [0, 200, 20]], atol=1e-12)


def test_points_at_or_behind_the_camera_are_flagged_not_projected():
    cam = camera(14)
    p = points(5)
    bad = p.copy()
    bad[1, 2] = 0.0
    bad[3, 2] = -0.7
    bad[4, 2] = MIN_DEPTH / 2
    seen = cam.projection(bad, derivatives=True)
    assert seen.in_front.tolist() == [True, False, True, False, False]
    assert np.all(np.isnan(seen.pixels[~seen.in_front]))
    assert np.all(np.isnan(seen.d_point[~seen.in_front]))
    # the points in front keep the pixels they have alone (OpenCV's, as above)
    np.testing.assert_allclose(seen.pixels[[0, 2]], opencv(cam, p[[0, 2]])[0], atol=1e-9)
    with pytest.raises(InvalidArgumentError, match=r"3 of 5 points .*behind the camera.*point 1"):
        cam.project(bad)
    # OpenCV itself projects a point behind the camera, mirrored: what calib refuses to do
    assert np.all(np.isfinite(opencv(cam, bad[[3]])[0]))


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((0.0, 600.0, 320.0, 240.0), "fx must be a finite number > 0"),
        ((600.0, -1.0, 320.0, 240.0), "fy must be a finite number > 0"),
        ((600.0, float("nan"), 320.0, 240.0), "fy must be a finite number"),
        ((600.0, 600.0, "320", 240.0), "cx must be a finite number"),
        ((600.0, 600.0, 320.0, 1e300), "cy must be a finite number"),
        ((600.0, 600.0, 320.0, 240.0, np.zeros(6)), "4, 5, 8, 12 or 14 coefficients, got 6"),
        ((600.0, 600.0, 320.0, 240.0, [0, 0, 0, np.inf]), "NaN or infinity"),
        ((600.0, 600.0, 320.0, 240.0, np.zeros((1, 5))), "shape"),
    ],
)
def test_a_camera_that_is_none_is_refused(args, message):
    with pytest.raises(InvalidArgumentError, match=message):
        Pinhole(*args)


def test_bad_points_are_refused():
    with pytest.raises(InvalidArgumentError, match="shape"):
        camera(5).project(np.zeros((3, 2)))
    with pytest.raises(InvalidArgumentError, match="NaN"):
        camera(5).projection([[0.0, 0.0, np.nan]])


def test_parameters_round_trip_and_are_named_in_opencvs_order():
    cam = camera(8)
    assert cam.parameter_names == (
        "fx",
        "fy",
        "cx",
        "cy",
        "k1",
        "k2",
        "p1",
        "p2",
        "k3",
        "k4",
        "k5",
        "k6",
    )
    again = cam.with_parameters(cam.parameters)
    np.testing.assert_array_equal(again.parameters, cam.parameters)
    assert not cam.distortion.flags.writeable
    with pytest.raises(InvalidArgumentError, match="shape"):
        cam.with_parameters(cam.parameters[:-1])
