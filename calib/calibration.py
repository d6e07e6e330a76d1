"""Identification of the base parameters from measurements: nonlinear least squares.

The unknowns are the b base parameters (the identifiable combinations kept by
:func:`~calib.identifiability.analyze_model` at the measured configurations, on the nominal
model with its URDF round-off removed, as ``calib analyze`` does): ``x = dX1 + B dX2``, dX the
errors of the standard parameters. The fit itself uses the exact nominal model. Frame -1 of
the model is the measurement frame, so the base rows (0 and 1) absorb the measurement-frame
-> robot-base transform.

A base correction x changes the standard parameters by the minimum-norm ``dX = G x`` with
``[I B] G = I`` (norm of the columns of W at the nominal model: an angle weighs like the
displacement it causes). A base parameter that stands alone moves only itself; a regrouped
one (``theta1 + theta0``) is shared by the parameters it stands for. To first order every
right inverse G gives the same model; beyond it, keeping the regrouped parameters at nominal
(G a selection) can be far off: where the regrouping coefficients are large (the marker of a
position measurement: ``theta6 - 182 r6 + ...`` on a UR5 with the marker at (0.05, 0.02, 0.1)
m) a 1 mm error needs a 0.2 rad correction, and in 10 to 30 % of simulated campaigns the
base-only model could not represent the measured robot at all (the fit stalled at 0.1-1 mm).

Residuals (measured - model) are stacked configuration by configuration:

* position rows ``x, y, z`` [m]: measured point - model point;
* for pose data, orientation rows ``rx, ry, rz`` [rad]: the rotation vector of
  ``R_meas R_model^T`` in the base frame, multiplied by ``orientation_weight`` [m/rad] so that
  every row is in metres. The default, 1 m/rad, weighs 1 mrad like 1 mm; choose the ratio of
  your instrument's position noise to its orientation noise.

The problem is solved by Levenberg-Marquardt (MINPACK through ``scipy.optimize.least_squares``)
with the analytic Jacobian ``W(dX) G`` (:func:`~calib.jacobian.identification_jacobian`; the
orientation rows are mapped through the inverse right Jacobian of SO(3), exact away from zero
residual), starting from the nominal model. At the solution, with J the weighted Jacobian (r
rows, b columns): sigma_hat^2 = RSS / (r - b), cov = sigma_hat^2 (J^T J)^-1, and the
condition number is that of J with its columns scaled to unit norm.

Checks of the data: the rank at the measured configurations is compared with the rank at
generic (random) configurations of the chain; a lower one means the configurations do not
excite every base parameter, and the result carries a warning.

A point measured on the last joint axis of the nominal model (position only, e.g. the tool
origin of a UR5): there the point's offset from that axis and the axis direction cannot be
identified (4R + 2P + 1 base parameters instead of 4R + 2P + 3), yet a real robot's point
is off the axis, and the nominal base set cannot follow it (residuals of micrometres to
millimetres, noise-free). After the first fit the base set is re-selected at the calibrated
geometry; if it is larger, the fit is repeated from the nominal model with that base set
and its minimum-norm lift, and kept if it converged and lowers the residual significantly
(F test of the nested fits, p < ``REFIT_P``): noise-free campaigns are then reproduced
exactly. Either way the result carries a warning: the offset and the axis direction are
poorly determined unless the point is well off the axis; measure a marker off it.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin
import scipy.linalg

from .exceptions import ConvergenceError, DataError, InvalidArgumentError
from .identifiability import DEFAULT_CONFIGS, Identifiability, analyze_model
from .jacobian import ROW_NAMES, Measurement, identification_jacobian, measured_point
from .mdh import Kinematics, MDHModel, from_chain
from .measurements import Measurements, check_against_chain
from .parameters import ParameterSet, parameter_set
from .robot import Chain
from .so3 import inverse_right_jacobian, rotation_vector

DEFAULT_PARAMS = "complete"
"""Parameter set of a calibration (the paper's set misses errors where lines coincide)."""

DEFAULT_ORIENTATION_WEIGHT = 1.0
"""Weight of the orientation rows [m/rad]: 1 mrad of orientation error counts as 1 mm."""

DEFAULT_MAX_ITERATIONS = 100
"""Most residual evaluations of the solver before it gives up (an iteration takes one or more)."""

ILL_CONDITIONED = 1e6
"""Condition number of the scaled W_b above which a result carries a warning."""

TOLERANCE = 1e-10
"""Relative tolerance on the cost, the step and the gradient (scipy's ftol, xtol, gtol)."""

REFIT_P = 1e-3
"""Significance of the F test under which the refit of a point on the last axis is kept."""


@dataclass(frozen=True)
class ResidualStats:
    """Residuals measured - model of a set of measurements.

    Attributes:
        axes: Names of the residual rows: ``x, y, z`` and, for poses, ``rx, ry, rz``.
        rms: Root mean square per axis [m for x, y, z; rad for rx, ry, rz].
        position_rms: sqrt(mean |e_p|^2) of the 3D position error [m].
        position_max: Largest 3D position error [m].
        orientation_rms: sqrt(mean |e_r|^2) of the rotation error [rad], or None.
        orientation_max: Largest rotation error [rad], or None.
    """

    axes: tuple[str, ...]
    rms: tuple[float, ...]
    position_rms: float
    position_max: float
    orientation_rms: float | None = None
    orientation_max: float | None = None

    @staticmethod
    def of(residual: np.ndarray) -> ResidualStats:
        """Statistics of residuals ``(m, 3)`` or ``(m, 6)`` (position then rotation vector)."""
        residual = np.asarray(residual, dtype=float)
        rms = np.sqrt(np.mean(residual**2, axis=0))
        pos = np.linalg.norm(residual[:, :3], axis=1)
        rot = np.linalg.norm(residual[:, 3:6], axis=1) if residual.shape[1] == 6 else None
        return ResidualStats(
            axes=ROW_NAMES[: residual.shape[1]],
            rms=tuple(float(v) for v in rms),
            position_rms=float(np.sqrt(np.mean(pos**2))),
            position_max=float(np.max(pos)),
            orientation_rms=None if rot is None else float(np.sqrt(np.mean(rot**2))),
            orientation_max=None if rot is None else float(np.max(rot)),
        )

    def to_dict(self) -> dict:
        """JSON-ready form (metres, radians)."""
        return {
            "rms": {a: _finite(v) for a, v in zip(self.axes, self.rms, strict=True)},
            "position_rms": _finite(self.position_rms),
            "position_max": _finite(self.position_max),
            "orientation_rms": _finite(self.orientation_rms),
            "orientation_max": _finite(self.orientation_max),
        }


def model_residuals(mdh: MDHModel, data: Measurements, marker=None) -> np.ndarray:
    """Residuals measured - model, ``(m, 3)`` [m] or, for poses, ``(m, 6)`` [m, rad].

    Args:
        mdh: The model (frame -1 = the measurement frame).
        data: The measurements.
        marker: Measured point in the tool frame [m] (default: the tool origin).
    """
    kin = mdh.kinematics(data.q)
    return _residuals(kin, data, Measurement.of(data.measure, marker).marker_array)


def _residuals(kin: Kinematics, data: Measurements, marker: np.ndarray) -> np.ndarray:
    e_pos = data.position - measured_point(kin, marker)
    if data.quaternion is None:
        return e_pos
    e_rot = rotation_vector(data.rotations @ np.swapaxes(kin.R[:, -1], 1, 2))
    return np.hstack([e_pos, e_rot])


def row_weights(measurement: Measurement, orientation_weight: float) -> np.ndarray:
    """Weights of the residual rows of one configuration.

    1 for x, y, z and the orientation weight [m/rad] for rx, ry, rz.
    """
    w = orientation_weight
    return np.array([1.0, 1.0, 1.0, w, w, w])[list(measurement.rows)]


class _Problem:
    """Weighted residual model - measured and its Jacobian, as functions of the base values."""

    def __init__(
        self,
        nominal: MDHModel,
        params: ParameterSet,
        lift: np.ndarray,
        data: Measurements,
        measurement: Measurement,
        weight: float,
    ):
        self.nominal, self.params, self.lift = nominal, params, lift
        self.data, self.measurement = data, measurement
        self.marker = measurement.marker_array
        self.k = len(measurement.rows)
        self.row_weight = row_weights(measurement, weight)
        self._x: np.ndarray | None = None
        self._state: tuple[MDHModel, Kinematics, np.ndarray] | None = None

    def state(self, x: np.ndarray) -> tuple[MDHModel, Kinematics, np.ndarray]:
        """Model, kinematics and residual measured - model at base values x (cached)."""
        if self._x is None or not np.array_equal(x, self._x):
            mdh = self.params.apply(self.nominal, self.lift @ x)
            kin = mdh.kinematics(self.data.q)
            self._state = (mdh, kin, _residuals(kin, self.data, self.marker))
            self._x = np.array(x, dtype=float)
        return self._state

    def fun(self, x: np.ndarray) -> np.ndarray:
        """Weighted residuals model - measured, configuration-major ``(m k,)``."""
        return (-self.state(x)[2] * self.row_weight).ravel()

    def jac(self, x: np.ndarray) -> np.ndarray:
        """Jacobian of :meth:`fun`, ``(m k, b)``."""
        mdh, kin, res = self.state(x)
        W = identification_jacobian(mdh, self.params, self.data.q, self.measurement, kin=kin)
        J = (W @ self.lift).reshape(self.data.m, self.k, -1)
        if self.k == 6:
            J[:, 3:] = inverse_right_jacobian(res[:, 3:]) @ J[:, 3:]
        return (J * self.row_weight[None, :, None]).reshape(-1, J.shape[2])


def minimum_norm_lift(analysis: Identifiability, scale: np.ndarray) -> np.ndarray:
    """Map base values x to the smallest standard-parameter errors dX with ``[I B] dX = x``.

    Args:
        analysis: Base set and regrouping of the standard set ``analysis.params``.
        scale: Weight of each standard parameter in the norm (e.g. the norms of W's columns);
            zero weights (parameters with no effect) are taken as one.

    Returns:
        G of shape ``(len(params), b)``: ``dX = G x`` (in the set's order).
    """
    names = analysis.params.names
    index = {n: i for i, n in enumerate(names)}
    b = analysis.n_base
    regroup = np.zeros((b, len(names)))  # base values = regroup @ dX
    regroup[np.arange(b), [index[n] for n in analysis.base]] = 1.0
    if analysis.others:
        regroup[:, [index[n] for n in analysis.others]] = analysis.B
    d = np.where(np.asarray(scale, dtype=float) > 0, scale, 1.0)
    A = regroup / d  # regroup D^-1
    return (A.T @ np.linalg.solve(A @ A.T, np.eye(b))) / d[:, None]


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Result of a calibration.

    Attributes:
        robot: Robot name.
        chain: The nominal chain (its URDF is what :mod:`calib.urdf_export` edits).
        data: The measurements used.
        measurement: Measured rows and marker.
        analysis: Identifiability of the nominal model (URDF round-off removed) at the
            measured configurations: base set, regrouping B, standard set ``params``. After
            a refit (``refitted``), that of the first fit's model instead.
        lift: G, the map from base values to standard-parameter errors ``(k, b)``.
        nominal: The nominal MDH model (frame -1 = the URDF base frame).
        calibrated: The calibrated MDH model (frame -1 = the measurement frame).
        estimate: Identified value of each base parameter, ``dX1 + B dX2`` [rad or m], in
            the order of ``analysis.base``.
        corrections: Errors of the standard parameters applied to the nominal model,
            ``G @ estimate`` (in ``analysis.params`` order) [rad or m].
        std: Standard deviation of each base value [rad or m] (NaN when r = b).
        covariance: Covariance of the base values ``(b, b)``.
        sigma: Estimated noise of a (weighted) residual row sigma_hat [m].
        condition: Condition number of the weighted W_b with unit-norm columns.
        before: Residuals of the nominal model.
        after: Residuals of the calibrated model.
        iterations: Levenberg-Marquardt iterations (Jacobian evaluations; of both fits after a
            refit).
        evaluations: Residual evaluations (of both fits after a refit).
        converged: The solver met a convergence criterion.
        status: Solver status (scipy's ``least_squares`` status).
        message: Solver message.
        orientation_weight: Weight of the orientation rows [m/rad].
        measurement_to_base: Pose of the URDF base frame in the measurement frame ``(4, 4)``.
        warnings: Reasons to be careful with the result.
        timings_ms: Time of each stage [ms].
        refitted: The base set was re-selected at the first fit's geometry and the fit
            repeated (a position measured on the last joint axis of the nominal model).
    """

    robot: str
    chain: Chain
    data: Measurements
    measurement: Measurement
    analysis: Identifiability
    lift: np.ndarray
    nominal: MDHModel
    calibrated: MDHModel
    estimate: np.ndarray
    corrections: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    sigma: float
    condition: float
    before: ResidualStats
    after: ResidualStats
    iterations: int
    evaluations: int
    converged: bool
    status: int
    message: str
    orientation_weight: float
    measurement_to_base: np.ndarray
    warnings: tuple[str, ...] = ()
    timings_ms: dict[str, float] = field(default_factory=dict)
    refitted: bool = False

    @property
    def n_base(self) -> int:
        """Number of identified base parameters b."""
        return self.analysis.n_base

    @property
    def base_names(self) -> tuple[str, ...]:
        """Names of the base parameters (each named after the standard parameter kept)."""
        return self.analysis.base

    @property
    def n_rows(self) -> int:
        """Number of scalar equations r = m * rows per configuration."""
        return self.data.m * len(self.measurement.rows)

    def check(self) -> CalibrationResult:
        """Return self if the fit converged.

        Raises:
            ConvergenceError: The fit did not converge.
        """
        if not self.converged:
            raise ConvergenceError(
                f"the fit did not converge after {self.iterations} iterations "
                f"(status {self.status}: {self.message})"
            )
        return self

    def points(self, q: np.ndarray) -> np.ndarray:
        """Measured point predicted by the calibrated model, measurement frame ``(m, 3)`` [m]."""
        return measured_point(self.calibrated.kinematics(q), self.measurement.marker_array)

    def to_dict(self) -> dict:
        """JSON-ready report (radians, metres); undefined or infinite numbers are None."""
        T = self.measurement_to_base
        regrouping = self.analysis.regrouping()
        params = self.analysis.params
        report = {
            "robot": self.robot,
            "urdf": str(self.chain.urdf_path),
            "data": self.data.source,
            "base_frame": self.chain.base_frame,
            "tool_frame": self.chain.tool_frame,
            "measure": self.measurement.label,
            "marker": list(self.measurement.marker),
            "params": self.analysis.params.label,
            "configs": self.data.m,
            "rows": self.n_rows,
            "n_base": self.n_base,
            "refitted": self.refitted,
            "converged": self.converged,
            "status": self.status,
            "message": self.message,
            "iterations": self.iterations,
            "evaluations": self.evaluations,
            "orientation_weight": self.orientation_weight,
            "residuals": {"before": self.before.to_dict(), "after": self.after.to_dict()},
            "sigma": _finite(self.sigma),
            "condition_number": _finite(self.condition),
            "base_parameters": [
                {"name": n, "stands_for": regrouping[n], "value": _finite(v), "std": _finite(s)}
                for n, v, s in zip(self.base_names, self.estimate, self.std, strict=True)
            ],
            "standard_corrections": {
                n: _finite(v) for n, v in zip(params.names, self.corrections, strict=True)
            },
            "measurement_to_base": {
                "xyz": [_finite(v) for v in T[:3, 3]],
                "rpy": [_finite(v) for v in pin.rpy.matrixToRpy(T[:3, :3])],
                "matrix": T.tolist(),
            },
            "mdh_nominal": self.nominal.rows(),
            "mdh_calibrated": self.calibrated.rows(),
            "warnings": list(self.warnings),
            "timings_ms": dict(self.timings_ms),
        }
        # Every float, the MDH rows and the matrix included: JSON has no inf or NaN.
        return _finite_tree(report)


def _finite(x: float | None) -> float | None:
    """``float(x)``, or None for None, an infinity or NaN."""
    return float(x) if x is not None and math.isfinite(x) else None


def _finite_tree(value):
    """A copy of a JSON-ready tree with every non-finite float replaced by None."""
    if isinstance(value, dict):
        return {k: _finite_tree(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_tree(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return _finite(value)
    return value


def frames_at_zero(mdh: MDHModel) -> np.ndarray:
    """Pose of every MDH frame 0..n+1 in frame -1 at the zero configuration ``(n+2, 4, 4)``."""
    kin = mdh.kinematics(np.zeros((1, mdh.n)))
    T = np.zeros((mdh.n + 2, 4, 4))
    T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = kin.R[0], kin.p[0], 1.0
    return T


def measurement_to_base(nominal: MDHModel, calibrated: MDHModel) -> np.ndarray:
    """Pose of the URDF base frame in the measurement frame ``(4, 4)``.

    The calibrated URDF keeps the nominal placement of joint 1 in its base link, so the base
    part of the calibration (rows 0 and 1) becomes
    ``T = T_cal(-1 -> 1, q=0) T_nom(-1 -> 1, q=0)^-1``, with
    ``T @ FK_urdf_calibrated(q) == FK_mdh_calibrated(q)``.
    """
    return frames_at_zero(calibrated)[1] @ np.linalg.inv(frames_at_zero(nominal)[1])


def _covariance(J: np.ndarray, rss: float) -> tuple[np.ndarray, float]:
    """Covariance sigma_hat^2 (J^T J)^-1 and sigma_hat, through the R factor of J.

    A singular J (no finite covariance) gives infinite variances.
    """
    r, b = J.shape
    sigma = math.sqrt(rss / (r - b)) if r > b else math.nan
    R = scipy.linalg.qr(J, mode="r", check_finite=False)[0][:b]
    if not np.all(np.isfinite(R)) or np.any(np.diag(R) == 0):
        return np.full((b, b), math.inf), sigma
    Rinv = scipy.linalg.solve_triangular(R, np.eye(b), check_finite=False)
    return sigma**2 * (Rinv @ Rinv.T), sigma


def _condition(J: np.ndarray) -> float:
    norms = np.linalg.norm(J, axis=0)
    if np.any(norms == 0):
        return math.inf
    s = np.linalg.svd(J / norms, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else math.inf


def _generic_rank(
    nominal: MDHModel, pset: ParameterSet, measurement: Measurement, chain: Chain
) -> int:
    """Base parameters of the set at generic (random) configurations of the chain."""
    q = chain.random_configurations(DEFAULT_CONFIGS, 0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return analyze_model(nominal.idealized(), pset, measurement, q).n_base


def _lift_at(
    mdh: MDHModel,
    analysis: Identifiability,
    data: Measurements,
    measurement: Measurement,
    weight: float,
) -> np.ndarray:
    """Minimum-norm lift G of a base set, columns of the weighted W at ``mdh`` as the norm."""
    W = identification_jacobian(mdh, analysis.params, data.q, measurement)
    W *= np.tile(row_weights(measurement, weight), data.m)[:, None]
    return minimum_norm_lift(analysis, np.linalg.norm(W, axis=0))


def _solve(problem: _Problem, b: int, max_iterations: int):
    """Levenberg-Marquardt from the nominal model (x = 0): scipy's OptimizeResult."""
    import scipy.optimize  # here: importing it costs every calib command 0.1 s at start-up

    return scipy.optimize.least_squares(
        problem.fun,
        np.zeros(b),
        jac=problem.jac,
        method="lm",
        ftol=TOLERANCE,
        xtol=TOLERANCE,
        gtol=TOLERANCE,
        max_nfev=max_iterations,
    )


def _significant(rss_small: float, rss_large: float, extra: int, dof: int) -> bool:
    """Whether ``extra`` more parameters lower the RSS significantly (F test, p < REFIT_P).

    With F = ((RSS_small - RSS_large) / extra) / (RSS_large / dof), the p-value
    P(F(extra, dof) > F) is the regularised incomplete beta I_x(dof/2, extra/2) at
    x = RSS_large / RSS_small.
    """
    import scipy.special

    if not (rss_small > 0 and 0 <= rss_large < rss_small and extra > 0 and dof > 0):
        return False
    p = float(scipy.special.betainc(dof / 2, extra / 2, rss_large / rss_small))
    return p < REFIT_P


def _counts(sol) -> tuple[int, int]:
    """Iterations (Jacobian evaluations) and residual evaluations of a solver result."""
    njev = sol.njev if sol.njev is not None else sol.nfev
    return int(njev), int(sol.nfev)


def _refit(
    problem: _Problem,
    sol,
    analysis: Identifiability,
    weight: float,
    max_iterations: int,
    robot: str,
) -> tuple[bool, tuple] | None:
    """Refit a point measured on the last axis with the base set of the first fit's geometry.

    The base set and its minimum-norm lift are taken at the model of the first fit (whose
    point is off the axis when the data say so); the fit restarts from the nominal model.

    Args:
        problem: The first fit's problem (nominal base set).
        sol: The first fit's solver result (converged or not: it only gives a geometry).
        analysis: The first fit's base set.
        weight: Weight of the orientation rows [m/rad].
        max_iterations: Most residual evaluations of the refit.
        robot: Robot name, for the analysis.

    Returns:
        None if there is nothing to refit (non-finite first fit, no larger base set, or no
        residual left to test it); else whether the refit is kept (converged, finite, and
        a significantly lower residual: :func:`_significant`) and its analysis, lift,
        problem and solver result.
    """
    data, measurement = problem.data, problem.measurement
    f = problem.fun(sol.x)
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(sol.x))):
        return None
    first = problem.state(sol.x)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        at_first = analyze_model(first, problem.params, measurement, data.q, robot=robot)
    b, b2, r = analysis.n_base, at_first.n_base, f.size
    if not b < b2 < r:
        return None
    lift = _lift_at(first, at_first, data, measurement, weight)
    refit = _Problem(problem.nominal, problem.params, lift, data, measurement, weight)
    sol2 = _solve(refit, b2, max_iterations)
    f2 = refit.fun(sol2.x)
    kept = bool(
        sol2.status > 0
        and np.all(np.isfinite(f2))
        and np.all(np.isfinite(sol2.x))
        and _significant(float(f @ f), float(f2 @ f2), b2 - b, r - b2)
    )
    return kept, (at_first, lift, refit, sol2)


def _max_iterations(value) -> int:
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, np.integer, float, np.floating))
        or not math.isfinite(value)
        or int(value) != value
        or int(value) < 1
    ):
        raise InvalidArgumentError(f"max_iterations must be an integer >= 1, got {value!r}")
    return int(value)


def calibrate(
    chain: Chain,
    data: Measurements,
    marker=None,
    params: str = DEFAULT_PARAMS,
    orientation_weight: float = DEFAULT_ORIENTATION_WEIGHT,
    max_iterations: int = DEFAULT_MAX_ITERATIONS,
) -> CalibrationResult:
    """Identify the base parameters of a chain from measurements.

    Args:
        chain: The nominal chain.
        data: Measurements of it (joints in chain order; see :mod:`calib.measurements`).
        marker: Measured point in the tool frame, 3 numbers [m] (default: the tool origin).
        params: Standard parameter set: ``complete`` (default) or ``paper``.
        orientation_weight: Weight of the orientation rows [m/rad] (pose data only).
        max_iterations: Most residual evaluations of the solver (each Levenberg-Marquardt
            iteration takes one or more), per fit.

    Returns:
        The result; check ``converged`` (or call :meth:`CalibrationResult.check`) and
        ``warnings``: configurations that identify fewer base parameters than generic ones
        would, a point measured on the last joint axis (see the module docstring: the fit
        is then repeated with the base set of the calibrated geometry), ill-conditioning.

    Raises:
        DataError: The data do not belong to the chain (joints, limits), or there are fewer
            equations than base parameters.
        InvalidArgumentError: A bad argument.
    """
    t0 = time.perf_counter()
    check_against_chain(data, chain)
    weight = float(orientation_weight)
    if not (math.isfinite(weight) and weight > 0):
        raise InvalidArgumentError(
            f"the orientation weight must be a finite number > 0 [m/rad], "
            f"got {orientation_weight!r}"
        )
    max_iterations = _max_iterations(max_iterations)
    measurement = Measurement.of(data.measure, marker)
    nominal = from_chain(chain)
    pset = parameter_set(nominal, params)
    k = len(measurement.rows)
    r = data.m * k
    notes: list[str] = []
    # The rank generic configurations give (cheap): the measured ones should reach it.
    needed = _generic_rank(nominal, pset, measurement, chain)
    if r < needed:
        raise DataError(
            data.source,
            f"{data.m} measurement rows give {r} equations, fewer than the {needed} base "
            f"parameters of {chain.name} ({data.measure}, {pset.label} set): at least "
            f"{math.ceil(needed / k)} rows are needed, many more for a useful fit",
        )
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        analysis = analyze_model(nominal.idealized(), pset, measurement, data.q, robot=chain.name)
    for w in caught:
        notes.append(str(w.message))
    if analysis.n_base < needed:
        notes.append(
            f"the measured configurations identify only {analysis.n_base} of the {needed} "
            f"base parameters of {chain.name} ({data.measure}, {pset.label} set) that varied "
            f"configurations identify: measure more varied configurations"
        )
    b = analysis.n_base
    lift = _lift_at(nominal, analysis, data, measurement, weight)
    problem = _Problem(nominal, pset, lift, data, measurement, weight)
    t1 = time.perf_counter()
    before = ResidualStats.of(problem.state(np.zeros(b))[2])
    sol = _solve(problem, b, max_iterations)
    t2 = time.perf_counter()
    iterations, evaluations = _counts(sol)
    on_axis = measurement.rows == (0, 1, 2) and analysis.on_last_axis
    refitted = False
    if on_axis:
        tried = _refit(problem, sol, analysis, weight, max_iterations, chain.name)
        if tried is not None:
            refitted, (analysis2, lift2, problem2, sol2) = tried
            more_iterations, more_evaluations = _counts(sol2)
            iterations += more_iterations
            evaluations += more_evaluations
            if refitted:
                analysis, lift, problem, sol = analysis2, lift2, problem2, sol2
                b = analysis.n_base
    t3 = time.perf_counter()
    if on_axis:
        notes.append(
            "the measured point lies on the last joint axis of the nominal model: its offset "
            "from that axis and the axis direction cannot be identified there, and a real "
            "robot's point is off the axis, so "
            + (
                f"the fit was repeated with the {b} base parameters of the calibrated geometry; "
                f"that offset and direction are poorly determined unless the point is well off "
                f"the axis"
                if refitted
                else "the fit cannot follow it exactly"
            )
            + "; measure a marker off the axis (--marker)"
        )
    x = sol.x
    calibrated, _, res = problem.state(x)
    J = problem.jac(x)
    f = problem.fun(x)
    finite = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(f)))
    converged = bool(sol.status > 0 and finite)
    cov, sigma = _covariance(J, float(f @ f))
    if r == b:
        notes.append(
            "as many equations as base parameters: no residual is left to estimate "
            "the noise, the standard deviations are undefined"
        )
    condition = _condition(J)
    if condition > ILL_CONDITIONED:
        notes.append(
            f"the scaled W_b is ill-conditioned at the solution (condition number "
            f"{condition:.3g}): some base values are poorly determined by these data"
        )
    t4 = time.perf_counter()
    return CalibrationResult(
        robot=chain.name,
        chain=chain,
        data=data,
        measurement=measurement,
        analysis=analysis,
        lift=lift,
        nominal=nominal,
        calibrated=calibrated,
        estimate=x,
        corrections=lift @ x,
        std=np.sqrt(np.diag(cov)),
        covariance=cov,
        sigma=sigma,
        condition=condition,
        before=before,
        after=ResidualStats.of(res),
        iterations=iterations,
        evaluations=evaluations,
        converged=converged,
        status=int(sol.status),
        message=str(sol.message) if finite else "non-finite parameters or residuals",
        orientation_weight=weight,
        measurement_to_base=measurement_to_base(nominal, calibrated),
        warnings=tuple(notes),
        timings_ms={
            "setup": 1e3 * (t1 - t0),
            "fit": 1e3 * (t2 - t1),
            "refit": 1e3 * (t3 - t2),
            "statistics": 1e3 * (t4 - t3),
        },
        refitted=refitted,
    )


def _mm(x: float | None) -> str:
    return "-" if x is None else f"{1e3 * x:.4g}"


def calibration_text(result: CalibrationResult) -> str:
    """Human-readable summary: residuals before/after [mm, mrad], base values, base transform."""
    r = result
    where = (
        f" at marker ({', '.join(f'{v:g}' for v in r.measurement.marker)}) m"
        if any(r.measurement.marker)
        else ""
    )
    lines = [
        f"{r.robot}: {r.chain.base_frame} -> {r.chain.tool_frame}, {r.data.m} configurations, "
        f"measure {r.measurement.label}{where}, {r.analysis.params.label} set, "
        f"{r.n_base} base parameters, {r.n_rows} equations",
    ]
    if r.converged:
        lines.append(f"converged in {r.iterations} iterations ({r.message})")
    else:
        lines.append(
            f"NOT CONVERGED after {r.iterations} iterations (status {r.status}: {r.message})"
        )
    pose = r.after.orientation_rms is not None
    header = [
        "residuals",
        *(f"{a}[{'mm' if i < 3 else 'mrad'}]" for i, a in enumerate(r.after.axes)),
        "|p| rms",
        "|p| max",
    ]
    if pose:
        header += ["|r| rms", "|r| max"]
    rows = []
    for label, st in (("before", r.before), ("after", r.after)):
        row = [label, *(_mm(v) for v in st.rms), _mm(st.position_rms), _mm(st.position_max)]
        if pose:
            row += [_mm(st.orientation_rms), _mm(st.orientation_max)]
        rows.append(row)
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(header)]
    for row in (header, *rows):
        lines.append("  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)))
    lines.append(
        f"sigma_hat = {_mm(r.sigma) if math.isfinite(r.sigma) else 'undefined'} mm (weighted "
        f"rows), condition number of the scaled W_b = {r.condition:.4g}"
    )
    lines.append("base parameters (value +- std; mm for lengths, mrad for angles):")
    regrouping = r.analysis.regrouping()
    width = max(len(n) for n in r.base_names)
    for name, v, s in zip(r.base_names, r.estimate, r.std, strict=True):
        lines.append(
            f"  {name:>{width}} = {_mm(v):>9} +- {_mm(s) if math.isfinite(s) else '-':<8}"
            f"  ({regrouping[name]})"
        )
    T = r.measurement_to_base
    rpy = pin.rpy.matrixToRpy(T[:3, :3])
    lines.append(
        "measurement frame -> URDF base frame: xyz "
        f"[{', '.join(f'{v:.6f}' for v in T[:3, 3])}] m, rpy "
        f"[{', '.join(f'{v:.6f}' for v in rpy)}] rad"
    )
    lines += [f"warning: {w}" for w in r.warnings]
    return "\n".join(lines)
