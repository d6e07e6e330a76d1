"""Intrinsics files (calib.measurements.intrinsics): what OpenCV writes is read back equal.

- files written by ``cv2.FileStorage`` (YAML and JSON, 1xN and Nx1 coefficients, the
  calibration sample's other keys and comments) read back to the numbers written; calib's own
  writer read by ``cv2.FileStorage`` to the same numbers;
- OpenCV 4's ``%YAML:1.0`` text, ROS's camera file and plain YAML or JSON of the same keys;
- every bad input is one DataError line naming the file and the key; a principal point far
  from the centre (width and height swapped) is a DataWarning.
"""

from __future__ import annotations

import json
import warnings

import cv2
import numpy as np
import pytest

from calib.exceptions import DataError, InvalidArgumentError
from calib.identification.pinhole import Pinhole
from calib.measurements.data import DataWarning
from calib.measurements.intrinsics import (
    Intrinsics,
    intrinsics_yaml,
    parse_intrinsics,
    read_intrinsics,
    write_intrinsics,
)
from calib.measurements.yaml_subset import parse_yaml

K = np.array([[612.5, 0.0, 321.7], [0.0, 608.25, 238.4], [0.0, 0.0, 1.0]])
DIST = np.array([-0.2812345678901234, 0.0712, 1.2e-3, -8e-4, 0.0123456789, 0.09, -0.015, 0.004])


def opencv_file(path, dist: np.ndarray, extra=None) -> None:
    """A file as OpenCV's FileStorage writes it (its format from the suffix)."""
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    for key, value in (extra or {}).items():
        fs.write(key, value)
    fs.write("camera_matrix", K)
    fs.write("distortion_coefficients", dist)
    fs.release()


def assert_read(intr: Intrinsics, dist: np.ndarray, width: int = 640, height: int = 480) -> None:
    assert (intr.width, intr.height) == (width, height)
    np.testing.assert_array_equal(intr.camera_matrix, K)
    np.testing.assert_array_equal(intr.distortion, dist.ravel())


@pytest.mark.parametrize("suffix", ["yaml", "yml", "json"])
@pytest.mark.parametrize("shape", [(1, 5), (5, 1), (1, 4), (1, 8), (12, 1), (1, 14)])
def test_what_opencv_writes_reads_back_equal(tmp_path, suffix, shape):
    dist = np.resize(DIST, shape)
    path = tmp_path / f"camera.{suffix}"
    opencv_file(path, dist)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert_read(read_intrinsics(path), dist)


def test_the_calibration_samples_other_keys_are_ignored(tmp_path):
    path = tmp_path / "out_camera_data.yml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("calibration_time", "Sat Nov 28 05:00:00 2026")
    fs.write("nr_of_frames", 25)
    fs.write("board_width", 9)
    fs.writeComment("flags: +fix_aspectRatio # and a hash")
    fs.write("flags", 2)
    fs.write("fisheye_model", 0)
    fs.write("camera_matrix", K)
    fs.write("image_width", 640)
    fs.write("image_height", 480)
    fs.write("distortion_coefficients", DIST[:5].reshape(5, 1))
    fs.write("avg_reprojection_error", 0.31)
    fs.write("per_view_reprojection_errors", np.array([[0.3], [0.25], [0.4]], dtype=np.float32))
    fs.write("extrinsic_parameters", np.arange(18.0).reshape(3, 6))
    fs.release()
    assert_read(read_intrinsics(path), DIST[:5])


@pytest.mark.parametrize("k", [4, 5, 14])
def test_calibs_file_reads_in_opencv_and_back(tmp_path, k):
    intr = Intrinsics(640, 480, Pinhole(K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.resize(DIST, k)))
    path = tmp_path / "cam.yaml"
    write_intrinsics(path, intr)
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    assert fs.getNode("image_width").real() == 640
    assert fs.getNode("image_height").real() == 480
    np.testing.assert_array_equal(fs.getNode("camera_matrix").mat(), K)
    np.testing.assert_array_equal(
        fs.getNode("distortion_coefficients").mat().ravel(), intr.distortion
    )
    fs.release()
    assert_read(read_intrinsics(path), intr.distortion)
    assert path.read_text().startswith("%YAML:1.0\n")


OPENCV4 = """%YAML:1.0
---
image_width: 640
image_height: 480
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 6.1250000000000000e+02, 0., 3.2170000000000000e+02, 0.,
       6.0825000000000000e+02, 2.3840000000000001e+02, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ -2.8000000000000003e-01, 7.0000000000000007e-02,
       1.0000000000000000e-03, -2.0000000000000001e-04, 0. ]
"""


def test_opencv4s_text_reads():
    intr = parse_intrinsics(OPENCV4, "opencv4.yaml")
    assert_read(intr, np.array([-0.28, 0.07, 1e-3, -2e-4, 0.0]))


ROS = """image_width: 640
image_height: 480
camera_name: narrow_stereo
camera_matrix:
  rows: 3
  cols: 3
  data: [612.5, 0, 321.7, 0, 608.25, 238.4, 0, 0, 1]
distortion_model: plumb_bob
distortion_coefficients:
  rows: 1
  cols: 5
  data: [-0.28, 0.07, 0.001, -0.0002, 0]
rectification_matrix:
  rows: 3
  cols: 3
  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]
projection_matrix:
  rows: 3
  cols: 4
  data: [612.5, 0, 321.7, 0, 0, 608.25, 238.4, 0, 0, 0, 1, 0]
"""


def test_ros_camera_file_reads():
    assert_read(parse_intrinsics(ROS, "ros.yaml"), np.array([-0.28, 0.07, 1e-3, -2e-4, 0.0]))


PLAIN = """# plain YAML, nested lists
image_width: 640
image_height: 480
camera_matrix:
  - [612.5, 0, 321.7]
  - [0, 608.25, 238.4]
  - [0, 0, 1]
distortion_coefficients: [-0.28, 0.07, 0.001, -0.0002]
"""


def test_plain_yaml_and_json_of_the_same_keys_read():
    dist = np.array([-0.28, 0.07, 1e-3, -2e-4])
    assert_read(parse_intrinsics(PLAIN, "plain.yaml"), dist)
    text = json.dumps(
        {
            "image_width": 640,
            "image_height": 480,
            "camera_matrix": K.tolist(),
            "distortion_coefficients": [[v] for v in dist],
        }
    )
    assert_read(parse_intrinsics(text, "plain.json"), dist)


def replaced(old: str, new: str, text: str = ROS) -> str:
    assert old in text
    return text.replace(old, new)


JSON_START = '{"image_width": 640, "image_height": 480, "camera_matrix": [[1, 0, 1], [0, 1, 1], '
JSON_START += "[0, 0, 1]], "
BAD = [
    (replaced("image_width: 640\n", ""), "image_width: missing"),
    (replaced("image_height: 480\n", "image_height:\n"), "image_height: missing"),
    (PLAIN.replace("distortion_coefficients", "distortion"), "distortion_coefficients: missing"),
    (replaced("camera_matrix:", "camera:"), "camera_matrix: missing"),
    (
        replaced(
            "cols: 5\n  data: [-0.28, 0.07, 0.001, -0.0002, 0]",
            "cols: 6\n  data: [0, 0, 0, 0, 0, 0]",
        ),
        "14 coefficients .* got 6",
    ),
    (replaced("data: [-0.28, 0.07", "data: [.nan, 0.07"), "not a finite number"),
    (replaced("data: [612.5, 0, 321.7", "data: [0, 0, 321.7"), "focal lengths fx = 0"),
    (replaced("data: [612.5, 0, 321.7", "data: [612.5, 0.5, 321.7"), "a skew of 0.5"),
    (replaced("0, 0, 1]\ndistortion_model", "0.1, 0, 1]\ndistortion_model"), r"\[0, 0, 1\]\]"),
    (
        replaced("rows: 3\n  cols: 3\n  data: [612.5", "rows: 2\n  cols: 3\n  data: [612.5"),
        "2x3 matrix with 9 numbers",
    ),
    (replaced("image_width: 640", "image_width: 640.5"), "not a whole number of pixels"),
    (replaced("image_width: 640", "image_width: 0"), "not an image side"),
    (replaced("image_height: 480", "image_height: '480'"), "not a whole number"),
    (
        replaced("plumb_bob", "equidistant"),
        "distortion_model: 'equidistant' is not OpenCV's pinhole",
    ),
    (ROS + "fisheye_model: 1\n", "fisheye_model: a fisheye lens"),
    (replaced("data: [-0.28,", "data: [abc,"), "distortion_coefficients: 'abc' is not a number"),
    (replaced("image_height: 480", "\timage_height: 480"), "row 2.*tab"),
    (ROS + "image_width: 640\n", "row 21.*'image_width' given twice"),
    (replaced("camera_matrix:", "camera_matrix: !!python/object"), "row 4.*'!'"),
    (replaced("data: [612.5, 0, 321.7, 0, 608.25", "data: [612.5, 0, 321.7, 0, 608.25 }"), "row 7"),
    (
        replaced("  rows: 3\n  cols: 3\n  data: [612.5", "    rows: 3\n  cols: 3\n  data: [612.5"),
        "row 6.*unexpected indentation",
    ),
    ("x,y,z\n0.1,0.2,0.3\n", "expected 'key: value'"),
    ('<?xml version="1.0"?>\n<robot name="r"/>\n', "expected 'key: value'"),
    ("", "empty file"),
    ("- 1\n- 2\n", "expected YAML keys"),
    ("%YAML:1.0\n---\nimage_width: 640\n---\n", "one YAML document"),
    ('{"image_width": 640,}', "not valid JSON"),
    (
        JSON_START + '"distortion_coefficients": [NaN, 0, 0, 0]}',
        "nan is not a finite",
    ),
    (
        JSON_START + '"distortion_coefficients": [[1, 2], [3, 4]]}',
        r"\(1xN or Nx1\), got 2x2",
    ),
]


@pytest.mark.parametrize(("text", "message"), BAD, ids=[m for _, m in BAD])
def test_bad_intrinsics_are_one_line_errors(text, message):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        with pytest.raises(DataError, match=message) as caught:
            parse_intrinsics(text, "cam.yaml")
    assert "\n" not in str(caught.value) and str(caught.value).startswith("cam.yaml")


def test_swapped_width_and_height_are_warned_about():
    with pytest.warns(DataWarning, match=r"far from the centre \(240, 320\).*swapped"):
        intr = parse_intrinsics(
            replaced("image_width: 640\nimage_height: 480", "image_width: 480\nimage_height: 640"),
            "cam.yaml",
        )
    assert (intr.width, intr.height) == (480, 640)  # read as given: a warning, not an error
    off_centre = replaced("321.7, 0, 608.25, 238.4", "321.7, 0, 608.25, 400")
    with pytest.warns(DataWarning, match=r"\(321.7, 400\) px is far .* image$"):
        parse_intrinsics(off_centre, "cam.yaml")


def test_a_missing_file_and_a_bad_value_to_write(tmp_path):
    with pytest.raises(DataError, match=r"nope\.yaml"):
        read_intrinsics(tmp_path / "nope.yaml")
    with pytest.raises(InvalidArgumentError, match="Intrinsics"):
        write_intrinsics(tmp_path / "out.yaml", "camera")
    assert not (tmp_path / "out.yaml").exists()
    with pytest.raises(InvalidArgumentError, match="whole number of pixels"):
        Intrinsics(640.0, 480, Pinhole(1.0, 1.0, 0.0, 0.0))
    with pytest.raises(InvalidArgumentError, match="Pinhole"):
        Intrinsics(640, 480, K)


def test_inside_the_image_is_opencvs_pixel_grid():
    intr = parse_intrinsics(ROS, "ros.yaml")
    uv = np.array([[-0.5, -0.5], [639.5, 479.5], [-0.51, 10], [10, 479.51], [320, 240]])
    assert intr.inside(uv).tolist() == [True, True, False, False, True]
    assert intrinsics_yaml(intr).count("!!opencv-matrix") == 2


def test_the_yaml_subset_reads_what_yaml_means():
    text = """%YAML 1.2
---
a: 'it''s # no comment'   # a comment
b: "x: y"
c:
- 1
- -2.5e-01
- [0., .5, .Inf, -.inf, ~, true]
d: {e: [1, {f: g}], h: null}
i:
  j:
    - k
  l: 3
"""
    got = parse_yaml(text, "t.yaml")
    assert got["a"] == "it's # no comment" and got["b"] == "x: y"
    assert got["c"][:2] == [1, -0.25]
    assert got["c"][2] == [0.0, 0.5, float("inf"), float("-inf"), None, True]
    assert got["d"] == {"e": [1, {"f": "g"}], "h": None}
    assert got["i"] == {"j": ["k"], "l": 3}
    assert list(got) == ["a", "b", "c", "d", "i"]


def test_opencvs_other_structures_beside_the_keys_are_read(tmp_path):
    path = tmp_path / "cam.yaml"
    fs = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    fs.write("image_points", np.zeros((3, 1, 2), np.float32))  # dt: "2f"
    fs.startWriteStruct("views", cv2.FileNode_SEQ)
    fs.startWriteStruct("", cv2.FileNode_MAP | cv2.FileNode_FLOW)
    fs.write("x", 41)
    fs.write("name", "a b")
    fs.endWriteStruct()
    fs.write("", 3)
    fs.endWriteStruct()
    fs.startWriteStruct("board", cv2.FileNode_MAP)
    fs.write("square", 0.025)
    fs.endWriteStruct()
    fs.release()
    text = path.read_text()
    assert "{ x:41, name:a b }" in text  # OpenCV's flow mapping, no space after the colon
    got = parse_yaml(text, "cam.yaml")
    assert got["views"] == [{"x": 41, "name": "a b"}, 3] and got["board"] == {"square": 0.025}
    assert got["image_points"]["dt"] == "2f" and got["image_points"]["data"] == [0.0] * 6
    tagged = text.replace("!!opencv-matrix", "!!opencv-nd-matrix")
    assert parse_yaml(tagged, "cam.yaml")["image_points"]["rows"] == 3
    with pytest.raises(DataError, match=r"row 3.*an !!opencv- tag is on a block of keys"):
        parse_yaml("%YAML:1.0\n---\nk: !!opencv-matrix 3\n", "cam.yaml")
