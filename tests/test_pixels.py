"""Pixel observations and targets (calib.measurements.pixels): written, read back equal; bad
files refused with one line naming the row."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

from calib.exceptions import CalibError, DataError, InvalidArgumentError
from calib.identification.pinhole import Pinhole
from calib.measurements.data import DataWarning
from calib.measurements.intrinsics import (
    Intrinsics,
    parse_intrinsics,
    read_intrinsics,
    write_intrinsics,
)
from calib.measurements.pixels import (
    PixelObservations,
    Target,
    observations_csv,
    parse_observations,
    parse_target,
    read_observations,
    read_target,
    target_csv,
    write_observations,
    write_target,
)

CAMERAS = {
    "head": Intrinsics(640, 480, Pinhole(600.0, 600.0, 320.0, 240.0)),
    "wrist": Intrinsics(1280, 720, Pinhole(900.0, 900.0, 640.0, 360.0, np.zeros(5))),
}
JOINTS = ("shoulder", "u", "elbow")  # a joint named like the pixel column


def target(seed: int = 0) -> Target:
    rng = np.random.default_rng(seed)
    ids = tuple(f"c{i}" for i in range(6))
    links = ("hand",) * 3 + ("left hand",) * 3
    return Target(ids, rng.uniform(-0.1, 0.1, (6, 3)), links, rng.normal(size=(6, 3)), "t.csv")


def observations(seed: int = 0) -> PixelObservations:
    rng = np.random.default_rng(seed)
    m = 24
    camera = tuple(rng.choice(["head", "wrist"], m))
    size = np.array([[CAMERAS[c].width, CAMERAS[c].height] for c in camera])
    pixels = rng.uniform(0, 1, (m, 2)) * size - 0.5
    point = tuple(f"c{i % 6}" for i in range(m))
    q = rng.uniform(-3, 3, (m // 6, 3)).repeat(6, axis=0)
    return PixelObservations(JOINTS, q, camera, point, pixels, "o.csv")


def test_observations_and_target_round_trip(tmp_path):
    obs, tgt = observations(), target()
    write_target(tmp_path / "t.csv", tgt)
    write_observations(tmp_path / "o.csv", obs)
    assert (tmp_path / "o.csv").read_text().splitlines()[
        0
    ] == "shoulder,joint:u,elbow,camera,point,u,v"
    t = read_target(tmp_path / "t.csv")
    assert t.point == tgt.point and t.link == tgt.link and t.rows == tuple(range(2, 8))
    np.testing.assert_array_equal(t.position, tgt.position)
    np.testing.assert_array_equal(t.normal, tgt.normal)
    np.testing.assert_allclose(np.linalg.norm(t.normal, axis=1), 1.0, rtol=1e-15)
    o = read_observations(tmp_path / "o.csv", JOINTS, CAMERAS, t)
    assert o.joint_names == JOINTS and o.camera == obs.camera and o.point == obs.point
    np.testing.assert_array_equal(o.q, obs.q)
    np.testing.assert_array_equal(o.pixels, obs.pixels)
    assert o.cameras == tuple(dict.fromkeys(obs.camera))


def test_columns_in_any_order_and_the_minimal_target():
    t = parse_target("z,point,y,x\n0.3,a,0.2,0.1\n-0.05,b,0,0\n", "t.csv")
    assert t.point == ("a", "b") and t.link is None and t.normal is None
    np.testing.assert_array_equal(t.position, [[0.1, 0.2, 0.3], [0, 0, -0.05]])
    text = "v,u,camera,point,joint:u,shoulder,elbow\n479.5,-0.5,head,a,1.5,0.25,-1\n"
    o = parse_observations(text, JOINTS, CAMERAS, t, "o.csv")
    np.testing.assert_array_equal(o.q, [[0.25, 1.5, -1.0]])
    np.testing.assert_array_equal(o.pixels, [[-0.5, 479.5]])


OBS = "shoulder,joint:u,elbow,camera,point,u,v\n0,0,0,head,c0,100,200\n0,0,0,head,c1,110,210\n"


def obs_error(text: str, match: str) -> None:
    with pytest.raises(DataError, match=match) as caught:
        parse_observations(text, JOINTS, CAMERAS, target(), "o.csv")
    assert "\n" not in str(caught.value) and str(caught.value).startswith("o.csv")


def test_pixels_with_u_and_v_swapped_are_named_so():
    """Pixels that fit a 640x480 image only with u and v exchanged: the error says so; a pixel
    off the image either way does not."""
    text = OBS.replace("100,200", "200,100").replace("110,210", "470,600")
    obs_error(text, r"row 3\).*pixel \(470, 600\) is outside.*: u and v swapped")
    with pytest.raises(DataError, match="outside") as caught:
        parse_observations(text.replace("200,100", "200,700"), JOINTS, CAMERAS, target(), "o")
    assert "swapped" not in str(caught.value)


def _wrist_rows(pixels) -> str:
    rows = (f"0,0,{k},wrist,c0,{u!r},{v!r}" for k, (u, v) in enumerate(pixels.tolist()))
    return OBS.splitlines()[0] + "\n" + "\n".join(rows) + "\n"


def test_pixels_on_the_top_left_quarter_only_are_warned_about():
    """The wrist camera's intrinsics are of a 1280x720 image: pixels spread over its top-left
    quarter (u <= 639.5, v <= 359.5), as a 640x360 image's would, are warned about; pixels
    over the whole image, a cluster in that quarter, or one pixel past it are not."""
    rng = np.random.default_rng(7)
    quarter = rng.uniform(0, 1, (40, 2)) * [640, 360] - 0.5
    with pytest.warns(DataWarning, match=r"o.csv: camera 'wrist': every pixel is in the top-lef"):
        parse_observations(_wrist_rows(quarter), JOINTS, CAMERAS, None, "o.csv")
    with pytest.warns(DataWarning, match=r"for images of 640x360\?"):
        parse_observations(_wrist_rows(quarter), JOINTS, CAMERAS, None, "o.csv")
    past = np.vstack([quarter, [[641.0, 100.0]]])
    for pixels in (2 * quarter + 0.5, 100 + 0.3 * quarter, past):
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            parse_observations(_wrist_rows(pixels), JOINTS, CAMERAS, None, "o.csv")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (
            OBS.replace("110,210", "640,210"),
            r"row 3\).*pixel \(640, 210\) is outside the 640x480 image of camera 'head'",
        ),
        (OBS.replace("110,210", "110,-0.6"), r"row 3\).*outside"),
        (
            OBS.replace("100,200", "0.12,-0.3").replace("110,210", "-1.1,0.4"),
            "row 2.*look like normalised",
        ),
        (
            OBS.replace("head,c1", "hed,c1"),
            r"row 3, column 'camera'\): unknown camera 'hed': the cameras are head, wrist",
        ),
        (OBS.replace("head,c1", "head,c9"), r"row 3\): point 'c9' is not in the target t.csv"),
        (OBS.replace("c1", "c0"), r"row 3\).*'head' sees point 'c0' twice .*rows 2 and 3"),
        (OBS.replace(",camera,", ",cam,"), "column 'camera'.*missing column"),
        (OBS.replace(",v\n", ",w\n"), "column 'v'.*missing column"),
        (OBS.replace("shoulder,", "shoulder_joint,"), "column 'shoulder'.*missing joint column"),
        (OBS.replace("head,c1", ",c1"), "row 3, column 'camera'.*empty cell"),
        (OBS.replace("110,210", "110,abc"), "row 3, column 'v'.*not a number"),
        (
            OBS.replace("110,210", "110,nan"),
            "row 3, column 'v'.*'nan': a value not measured leaves the row out",
        ),
        (OBS.replace("0,0,0,head,c1", "0,0,head,c1"), "row 3.*expected 7 cells, found 6"),
        (OBS.splitlines()[0] + "\n", "no observations after the header"),
        ("", "empty file"),
    ],
)
def test_bad_observations_name_their_row(text, match):
    obs_error(text, match)


def test_the_same_point_in_other_images_is_no_repeat():
    again = OBS.replace("0,0,0,head,c1", "0,0.1,0,head,c0")
    assert parse_observations(again, JOINTS, CAMERAS, target(), "o.csv").m == 2
    other = OBS.replace("head,c1,110,210", "wrist,c0,110,210")
    assert parse_observations(other, JOINTS, CAMERAS, None, "o.csv").cameras == ("head", "wrist")


def test_an_unread_column_is_noted():
    text = "image,shoulder,joint:u,elbow,camera,point,u,v\nimg1.png,0,0,0,head,c0,100,200\n"
    with pytest.warns(DataWarning, match=r"columns ignored .*: image$"):
        parse_observations(text, JOINTS, CAMERAS)


TARGET = "point,x,y,z,link,nx,ny,nz\na,0.1,0,0,hand,0,0,1\nb,0,0.1,0,hand,0,0,2\n"
INTRINSICS_YAML = (  # given for the target or the observations: named by a missing column
    "image_width: 640\nimage_height: 480\n"
    "camera_matrix: [[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]]\n"
)


def test_another_file_for_the_target_or_the_observations_is_named_by_a_missing_column():
    """An intrinsics YAML given as ``--target``: "expected 1 cells, found 9" (its inline
    lists counted as cells) before the columns were looked for."""
    with pytest.raises(DataError, match=r"row 1, column 'point'\): missing column$"):
        parse_target(INTRINSICS_YAML, "intr.yaml")
    obs_error(INTRINSICS_YAML, r"row 1, column 'camera'\): missing column$")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (TARGET.replace("b,0,", "a,0,"), r"row 3\): point 'a' is given twice \(rows 2 and 3\)"),
        (
            TARGET.replace("0.1,0,0,hand", "100,0,0,hand"),
            r"row 2\).*100 m from its link's origin.*millimetres",
        ),
        (
            TARGET.replace("0.1,0,0,hand", "-3,0,0,hand").replace("0,0.1,0,hand", "3,0,0,hand"),
            "spread over 6 m.*millimetres",
        ),
        (TARGET.replace("0,0,2\n", "0,0,0\n"), r"row 3\): a zero normal"),
        (TARGET.replace(",nz", ",nw"), "column 'nz'.*missing column"),
        (TARGET.replace("point,", "id,"), "column 'point'.*missing column"),
        (TARGET.replace("hand,0,0,1", ",0,0,1"), "row 2, column 'link'.*empty cell"),
        (TARGET.replace("0.1,0,0", "0.1,0,1e999"), "row 2, column 'z'.*not a finite number"),
    ],
)
def test_bad_targets_name_their_row(text, match):
    with pytest.raises(DataError, match=match) as caught:
        parse_target(text, "t.csv")
    assert "\n" not in str(caught.value)


def test_points_on_two_links_far_apart_are_metres():
    # each link's points are near its origin: two hands do not make one spread
    text = "point,x,y,z,link\na,2.5,0,0,left\nb,2.4,0,0,left\nc,-2.5,0,0,right\n"
    assert parse_target(text, "t.csv").link == ("left", "left", "right")


def test_values_of_the_wrong_kind_are_refused(tmp_path):
    with pytest.raises(InvalidArgumentError, match="distinct"):
        Target(("a", "a"), np.zeros((2, 3)))
    with pytest.raises(InvalidArgumentError, match="zero"):
        Target(("a",), np.zeros((1, 3)), normal=np.zeros((1, 3)))
    with pytest.raises(InvalidArgumentError, match="shape"):
        PixelObservations(("j",), np.zeros((2, 1)), ("c", "c"), ("a", "b"), np.zeros((2, 3)))
    with pytest.raises(InvalidArgumentError, match="Intrinsics"):
        parse_observations(OBS, JOINTS, {"head": "intrinsics.yaml"})
    with pytest.raises(InvalidArgumentError, match="joint names"):
        parse_observations(OBS, "shoulder", CAMERAS)
    with pytest.raises(InvalidArgumentError, match="Target"):
        write_target(tmp_path / "t.csv", "target")
    with pytest.raises(InvalidArgumentError, match="PixelObservations"):
        observations_csv(target())
    assert not (tmp_path / "t.csv").exists()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert target_csv(target()).startswith("point,x,y,z,link,nx,ny,nz\nc0,")


API_ERRORS = {
    "parse_intrinsics text=int": lambda: parse_intrinsics(5),
    "parse_intrinsics text=bytes": lambda: parse_intrinsics(b"image_width: 640"),
    "read_intrinsics path=None": lambda: read_intrinsics(None),
    "write_intrinsics path=None": lambda: write_intrinsics(None, CAMERAS["head"]),
    "parse_target text=int": lambda: parse_target(5),
    "read_target path=None": lambda: read_target(None),
    "parse_observations text=int": lambda: parse_observations(5, JOINTS, CAMERAS),
    "read_observations cameras=str": lambda: read_observations("o.csv", JOINTS, "head"),
    "read_observations target=str": lambda: read_observations("o.csv", JOINTS, CAMERAS, "t"),
    "Target point=str": lambda: Target("ab", np.zeros((2, 3))),
    "Target link=str": lambda: Target(("a",), np.zeros((1, 3)), "hand"),
    "PixelObservations camera=str": lambda: PixelObservations(
        ("j",), np.zeros((1, 1)), "c", ("a",), np.zeros((1, 2))
    ),
    "Intrinsics.inside str": lambda: CAMERAS["head"].inside("abc"),
    "Pinhole.project str": lambda: CAMERAS["head"].camera.project("abc"),
    "Pinhole fx=str": lambda: Pinhole("600", 600.0, 320.0, 240.0),
}


@pytest.mark.parametrize("case", sorted(API_ERRORS))
def test_api_errors_are_one_line_calib_errors(case):
    with pytest.raises(CalibError) as caught:
        API_ERRORS[case]()
    assert str(caught.value).strip() and "\n" not in str(caught.value)


def test_the_camera_modules_need_no_opencv():
    # OpenCV is a test extra: with cv2 unimportable, calib's camera modules still work
    code = (
        "import sys; sys.modules['cv2'] = None\n"
        "from calib.identification.pinhole import Pinhole\n"
        "from calib.measurements import parse_intrinsics, parse_target\n"
        "print(Pinhole(1.0, 1.0, 0.0, 0.0).project([[0.0, 0.0, 1.0]]).tolist())\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    assert out.stdout.strip() == "[[0.0, 0.0]]"
