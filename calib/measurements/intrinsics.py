"""A camera's intrinsics file: what OpenCV's FileStorage writes, or the same keys in YAML or JSON.

The keys read (others, such as ``avg_reprojection_error`` or ``camera_name``, are ignored):

* ``image_width``, ``image_height``: the image's size [px];
* ``camera_matrix``: ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` [px] (no skew: OpenCV's model
  has none), as OpenCV's ``!!opencv-matrix`` (``rows``, ``cols``, ``dt``, ``data``), as
  the same keys without the tag (ROS's camera files), or as a list of 9 numbers or 3 rows;
* ``distortion_coefficients``: 4, 5, 8, 12 or 14 numbers in OpenCV's order
  (:data:`~calib.identification.pinhole.DISTORTION_NAMES`), a ``1xN`` or ``Nx1`` matrix or
  a list;
* a ``distortion_model`` (ROS) must be ``plumb_bob`` or ``rational_polynomial``, and a
  ``fisheye_model`` (OpenCV's calibration sample) must be 0: a fisheye lens follows another
  model.

A text starting with ``{`` is read as JSON (what ``cv2.FileStorage`` writes to a ``.json``
file), anything else as YAML (:mod:`.yaml_subset`: OpenCV's ``%YAML:1.0`` header and
``!!opencv-matrix`` tags included). A missing key, a wrong count, a number that is not finite,
a focal length that is not positive: one :class:`~calib.exceptions.DataError`. A principal
point far from the image's centre (the width and height swapped, often) is a
:class:`~calib.measurements.data.DataWarning`.
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.checks import real_array
from ..core.fileio import write_atomic
from ..exceptions import DataError, InvalidArgumentError, warn_user
from ..identification.pinhole import DISTORTION_COUNTS, Pinhole
from .csvfile import read_data_text
from .data import DataWarning
from .yaml_subset import parse_yaml

__all__ = [
    "DISTORTION_MODELS",
    "MAX_IMAGE_SIDE",
    "MAX_INTRINSICS_BYTES",
    "PRINCIPAL_POINT_WARNING",
    "Intrinsics",
    "intrinsics_yaml",
    "parse_intrinsics",
    "read_intrinsics",
    "write_intrinsics",
]

MAX_IMAGE_SIDE = 100_000
"""Largest image width or height [px]."""

MAX_INTRINSICS_BYTES = 16 << 20
"""Largest intrinsics file read [B] (OpenCV's sample may add every view's corners)."""

PRINCIPAL_POINT_WARNING = 0.1
"""A principal point farther than this fraction of the image's side from its centre is
warned about (a lens's is within a few percent; a swapped width and height moves it more)."""

DISTORTION_MODELS = ("plumb_bob", "rational_polynomial")
"""ROS's names of OpenCV's pinhole distortion model (``distortion_model``)."""


@dataclass(frozen=True, eq=False)
class Intrinsics:
    """A camera's image size and pinhole model, as an intrinsics file gives them.

    Attributes:
        width: Image width [px] (columns).
        height: Image height [px] (rows).
        camera: The pinhole camera with its distortion.
        source: Where the intrinsics came from (a file path), for messages.
        path: The file read, resolved when it was read (absolute, links followed), or None
            (not read from a file): what ``Result.write`` never overwrites, wherever the
            working directory is then.
    """

    width: int
    height: int
    camera: Pinhole
    source: str = "<intrinsics>"
    path: str | None = None

    def __post_init__(self) -> None:
        for what, side in (("width", self.width), ("height", self.height)):
            whole = isinstance(side, int | np.integer) and not isinstance(side, bool)
            if not whole or not 1 <= side <= MAX_IMAGE_SIDE:
                raise InvalidArgumentError(
                    f"the image {what} must be a whole number of pixels in [1, {MAX_IMAGE_SIDE}], "
                    f"got {side!r:.40}"
                )
        if not isinstance(self.camera, Pinhole):
            raise InvalidArgumentError(f"camera must be a Pinhole, got {self.camera!r:.60}")

    def __repr__(self) -> str:
        """One line (the distortion coefficients are in ``camera``)."""
        c = self.camera
        return (
            f"<Intrinsics {self.source}: {self.width}x{self.height} px, fx {c.fx:g}, "
            f"fy {c.fy:g}, cx {c.cx:g}, cy {c.cy:g} px>"
        )

    @property
    def camera_matrix(self) -> np.ndarray:
        """OpenCV's camera matrix ``(3, 3)`` [px]."""
        return self.camera.camera_matrix

    @property
    def distortion(self) -> np.ndarray:
        """The distortion coefficients in OpenCV's order ``(k,)``."""
        return self.camera.distortion

    def inside(self, pixels) -> np.ndarray:
        """Whether pixels ``(m, 2)`` [px] fall on the image (pixel centres at whole numbers).

        The image spans ``[-0.5, width - 0.5] x [-0.5, height - 0.5]``.

        Raises:
            InvalidArgumentError: Pixels not ``(m, 2)`` finite numbers.
        """
        uv = real_array(pixels, "pixels", (None, 2))
        return (
            (uv[:, 0] >= -0.5)
            & (uv[:, 0] <= self.width - 0.5)
            & (uv[:, 1] >= -0.5)
            & (uv[:, 1] <= self.height - 0.5)
        )

    def half_size_hint(self, pixels) -> str:
        """What to say when pixels ``(m, 2)`` fill the top-left quarter of the image only.

        Pixels spread over more than half of the quarter's width and height, none past it: the
        intrinsics of this camera at twice the images' resolution, most likely. "" otherwise.
        """
        uv = real_array(pixels, "pixels", (None, 2))
        half = np.array([self.width, self.height]) / 2
        if len(uv) < 2 or np.any(uv.max(axis=0) > half - 0.5):
            return ""
        if np.any(np.ptp(uv, axis=0) <= half / 2):
            return ""
        return (
            f"every pixel is in the top-left quarter of the {self.width}x{self.height} image "
            f"(u <= {half[0] - 0.5:g}, v <= {half[1] - 0.5:g}) and spreads over it: intrinsics "
            f"of a {self.width}x{self.height} camera for images of {half[0]:g}x{half[1]:g}? "
            "give the intrinsics calibrated at the images' resolution"
        )


def read_intrinsics(path: str | Path) -> Intrinsics:
    """Read and check a camera's intrinsics file, as OpenCV's FileStorage writes it.

    The keys read: ``image_width``, ``image_height`` [px]; ``camera_matrix``
    ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` [px] (an ``!!opencv-matrix``, the same keys
    without the tag, 9 numbers or 3 rows); ``distortion_coefficients``, 4, 5, 8, 12 or 14 in
    OpenCV's order. Other keys are ignored. A text starting with ``{`` is read as JSON, any
    other as YAML. The module ``calib.measurements.intrinsics`` has the long form.

    Args:
        path: The file: OpenCV's FileStorage YAML, plain YAML or JSON.

    Returns:
        The intrinsics (the image's size and the pinhole camera), ``path`` resolved.

    Raises:
        DataError: The file is missing, unreadable or too large, or its content is not valid
            (see :func:`!parse_intrinsics`).
    """
    found = parse_intrinsics(read_data_text(path, MAX_INTRINSICS_BYTES), str(path))
    return dataclasses.replace(found, path=str(Path(path).resolve()))


def parse_intrinsics(text: str, source: str = "<text>") -> Intrinsics:
    """Intrinsics from the text of an intrinsics file.

    Args:
        text: The file's content: OpenCV's FileStorage YAML, plain YAML or JSON.
        source: Its name, for messages.

    Returns:
        The intrinsics.

    Raises:
        DataError: Not YAML or JSON of the subset read, no mapping, a missing key, a matrix of
            the wrong size or with a skew, a count of distortion coefficients OpenCV has no
            model for, a number that is not finite, a focal length not positive, an image
            size that is no whole number of pixels, a fisheye model.
    """
    if not isinstance(text, str):
        raise InvalidArgumentError(f"text must be the file's content (str), got {text!r:.60}")
    keys = _mapping(text, source)
    _check_model(keys, source)
    width, height = (_side(keys, k, source) for k in ("image_width", "image_height"))
    matrix = _matrix(_key(keys, "camera_matrix", source), "camera_matrix", source)
    if matrix.size != 9:
        raise _error(source, "camera_matrix", f"must be 3x3, got {_shape_text(matrix)}")
    k = matrix.reshape(3, 3)
    _check_camera_matrix(k, source)
    dist = _matrix(_key(keys, "distortion_coefficients", source), "distortion_coefficients", source)
    if min(dist.shape) != 1 or dist.size not in DISTORTION_COUNTS:
        raise _error(
            source,
            "distortion_coefficients",
            f"OpenCV's distortion model takes 4, 5, 8, 12 or 14 coefficients (1xN or Nx1), got "
            f"{_shape_text(dist)}",
        )
    intrinsics = Intrinsics(
        width, height, Pinhole(k[0, 0], k[1, 1], k[0, 2], k[1, 2], dist.ravel()), source
    )
    _warn_principal_point(intrinsics)
    return intrinsics


def _mapping(text: str, source: str) -> dict:
    """The file's top-level mapping, from JSON (text starting with ``{``) or YAML."""
    if not text.lstrip().startswith("{"):
        return parse_yaml(text, source)
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DataError(source, f"not valid JSON: {exc.msg}", row=exc.lineno) from None
    if not isinstance(value, dict):  # pragma: no cover (a text starting with "{" is an object)
        raise DataError(source, "expected a JSON object")
    return value


def _error(source: str, key: str, reason: str) -> DataError:
    """The error about a key of the file: ``SOURCE: KEY: REASON``."""
    return DataError(source, f"{key}: {reason}")


def _key(keys: dict, name: str, source: str) -> object:
    """A key's value; DataError naming a missing key."""
    if name not in keys or keys[name] is None:
        raise _error(
            source,
            name,
            "missing: an intrinsics file gives image_width, image_height, camera_matrix and "
            "distortion_coefficients",
        )
    return keys[name]


def _check_model(keys: dict, source: str) -> None:
    """Refuse a distortion model other than OpenCV's pinhole one (a fisheye, ...)."""
    model = keys.get("distortion_model")
    if model is not None and model not in DISTORTION_MODELS:
        raise _error(
            source,
            "distortion_model",
            f"{model!r:.40} is not OpenCV's pinhole model ({', '.join(DISTORTION_MODELS)})",
        )
    if keys.get("fisheye_model") not in (None, 0, False):
        raise _error(
            source, "fisheye_model", "a fisheye lens: its distortion is not OpenCV's pinhole model"
        )


def _side(keys: dict, name: str, source: str) -> int:
    """``image_width`` or ``image_height``: a whole number of pixels in range."""
    value = _key(keys, name, source)
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise _error(source, name, f"{value!r:.40} is not a whole number of pixels")
    if value != int(value):
        raise _error(source, name, f"{value!r:.40} is not a whole number of pixels")
    if not 1 <= value <= MAX_IMAGE_SIDE:
        raise _error(source, name, f"{value:g} px is not an image side (1 to {MAX_IMAGE_SIDE} px)")
    return int(value)


def _numbers(values: list, name: str, source: str) -> np.ndarray:
    """Finite numbers from a list (not booleans, not text)."""
    for v in values:
        if not isinstance(v, int | float) or isinstance(v, bool):
            raise _error(source, name, f"{v!r:.40} is not a number")
        if not math.isfinite(v):
            raise _error(source, name, f"{v!r} is not a finite number")
    return np.array(values, dtype=float)


def _matrix(value: object, name: str, source: str) -> np.ndarray:
    """A matrix ``(rows, cols)`` from OpenCV's (or ROS's) mapping or from (nested) lists."""
    if isinstance(value, dict):
        rows, cols, data = (value.get(k) for k in ("rows", "cols", "data"))
        sizes_ok = all(
            isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in (rows, cols)
        )
        if not sizes_ok or not isinstance(data, list):
            raise _error(source, name, "a matrix needs rows, cols and data")
        if len(data) != rows * cols:  # type: ignore[operator]
            raise _error(source, name, f"{rows}x{cols} matrix with {len(data)} numbers in its data")
        return _numbers(data, name, source).reshape(rows, cols)  # type: ignore[arg-type]
    if isinstance(value, list) and value and all(isinstance(r, list) for r in value):
        widths = {len(r) for r in value}
        if len(widths) != 1:
            raise _error(source, name, "rows of different lengths")
        flat = [v for r in value for v in r]
        return _numbers(flat, name, source).reshape(len(value), widths.pop())
    if isinstance(value, list) and value:
        return _numbers(value, name, source).reshape(1, len(value))
    raise _error(source, name, f"expected a matrix or a list of numbers, got {value!r:.40}")


def _shape_text(a: np.ndarray) -> str:
    """``RxC`` of a matrix (``1xN`` for a list)."""
    return f"{a.shape[0]}x{a.shape[1]}" if a.shape[0] > 1 else f"{a.size} numbers"


def _check_camera_matrix(k: np.ndarray, source: str) -> None:
    """Refuse a camera matrix that is not ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]``, fx, fy > 0."""
    if k[0, 1] != 0:
        raise _error(
            source,
            "camera_matrix",
            f"a skew of {k[0, 1]:g} (row 1, column 2): OpenCV's pinhole model has none",
        )
    if k[1, 0] != 0 or np.any(k[2] != [0, 0, 1]):
        raise _error(
            source, "camera_matrix", "a camera matrix is [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]"
        )
    if k[0, 0] <= 0 or k[1, 1] <= 0:
        raise _error(
            source,
            "camera_matrix",
            f"the focal lengths fx = {k[0, 0]:g}, fy = {k[1, 1]:g} must be positive [px]",
        )


def _warn_principal_point(intr: Intrinsics) -> None:
    """Warn when the principal point is far from the image's centre (a swapped size, often)."""
    cam = intr.camera

    def off(width: int, height: int) -> float:
        return max(abs(cam.cx - width / 2) / width, abs(cam.cy - height / 2) / height)

    if off(intr.width, intr.height) <= PRINCIPAL_POINT_WARNING:
        return
    hint = (
        ": are image_width and image_height swapped?"
        if off(intr.height, intr.width) <= PRINCIPAL_POINT_WARNING
        else ""
    )
    warn_user(
        f"{intr.source}: the principal point ({cam.cx:g}, {cam.cy:g}) px is far from the "
        f"centre ({intr.width / 2:g}, {intr.height / 2:g}) px of the {intr.width}x{intr.height} "
        f"image{hint}",
        DataWarning,
    )


def _opencv_matrix(name: str, a: np.ndarray) -> str:
    """An ``!!opencv-matrix`` entry as FileStorage writes it (every number ``repr``'d)."""
    data = ", ".join(repr(float(v)) for v in a.ravel())
    rows, cols = a.shape
    return (
        f"{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n"
        f"   data: [ {data} ]\n"
    )


def intrinsics_yaml(intrinsics: Intrinsics) -> str:
    """The intrinsics as OpenCV's FileStorage YAML (``%YAML:1.0``; ``cv2.FileStorage`` reads it)."""
    if not isinstance(intrinsics, Intrinsics):
        raise InvalidArgumentError(f"intrinsics must be Intrinsics, got {intrinsics!r:.60}")
    return (
        "%YAML:1.0\n---\n"
        f"image_width: {intrinsics.width}\nimage_height: {intrinsics.height}\n"
        + _opencv_matrix("camera_matrix", intrinsics.camera_matrix)
        + _opencv_matrix("distortion_coefficients", intrinsics.distortion.reshape(1, -1))
    )


def write_intrinsics(path: str | Path, intrinsics: Intrinsics) -> None:
    """Write intrinsics as OpenCV's FileStorage YAML, atomically.

    Raises:
        InvalidArgumentError: ``intrinsics`` is no :class:`Intrinsics`.
        OutputError: The file cannot be written.
    """
    write_atomic(path, intrinsics_yaml(intrinsics))
