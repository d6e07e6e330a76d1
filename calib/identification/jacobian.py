"""The analytic identification Jacobian and the complete reference error model."""

from __future__ import annotations

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.mdh import Kinematics, MDHModel
from .measures import MAX_MARKER, POSE, POSE_ROWS, ROW_NAMES, MeasureKind, Measurement
from .parameters import ParameterSet

__all__ = [
    "MAX_MARKER",
    "ROW_NAMES",
    "Measurement",
    "complete_jacobian",
    "identification_jacobian",
    "measured_point",
]


def _check_types(mdh: MDHModel, measurement: MeasureKind, params=None) -> None:
    """Raise InvalidArgumentError for arguments of the wrong kind (not for their values)."""
    if not isinstance(mdh, MDHModel):
        raise InvalidArgumentError(f"mdh must be an MDHModel (see from_chain), got {mdh!r:.60}")
    # Measurement first (tried in order): the protocol's check inspects every member (slow).
    if not isinstance(measurement, (Measurement, MeasureKind)):
        raise InvalidArgumentError(
            f"measurement must be a measurement kind (see kind_of, Measurement.of), got "
            f"{measurement!r:.60}"
        )
    if params is not None and not (
        isinstance(params, ParameterSet) and _rows_within(params.layout.axis_row, mdh.n + 1)
    ):
        raise InvalidArgumentError(
            f"params must be a ParameterSet of this model's rows, got {params!r:.60}"
        )


def _rows_within(rows: np.ndarray, last: int) -> bool:
    return not rows.size or (int(rows.min()) >= 0 and int(rows.max()) <= last)


def measured_point(kin: Kinematics, marker: np.ndarray) -> np.ndarray:
    """Measured point in the base frame at every configuration ``(m, 3)`` [m]."""
    return kin.p[:, -1] + kin.R[:, -1] @ marker


def identification_jacobian(
    mdh: MDHModel,
    params: ParameterSet,
    q: np.ndarray,
    measurement: MeasureKind = POSE,
    kin: Kinematics | None = None,
) -> np.ndarray:
    """Observation matrix W: stacked identification Jacobians, analytic (docs/method.md eq. 2).

    Args:
        mdh: Nominal (or current) model.
        params: Parameters whose errors are the columns.
        q: Joint positions ``(m, n)`` [rad or m].
        measurement: The measurement kind (its rows; a measured point: its marker).
        kin: Kinematics of ``mdh`` at ``q`` if already computed.

    Returns:
        ``W`` of shape ``(m * rows, len(params))`` (``rows = measurement.n_rows``):
        configuration-major, so rows ``i*rows:(i+1)*rows`` belong to configuration i.
    """
    _check_types(mdh, measurement, params)
    if kin is None:
        kin = mdh.kinematics(q)
    plan = params.layout
    # Component-major (row, xyz, configuration): contiguous for :meth:`MDHModel.kinematics`'s
    # arrays, so that every operation runs along the configurations.
    y_prev, x_mid, q_mid, p = (
        a.transpose(1, 2, 0) for a in (kin.y_prev, kin.x_mid, kin.q_mid, kin.p)
    )
    z = kin.R[:, :, :, 2].transpose(1, 2, 0)
    # One gather per kind of vector: each column's axis (k, 3, m), each rotation's point.
    axes = np.stack([y_prev, x_mid, z])[plan.axis_source, plan.axis_row]
    rot = plan.rotations
    L = None
    if rot.size:
        L = _point(kin, measurement) - np.stack([q_mid, p])[plan.point_source, plan.point_row]
    return _measured_rows(axes, rot, L, measurement, kin)


def _measured_rows(axes, rot, L, measurement: MeasureKind, kin: Kinematics) -> np.ndarray:
    """W of a kind: an instrument's rows directly, other kinds from the pose-error rows."""
    if isinstance(measurement, Measurement):
        return _assemble(axes, rot, L, measurement.rows)
    W6 = _assemble(axes, rot, L, POSE_ROWS)
    m, k = kin.R.shape[0], axes.shape[0]
    rows = measurement.jacobian_rows(W6.reshape(m, 6, k), kin.R[:, -1])
    return rows.reshape(-1, k)


def _point(kin: Kinematics, measurement: MeasureKind) -> np.ndarray:
    """The measured point in the base frame, component-major ``(3, m)`` [m]."""
    E = kin.p[:, -1].T
    if any(measurement.marker):
        E = E + np.einsum("mij,j->im", kin.R[:, -1], np.array(measurement.marker))
    return E


def _assemble(
    axes: np.ndarray, rot: np.ndarray, L: np.ndarray | None, rows: tuple[int, ...]
) -> np.ndarray:
    """W from each column's axis ``(k, 3, m)`` and each rotation column's lever ``L``.

    A translation moves the point along its axis; a rotation (columns ``rot``) moves it by
    axis x L and turns the tool about its axis. Only the measured rows are built.

    Returns:
        ``W`` ``(m * len(rows), k)``, configuration-major.
    """
    k, _, m = axes.shape
    lin = [r for r in rows if r < 3]  # rows are sorted: position rows first
    ang = [r - 3 for r in rows if r >= 3]
    n_lin = len(lin)
    out = np.empty((k, len(rows), m))
    out[:, :n_lin] = _components(axes, lin)
    out[:, n_lin:] = 0.0
    if rot.size and L is not None:  # L is given whenever there are rotation columns
        a = axes[rot]
        if lin:
            out[rot, :n_lin] = _cross_rows(a, L, lin)
        if ang:
            out[rot, n_lin:] = _components(a, ang)
    return out.transpose(2, 1, 0).reshape(-1, k)


_NEXT, _AFTER = np.array([1, 2, 0]), np.array([2, 0, 1])


def _cross_rows(a: np.ndarray, L: np.ndarray, lin: list[int]) -> np.ndarray:
    """Components ``lin`` of a x L for vectors ``(k, 3, m)`` (np.take: a[:, list] is slower)."""
    c1, c2 = _NEXT[lin], _AFTER[lin]
    a1, a2 = np.take(a, c1, axis=1), np.take(a, c2, axis=1)
    return a1 * np.take(L, c2, axis=1) - a2 * np.take(L, c1, axis=1)


def _components(v: np.ndarray, which: list[int]) -> np.ndarray:
    """Components ``which`` of vectors ``(k, 3, m)``: a view when they are all three."""
    return v if which == [0, 1, 2] else np.take(v, which, axis=1)


def complete_jacobian(
    mdh: MDHModel,
    q: np.ndarray,
    measurement: MeasureKind = POSE,
    kin: Kinematics | None = None,
) -> np.ndarray:
    """Observation matrix of the complete reference error model.

    A generic 6-DOF error (3 translations, 3 rotations about the frame's own axes) on the
    base and on every link carrying a joint placement or the tool, i.e. on frames -1, 1..n.
    Any frame fixed to a link gives the same column space, so the placement of joint k+1 and
    the tool placement are covered by link k's frame. Its rank is the number of independent
    geometric errors the measurement can see, whatever the parameterisation.

    Returns:
        ``W`` of shape ``(m * measurement.n_rows, 6 (n + 1))``.
    """
    _check_types(mdh, measurement)
    if kin is None:
        kin = mdh.kinematics(q)
    n, m = mdh.n, kin.R.shape[0]
    # Component-major frames -1, 1..n: the columns of each rotation are the axes (3 (n+1),
    # 3, m), each frame's origin the point of its three rotations.
    R = np.empty((n + 1, 3, 3, m))
    R[0] = np.eye(3)[:, :, None]
    R[1:] = kin.R[:, 1 : n + 1].transpose(1, 3, 2, 0)  # (frame, column, xyz, m)
    axes = R.reshape(-1, 3, m)
    points = np.zeros((n + 1, 1, 3, m))
    points[1:, 0] = kin.p[:, 1 : n + 1].transpose(1, 2, 0)
    L = _point(kin, measurement) - np.broadcast_to(points, (n + 1, 3, 3, m)).reshape(-1, 3, m)
    rot = np.arange(axes.shape[0], 2 * axes.shape[0])
    return _measured_rows(np.concatenate([axes, axes]), rot, L, measurement, kin)
