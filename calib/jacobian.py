"""The analytic identification Jacobian and the complete reference error model."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .exceptions import InvalidArgumentError
from .mdh import Kinematics, MDHModel
from .parameters import ParameterSet

MAX_MARKER = 1e3
"""Largest marker coordinate [m]: a measured point on a robot's tool, not a kilometre away."""

ROW_NAMES = ("x", "y", "z", "rx", "ry", "rz")
"""The six rows of a pose error: position [m] then orientation [rad], in the base frame."""


@dataclass(frozen=True)
class Measurement:
    """What is measured: some rows of the tool pose error, at a point of the tool.

    Attributes:
        rows: Indices into ``(x, y, z, rx, ry, rz)``.
        marker: Measured point in the tool frame ``(3,)`` [m].
        label: ``pose``, ``position`` or the row names.
    """

    rows: tuple[int, ...]
    marker: tuple[float, float, float] = (0.0, 0.0, 0.0)
    label: str = "pose"

    @staticmethod
    def of(measure: str = "pose", marker=None) -> Measurement:
        """Build from ``pose``, ``position`` or comma-separated row names (``x,y,rz``).

        Raises:
            InvalidArgumentError: Unknown measure or a marker that is not 3 finite numbers.
        """
        if measure == "pose":
            rows = (0, 1, 2, 3, 4, 5)
        elif measure == "position":
            rows = (0, 1, 2)
        else:
            names = [s.strip() for s in str(measure).split(",") if s.strip()]
            if not names or any(s not in ROW_NAMES for s in names):
                raise InvalidArgumentError(
                    f"unknown measure '{measure}': choose pose, position or rows among "
                    f"{', '.join(ROW_NAMES)}"
                )
            rows = tuple(sorted({ROW_NAMES.index(s) for s in names}))
        if marker is None:
            marker = (0.0, 0.0, 0.0)
        mk = np.asarray(marker, dtype=float).ravel() if _numeric(marker) else None
        if (
            mk is None
            or mk.shape != (3,)
            or not np.all(np.isfinite(mk))
            or np.max(np.abs(mk)) > MAX_MARKER
        ):
            raise InvalidArgumentError(
                f"a marker is 3 finite numbers (x y z in metres, each within {MAX_MARKER:g} m), "
                f"got {marker!r}"
            )
        return Measurement(rows, (float(mk[0]), float(mk[1]), float(mk[2])), measure)

    @property
    def marker_array(self) -> np.ndarray:
        """The marker as an array [m]."""
        return np.array(self.marker)


def _numeric(value) -> bool:
    try:
        np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return False
    return True


def _check_types(mdh: MDHModel, measurement: Measurement, params=None) -> None:
    """Raise InvalidArgumentError for arguments of the wrong kind (not for their values)."""
    if not isinstance(mdh, MDHModel):
        raise InvalidArgumentError(f"mdh must be an MDHModel (see from_chain), got {mdh!r:.60}")
    if not isinstance(measurement, Measurement):
        raise InvalidArgumentError(
            f"measurement must be a Measurement (see Measurement.of), got {measurement!r:.60}"
        )
    last = mdh.n + 1
    if params is not None and not (
        isinstance(params, ParameterSet) and all(0 <= p.row <= last for p in params.parameters)
    ):
        raise InvalidArgumentError(
            f"params must be a ParameterSet of this model's rows, got {params!r:.60}"
        )


def measured_point(kin: Kinematics, marker: np.ndarray) -> np.ndarray:
    """Measured point in the base frame at every configuration ``(m, 3)`` [m]."""
    return kin.p[:, -1] + kin.R[:, -1] @ marker


def _stack(columns_lin: np.ndarray, columns_ang: np.ndarray, rows: tuple[int, ...]) -> np.ndarray:
    J = np.concatenate([columns_lin, columns_ang], axis=2)  # (m, k, 6)
    J = np.swapaxes(J, 1, 2)[:, list(rows), :]  # (m, nrows, k)
    return J.reshape(-1, J.shape[2])


def identification_jacobian(
    mdh: MDHModel,
    params: ParameterSet,
    q: np.ndarray,
    measurement: Measurement = Measurement((0, 1, 2, 3, 4, 5)),
    kin: Kinematics | None = None,
) -> np.ndarray:
    """Observation matrix W: stacked identification Jacobians, analytic (docs/method.md eq. 2).

    Args:
        mdh: Nominal (or current) model.
        params: Parameters whose errors are the columns.
        q: Joint positions ``(m, n)`` [rad or m].
        measurement: Measured rows and marker.
        kin: Kinematics of ``mdh`` at ``q`` if already computed.

    Returns:
        ``W`` of shape ``(m * len(rows), len(params))``: configuration-major, so rows
        ``i*len(rows):(i+1)*len(rows)`` belong to configuration i.
    """
    _check_types(mdh, measurement, params)
    if kin is None:
        kin = mdh.kinematics(q)
    plan = params.layout
    m, k, frames = kin.p.shape[0], len(params), kin.p.shape[1]
    # One gather per kind of vector: the sources side by side, indexed by source and row.
    index = np.empty(k, dtype=int)
    for src, cols, rows in plan.axes:
        index[cols] = src * frames + rows
    axes = np.concatenate([kin.y_prev, kin.x_mid, kin.R[:, :, :, 2]], axis=1)[:, index]
    out = np.empty((m, len(measurement.rows), k))  # only the rows measured
    rot = plan.rotations
    if rot.size:
        E = measured_point(kin, measurement.marker_array)
        index = np.empty(rot.size, dtype=int)
        for src, cols, rows in plan.points:
            index[cols] = src * frames + rows
        L = E[:, None, :] - np.concatenate([kin.q_mid, kin.p], axis=1)[:, index]
        a = axes[:, rot]
    for i, row in enumerate(measurement.rows):
        if row < 3:  # a translation moves the point along its axis; a rotation: axis x L
            out[:, i] = axes[:, :, row]
            if rot.size:
                c1, c2 = (row + 1) % 3, (row + 2) % 3
                out[:, i, rot] = a[:, :, c1] * L[:, :, c2] - a[:, :, c2] * L[:, :, c1]
        else:  # orientation rows: a rotation turns the tool about its axis
            out[:, i] = 0.0
            if rot.size:
                out[:, i, rot] = a[:, :, row - 3]
    return out.reshape(-1, k)


def complete_jacobian(
    mdh: MDHModel,
    q: np.ndarray,
    measurement: Measurement = Measurement((0, 1, 2, 3, 4, 5)),
    kin: Kinematics | None = None,
) -> np.ndarray:
    """Observation matrix of the complete reference error model.

    A generic 6-DOF error (3 translations, 3 rotations about the frame's own axes) on the
    base and on every link carrying a joint placement or the tool, i.e. on frames -1, 1..n.
    Any frame fixed to a link gives the same column space, so the placement of joint k+1 and
    the tool placement are covered by link k's frame. Its rank is the number of independent
    geometric errors the measurement can see, whatever the parameterisation.

    Returns:
        ``W`` of shape ``(m * len(rows), 6 (n + 1))``.
    """
    _check_types(mdh, measurement)
    if kin is None:
        kin = mdh.kinematics(q)
    m = kin.R.shape[0]
    eye = np.broadcast_to(np.eye(3), (m, 1, 3, 3))
    R = np.concatenate([eye, kin.R[:, 1 : mdh.n + 1]], axis=1)  # frames -1, 1..n
    p = np.concatenate([np.zeros((m, 1, 3)), kin.p[:, 1 : mdh.n + 1]], axis=1)
    axes = np.swapaxes(R, 2, 3).reshape(m, -1, 3)  # rows of R^T = columns of R
    points = np.repeat(p, 3, axis=1)
    E = measured_point(kin, measurement.marker_array)
    rot_lin = np.cross(axes, E[:, None, :] - points)
    zeros = np.zeros_like(axes)
    lin = np.concatenate([axes, rot_lin], axis=1)
    ang = np.concatenate([zeros, axes], axis=1)
    return _stack(lin, ang, measurement.rows)
