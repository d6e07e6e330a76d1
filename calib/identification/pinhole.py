"""The pinhole camera with OpenCV's distortion model: pixels of points and their derivatives.

A point ``(X, Y, Z)`` in the camera's optical frame (z forward, x right, y down) [m] is seen
at the pixel ``(u, v)`` [px], ``u`` the column and ``v`` the row, the origin at the centre of
the top-left pixel, as OpenCV's ``projectPoints`` gives it::

    a, b = X / Z, Y / Z,  r2 = a^2 + b^2
    radial = (1 + k1 r2 + k2 r2^2 + k3 r2^3) / (1 + k4 r2 + k5 r2^2 + k6 r2^3)
    x = a radial + 2 p1 a b + p2 (r2 + 2 a^2) + s1 r2 + s2 r2^2
    y = b radial + p1 (r2 + 2 b^2) + 2 p2 a b + s3 r2 + s4 r2^2
    (x', y') = the tilted sensor's projection of (x, y) (tx, ty; OpenCV's tilt matrix)
    u = fx x' + cx,  v = fy y' + cy

The distortion coefficients come in OpenCV's order, ``k1, k2, p1, p2[, k3[, k4, k5, k6[, s1,
s2, s3, s4[, tx, ty]]]]``: 4, 5, 8, 12 or 14 of them (:data:`DISTORTION_COUNTS`); the missing
ones are zero. A point at or behind the camera (``Z <=`` :data:`MIN_DEPTH`) has no pixel:
:meth:`Pinhole.projection` flags it (its pixel and derivatives are NaN) and
:meth:`Pinhole.project` refuses it. Everything is vectorised over the points.

The derivatives are analytic: with respect to the point in the camera frame ``(m, 2, 3)``
[px/m] and with respect to the intrinsics ``fx, fy, cx, cy`` and the distortion coefficients
``(m, 2, 4 + k)`` (:attr:`Pinhole.parameter_names`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..core.checks import check_number, real_array
from ..exceptions import InvalidArgumentError

__all__ = [
    "DISTORTION_COUNTS",
    "DISTORTION_NAMES",
    "MAX_PIXELS",
    "MIN_DEPTH",
    "Pinhole",
    "Projection",
]

DISTORTION_COUNTS = (4, 5, 8, 12, 14)
"""How many distortion coefficients OpenCV's model takes (its flags' models)."""

DISTORTION_NAMES = (
    "k1",
    "k2",
    "p1",
    "p2",
    "k3",
    "k4",
    "k5",
    "k6",
    "s1",
    "s2",
    "s3",
    "s4",
    "tx",
    "ty",
)
"""The distortion coefficients in OpenCV's order (``tx``, ``ty``: the sensor's tilt [rad])."""

MAX_PIXELS = 1e7
"""Largest focal length and principal point coordinate [px] (an image is at most 1e5 px wide)."""

MIN_DEPTH = 1e-9
"""Smallest depth ``Z`` of a point in front of the camera [m]; nearer points have no pixel."""

_FULL = len(DISTORTION_NAMES)


@dataclass(frozen=True, eq=False)
class Projection:
    """The pixels of points and, when asked for, their derivatives.

    Attributes:
        pixels: ``(u, v)`` of each point ``(m, 2)`` [px]; NaN for a point not in front.
        in_front: Whether each point is in front of the camera (``Z >`` :data:`MIN_DEPTH`)
            ``(m,)``.
        d_point: Derivative of the pixel with respect to the point in the camera frame
            ``(m, 2, 3)`` [px/m] (NaN for a point not in front), or None.
        d_parameters: Derivative of the pixel with respect to ``fx, fy, cx, cy`` and the
            distortion coefficients ``(m, 2, 4 + k)`` [px per unit], or None.
    """

    pixels: np.ndarray
    in_front: np.ndarray
    d_point: np.ndarray | None = None
    d_parameters: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class Pinhole:
    """A pinhole camera with OpenCV's distortion model, as OpenCV's ``projectPoints`` has it.

    A point ``(X, Y, Z)`` [m] in the camera's optical frame (z forward, x right, y down) is seen at
    the pixel ``u = fx x' + cx``, ``v = fy y' + cy`` [px] (``u`` the column, ``v`` the row, the
    origin at the centre of the top-left pixel), ``(x', y')`` the distorted ``(X / Z, Y / Z)``. A
    point at or behind the camera (``Z <=`` :data:`!MIN_DEPTH`) has no pixel. The module
    ``calib.identification.pinhole`` has the distortion's formulas.

    Attributes:
        fx: Focal length along the columns [px], positive, at most :data:`!MAX_PIXELS`.
        fy: Focal length along the rows [px], positive, at most :data:`!MAX_PIXELS`.
        cx: Column of the principal point [px], within :data:`!MAX_PIXELS` of 0.
        cy: Row of the principal point [px], within :data:`!MAX_PIXELS` of 0.
        distortion: The distortion coefficients in OpenCV's order, 4, 5, 8, 12 or 14 of
            them (``tx``, ``ty`` [rad]; the others have no unit).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    distortion: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(4))

    def __post_init__(self) -> None:
        for name in ("fx", "fy"):  # numbers, not text that reads as one
            check_number(getattr(self, name), name, 0.0, MAX_PIXELS, above=True)
        for name in ("cx", "cy"):
            check_number(getattr(self, name), name, -MAX_PIXELS, MAX_PIXELS)
        dist = real_array(self.distortion, "distortion coefficients", (None,))
        if len(dist) not in DISTORTION_COUNTS:
            raise InvalidArgumentError(
                f"OpenCV's distortion model takes 4, 5, 8, 12 or 14 coefficients, got {len(dist)}"
            )
        dist.flags.writeable = False
        for name in ("fx", "fy", "cx", "cy"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "distortion", dist)

    def __repr__(self) -> str:
        """One line (NumPy wraps 8 or more distortion coefficients over lines)."""
        dist = ", ".join(f"{d:g}" for d in self.distortion)
        return (
            f"Pinhole(fx={self.fx!r}, fy={self.fy!r}, cx={self.cx!r}, cy={self.cy!r}, "
            f"distortion=({dist}))"
        )

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """Names of the intrinsic parameters, the columns of ``d_parameters``."""
        return ("fx", "fy", "cx", "cy", *DISTORTION_NAMES[: len(self.distortion)])

    @property
    def parameters(self) -> np.ndarray:
        """The intrinsic parameters ``(4 + k,)`` in the order of :attr:`parameter_names`."""
        return np.concatenate([[self.fx, self.fy, self.cx, self.cy], self.distortion])

    def with_parameters(self, values) -> Pinhole:
        """The camera with other intrinsic parameters (order of :attr:`parameter_names`).

        Raises:
            InvalidArgumentError: Not ``4 + k`` finite numbers, or a focal length not positive.
        """
        p = real_array(values, "intrinsic parameters", (4 + len(self.distortion),))
        return Pinhole(p[0], p[1], p[2], p[3], p[4:])

    @property
    def camera_matrix(self) -> np.ndarray:
        """OpenCV's camera matrix ``[[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` [px]."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def project(self, points) -> np.ndarray:
        """The pixels ``(m, 2)`` [px] of points ``(m, 3)`` in the camera frame [m].

        Raises:
            InvalidArgumentError: Points not ``(m, 3)`` finite numbers, or a point at or
                behind the camera (``Z <=`` :data:`MIN_DEPTH`), named by its index.
        """
        seen = self.projection(points)
        if not np.all(seen.in_front):
            behind = np.flatnonzero(~seen.in_front)
            raise InvalidArgumentError(
                f"{len(behind)} of {len(seen.in_front)} points are at or behind the camera "
                f"(z <= {MIN_DEPTH:g} m; first: point {int(behind[0])}): they have no pixel"
            )
        return seen.pixels

    def projection(self, points, derivatives: bool = False) -> Projection:
        """The pixels of points in the camera frame, flagged when not in front.

        Args:
            points: Points in the camera's optical frame ``(m, 3)`` [m].
            derivatives: Also the derivatives with respect to the points and to the
                intrinsic parameters.

        Returns:
            The pixels, which points are in front, and the derivatives if asked for.

        Raises:
            InvalidArgumentError: Points not ``(m, 3)`` finite numbers.
        """
        p = real_array(points, "points in the camera frame", (None, 3))
        in_front = p[:, 2] > MIN_DEPTH
        z = np.where(in_front, p[:, 2], np.nan)
        a, b = p[:, 0] / z, p[:, 1] / z
        dist = np.zeros(_FULL)
        dist[: len(self.distortion)] = self.distortion
        model = _Distorted(a, b, dist)
        tilt = dist[12:] if len(self.distortion) == _FULL else None
        f = np.array([self.fx, self.fy])
        if not derivatives:
            xy = model.xy if tilt is None else _tilt_only(model.xy, tilt)
            return Projection(xy * f + np.array([self.cx, self.cy]), in_front)
        k = len(self.distortion)
        xy, d_ab, d_dist = model.xy, model.d_ab(), model.d_coefficients(k)
        if tilt is not None:  # through the tilt
            xy, tilt_d = _tilted(model.xy, tilt)
            d_ab, d_dist = _times(tilt_d.d_xy, d_ab), _times(tilt_d.d_xy, d_dist)
            d_dist[:, :, 12:] = tilt_d.d_tilt
        d_norm = f[None, :, None] * d_ab  # (m, 2, 2): d(u, v)/d(a, b)
        d_point = np.empty((len(p), 2, 3))  # d(a, b)/d(X, Y, Z) = [[1, 0, -a], [0, 1, -b]] / Z
        d_point[:, :, 0] = d_norm[:, :, 0] / z[:, None]
        d_point[:, :, 1] = d_norm[:, :, 1] / z[:, None]
        d_point[:, :, 2] = (
            -(d_norm[:, :, 0] * a[:, None] + d_norm[:, :, 1] * b[:, None]) / z[:, None]
        )
        d_params = np.zeros((len(p), 2, 4 + k))
        d_params[:, 0, 0] = xy[:, 0]
        d_params[:, 1, 1] = xy[:, 1]
        d_params[:, 0, 2] = d_params[:, 1, 3] = 1.0
        d_params[:, :, 4:] = f[None, :, None] * d_dist
        pixels = xy * f + np.array([self.cx, self.cy])
        return Projection(pixels, in_front, d_point, d_params)


class _Distorted:
    """The distorted normalised coordinates of ``(a, b) = (X/Z, Y/Z)``, before the tilt.

    Attributes:
        xy: ``(x, y)`` ``(m, 2)``.
    """

    def __init__(self, a: np.ndarray, b: np.ndarray, c: np.ndarray):
        self.a, self.b, self.c = a, b, c
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = c[:12]
        r2 = a * a + b * b
        self.r = (r2, r2 * r2, r2 * r2 * r2)
        r4, r6 = self.r[1:]
        self.den = 1 + k4 * r2 + k5 * r4 + k6 * r6
        self.radial = (1 + k1 * r2 + k2 * r4 + k3 * r6) / self.den
        ab = a * b
        self.xy = np.column_stack(
            [
                a * self.radial + 2 * p1 * ab + p2 * (r2 + 2 * a * a) + s1 * r2 + s2 * r4,
                b * self.radial + p1 * (r2 + 2 * b * b) + 2 * p2 * ab + s3 * r2 + s4 * r4,
            ]
        )

    def d_ab(self) -> np.ndarray:
        """The derivative of ``xy`` with respect to ``(a, b)`` ``(m, 2, 2)``."""
        a, b, radial = self.a, self.b, self.radial
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = self.c[:12]
        r2, r4 = self.r[:2]
        d_radial = (
            (k1 + 2 * k2 * r2 + 3 * k3 * r4) - radial * (k4 + 2 * k5 * r2 + 3 * k6 * r4)
        ) / self.den
        sx, sy = s1 + 2 * s2 * r2, s3 + 2 * s4 * r2  # the thin prism's d/d(r2)
        d = np.empty((len(a), 2, 2))
        d[:, 0, 0] = radial + 2 * a * a * d_radial + 2 * p1 * b + 6 * p2 * a + 2 * a * sx
        d[:, 0, 1] = 2 * a * b * d_radial + 2 * p1 * a + 2 * p2 * b + 2 * b * sx
        d[:, 1, 0] = 2 * a * b * d_radial + 2 * p1 * a + 2 * p2 * b + 2 * a * sy
        d[:, 1, 1] = radial + 2 * b * b * d_radial + 6 * p1 * b + 2 * p2 * a + 2 * b * sy
        return d

    def d_coefficients(self, count: int) -> np.ndarray:
        """The derivative of ``xy`` by the first ``count`` coefficients ``(m, 2, count)``.

        The tilt's columns are zero: the tilt comes after.
        """
        a, b, radial = self.a, self.b, self.radial
        r2, r4, r6 = self.r
        out = np.zeros((len(a), 2, _FULL))
        # k1, k2, k3 (columns 0, 1, 4) and k4, k5, k6 (5, 6, 7) move the radial factor
        factors = (r2, r4, r6, -radial * r2, -radial * r4, -radial * r6)
        for j, g in zip((0, 1, 4, 5, 6, 7), factors, strict=True):
            if j < count:
                out[:, 0, j] = a * g / self.den
                out[:, 1, j] = b * g / self.den
        out[:, 0, 2] = out[:, 1, 3] = 2 * a * b  # p1, p2
        out[:, 1, 2] = r2 + 2 * b * b
        out[:, 0, 3] = r2 + 2 * a * a
        out[:, 0, 8], out[:, 0, 9], out[:, 1, 10], out[:, 1, 11] = r2, r4, r2, r4  # s1..s4
        return out[:, :, :count]  # tx, ty (12, 13) act after: zero here


@dataclass(frozen=True)
class _TiltDerivatives:
    """Derivatives of the tilted coordinates: ``d_xy`` ``(m, 2, 2)``, ``d_tilt`` ``(m, 2, 2)``."""

    d_xy: np.ndarray
    d_tilt: np.ndarray


def _along_axis(r: np.ndarray, last: float) -> np.ndarray:
    """OpenCV's projection back along the optical axis of a tilt ``r`` (``last`` 1).

    With ``last`` 0 and ``r`` a derivative of the tilt: the projection's derivative.
    """
    return np.array([[r[2, 2], 0, -r[0, 2]], [0, r[2, 2], -r[1, 2]], [0, 0, last]])


def _tilt_matrix(tx: float, ty: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """OpenCV's tilted-sensor projection matrix and its derivatives by ``tx`` and ``ty``.

    The sensor turned by ``tx`` about x then ``ty`` about y, ``R = Ry(ty) Rx(tx)``, projected
    back along the optical axis: ``T = [[R22, 0, -R02], [0, R22, -R12], [0, 0, 1]] R``.
    """
    c1, s1, c2, s2 = np.cos(tx), np.sin(tx), np.cos(ty), np.sin(ty)
    rx = np.array([[1, 0, 0], [0, c1, s1], [0, -s1, c1]])
    ry = np.array([[c2, 0, -s2], [0, 1, 0], [s2, 0, c2]])
    drx = np.array([[0, 0, 0], [0, -s1, c1], [0, -c1, -s1]])
    dry = np.array([[-s2, 0, -c2], [0, 0, 0], [c2, 0, -s2]])
    r = ry @ rx
    full = _along_axis(r, 1.0)
    derivatives = [_along_axis(dr, 0.0) @ r + full @ dr for dr in (ry @ drx, dry @ rx)]
    return full @ r, derivatives[0], derivatives[1]


def _times(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """The products of ``(m, 2, 2)`` and ``(m, 2, n)`` matrices ``(m, 2, n)``."""
    return left[:, :, 0:1] * right[:, None, 0, :] + left[:, :, 1:2] * right[:, None, 1, :]


def _tilt_only(xy: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """The tilted sensor's coordinates of ``xy`` ``(m, 2)`` (``tilt``: ``(tx, ty)`` [rad])."""
    t = _tilt_matrix(float(tilt[0]), float(tilt[1]))[0]
    w = xy @ t[:, :2].T + t[:, 2]
    return w[:, :2] / w[:, 2:]


def _tilted(xy: np.ndarray, tilt: np.ndarray) -> tuple[np.ndarray, _TiltDerivatives]:
    """The tilted sensor's coordinates of ``xy`` ``(m, 2)`` and their derivatives.

    ``tilt``: ``(tx, ty)`` [rad].
    """
    m = len(xy)
    t, dt_x, dt_y = _tilt_matrix(float(tilt[0]), float(tilt[1]))
    h = np.column_stack([xy, np.ones(m)])
    w = h @ t.T  # (m, 3)
    out = w[:, :2] / w[:, 2:]
    d_xy = (t[None, :2, :2] - out[:, :, None] * t[None, 2:3, :2]) / w[:, 2, None, None]
    d_tilt = np.empty((m, 2, 2))
    for j, dt in enumerate((dt_x, dt_y)):
        dw = h @ dt.T
        d_tilt[:, :, j] = (dw[:, :2] - out * dw[:, 2:]) / w[:, 2:]
    return out, _TiltDerivatives(d_xy, d_tilt)
