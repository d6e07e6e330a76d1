"""Boards found in images: the pixels of their corners, for the camera kind (issue 32).

A *board* is a flat calibration target of known geometry: a ``checkerboard`` (its inner
corners), a ``charuco`` board (a checkerboard with ArUco markers in its white squares: its
inner corners, each with an id) or an ``aruco`` grid (the four corners of each marker).
:func:`detect_board` finds one in an image with OpenCV (the optional ``vision`` extra,
``pip install calib[vision]``) and gives each corner's id and pixel; :meth:`Board.target`
gives the same ids' positions in the board's frame [m] (OpenCV's: x along the columns, y
along the rows, z out of the back of the board, the origin at the first corner of the
board's outline), the ``TARGET.csv`` of ``calib calibrate --measure pixels``.

Pixels follow OpenCV: ``u`` the column, ``v`` the row, the centre of the top-left pixel at
``(0, 0)``. Corners are refined to a tenth of a pixel or better (``cv2.cornerSubPix`` for a
checkerboard and an ArUco grid's markers; the ChArUco interpolation refines its own).

Ids: a ChArUco corner's id is OpenCV's (row-major from the board's first inner corner); an
ArUco grid's corner ``M_c`` is corner ``c`` (0..3, clockwise from the marker's top left) of
marker ``M``; a checkerboard's corners are numbered in the order OpenCV returns them, so a
checkerboard must not look the same turned by half a turn: give it an even number of squares
along one side and an odd number along the other, and keep it from being seen upside down
(a ChArUco board has no such ambiguity).
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from .intrinsics import Intrinsics
from .pixels import Target

__all__ = [
    "BOARDS",
    "MIN_INTRINSICS_POINTS",
    "Board",
    "Detection",
    "calibrate_intrinsics",
    "detect_board",
    "opencv",
]

BOARDS = ("charuco", "checkerboard", "aruco")
"""The board kinds :func:`detect_board` finds."""

MIN_INTRINSICS_POINTS = 6
"""Fewest corners of an image that :func:`calibrate_intrinsics` uses (a homography needs 4)."""

MAX_SQUARES = 100
"""Most squares (or markers) along a side of a board."""

_SUBPIX_WINDOW = (5, 5)
_SUBPIX_STOP = (3, 50, 1e-4)  # cv2.TERM_CRITERIA_EPS + MAX_ITER, 50 steps, 1e-4 px


def opencv() -> ModuleType:
    """OpenCV's ``cv2`` module with its ``aruco`` detectors.

    Raises:
        InvalidArgumentError: OpenCV is not installed (one line: how to install it), or has
            no ``cv2.aruco.CharucoDetector`` (OpenCV older than 4.7).
    """
    try:
        import cv2
    except ImportError:
        raise InvalidArgumentError(
            "reading images needs OpenCV: pip install 'calib[vision]' "
            "(or opencv-python-headless>=4.8)"
        ) from None
    if not hasattr(getattr(cv2, "aruco", None), "CharucoDetector"):
        raise InvalidArgumentError(
            f"OpenCV {cv2.__version__} has no cv2.aruco.CharucoDetector: install "
            "opencv-python-headless>=4.8"
        )
    return cv2


@dataclass(frozen=True)
class Board:
    """A flat board's kind and geometry.

    Attributes:
        kind: ``charuco``, ``checkerboard`` or ``aruco``.
        columns: Squares along the board's x axis (markers, for ``aruco``).
        rows: Squares along its y axis (markers, for ``aruco``).
        square: A square's side [m] (``checkerboard``, ``charuco``).
        marker: A marker's side [m] (``charuco``, ``aruco``).
        separation: The gap between two markers [m] (``aruco``).
        dictionary: OpenCV's ArUco dictionary, e.g. ``DICT_6X6_250`` (``charuco``, ``aruco``).
        legacy: A ChArUco board of OpenCV before 4.6 (with an even number of rows, its
            squares' colours were swapped).
    """

    kind: str
    columns: int
    rows: int
    square: float = 0.0
    marker: float = 0.0
    separation: float = 0.0
    dictionary: str = "DICT_6X6_250"
    legacy: bool = False

    def __post_init__(self) -> None:
        if self.kind not in BOARDS:
            raise InvalidArgumentError(
                f"board must be one of {', '.join(BOARDS)}, got {self.kind!r:.40}"
            )
        least = 1 if self.kind == "aruco" else 2
        for name in ("columns", "rows"):
            value = getattr(self, name)
            whole = isinstance(value, int | np.integer) and not isinstance(value, bool)
            if not whole or not least <= value <= MAX_SQUARES:
                raise InvalidArgumentError(
                    f"the board's {name} must be a whole number in [{least}, {MAX_SQUARES}], "
                    f"got {value!r:.40}"
                )
        self._check_lengths()
        if not isinstance(self.dictionary, str) or not self.dictionary.startswith("DICT_"):
            raise InvalidArgumentError(
                f"an ArUco dictionary is named as OpenCV's, e.g. DICT_6X6_250, got "
                f"{self.dictionary!r:.40}"
            )

    def _check_lengths(self) -> None:
        """The lengths the kind needs: metres, a ChArUco marker inside its square."""
        need = {
            "checkerboard": ("square",),
            "charuco": ("square", "marker"),
            "aruco": ("marker", "separation"),
        }[self.kind]
        for name in ("square", "marker", "separation"):
            value = getattr(self, name)
            number = isinstance(value, float | int) and not isinstance(value, bool)
            if not number or not 0 <= value < 1 or (name in need and value == 0):
                raise InvalidArgumentError(
                    f"the board's {name} length is in metres, in (0, 1), got {value!r:.40}"
                )
        if self.kind == "charuco" and self.marker >= self.square:
            raise InvalidArgumentError(
                f"a ChArUco marker ({self.marker:g} m) must be smaller than its square "
                f"({self.square:g} m)"
            )

    def opencv_board(self, cv2: ModuleType):
        """OpenCV's board (``cv2.aruco.CharucoBoard`` or ``GridBoard``); None: a checkerboard.

        Raises:
            InvalidArgumentError: An ArUco dictionary OpenCV does not have, or too small for
                the board's markers.
        """
        if self.kind == "checkerboard":
            return None
        code = getattr(cv2.aruco, self.dictionary, None)
        if not isinstance(code, int):
            raise InvalidArgumentError(f"OpenCV has no ArUco dictionary {self.dictionary}")
        words = cv2.aruco.getPredefinedDictionary(code)
        size = (self.columns, self.rows)
        if self.kind == "charuco":
            board = cv2.aruco.CharucoBoard(size, self.square, self.marker, words)
            board.setLegacyPattern(self.legacy)
            markers = len(board.getIds())
        else:
            board = cv2.aruco.GridBoard(size, self.marker, self.separation, words)
            markers = self.columns * self.rows
        if markers > words.bytesList.shape[0]:
            raise InvalidArgumentError(
                f"{self.dictionary} has {words.bytesList.shape[0]} markers, the board needs "
                f"{markers}"
            )
        return board

    def corners(self, cv2: ModuleType) -> tuple[tuple[str, ...], np.ndarray]:
        """Every corner's id and position in the board's frame ``(k, 3)`` [m].

        Computed in double precision from the board's lengths (OpenCV's boards hold them in
        single precision), in OpenCV's order.
        """
        if self.kind != "aruco":  # the inner corners, row by row
            inner = [(i, j) for j in range(1, self.rows) for i in range(1, self.columns)]
            xyz = np.array([(i * self.square, j * self.square, 0.0) for i, j in inner])
            return tuple(str(k) for k in range(len(xyz))), xyz
        step = self.marker + self.separation
        quad = np.array([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]) * self.marker
        ids = np.ravel(self.opencv_board(cv2).getIds())
        xy = [quad + np.array([i, j]) * step for j in range(self.rows) for i in range(self.columns)]
        xyz = np.column_stack([np.concatenate(xy), np.zeros(4 * len(xy))])
        return tuple(f"{m}_{c}" for m in ids for c in range(4)), xyz

    def target(self, cv2: ModuleType) -> Target:
        """The board's corners as a target (``TARGET.csv``: ids and positions [m])."""
        ids, xyz = self.corners(cv2)
        return Target(ids, xyz, source=f"<{self.kind} board>")


@dataclass(frozen=True, eq=False)
class Detection:
    """The corners of a board found in one image.

    Attributes:
        point: Each corner's id ``(k,)`` (:meth:`Board.corners`'s).
        pixels: Each corner's ``(u, v)`` ``(k, 2)`` [px]: column, row (OpenCV's convention).
    """

    point: tuple[str, ...]
    pixels: np.ndarray

    @property
    def found(self) -> bool:
        """Whether any corner was found."""
        return bool(self.point)


def _gray(image: np.ndarray, cv2: ModuleType) -> np.ndarray:
    """The image as 8-bit grey levels (colour converted; 16 bits scaled)."""
    if image.ndim == 3:
        code = cv2.COLOR_BGRA2GRAY if image.shape[2] == 4 else cv2.COLOR_BGR2GRAY
        image = cv2.cvtColor(image, code)
    if image.dtype != np.uint8:
        image = cv2.normalize(image, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    return image


def _checkerboard(gray: np.ndarray, board: Board, cv2: ModuleType) -> Detection:
    pattern = (board.columns - 1, board.rows - 1)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH + cv2.CALIB_CB_NORMALIZE_IMAGE + cv2.CALIB_CB_FAST_CHECK
    found, corners = cv2.findChessboardCorners(gray, pattern, flags=flags)
    if not found:
        return Detection((), np.zeros((0, 2)))
    corners = cv2.cornerSubPix(gray, corners, _SUBPIX_WINDOW, (-1, -1), _SUBPIX_STOP)
    pixels = np.asarray(corners, float).reshape(-1, 2)
    return Detection(tuple(str(k) for k in range(len(pixels))), pixels)


def _charuco(gray: np.ndarray, board: Board, cv2: ModuleType) -> Detection:
    parameters = cv2.aruco.CharucoParameters()
    parameters.tryRefineMarkers = True  # markers missed at first, found near the board
    detector = cv2.aruco.CharucoDetector(board.opencv_board(cv2), parameters)
    corners, ids = detector.detectBoard(gray)[:2]
    if ids is None or not len(ids):
        return Detection((), np.zeros((0, 2)))
    return Detection(
        tuple(str(int(i)) for i in np.ravel(ids)), np.asarray(corners, float).reshape(-1, 2)
    )


def _aruco(gray: np.ndarray, board: Board, cv2: ModuleType) -> Detection:
    grid = board.opencv_board(cv2)
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
    detector = cv2.aruco.ArucoDetector(grid.getDictionary(), parameters)
    corners, ids, rejected = detector.detectMarkers(gray)
    if ids is not None and len(ids):
        corners, ids = detector.refineDetectedMarkers(gray, grid, corners, ids, rejected)[:2]
    known = set(np.ravel(grid.getIds()).tolist())
    points, pixels = [], []
    for marker, quad in zip(np.ravel(ids) if ids is not None else (), corners, strict=True):
        if int(marker) in known:
            points += [f"{int(marker)}_{c}" for c in range(4)]
            pixels.append(np.asarray(quad, float).reshape(4, 2))
    if not points:
        return Detection((), np.zeros((0, 2)))
    return Detection(tuple(points), np.concatenate(pixels))


def detect_board(image: np.ndarray, board: Board) -> Detection:
    """The board's corners found in an image (none when the board is not found).

    Args:
        image: The image as OpenCV reads it: grey levels ``(H, W)`` or BGR(A) ``(H, W, 3|4)``,
            8 or 16 bits.
        board: The board to find.

    Returns:
        The corners found, in :meth:`Board.corners`' ids, pixels in OpenCV's convention.

    Raises:
        InvalidArgumentError: No OpenCV (:func:`opencv`), an image that is not 2-D grey
            levels or colour, a dictionary OpenCV does not have.
    """
    cv2 = opencv()
    if not isinstance(image, np.ndarray) or image.ndim not in (2, 3) or image.size == 0:
        raise InvalidArgumentError("an image is a (H, W) or (H, W, 3) array, as cv2.imread gives")
    if image.ndim == 3 and image.shape[2] not in (1, 3, 4):
        raise InvalidArgumentError(f"an image has 1, 3 or 4 channels, got {image.shape[2]}")
    gray = _gray(image[:, :, 0] if image.ndim == 3 and image.shape[2] == 1 else image, cv2)
    find = {"checkerboard": _checkerboard, "charuco": _charuco, "aruco": _aruco}[board.kind]
    return find(gray, board, cv2)


def calibrate_intrinsics(
    detections: list[Detection], board: Board, width: int, height: int, source: str
) -> tuple[Intrinsics, float]:
    """The camera's intrinsics from its views of a board (``cv2.calibrateCamera``).

    OpenCV's default model: focal lengths, principal point and five distortion
    coefficients (``k1 k2 p1 p2 k3``), from the images with at least
    :data:`MIN_INTRINSICS_POINTS` corners.

    Args:
        detections: The board's corners in each image.
        board: The board.
        width: The images' width [px].
        height: The images' height [px].
        source: What the intrinsics are from (for messages and the result's ``source``).

    Returns:
        The intrinsics and the RMS reprojection error of the calibration [px].

    Raises:
        DataError: Fewer than 3 images with enough corners.
    """
    cv2 = opencv()
    ids, xyz = board.corners(cv2)
    index = {p: i for i, p in enumerate(ids)}
    used = [d for d in detections if len(d.point) >= MIN_INTRINSICS_POINTS]
    if len(used) < 3:
        raise DataError(
            source,
            f"calibrating the camera needs 3 images with {MIN_INTRINSICS_POINTS} corners or "
            f"more, got {len(used)}",
        )
    objects = [xyz[[index[p] for p in d.point]].astype(np.float32) for d in used]
    images = [d.pixels.astype(np.float32).reshape(-1, 1, 2) for d in used]
    rms, K, dist = cv2.calibrateCamera(objects, images, (width, height), None, None)[:3]
    from ..identification.pinhole import Pinhole

    lens = Pinhole(K[0, 0], K[1, 1], K[0, 2], K[1, 2], np.ravel(dist))
    return Intrinsics(width, height, lens, source), float(rms)
