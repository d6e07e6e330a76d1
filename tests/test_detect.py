"""``calib detect``: boards found in images, into the files ``calibrate --measure pixels`` reads.

Real images: ros-industrial/industrial_calibration's test images (tests/data/industrial_calibration,
its README). The counts are the ones that repository's own test records
(``test/target_finder_utest.cpp``); the pixels are OpenCV's ChArUco detector run here on its own;
the end-to-end run is accepted by the data set's own bound (its hand-eye test: reprojection RMS
under 1.5 px) and its intrinsics are compared with the data set's calibrated ones.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib.cli import main
from calib.exceptions import InvalidArgumentError
from calib.measurements.detection import Board, detect_board
from calib.measurements.intrinsics import read_intrinsics
from calib.measurements.pixels import Target, read_observations, read_target

DATA = Path(__file__).parent / "data" / "industrial_calibration"
SMALL = Board("charuco", 5, 7, 0.02, 0.01)  # test_images: CharucoGridTarget(7, 5, 0.02, 0.01)
SET = DATA / "test_set_charuco"
# The board of cal_data.yaml's target_finder.
SET_BOARD = [
    "--board",
    "charuco",
    "--squares",
    "5",
    "7",
    "--square",
    "0.036195",
    "--marker",
    "0.018256",
]
POSE_JOINTS = ("px", "py", "pz", "yaw", "pitch", "roll")


def run(capsys, *argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize(
    ("name", "recorded"),
    [
        ("charuco_unobscured.jpg", 24),
        ("charuco_obscured.jpg", 24 - 7),
        ("charuco_one_corner.jpg", 1),
    ],
)
def test_real_charuco_images_give_the_recorded_counts_and_opencvs_pixels(name, recorded):
    image = cv2.imread(str(DATA / "test_images" / name))
    found = detect_board(image, SMALL)
    assert len(found.point) == recorded  # industrial_calibration's target_finder_utest
    words = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_6X6_250)
    params = cv2.aruco.CharucoParameters()
    params.tryRefineMarkers = True
    board = cv2.aruco.CharucoBoard((5, 7), 0.02, 0.01, words)
    corners, ids = cv2.aruco.CharucoDetector(board, params).detectBoard(image)[:2]
    assert found.point == tuple(str(int(i)) for i in ids.ravel())
    assert np.array_equal(found.pixels, corners.reshape(-1, 2).astype(float))
    xyz = SMALL.corners(cv2)[1]
    assert np.max(np.abs(xyz - board.getChessboardCorners())) < 1e-7  # OpenCV's, in float32


def test_checkerboard_corners_in_opencvs_pixel_convention():
    """A drawn board: the corner between pixel columns 119 and 120 is at u = 119.5."""
    image = np.full((480, 640), 255, np.uint8)
    for j in range(7):
        for i in range(8):
            if (i + j) % 2 == 0:
                image[60 + 40 * j : 100 + 40 * j, 80 + 40 * i : 120 + 40 * i] = 0
    found = detect_board(image, Board("checkerboard", 8, 7, 0.03))
    ids, xyz = Board("checkerboard", 8, 7, 0.03).corners(cv2)
    expected = 80 - 0.5 + xyz[:, :2] / 0.03 * 40 + [0, -20]  # the row starts at 60
    assert found.point == ids and len(ids) == 7 * 6
    assert np.max(np.abs(found.pixels - expected)) < 0.05


def test_aruco_grid_corners_and_their_board_positions():
    board = Board("aruco", 4, 3, marker=0.04, separation=0.01)
    image = board.opencv_board(cv2).generateImage((640, 480), marginSize=20)
    found = detect_board(image, board)
    ids, xyz = board.corners(cv2)
    assert sorted(found.point) == sorted(ids)
    index = {p: i for i, p in enumerate(ids)}
    X = xyz[[index[p] for p in found.point], :2]
    H = cv2.findHomography(X, found.pixels)[0]  # the image is the board, scaled
    mapped = cv2.perspectiveTransform(X.reshape(-1, 1, 2), H).reshape(-1, 2)
    assert np.max(np.abs(mapped - found.pixels)) < 1.0  # generateImage rounds each marker


def _pose_robot(folder: Path) -> Path:
    """A URDF whose six joints are a pose: x, y, z, then yaw, pitch, roll (R = Rz Ry Rx)."""
    axes = ("1 0 0", "0 1 0", "0 0 1", "0 0 1", "0 1 0", "1 0 0")
    links = ["world", "l1", "l2", "l3", "l4", "l5", "tool"]
    joints = "".join(
        f'<joint name="{n}" type="{"prismatic" if k < 3 else "revolute"}"><parent link='
        f'"{links[k]}"/><child link="{links[k + 1]}"/><axis xyz="{axes[k]}"/><limit lower="-4" '
        f'upper="4" effort="1" velocity="1"/></joint>'
        for k, n in enumerate(POSE_JOINTS)
    )
    text = '<robot name="pose">' + "".join(f'<link name="{n}"/>' for n in links) + joints
    (folder / "pose.urdf").write_text(text + "</robot>")
    return folder / "pose.urdf"


def _numbers(path: Path) -> dict[str, float]:
    return {
        k.strip(): float(v)
        for k, v in (line.split(":") for line in path.read_text().split("\n") if line)
    }


def _joints_csv(folder: Path, count: int) -> Path:
    """JOINTS.csv of the recorded wrist poses (the pose robot's joints)."""
    rows = ["image," + ",".join(POSE_JOINTS)]
    for i in range(count):
        d = _numbers(SET / "poses" / f"{i}.yaml")
        rpy = Rotation.from_quat([d["qx"], d["qy"], d["qz"], d["qw"]]).as_euler("ZYX")
        values = [d["x"], d["y"], d["z"], *rpy]
        rows.append(f"{i}.jpg," + ",".join(repr(float(v)) for v in values))
    (folder / "joints.csv").write_text("\n".join(rows) + "\n")
    return folder / "joints.csv"


def _guesses(folder: Path, target: Path) -> list[str]:
    """The data set's hand-eye guesses: the camera's six numbers, the target in the tool."""
    text = (SET / "cal_data.yaml").read_text()

    def pose(key):
        block = text[text.index(key) :].split("\n")[1:8]
        d = {k.strip(): float(v) for k, v in (line.split(":")[:2] for line in block)}
        return np.array([d[a] for a in "xyz"]), Rotation.from_quat([d[f"q{a}"] for a in "xyzw"])

    p, R = pose("camera_mount_to_camera_guess:")
    q, M = pose("target_mount_to_target_guess:")
    board = read_target(target)
    X = M.apply(np.array(board.position)) + q
    lines = [
        "point,x,y,z",
        *(f"{n},{x!r},{y!r},{z!r}" for n, (x, y, z) in zip(board.point, X.tolist(), strict=True)),
    ]
    (folder / "tool_target.csv").write_text("\n".join(lines) + "\n")
    return [*(repr(float(v)) for v in p), *(repr(float(v)) for v in R.as_euler("xyz"))]


def test_detect_real_images_then_calibrate(capsys, tmp_path):
    """8 real images: every board found, OBS.csv and TARGET.csv read by calibrate, which fits
    the camera within the data set's own bound; the intrinsics near the data set's."""
    joints = _joints_csv(tmp_path, 8)
    images = [SET / "images" / f"{i}.jpg" for i in range(8)]
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((1200, 1600), 128, np.uint8))
    joints.write_text(joints.read_text() + "blank.png,0,0,0,0,0,0\n")
    obs, target, intr = tmp_path / "obs.csv", tmp_path / "target.csv", tmp_path / "intr.yaml"
    code, out, err = run(
        capsys,
        "detect",
        *images,
        blank,
        *SET_BOARD,
        "--joints",
        joints,
        "--camera",
        "mako",
        "--out",
        obs,
        "--target",
        target,
        "--intrinsics-out",
        intr,
    )
    assert code == 0, err
    assert "found in 8 of 9 images (1600x1200 px): 192 corners" in out
    assert f"not found: {blank}" in out
    fitted = read_intrinsics(intr)  # the data set's: fx 1352.0, fy 1356.1, cx 789.7, cy 627.3
    assert fitted.camera.fx == pytest.approx(1352.03, rel=0.02)
    assert fitted.camera.fy == pytest.approx(1356.14, rel=0.02)
    assert abs(fitted.camera.cx - 789.67) < 30 and abs(fitted.camera.cy - 627.30) < 30
    given = tmp_path / "given.yaml"  # the data set's calibrated intrinsics
    given.write_text(
        "image_width: 1600\nimage_height: 1200\ndistortion_coefficients: [0, 0, 0, 0, 0]\n"
        "camera_matrix: [1352.02747, 0, 789.67065, 0, 1356.14287, 627.2995, 0, 0, 1]\n"
    )
    camera = _guesses(tmp_path, target)
    urdf, report = tmp_path / "cal.urdf", tmp_path / "r.json"
    code, out, err = run(
        capsys,
        "calibrate",
        _pose_robot(tmp_path),
        "--measure",
        "pixels",
        "--data",
        obs,
        "--camera",
        "mako",
        "world",
        given,
        *camera,
        "--target",
        tmp_path / "tool_target.csv",
        "--tool",
        "tool",
        "--params",
        "complete",
        "--out",
        urdf,
        "--report",
        report,
    )
    assert code == 0, err
    assert urdf.is_file()
    pixels = json.loads(report.read_text())["errors"]["terms"][0]["train"]["pixels"]
    assert pixels["calibrated"]["reprojection_rms_px"] < 1.5  # the data set's bound
    seen = read_observations(obs, POSE_JOINTS, {"mako": read_intrinsics(given)})
    assert seen.m == 192


def _two_images(tmp_path: Path) -> tuple[list[Path], Path]:
    images = [SET / "images" / f"{i}.jpg" for i in range(2)]
    return images, _joints_csv(tmp_path, 2)


def test_no_board_in_any_image_is_one_line_and_no_file(capsys, tmp_path):
    images, joints = _two_images(tmp_path)
    obs = tmp_path / "obs.csv"
    code, _, err = run(
        capsys,
        "detect",
        *images,
        "--board",
        "checkerboard",
        "--squares",
        "9",
        "6",
        "--square",
        "0.03",
        "--joints",
        joints,
        "--camera",
        "c",
        "--out",
        obs,
    )
    assert code == 2 and err.count("\n") == 1
    assert "no checkerboard board found in any of 2 images" in err
    assert not obs.exists()


def test_an_image_without_joint_readings_is_one_line_and_no_file(capsys, tmp_path):
    images, joints = _two_images(tmp_path)
    joints.write_text("\n".join(joints.read_text().split("\n")[:2]) + "\n")  # image 1 dropped
    obs = tmp_path / "obs.csv"
    code, _, err = run(
        capsys, "detect", *images, *SET_BOARD, "--joints", joints, "--camera", "c", "--out", obs
    )
    assert code == 2 and err.count("\n") == 1
    assert f"no row for image {images[1]}" in err
    assert not obs.exists()


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--board", "charuco", "--squares", "5", "7", "--square", "0.03"], "marker length"),
        (["--board", "aruco", "--squares", "5", "7", "--marker", "0.03"], "separation length"),
        ([*SET_BOARD, "--dictionary", "DICT_NOPE"], "no ArUco dictionary DICT_NOPE"),
        ([*SET_BOARD[:-2], "--marker", "0.05"], "must be smaller than its square"),
    ],
)
def test_bad_boards_are_one_line(capsys, tmp_path, options, message):
    images, joints = _two_images(tmp_path)
    code, _, err = run(
        capsys,
        "detect",
        *images,
        *options,
        "--joints",
        joints,
        "--camera",
        "c",
        "--out",
        tmp_path / "obs.csv",
    )
    assert code == 2 and err.count("\n") == 1 and message in err


def test_a_legacy_charuco_board_is_found_only_as_legacy():
    """OpenCV 4.6 swapped the squares of ChArUco boards with an even number of rows."""
    legacy = Board("charuco", 5, 6, 0.04, 0.03, legacy=True)
    current = Board("charuco", 5, 6, 0.04, 0.03)
    for made, other in ((legacy, current), (current, legacy)):
        image = made.opencv_board(cv2).generateImage((500, 600), marginSize=40)
        assert len(detect_board(image, made).point) == 4 * 5
        assert not detect_board(image, other).found


def test_a_board_with_a_length_that_is_no_number_is_refused():
    with pytest.raises(InvalidArgumentError, match="separation length is in metres"):
        Board("charuco", 7, 5, 0.06, 0.045, "DICT_4X4_50")  # type: ignore[arg-type]
    with pytest.raises(InvalidArgumentError, match="square length is in metres"):
        Board("checkerboard", 7, 5, 30.0)  # millimetres


def test_without_opencv_the_error_says_how_to_install_it(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "cv2", None)  # import cv2 raises ImportError
    with pytest.raises(InvalidArgumentError, match=r"pip install 'calib\[vision\]'"):
        detect_board(np.zeros((10, 10), np.uint8), SMALL)
    images, joints = _two_images(tmp_path)
    code, _, err = run(
        capsys,
        "detect",
        *images,
        *SET_BOARD,
        "--joints",
        joints,
        "--camera",
        "c",
        "--out",
        tmp_path / "obs.csv",
    )
    assert code == 2 and err.count("\n") == 1 and "calib[vision]" in err


def _render(board_image: np.ndarray, per_m: float, K: np.ndarray, T: np.ndarray) -> np.ndarray:
    """The board image seen by a pinhole camera without distortion (board pose ``T`` in it).

    A board point (x, y) [m] is the board image's pixel (x, y) * per_m - 0.5 (the outline's
    corner at the top-left pixel's outer corner).
    """
    S = np.array([[1 / per_m, 0, 0.5 / per_m], [0, 1 / per_m, 0.5 / per_m], [0, 0, 1]])
    H = K @ np.column_stack([T[:3, 0], T[:3, 1], T[:3, 3]]) @ S
    return cv2.warpPerspective(board_image, H, (1280, 960), flags=cv2.INTER_LINEAR, borderValue=160)


def test_rendered_board_round_trip(capsys, tmp_path):
    """A ChArUco board on a UR5's tool0 rendered in a camera in the cell: the corners found are
    cv2.projectPoints' of the true corners, and the hand-eye fit recovers the true camera."""
    from pixel_setups import look_at

    from calib import load_chain
    from calib.calibration.hand_eye import hand_eye
    from calib.calibration.pixel_chain import PixelCamera
    from calib.identification.pinhole import Pinhole
    from calib.kinematics.mdh import from_chain
    from calib.measurements.intrinsics import Intrinsics, write_intrinsics

    lens = Intrinsics(1280, 960, Pinhole(900.0, 900.0, 640.0, 480.0))
    K = lens.camera_matrix
    board = Board("charuco", 7, 5, 0.06, 0.045, dictionary="DICT_4X4_50")
    per_m = 2000.0  # 120 px a square
    image = board.opencv_board(cv2).generateImage((840, 600), marginSize=0)
    chain = load_chain("ur5", base="world", tool="tool0")
    C = look_at(np.array([0.9, 0.3, 0.7]), [0.2, 0.0, 0.3])
    M = np.eye(4)
    M[:3, :3] = Rotation.from_euler("x", np.pi).as_matrix()
    M[:3, 3] = (-0.21, 0.15, 0.01)  # the board's centre near the flange's axis
    ids, B = board.corners(cv2)
    q = chain.random_configurations(20_000, 5)
    kin = from_chain(chain).kinematics(q)
    T = np.linalg.inv(C) @ np.einsum("mij,jk->mik", _homogeneous(kin.R[:, -1], kin.p[:, -1]), M)
    corners = np.einsum("mij,kj->mki", T[:, :3, :3], B) + T[:, None, :3, 3]
    uv = corners[..., :2] / corners[..., 2:]
    inside = (corners[..., 2] > 0.3).all(1) & (T[:, 2, 2] > 0.85)  # seen from the front
    inside &= (np.abs(uv[..., 0]) < 0.6).all(1) & (np.abs(uv[..., 1]) < 0.45).all(1)
    chosen = np.flatnonzero(inside)[:10]
    assert len(chosen) == 10
    rows = ["image," + ",".join(chain.joint_names)]
    for k, i in enumerate(chosen):
        cv2.imwrite(str(tmp_path / f"{k}.png"), _render(image, per_m, K, T[i]))
        rows.append(f"{k}.png," + ",".join(repr(float(v)) for v in q[i]))
    (tmp_path / "joints.csv").write_text("\n".join(rows) + "\n")
    obs_path, target_path = tmp_path / "obs.csv", tmp_path / "target.csv"
    code, _, err = run(
        capsys,
        "detect",
        *(tmp_path / f"{k}.png" for k in range(10)),
        "--board",
        "charuco",
        "--squares",
        7,
        5,
        "--square",
        0.06,
        "--marker",
        0.045,
        "--dictionary",
        "DICT_4X4_50",
        "--joints",
        tmp_path / "joints.csv",
        "--camera",
        "cam",
        "--out",
        obs_path,
        "--target",
        target_path,
    )
    assert code == 0, err
    write_intrinsics(tmp_path / "intr.yaml", lens)
    obs = read_observations(obs_path, chain.joint_names, {"cam": lens})
    assert obs.m == 10 * len(ids)  # every corner of every image
    target = read_target(target_path)
    assert target.point == ids
    errors = []
    for i in chosen:  # the truth: cv2.projectPoints of the true corners
        rvec = cv2.Rodrigues(T[i][:3, :3])[0]
        truth = cv2.projectPoints(target.position, rvec, T[i][:3, 3], K, None)[0].reshape(-1, 2)
        rows_k = np.flatnonzero(np.all(obs.q == q[i], axis=1))
        index = [target.index[p] for p in np.array(obs.point)[rows_k]]
        errors.append(obs.pixels[rows_k] - truth[index])
    errors = np.concatenate(errors)
    rms = np.sqrt(np.mean(errors**2))
    assert np.max(np.abs(errors)) < 1.0 and rms < 0.2  # 0.54 and 0.10 px measured
    guess = Target(target.point, target.position @ M[:3, :3].T + M[:3, 3] + 0.005)
    fit = hand_eye(chain, PixelCamera("cam", "world", lens, None), guess, obs)
    assert fit.rms_px < 0.2  # the detection's noise
    assert np.linalg.norm(fit.camera[:3, 3] - C[:3, 3]) < 5e-4  # [m] (0.06 mm measured)
    angle = np.linalg.norm(Rotation.from_matrix(fit.camera[:3, :3].T @ C[:3, :3]).as_rotvec())
    assert angle < 5e-4  # [rad] (0.06 mrad measured)


def _homogeneous(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.tile(np.eye(4), (len(R), 1, 1))
    T[:, :3, :3], T[:, :3, 3] = R, p
    return T


def test_intrinsics_written_to_stdout_are_alone_there(capsys, tmp_path):
    """``calib detect ... --intrinsics-out - > intr.yaml``: the summary was printed after the
    YAML, on standard output too."""
    images = [SET / "images" / f"{i}.jpg" for i in range(8)]
    code, out, err = run(
        capsys,
        "detect",
        *images,
        *SET_BOARD,
        "--joints",
        _joints_csv(tmp_path, 8),
        "--camera",
        "mako",
        "--out",
        tmp_path / "obs.csv",
        "--intrinsics-out",
        "-",
    )
    assert code == 0, err
    assert out.startswith("%YAML") and "found in" not in out and "wrote" not in out
    assert "found in 8 of 8 images" in err
