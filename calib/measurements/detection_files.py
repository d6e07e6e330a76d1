"""Images and the joint readings taken with them, into pixel observations (``calib detect``).

``JOINTS.csv`` (one header line, one row per image; comma separated): ``image``, the image's
file (its name, or its path relative to ``JOINTS.csv``'s folder), then one column per joint,
named as the URDF joint [rad or m]. Each image given must have exactly one row; rows of
images not given are not read.

:func:`detect_images` finds the board in every image (:func:`~.detection.detect_board`) and
pairs each image's corners with its joint readings into
:class:`~.pixels.PixelObservations` (``OBS.csv``); images where the board is not found are
listed, not fatal, unless it is found in none.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from .csvfile import csv_records, parse_number, read_data_text
from .detection import Board, Detection, detect_board, opencv
from .pixels import PixelObservations

__all__ = ["IMAGE_COLUMN", "ImageJoints", "ImageSet", "detect_images", "read_image_joints"]

IMAGE_COLUMN = "image"
"""The column of ``JOINTS.csv`` that names each image's file."""

MAX_IMAGES = 10_000
"""Most images of one detection."""


@dataclass(frozen=True, eq=False)
class ImageJoints:
    """The joint readings taken with each image (``JOINTS.csv``).

    Attributes:
        joint_names: The joints, in the file's order.
        image: Each row's image (as written in the file).
        q: Each row's joint positions ``(m, n)`` [rad or m].
        lines: Each row's line in the file.
        source: The file's path, for messages.
    """

    joint_names: tuple[str, ...]
    image: tuple[str, ...]
    q: np.ndarray
    lines: tuple[int, ...]
    source: str

    def row_of(self, path: Path) -> int:
        """The row of an image file: by its path relative to the file's folder, or its name.

        Raises:
            DataError: No row, or several rows, name the image.
        """
        folder = Path(self.source).parent
        target = path.resolve()
        rows = [
            i
            for i, name in enumerate(self.image)
            if (folder / name).resolve() == target or name == path.name
        ]
        if not rows:
            raise DataError(self.source, f"no row for image {path} (column '{IMAGE_COLUMN}')")
        if len(rows) > 1:
            raise DataError(self.source, f"image {path} has several rows", row=self.lines[rows[1]])
        return rows[0]


def read_image_joints(path: str | Path) -> ImageJoints:
    """Read ``JOINTS.csv``: the joint readings taken with each image.

    One header line, one row per image, comma separated: an ``image`` column (the image's
    file, its name or its path relative to the file's folder), then one column per joint,
    named as the URDF joint.

    Args:
        path: The ``JOINTS.csv`` file.

    Returns:
        The images and their joint readings [rad or m], in the file's order.

    Raises:
        DataError: Missing or unreadable, no ``image`` column, no joint column, a column
            named twice, a row of the wrong length, an empty image cell, a joint reading
            that is not a finite number.
    """
    source = str(path)
    records = csv_records(read_data_text(path), source)
    header = next(records, None)
    if header is None:
        raise DataError(source, "empty file: expected a header 'image,<joint>,...'")
    names = [c.strip() for c in header[1]]
    if IMAGE_COLUMN not in names:
        raise DataError(
            source, f"no '{IMAGE_COLUMN}' column (each row's image file)", row=header[0]
        )
    if len(set(names)) != len(names) or not all(names):
        raise DataError(source, "a column is empty or named twice", row=header[0])
    col = names.index(IMAGE_COLUMN)
    joints = tuple(n for n in names if n != IMAGE_COLUMN)
    if not joints:
        raise DataError(source, "no joint column besides 'image'", row=header[0])
    images, q, lines = [], [], []
    for line, cells in records:
        if len(cells) != len(names):
            raise DataError(source, f"expected {len(names)} cells, got {len(cells)}", row=line)
        image = cells[col].strip()
        if not image:
            raise DataError(source, "empty cell", row=line, column=IMAGE_COLUMN)
        images.append(image)
        q.append(
            [
                parse_number(c, source, line, n)
                for c, n in zip(cells, names, strict=True)
                if n in joints
            ]
        )
        lines.append(line)
    if not images:
        raise DataError(source, "no row: one row per image")
    return ImageJoints(joints, tuple(images), np.array(q, float), tuple(lines), source)


@dataclass(frozen=True, eq=False)
class ImageSet:
    """What :func:`detect_images` found.

    Attributes:
        observations: The corners found, each with its image's joint readings (``OBS.csv``).
        detections: Each image's detection (empty where the board was not found).
        paths: The images, in the order given.
        width: The images' width [px].
        height: The images' height [px].
    """

    observations: PixelObservations
    detections: tuple[Detection, ...]
    paths: tuple[Path, ...]
    width: int
    height: int

    @property
    def missed(self) -> tuple[Path, ...]:
        """The images where the board was not found."""
        return tuple(p for p, d in zip(self.paths, self.detections, strict=True) if not d.found)


def _read_image(path: Path, cv2) -> np.ndarray:
    if not path.is_file():
        raise DataError(str(path), "no such image file")
    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise DataError(str(path), "not an image OpenCV can read")
    return image


def detect_images(paths: list[Path], board: Board, joints: ImageJoints, camera: str) -> ImageSet:
    """Find the board in each image; its corners with the image's joint readings.

    Args:
        paths: The image files.
        board: The board seen.
        joints: The joint readings of each image (``JOINTS.csv``).
        camera: The camera's name (the ``camera`` column of the observations).

    Raises:
        InvalidArgumentError: No image, too many, an image given twice, no OpenCV.
        DataError: An image missing, unreadable, of another size than the first, without
            its row in ``JOINTS.csv``; the board found in no image.
    """
    cv2 = opencv()
    if not paths or len(paths) > MAX_IMAGES:
        raise InvalidArgumentError(f"give 1 to {MAX_IMAGES} images, got {len(paths)}")
    if len({p.resolve() for p in paths}) != len(paths):
        raise InvalidArgumentError("an image is given twice")
    rows = [joints.row_of(p) for p in paths]  # every image's row, before reading any
    found, size = [], None
    for path in paths:
        image = _read_image(path, cv2)
        shape = image.shape[1::-1]
        if size is not None and shape != size:
            raise DataError(
                str(path), f"image of {shape[0]}x{shape[1]} px, the first is {size[0]}x{size[1]}"
            )
        size = shape
        found.append(detect_board(image, board))
    if not any(d.found for d in found):
        raise DataError(str(paths[0]), f"no {board.kind} board found in any of {len(paths)} images")
    q = np.concatenate(
        [np.repeat(joints.q[r][None], len(d.point), 0) for r, d in zip(rows, found, strict=True)]
    )
    obs = PixelObservations(
        joints.joint_names,
        q,
        (camera,) * len(q),
        tuple(p for d in found for p in d.point),
        np.concatenate([d.pixels for d in found]),
        source="<detected>",
    )
    width, height = size or (0, 0)
    return ImageSet(obs, tuple(found), tuple(paths), int(width), int(height))
