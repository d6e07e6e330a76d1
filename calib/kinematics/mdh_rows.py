"""The MDH rows of joint lines: the conversion's frame choices, row by row.

:func:`line_rows` walks the lines (the base z axis, each joint's axis, the tool's z axis) and
places frame k-1 against line k: along the common normal, or with Hayati's beta where the
lines are parallel (see :func:`~calib.kinematics.mdh.from_lines`, which checks the inputs).
A line's 3-vectors are plain Python floats: NumPy's calls on arrays of 3 (``cross``, ``norm``,
``dot``) cost microseconds each, ten times the arithmetic.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

__all__ = ["COINCIDENT_TOL", "FREE_DIRECTION_TOL", "line_rows"]

FREE_DIRECTION_TOL = 1e-10
"""Length [m] under which a perpendicular has no direction (the x axis is then free)."""

COINCIDENT_TOL = 1e-6
"""Distance [m] under which two parallel lines are coincident (the complete set adds y)."""

_Vec = tuple[float, float, float]
"""A 3-vector as plain floats: the conversion's per-row arithmetic, much cheaper than NumPy's
calls on arrays of 3."""


def _dot(a: _Vec, b: _Vec) -> float:
    # From +0.0 as NumPy's dot sums, so that a zero is never -0.0 (atan2 tells them apart).
    return 0.0 + a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _cross(a: _Vec, b: _Vec) -> _Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _along(a: _Vec, t: float, u: _Vec) -> _Vec:
    """The point ``a + t u``."""
    return (a[0] + t * u[0], a[1] + t * u[1], a[2] + t * u[2])


def _diff(a: _Vec, b: _Vec) -> _Vec:
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def _norm(v: _Vec) -> float:
    return math.sqrt(_dot(v, v))


def _unit(v: _Vec) -> _Vec:
    n = _norm(v)
    return (v[0] / n, v[1] / n, v[2] / n)


def _signed_angle(a: _Vec, b: _Vec, axis: _Vec) -> float:
    """Angle [rad] from unit vector a to unit vector b about ``axis`` (both orthogonal to it)."""
    return math.atan2(_dot(_cross(a, b), axis), _dot(a, b))


def _sign_towards(x: _Vec, x_ref: _Vec, z: _Vec) -> _Vec:
    """Choose +x or -x so that the angle from x_ref to it about z lies in (-90, 90] degrees."""
    dot = _dot(x, x_ref)
    if abs(dot) > 1e-9:
        return x if dot > 0 else (-x[0], -x[1], -x[2])
    return x if _dot(_cross(x_ref, x), z) > 0 else (-x[0], -x[1], -x[2])


def _closest_points(p1: _Vec, u1: _Vec, p2: _Vec, u2: _Vec) -> tuple[float, float]:
    """Parameters t, s of the closest points p1 + t u1 and p2 + s u2 of two skew lines."""
    w0 = _diff(p1, p2)
    b = _dot(u1, u2)
    dd, e = _dot(u1, w0), _dot(u2, w0)
    den = 1.0 - b * b
    return (b * e - dd) / den, (e - b * dd) / den


class _Row(NamedTuple):
    """Row k of the conversion, from the state of frame k-1 and line k.

    Attributes:
        x: x axis of frame k-1 (along the common normal to line k).
        origin: Origin of frame k-1 (on line k-1) [m].
        beta: beta_k (nonzero only after a parallel line) [rad].
        alpha: alpha_k [rad].
        d: d_k [m].
        x_mid: x axis after ``Rot(y, beta_k) Rot(x, alpha_k)``.
        foot: Where row k lands on line k [m].
        coincident: Line k lies on line k-1.
    """

    x: _Vec
    origin: _Vec
    beta: float
    alpha: float
    d: float
    x_mid: _Vec
    foot: _Vec
    coincident: bool


def _skew_row(z: _Vec, entry: _Vec, x_zero: _Vec, pk: _Vec, uk: _Vec) -> _Row:
    """Row k where line k is not parallel to line k-1 (``z``, through ``entry``)."""
    t, s = _closest_points(entry, z, pk, uk)
    origin, foot = _along(entry, t, z), _along(pk, s, uk)
    x = _sign_towards(_unit(_cross(z, uk)), x_zero, z)
    d = _dot(_diff(foot, origin), x)
    return _Row(x, origin, 0.0, _signed_angle(z, uk, x), d, x, foot, False)


def _parallel_row(z: _Vec, entry: _Vec, x_zero: _Vec, pk: _Vec, uk: _Vec) -> _Row:
    """Row k where line k is parallel to line k-1: Hayati's beta, the origin at ``entry``."""
    v = _diff(pk, entry)
    w = _along(v, -_dot(v, uk), uk)  # from entry to line k, perpendicular to it
    wp = _along(w, -_dot(w, z), z)
    x = _sign_towards(_unit(wp), x_zero, z) if _norm(wp) > FREE_DIRECTION_TOL else x_zero
    # line k's direction in frame k-1 (x, z cross x, z)
    ux, uy, uz = _dot(x, uk), _dot(_cross(z, x), uk), _dot(z, uk)
    sgn = 1.0 if uz >= 0 else -1.0
    alpha = math.atan2(-uy, sgn * math.hypot(ux, uz))
    beta = math.atan2(sgn * ux, sgn * uz)
    cb, sb = math.cos(beta), math.sin(beta)
    x_mid = (0.0 + x[0] * cb - z[0] * sb, 0.0 + x[1] * cb - z[1] * sb, 0.0 + x[2] * cb - z[2] * sb)
    d = _dot(w, x_mid)
    return _Row(x, entry, beta, alpha, d, x_mid, _along(entry, d, x_mid), _norm(w) < COINCIDENT_TOL)


def line_rows(
    points: np.ndarray,
    directions: np.ndarray,
    tool: np.ndarray,
    parallel_tol: float,
    parallel_rows: np.ndarray | None = None,
) -> tuple[np.ndarray, ...]:
    """The MDH rows 0..n+1 of joint lines already checked (see ``from_lines``).

    The state of frame k-1 while row k is built: its z axis, the point where row k-1 lands on
    its line (r_{k-1} measured from there) and its x axis at zero offset.

    Args:
        points: A point of each joint axis ``(n, 3)`` [m].
        directions: Unit direction of each joint axis ``(n, 3)``.
        tool: Tool pose ``(4, 4)`` in the base frame (a rigid transform).
        parallel_tol: Parallel-axis tolerance [rad].
        parallel_rows: Rows 0..n+1 placed with Hayati's beta whatever their angle (``(n+2,)``
            bool, a model's ``parallel``), or None: those within ``parallel_tol``.

    Returns:
        beta, alpha, d, theta, r ``(n+2,)`` [rad, m], and which rows are parallel to the
        previous one and which coincide with it ``(n+2,)`` (bool).
    """
    rows = len(points) + 2
    beta, alpha, d, theta, r = ([0.0] * rows for _ in range(5))
    parallel, coincident = [False] * rows, [False] * rows
    z, entry, x_zero = (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (1.0, 0.0, 0.0)
    lines = zip(
        [*map(tuple, points.tolist()), tuple(tool[:3, 3].tolist())],
        [*map(tuple, directions.tolist()), tuple(tool[:3, 2].tolist())],
        strict=True,
    )
    for k, (pk, uk) in enumerate(lines, start=1):
        parallel[k] = (
            bool(parallel_rows[k])
            if parallel_rows is not None
            else math.acos(min(abs(_dot(z, uk)), 1.0)) < parallel_tol
        )
        row = (_parallel_row if parallel[k] else _skew_row)(z, entry, x_zero, pk, uk)
        # Close row k-1: its offset theta and its distance r along z_{k-1}.
        theta[k - 1] = _signed_angle(x_zero, row.x, z)
        r[k - 1] = _dot(_diff(row.origin, entry), z)
        beta[k], alpha[k], d[k], coincident[k] = row.beta, row.alpha, row.d, row.coincident
        z, entry, x_zero = uk, row.foot, row.x_mid
    # Row n+1 lands on the tool z line; the tool frame fixes its x axis and origin.
    theta[-1] = _signed_angle(x_zero, tuple(tool[:3, 0].tolist()), z)
    r[-1] = _dot(_diff(tuple(tool[:3, 3].tolist()), entry), z)
    return tuple(np.array(v) for v in (beta, alpha, d, theta, r, parallel, coincident))
