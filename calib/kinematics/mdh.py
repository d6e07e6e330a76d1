"""Khalil-Kleinfinger modified Denavit-Hartenberg model of a chain, with Hayati's beta.

Frame -1 is the chosen base frame, frame 0 is fixed to it, frames 1..n follow the joints
and frame n+1 is the chosen tool frame. Row k (k = 0..n+1) places frame k in frame k-1:

    T(k-1, k) = Trans(y, y_k) Rot(y, beta_k) Rot(x, alpha_k) Trans(x, d_k)
                Rot(z, theta_k + (1 - sigma_k) s_k q_k) Trans(z, r_k + sigma_k s_k q_k)

``q_k`` is the URDF position of the joint and ``s_k`` (``sign``) is +1, or -1 for a joint the
chain traverses backwards, from its child link to its parent link (a chain from a foot to a
hand goes up the leg). z_k is the URDF axis of the joint in both cases: a positive position
turns the child link about +z_k relative to the parent link, so the frames after a reversed
joint (its parent's side) turn by -q_k about z_k. Fixed rows have ``s_k`` = +1.

``y_k`` is zero in every converted model; it only exists as an error parameter of the
complete set, where two consecutive lines coincide.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from ..core.checks import joint_positions, real_array
from ..exceptions import InvalidArgumentError
from . import urdf_xml
from .mdh_rows import COINCIDENT_TOL, FREE_DIRECTION_TOL, line_rows
from .robot import Chain

__all__ = [
    "COINCIDENT_TOL",
    "FREE_DIRECTION_TOL",
    "PARALLEL_TOL",
    "RIGID_TOL",
    "SNAP_ANGLE",
    "SNAP_LENGTH",
    "Kinematics",
    "MDHModel",
    "converted_chain",
    "frames_at_zero",
    "from_chain",
    "from_lines",
    "in_chart_of",
    "snap_angle",
    "snap_length",
]

PARALLEL_TOL = 0.01
"""Angle [rad] under which two consecutive axes are treated as parallel (Hayati's beta).

Between parallel axes the common normal is not unique and, for nearly parallel ones, lies
far away: a 6e-6 rad tilt over 0.4 m puts it kilometres off. Rounded URDF angles
(1.5708, 1.57) tilt axes by up to 1e-3 rad, so the tolerance is ten times that.
"""

SNAP_ANGLE = urdf_xml.SNAP_ANGLE
"""Angle [rad] within which :meth:`MDHModel.idealized` snaps to a multiple of 90 degrees.

URDF files round pi/2 to 1.5708 (3.7e-6 rad off), 1.57079 or 1.57079632679 (5e-12 off).
"""

SNAP_LENGTH = urdf_xml.SNAP_LENGTH
"""Length [m] under which :meth:`MDHModel.idealized` snaps a distance to zero."""


def snap_angle(a: np.ndarray, tol: float) -> np.ndarray:
    """Angles [rad] within ``tol`` of a multiple of 90 degrees, snapped to it."""
    quarter = math.pi / 2
    target = np.round(a / quarter) * quarter + 0.0  # no negative zero
    return np.where(np.abs(a - target) < tol, target, a)


def snap_length(v: np.ndarray, tol: float) -> np.ndarray:
    """Lengths [m] under ``tol`` in absolute value, snapped to zero."""
    return np.where(np.abs(v) < tol, 0.0, v)


_Y_AXIS = np.array([[0.0], [1.0], [0.0]])

_ARRAYS = ("sigma", "beta", "alpha", "d", "theta", "r", "y", "parallel", "coincident", "sign")
"""The array fields of :class:`MDHModel` (stored as private read-only copies)."""


def _pre_rotations(beta: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """``Rot(y, beta_k) Rot(x, alpha_k)`` of every row ``(rows, 3, 3)``, entry by entry.

    Each entry is the one term of the matrix product that is not zero, from +0.0 as the
    product sums (no -0.0).
    """
    out = []
    for b, a in zip(beta.tolist(), alpha.tolist(), strict=True):
        cb, sb, ca, sa = math.cos(b), math.sin(b), math.cos(a), math.sin(a)
        out.append((cb, 0.0 + sb * sa, 0.0 + sb * ca))
        out.append((0.0, ca, 0.0 - sa))
        out.append((0.0 - sb, 0.0 + cb * sa, 0.0 + cb * ca))
    pre = np.array(out).reshape(-1, 3, 3)
    pre.flags.writeable = False
    return pre


class Kinematics(NamedTuple):
    """Frames of an MDH model at m configurations, all in the base frame (frame -1).

    Attributes:
        R: Rotation of frame k, shape ``(m, n+2, 3, 3)``.
        p: Origin of frame k, ``(m, n+2, 3)`` [m].
        y_prev: y axis of frame k-1, ``(m, n+2, 3)``: axis of ``y_k`` and ``beta_k``.
        x_mid: x axis after ``Rot(y, beta_k) Rot(x, alpha_k)``, ``(m, n+2, 3)``: axis of
            ``alpha_k`` and ``d_k``.
        q_mid: Point where ``beta_k`` and ``alpha_k`` rotate, ``(m, n+2, 3)`` [m].
    """

    R: np.ndarray
    p: np.ndarray
    y_prev: np.ndarray
    x_mid: np.ndarray
    q_mid: np.ndarray


@dataclass(frozen=True, eq=False)
class MDHModel:
    """Modified-DH rows of a chain (frames 0..n+1), a value object.

    Attributes:
        sigma: 0 revolute, 1 prismatic, -1 fixed row, shape ``(n+2,)``.
        beta: Hayati angle about y_{k-1} [rad].
        alpha: Angle about x_{k-1} [rad].
        d: Distance along x_{k-1} [m].
        theta: Angle about z_k [rad] (joint offset for a revolute row).
        r: Distance along z_k [m] (joint offset for a prismatic row).
        y: Translation along y_{k-1} [m] (zero for a converted model).
        joint_names: URDF joint of each row, None for the fixed rows 0 and n+1.
        parallel: Row k whose axis is parallel to the previous one (beta convention).
        coincident: Row k whose axis lies on the previous one (parallel and through it).
        base_frame: Name of frame -1.
        tool_frame: Name of frame n+1.
        sign: +1, or -1 for a joint traversed backwards (its URDF position enters its row
            negated), shape ``(n+2,)``; +1 for the fixed rows. Default: all +1.
        source: The chain a model was converted from and the parallel tolerance of the
            conversion (set by :func:`~calib.from_chain`): :meth:`idealized` then converts the
            chain's URDF with round-off removed. None for other models.
    """

    sigma: np.ndarray
    beta: np.ndarray
    alpha: np.ndarray
    d: np.ndarray
    theta: np.ndarray
    r: np.ndarray
    y: np.ndarray
    joint_names: tuple[str | None, ...]
    parallel: np.ndarray
    coincident: np.ndarray
    base_frame: str = ""
    tool_frame: str = ""
    sign: np.ndarray = None  # type: ignore[assignment]
    source: tuple[Chain, float] | None = field(default=None, repr=False)
    _pre: np.ndarray = field(init=False, repr=False)
    _gain: np.ndarray = field(init=False, repr=False)
    _offsets: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if self.sign is None:
            object.__setattr__(self, "sign", np.ones(len(self.sigma), dtype=int))
        for name in _ARRAYS:
            a = np.array(getattr(self, name))  # a private, read-only copy: a value object
            a.flags.writeable = False
            object.__setattr__(self, name, a)
        if self.sign.shape != self.sigma.shape or not np.all(np.abs(self.sign) == 1):
            raise InvalidArgumentError(
                f"sign holds +1 or -1 per row ({len(self.sigma)}), got {self.sign.tolist()}"
            )
        object.__setattr__(self, "_pre", _pre_rotations(self.beta, self.alpha))
        # What q_k adds to each joint row's angle (row 0) and length (row 1): (1 - sigma) s
        # and sigma s.
        s, sig = self.sign[1:-1].astype(float), self.sigma[1:-1]
        gain = np.array([(sig == 0) * s, (sig == 1) * s])[:, :, None]
        offsets = np.array([self.theta, self.r])[:, :, None]  # theta_k and r_k, (2, rows, 1)
        for name, a in (("_gain", gain), ("_offsets", offsets)):
            a.flags.writeable = False
            object.__setattr__(self, name, a)

    @property
    def n(self) -> int:
        """Number of joints."""
        return len(self.sigma) - 2

    def __repr__(self) -> str:
        """One line: ``<MDHModel base_link -> tool0, 6 joints>`` (the rows are attributes)."""
        return f"<MDHModel {self.base_frame} -> {self.tool_frame}, {self.n} joints>"

    def replace(self, **changes: Any) -> MDHModel:
        """A copy with some fields replaced (the model itself is never mutated).

        ``source`` (the chain the model was converted from, which :meth:`idealized` converts
        again without round-off) is kept when only the frame names change
        (``base_frame``, ``tool_frame``). Any other change (a row's geometry, the joints)
        makes the model another robot's than the chain's, whose idealization would drop the
        change: ``source`` is then None, unless ``changes`` gives it.
        """
        if "source" not in changes and changes.keys() <= {"base_frame", "tool_frame"}:
            changes = {**changes, "source": self.source}
        fields = {
            name: getattr(self, name)
            for name in (
                "sigma",
                "beta",
                "alpha",
                "d",
                "theta",
                "r",
                "y",
                "joint_names",
                "parallel",
                "coincident",
                "base_frame",
                "tool_frame",
                "sign",
            )
        }
        fields.update(changes)
        return MDHModel(**fields)

    def idealized(self, angle_tol: float = SNAP_ANGLE, length_tol: float = SNAP_LENGTH) -> MDHModel:
        """A copy with URDF round-off removed, for structural (rank) analysis.

        A model converted from a URDF chain (:func:`~calib.from_chain`) starts from the conversion
        of the URDF geometry itself with round-off removed (each ``rpy`` angle within
        ``SNAP_ANGLE`` of a multiple of 90 degrees snapped to it, each ``xyz`` coordinate and
        axis component under ``SNAP_LENGTH`` / ``SNAP_ANGLE`` to zero): the lengths that a
        rounded angle induces (a tool 1e-6 m off the last axis) vanish with the angle. Then, and
        for any other model, angles within ``angle_tol`` of a multiple of 90 degrees are snapped
        to it and distances under ``length_tol`` to zero. A rounded ``rpy`` otherwise leaves a
        tool 4e-13 m off the last axis, and the rank counts directions that only round-off
        creates. The forward kinematics moves by at most ``angle_tol`` times the reach plus
        ``length_tol`` per row: use the exact model for calibration.
        """
        source = self
        if self.source is not None and (angle_tol, length_tol) == (SNAP_ANGLE, SNAP_LENGTH):
            chain, parallel_tol = self.source
            if chain.ideal_model is not None:
                source = converted_chain(chain.idealized(), parallel_tol)
        return source.replace(
            beta=snap_angle(source.beta, angle_tol),
            alpha=snap_angle(source.alpha, angle_tol),
            theta=snap_angle(source.theta, angle_tol),
            d=snap_length(source.d, length_tol),
            r=snap_length(source.r, length_tol),
            y=snap_length(source.y, length_tol),
            base_frame=self.base_frame,
            tool_frame=self.tool_frame,
        )

    @property
    def antecedent(self) -> np.ndarray:
        """Row each row is placed from, ``k - 1`` (-1 for row 0), as a tree's antecedents."""
        return np.arange(-1, self.n + 1)

    @property
    def tool_rows(self) -> tuple[int, ...]:
        """Rows of the tool frames, ``(n + 1,)``."""
        return (self.n + 1,)

    def tool_frame_of(self, k: int) -> str | None:
        """The tool frame row ``k`` stands for (row n+1), or None (another row)."""
        return self.tool_frame if k == self.n + 1 else None

    def kinematics(self, q: np.ndarray) -> Kinematics:
        """Every frame at every configuration, vectorised over configurations.

        Args:
            q: Joint positions ``(m, n)`` or ``(n,)`` [rad or m].

        Returns:
            The frames (see :class:`Kinematics`).

        Raises:
            InvalidArgumentError: ``q`` has the wrong shape, NaN or values beyond
                :data:`!calib.core.checks.MAX_JOINT_POSITION`.
        """
        q = joint_positions(q, self.n)
        m, rows, n = q.shape[0], self.n + 2, self.n
        # Component-major work arrays (row, ..., configuration): every operation runs along
        # the m configurations, the innermost (contiguous) axis.
        angle, length = offsets = np.repeat(self._offsets, m, axis=2)  # theta_k, r_k
        offsets[:, 1 : n + 1] += q.T * self._gain
        # Frame k = frame k-1 L_k with L_k = Pre_k Rot(z, angle_k) (rows [c p0 + s p1,
        # c p1 - s p0, p2] of Pre_k's columns p_j), built for all rows at once, then one
        # product per row along the chain.
        C, S = np.cos(angle)[:, None], np.sin(angle)[:, None]
        pre = self._pre[..., None]  # (rows, 3, 3, 1)
        local = np.empty((rows, 3, 3, m))
        local[:, :, 0] = C * pre[:, :, 0] + S * pre[:, :, 1]
        local[:, :, 1] = C * pre[:, :, 1] - S * pre[:, :, 0]
        local[:, :, 2] = pre[:, :, 2]
        Rt = np.empty((rows, 3, 3, m))
        Rt[0] = local[0]
        for k in range(1, rows):
            np.einsum("ilm,ljm->ijm", Rt[k - 1], local[k], out=Rt[k])
        # x_mid_k = R_(k-1) Pre_k e_x: the x axis after beta_k and alpha_k
        x_mid = np.empty((rows, 3, m))
        x_mid[0] = self._pre[0][:, 0, None]
        np.einsum("kilm,kl->kim", Rt[:-1], self._pre[1:, :, 0], out=x_mid[1:])
        y_prev = np.empty((rows, 3, m))
        y_prev[0] = _Y_AXIS
        y_prev[1:] = Rt[:-1, :, 1]
        # p_k = p_(k-1) + y_k y_(k-1) + d_k x_mid_k + (r_k + sigma_k q_k) z_k along the chain
        step = self.d[:, None, None] * x_mid + length[:, None] * Rt[:, :, 2]
        has_y = self.y.any()
        if has_y:
            step += self.y[:, None, None] * y_prev
        p = np.cumsum(step, axis=0, out=step)
        q_mid = np.empty((rows, 3, m))
        q_mid[0] = 0.0
        q_mid[1:] = p[:-1]
        if has_y:
            q_mid += self.y[:, None, None] * y_prev
        # Views in the documented (configuration, row, ...) order: transposing them back (as
        # the Jacobians do) gives the contiguous component-major arrays again.
        R = Rt.transpose(3, 0, 1, 2)
        p, y_prev, x_mid, q_mid = (a.transpose(2, 0, 1) for a in (p, y_prev, x_mid, q_mid))
        return Kinematics(R, p, y_prev, x_mid, q_mid)

    def forward(self, q: np.ndarray) -> np.ndarray:
        """Tool frame in the base frame, homogeneous, shape ``(m, 4, 4)``."""
        kin = self.kinematics(q)
        T = np.zeros((kin.R.shape[0], 4, 4))
        T[:, :3, :3] = kin.R[:, -1]
        T[:, :3, 3] = kin.p[:, -1]
        T[:, 3, 3] = 1.0
        return T

    def rows(self) -> list[dict]:
        """The rows as JSON-ready dictionaries (radians, metres), from base to tool.

        ``y`` is zero in a converted model; a calibrated one may carry y1 or y_{n+1}.
        ``sign`` is -1 for a joint traversed backwards, else +1 (fixed rows too).
        """
        out = []
        for k in range(self.n + 2):
            s = int(self.sigma[k])
            out.append(
                {
                    "name": str(k),
                    "joint": self.joint_names[k],
                    "sigma": None if s < 0 else s,
                    "sign": int(self.sign[k]),
                    "beta": float(self.beta[k]),
                    "alpha": float(self.alpha[k]),
                    "d": float(self.d[k]),
                    "theta": float(self.theta[k]),
                    "r": float(self.r[k]),
                    "y": float(self.y[k]),
                }
            )
        return out


RIGID_TOL = 1e-6
"""Largest deviation of a tool rotation from orthonormality accepted by :func:`from_lines`."""


def _checked_lines(points, directions, sigma, tool):
    """The inputs of :func:`from_lines` as checked arrays (unit directions)."""
    s = real_array(sigma, "sigma", (None,))
    n = len(s)
    if n == 0:  # before the points, whose count sigma's length sets
        raise InvalidArgumentError(
            "a chain has at least one joint: sigma (0 revolute or 1 prismatic per joint) is empty"
        )
    if not np.all((s == 0) | (s == 1)):
        raise InvalidArgumentError(f"sigma holds 0 (revolute) or 1 (prismatic), got {s.tolist()}")
    bound = urdf_xml.MAX_COORDINATE
    each = f"one per joint of sigma's {n}"
    p = real_array(points, f"joint points ({each})", (n, 3), bound=bound).reshape(n, 3)
    u = real_array(directions, f"joint directions ({each})", (n, 3)).reshape(n, 3)
    scale = np.max(np.abs(u), axis=1) if n else np.ones(0)
    zero = np.flatnonzero(scale < urdf_xml.MIN_AXIS_NORM)
    if zero.size:
        raise InvalidArgumentError(f"joint direction {int(zero[0]) + 1} is zero: no axis")
    u = u / scale[:, None]
    u = u / np.linalg.norm(u, axis=1)[:, None]
    T = real_array(tool, "the tool pose", (4, 4))
    R = T[:3, :3]
    # np.allclose's tests, written out (the values are finite): |R^T R - I| <= RIGID_TOL, and
    # the last row within 1e-8 + 1e-5 |(0, 0, 0, 1)|.
    rigid = np.abs(R.T @ R - np.eye(3)).max() <= RIGID_TOL and np.linalg.det(R) > 0
    if not rigid or not np.all(np.abs(T[3] - _LAST_ROW) <= 1e-8 + 1e-5 * _LAST_ROW):
        raise InvalidArgumentError("the tool pose must be a rigid homogeneous transform (4, 4)")
    if np.max(np.abs(T[:3, 3])) > bound:
        raise InvalidArgumentError(f"the tool position must be within {bound:g} m")
    return p, u, s.astype(int), T


_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])


def _checked_options(n: int, joint_names, parallel_tol, sign) -> np.ndarray:
    """Check :func:`from_lines`'s options for n joints; the signs ``(n,)`` (default +1)."""
    signs = np.ones(n) if sign is None else real_array(sign, "sign", (n,)).reshape(n)
    if not np.all(np.abs(signs) == 1):
        raise InvalidArgumentError(f"sign holds +1 or -1 per joint, got {signs.tolist()}")
    if joint_names is not None and (
        len(joint_names) != n or not all(isinstance(x, str) for x in joint_names)
    ):
        raise InvalidArgumentError(f"joint_names must be {n} strings, got {joint_names!r:.60}")
    if not (isinstance(parallel_tol, int | float) and 0.0 < parallel_tol < math.pi / 4):
        raise InvalidArgumentError(f"parallel_tol must be in (0, pi/4) rad, got {parallel_tol!r}")
    return signs


def from_lines(
    points: np.ndarray,
    directions: np.ndarray,
    sigma: np.ndarray,
    tool: np.ndarray,
    joint_names: tuple[str, ...] | None = None,
    parallel_tol: float = PARALLEL_TOL,
    sign: np.ndarray | None = None,
) -> MDHModel:
    """Convert joint lines and a tool pose (all in the base frame) to MDH rows.

    Frame choices (documented in docs/reference/conventions.md):
        * z_k is the joint axis as given, so that theta (or r) grows with ``sign_k`` times
          the joint position;
        * x_k is along the common normal to the next axis; its sign makes the offset theta_k
          lie in (-90, 90] degrees, so d may be negative (as in Franka's table);
        * where the next axis is parallel (within ``parallel_tol``), Hayati's beta is used,
          the origin is the foot of the perpendicular from the previous origin (r_k = 0)
          and, where the two lines coincide, x_k keeps the previous direction (theta_k = 0);
        * frame 0 shares z with the base frame (z_{-1}) and frame n+1 is the tool frame.

    Args:
        points: A point of each joint axis ``(n, 3)`` [m].
        directions: Unit direction of each joint axis ``(n, 3)``.
        sigma: 0 revolute, 1 prismatic ``(n,)``.
        tool: Tool pose ``(4, 4)`` in the base frame.
        joint_names: Names for the joint rows.
        parallel_tol: Parallel-axis tolerance [rad].
        sign: Per joint, +1 (default) for a joint whose position moves the tool side along
            its direction, -1 for a joint traversed backwards (the tool side moves against
            it); the rows carry it (:attr:`MDHModel.sign`), the geometry does not depend on it.

    Returns:
        The model; its forward kinematics equals the input geometry.

    Raises:
        InvalidArgumentError: Arrays of the wrong shape, not finite, coordinates beyond
            :data:`~.urdf_xml.MAX_COORDINATE`, a zero direction, sigma empty or not 0 or 1, a
            sign not +1 or -1, a tool that is not a rigid transform, or a tolerance outside
            (0, pi/4).
    """
    return _converted_lines(points, directions, sigma, tool, joint_names, parallel_tol, sign)


def _converted_lines(
    points, directions, sigma, tool, joint_names, parallel_tol, sign, **fields
) -> MDHModel:
    """:func:`from_lines`, with other fields of the model (frame names, source) given."""
    points, directions, sigma, tool = _checked_lines(points, directions, sigma, tool)
    n = len(sigma)
    signs = _checked_options(n, joint_names, parallel_tol, sign)
    # The directions once more divided by their norm, as the conversion always did.
    directions = directions / np.linalg.norm(directions, axis=1)[:, None]
    beta, alpha, d, theta, r, parallel, coincident = line_rows(
        points, directions, tool, parallel_tol
    )
    sig = np.concatenate([[-1], sigma, [-1]])
    names = (None, *(joint_names or tuple(str(i + 1) for i in range(n))), None)
    row_sign = np.concatenate([[1], signs.astype(int), [1]])
    y = np.zeros(n + 2)
    return MDHModel(
        sig, beta, alpha, d, theta, r, y, names, parallel, coincident, sign=row_sign, **fields
    )


def from_chain(
    chain: Chain, parallel_tol: float = PARALLEL_TOL, *, zero: tuple | None = None
) -> MDHModel:
    """Convert a Pinocchio chain to its MDH model (base frame = frame -1).

    Args:
        chain: The serial chain.
        parallel_tol: Parallel-axis tolerance [rad].
        zero: The chain's :meth:`~calib.Chain.zero_frames`, when already computed.

    Returns:
        The MDH model, whose forward kinematics equals Pinocchio's.
    """
    if not isinstance(chain, Chain):
        raise InvalidArgumentError(
            f"from_chain converts a Chain (see load_chain), got {type(chain).__name__}"
        )
    return _chain_model(chain, parallel_tol, zero, source=(chain, parallel_tol))


def converted_chain(chain: Chain, parallel_tol: float) -> MDHModel:
    """The MDH model of a chain from its joint lines (no idealisation, no cache)."""
    return _chain_model(chain, parallel_tol)


def _chain_model(chain: Chain, parallel_tol: float, zero=None, **fields) -> MDHModel:
    """:func:`converted_chain`, with other fields of the model (``source``) given."""
    points, dirs, tool = chain.joint_lines(zero)
    frames = {"base_frame": chain.base_frame, "tool_frame": chain.tool_frame, **fields}
    return _converted_lines(
        points, dirs, chain.sigma, tool, chain.joint_names, parallel_tol, chain.sign, **frames
    )


def frames_at_zero(mdh: MDHModel) -> np.ndarray:
    """Pose of every MDH frame 0..n+1 in frame -1 at the zero configuration ``(n+2, 4, 4)``."""
    kin = mdh.kinematics(np.zeros((1, mdh.n)))
    T = np.zeros((mdh.n + 2, 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = kin.R[0], kin.p[0], 1.0
    return T


def in_chart_of(model: MDHModel, reference: MDHModel) -> MDHModel:
    """``model``'s robot in ``reference``'s choice of x axes: the same frames up to a half turn.

    :func:`from_lines` turns x_k so that theta_k lies in (-90, 90] degrees; a nominal offset
    of 90 degrees (a URDF's pitch joint after a yaw one) moved a little past it on a
    calibrated robot turns x_k, and with it every later x axis, by a half turn: the rows are
    right but no longer comparable with the nominal's (theta 180 degrees apart, alpha and d of
    the other sign). Here frame k (k = 0..n; the tool's is fixed) is turned back where its
    theta lies more than 90 degrees from the reference's, frames 0..k-1 already matched:
    theta_k and theta_{k+1} gain pi, and beta, alpha, d and y of row k+1 change sign (the
    frames after k and the kinematics are unchanged). Rows the reference places with
    Hayati's beta (parallel axes) are placed so here too, whatever their tilt.

    Raises:
        InvalidArgumentError: The models have different numbers of rows.
    """
    if reference.n != model.n:
        why = f"in_chart_of: {model.n} joints against a reference of {reference.n}"
        raise InvalidArgumentError(why)
    beta_rows = reference.parallel | model.parallel
    if not np.array_equal(beta_rows, model.parallel):
        model = _with_beta_rows(model, beta_rows)
    theta, later = model.theta.copy(), {a: getattr(model, a).copy() for a in _FLIPPED}
    for k in range(model.n + 1):
        if abs(_wrapped(theta[k] - reference.theta[k])) > math.pi / 2:
            theta[k : k + 2] = _wrapped(theta[k : k + 2] + math.pi)
            for values in later.values():
                values[k + 1] = 0.0 - values[k + 1]  # no -0.0
    if all(np.array_equal(a, getattr(model, n)) for n, a in [("theta", theta), *later.items()]):
        return model
    return model.replace(theta=theta, **later)


def _with_beta_rows(model: MDHModel, beta_rows: np.ndarray) -> MDHModel:
    """``model``'s robot converted again, Hayati's beta on ``beta_rows`` (``(n+2,)`` bool).

    A nominal pair of parallel axes tilted past :data:`PARALLEL_TOL` by a calibration (the
    TIAGo's torso lift and first arm joint: 0.02 rad) is converted along a common normal
    metres away; the nominal's beta row keeps it beside the nominal's.
    """
    T = frames_at_zero(model)  # frame k's z and origin lie on line k (k = 1..n)
    beta, alpha, d, theta, r, parallel, coincident = line_rows(
        T[1:-1, :3, 3], T[1:-1, :3, 2], T[-1], PARALLEL_TOL, beta_rows
    )
    rows = {"beta": beta, "alpha": alpha, "d": d, "theta": theta, "r": r}
    return model.replace(**rows, y=np.zeros(model.n + 2), parallel=parallel, coincident=coincident)


_FLIPPED = ("beta", "alpha", "d", "y")
"""Row k+1's parameters that change sign when frame k turns a half turn about z_k."""


def _wrapped(angle):
    """``angle`` [rad] in [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % (2 * math.pi) - math.pi
