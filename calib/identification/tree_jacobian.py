"""Parameter sets and identification Jacobians of a tree: the rows of every measured tool.

Along the path to one tool the tree is a serial chain (:meth:`TreeMDH.path_model`), so each
tool's rows come from the chain's analytic Jacobian: a tree parameter on that path is one
of the path's columns (gamma_k and b_k act as theta and r of the antecedent a(k)); a
parameter off the path is a zero column. Rows are configuration-major, then tool, then the
measured rows (x, y, z, rx, ry, rz subset).
"""

from __future__ import annotations

import functools

import numpy as np

from ..core.checks import joint_positions, shown
from ..exceptions import InvalidArgumentError
from ..kinematics.tree_model import TreeMDH
from .jacobian import Measurement, identification_jacobian, measured_point
from .parameters import Kind, Parameter, ParameterSet

__all__ = ["tree_complete_jacobian", "tree_jacobian", "tree_parameters"]

_POSE = Measurement((0, 1, 2, 3, 4, 5))
_ORDER = (Kind.GAMMA, Kind.B, Kind.Y, Kind.BETA, Kind.ALPHA, Kind.D, Kind.THETA, Kind.R)


def _check_tree(model) -> None:
    if not isinstance(model, TreeMDH):
        raise InvalidArgumentError(f"model must be a TreeMDH (see from_tree), got {model!r:.60}")


def tree_parameters(model: TreeMDH, label: str = "paper") -> ParameterSet:
    """The ``paper`` or ``complete`` standard set of a tree (the chain's for one tool).

    ``paper``: theta0, r0; for every other row alpha, d, theta, r, with gamma and b first for
    a child that is not the first of its antecedent; where the row's axis is parallel to its
    antecedent's (antecedent not frame 0) beta replaces r, as in a chain: r_k then moves the
    branch along the antecedent's z, as r_{a(k)} less the other children's b do. ``complete``
    adds beta where a child of frame 0 is parallel to the base z axis and y where two lines
    coincide.

    Raises:
        InvalidArgumentError: Not a tree model, or an unknown label.
    """
    _check_tree(model)
    if not isinstance(label, str) or label not in ("paper", "complete"):
        raise InvalidArgumentError(
            f"unknown parameter set {shown(label)}: choose paper or complete"
        )
    a = model.antecedent
    params = [Parameter(0, Kind.THETA), Parameter(0, Kind.R)]
    for k in range(1, len(a)):
        first = model.first_child(k)
        kinds = [] if first else [Kind.GAMMA, Kind.B]
        if model.parallel[k] and a[k] != 0:  # r_k: r_{a(k)} minus the other children's b
            kinds += [Kind.BETA, Kind.ALPHA, Kind.D, Kind.THETA]
        else:
            kinds += [Kind.ALPHA, Kind.D, Kind.THETA, Kind.R]
            if label == "complete" and model.parallel[k]:
                kinds.append(Kind.BETA)
        if label == "complete" and model.coincident[k]:
            kinds.append(Kind.Y)
        params += [Parameter(k, kind) for kind in sorted(kinds, key=_ORDER.index)]
    return ParameterSet(label, tuple(params))


@functools.lru_cache(maxsize=64)
def _plan(model: TreeMDH, params: ParameterSet) -> tuple[tuple[ParameterSet, np.ndarray], ...]:
    """Per tool: the path's parameter set and, per tree column, its path column (-1: off)."""
    out = []
    for t in range(model.n_tools):
        rows = model.path_rows(t)
        pos = {int(k): i for i, k in enumerate(rows)}
        path_params: dict[Parameter, int] = {}
        cols = np.full(len(params), -1)
        for c, p in enumerate(params.parameters):
            if p.row not in pos:
                continue
            if p.kind in (Kind.GAMMA, Kind.B):
                at = pos[int(model.antecedent[p.row])]
                own = Parameter(at, Kind.THETA if p.kind is Kind.GAMMA else Kind.R)
            else:
                own = Parameter(pos[p.row], p.kind)
            cols[c] = path_params.setdefault(own, len(path_params))
        out.append((ParameterSet(params.label, tuple(path_params)), cols))
    return tuple(out)


def _check_params(model: TreeMDH, params) -> None:
    rows = len(model.sigma)
    if not (
        isinstance(params, ParameterSet)
        and all(isinstance(p, Parameter) and 0 <= p.row < rows for p in params.parameters)
    ):
        raise InvalidArgumentError(
            f"params must be a ParameterSet of this tree's rows (see tree_parameters), "
            f"got {params!r:.60}"
        )


def _measured(measured, m: int, tools: int) -> np.ndarray | None:
    if measured is None:
        return None
    mask = np.asarray(measured)
    if mask.dtype != bool or mask.shape != (m, tools):
        raise InvalidArgumentError(
            f"measured must be a boolean array (m, T) = ({m}, {tools}) of measured tools"
        )
    return mask


def _checked(model, params, q, measurement, measured):
    """Checked arguments of the tree Jacobians: ``q`` as ``(m, n)`` and the measured mask."""
    _check_tree(model)
    if params is not None:
        _check_params(model, params)
    if not isinstance(measurement, Measurement):
        raise InvalidArgumentError(f"measurement must be a Measurement, got {measurement!r:.60}")
    q = joint_positions(q, model.n)
    return q, _measured(measured, len(q), model.n_tools)


def _set_blocks(model: TreeMDH, params: ParameterSet, q: np.ndarray, measurement: Measurement):
    """Per tool: the tree columns on its path and its rows ``(m, rows, columns)`` there."""
    for t, (path_set, cols) in enumerate(_plan(model, params)):
        on = np.flatnonzero(cols >= 0)
        if not on.size:
            yield t, on, np.zeros((len(q), len(measurement.rows), 0))
            continue
        path = model.path_model(t)
        Wt = identification_jacobian(path, path_set, q[:, model.path_joints(t)], measurement)
        yield t, on, Wt.reshape(len(q), len(measurement.rows), -1)[:, :, cols[on]]


def _complete_blocks(model: TreeMDH, q: np.ndarray, measurement: Measurement):
    """Per tool: the complete model's columns on its path and its rows there."""
    m = len(q)
    for t in range(model.n_tools):
        path_rows = model.path_rows(t)
        kin = model.path_model(t).kinematics(q[:, model.path_joints(t)])
        # the placement of row path_rows[i] is fixed to path frame i - 1; the base is frame -1
        R = np.concatenate([np.broadcast_to(np.eye(3), (m, 1, 3, 3)), kin.R[:, :-1]], axis=1)
        p = np.concatenate([np.zeros((m, 1, 3)), kin.p[:, :-1]], axis=1)
        cols = (6 * np.concatenate([[0], path_rows[1:]])[:, None] + np.arange(6)).ravel()
        J = _rigid_columns(R, p, measured_point(kin, measurement.marker_array))
        yield t, cols, J[:, list(measurement.rows)]


def _assemble(blocks, m: int, tools: int, nrows: int, k: int, mask) -> np.ndarray:
    J = np.zeros((m, tools, nrows, k))
    for t, cols, Wt in blocks:
        Jt = J[:, t]  # a view
        Jt[:, :, cols] = Wt
    return (J if mask is None else J[mask]).reshape(-1, k)


def _factor(blocks, k: int, mask) -> np.ndarray:
    """Stacked triangular factors of the tools' blocks: F with F^T F = W^T W."""
    out = []
    for t, cols, Wt in blocks:
        rows = Wt if mask is None else Wt[mask[:, t]]
        if rows.size:
            # numpy's stubs type qr(mode="r") as QRResult; it returns the R array.
            Rt: np.ndarray = np.linalg.qr(rows.reshape(-1, len(cols)), mode="r")  # type: ignore[assignment]
            F = np.zeros((Rt.shape[0], k))
            F[:, cols] = Rt
            out.append(F)
    return np.vstack(out) if out else np.zeros((0, k))


def tree_jacobian(
    model: TreeMDH,
    params: ParameterSet,
    q: np.ndarray,
    measurement: Measurement = _POSE,
    measured: np.ndarray | None = None,
    factor: bool = False,
) -> np.ndarray:
    """Observation matrix W of a tree: the rows of every measured tool at each configuration.

    Args:
        model: Nominal (or current) tree model.
        params: Parameters whose errors are the columns (see :func:`tree_parameters`).
        q: Joint positions ``(m, n)`` of the tree joints [rad or m].
        measurement: Measured rows and marker (the marker in each tool's frame).
        measured: Which tools each configuration measures, boolean ``(m, T)``; default all.
        factor: Return instead a small matrix F with W's column geometry (F^T F = W^T W):
            each tool's rows touch only the columns on its path, so their triangular
            factors, stacked, have W's ranks, pivoted-QR diagonal and column norms with at
            most the sum of the path sizes as rows (a rank tolerance still counts W's rows).

    Returns:
        ``W`` with ``len(rows)`` rows per measured (configuration, tool) pair,
        configuration-major then tool order, and ``len(params)`` columns.
    """
    q, mask = _checked(model, params, q, measurement, measured)
    blocks = _set_blocks(model, params, q, measurement)
    if factor:
        return _factor(blocks, len(params), mask)
    return _assemble(blocks, len(q), model.n_tools, len(measurement.rows), len(params), mask)


def _rigid_columns(R: np.ndarray, p: np.ndarray, E: np.ndarray) -> np.ndarray:
    """Pose-error columns of a 6-DOF error at each frame, seen at point E.

    Args:
        R: Frame rotations ``(m, F, 3, 3)``.
        p: Frame origins ``(m, F, 3)`` [m].
        E: Measured point ``(m, 3)`` [m].

    Returns:
        ``(m, 6, 6 F)``: per frame, translations along its x, y, z axes then rotations about
        them through its origin.
    """
    m, F = p.shape[:2]
    axes = np.swapaxes(R, 2, 3)  # axes[..., i, :] is axis i
    lever = np.cross(axes, (E[:, None, :] - p)[:, :, None, :])
    block = np.zeros((m, F, 2, 3, 6))  # (translation | rotation, axis, pose row)
    block[:, :, 0, :, :3] = axes
    block[:, :, 1, :, :3] = lever
    block[:, :, 1, :, 3:] = axes
    return np.moveaxis(block.reshape(m, 6 * F, 6), 1, 2)


def tree_complete_jacobian(
    model: TreeMDH,
    q: np.ndarray,
    measurement: Measurement = _POSE,
    measured: np.ndarray | None = None,
    factor: bool = False,
) -> np.ndarray:
    """Observation matrix of the tree's complete reference error model.

    A generic 6-DOF error on the base frame and on the placement of every row (each joint
    and each tool in the frame of its antecedent): 6 (1 + n + T) columns, base first then
    row by row. A placement error moves the branch below it and nothing else; where a frame
    carries one child this is the chain's link error. Its rank is the number of independent
    geometric errors the measurement can see.

    Args:
        model: Nominal tree model.
        q: Joint positions ``(m, n)`` [rad or m].
        measurement: Measured rows and marker.
        measured: Which tools each configuration measures ``(m, T)``; default all.
        factor: Return the small matrix with W's column geometry (see :func:`tree_jacobian`).

    Returns:
        ``W`` laid out as :func:`tree_jacobian`'s, with ``6 (n + T + 1)`` columns.
    """
    q, mask = _checked(model, None, q, measurement, measured)
    k = 6 * len(model.sigma)
    blocks = _complete_blocks(model, q, measurement)
    if factor:
        return _factor(blocks, k, mask)
    return _assemble(blocks, len(q), model.n_tools, len(measurement.rows), k, mask)
