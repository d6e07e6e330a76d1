"""The nonlinear least-squares fit of an error model, and its statistics."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar, runtime_checkable

import numpy as np
import scipy.linalg

__all__ = [
    "TOLERANCE",
    "Fit",
    "FitModel",
    "FitState",
    "Problem",
    "condition",
    "covariance",
    "fit",
    "fitted_values",
    "gauss_newton_finish",
    "solved",
    "unconverged",
]

TOLERANCE = 1e-10  # relative, on the cost, the step and the gradient (scipy's ftol, xtol, gtol)
_TOLERANCES = {"ftol": TOLERANCE, "xtol": TOLERANCE, "gtol": TOLERANCE}


@runtime_checkable
class FitState(Protocol):
    """What a fit needs of a state; its kinematics are made once per x (``step_kinematics``)."""

    def step_kinematics(self, data: Any, torque: np.ndarray | None) -> Any:
        """The frames at the data's joints."""

    def same_geometry(self, other: Any) -> bool:
        """Whether ``other``'s kinematics at the same data are this state's."""

    def residuals(self, data: Any, torque: np.ndarray | None = None, kin: Any = None) -> Any:
        """Measured - model per configuration ``(m, rows)``, at the kinematics ``kin`` if given."""


_State = TypeVar("_State", bound=FitState)


class FitModel(Protocol[_State]):
    """What a fit needs of a model (the registration's ``MeasuredKind``, a ``ChainsModel``)."""

    def size(self) -> int:
        """Number of free parameters."""

    def apply(self, start: _State, x: np.ndarray) -> _State:
        """The state at parameters x (x = 0 is ``start``)."""

    def jacobian(
        self, start: _State, x: np.ndarray, data: Any, torque: Any, state: Any, kin: Any
    ) -> np.ndarray:
        """d(model)/dx ``(m, rows, size)`` (``state`` at x and its ``kin``: None or made)."""


_Model = TypeVar("_Model", bound=FitModel[Any])


@dataclass(frozen=True, eq=False)
class Fit(Generic[_Model, _State]):
    """A solved fit: ``model`` (what was free) from ``start`` (x = 0) to ``state`` at ``x``.

    ``J`` ``(r, p)``, ``f`` ``(r,)`` [m]: the data rows' weighted Jacobian and model - measured
    at the solution; ``iterations``, ``evaluations``: of the Jacobian and the residuals.
    """

    model: _Model
    start: _State
    state: _State
    x: np.ndarray
    J: np.ndarray
    f: np.ndarray
    converged: bool
    status: int
    message: str
    iterations: int
    evaluations: int
    kin: Any = None


def unconverged(fitted: Fit, what: str = "the solver", hint: bool = True) -> str | None:
    """Why ``what`` (a fit, a registration) did not converge, or None; ``hint``: more iterations."""
    if fitted.converged:
        return None
    capped = fitted.status == 0
    more = f": it stopped after {fitted.evaluations} residual evaluations" if capped else ""
    more += ", a larger max_iterations may let it finish" if capped and hint else ""
    return f"{what} did not converge ({fitted.message}){more}"


class Problem:
    """Residuals model - measured (weighted by the state) and prior rows, their Jacobian, of x.

    Measurements: docs/developers/performance.md#problem-solve
    """

    def __init__(self, model, start, data, torque, prior=None, robust=True, kin=None):
        self.model, self.start, self.data, self.torque = model, start, data, torque
        self.start_kin = kin  # the start's kinematics at the data's joints, or None
        self.prior = prior  # (p,) weights of x in the prior rows, or None
        self.robust = robust  # SciPy scales the Jacobian it is given in place (a robust loss)
        self._kept: list[list] = []  # [x, state, kinematics or None, data Jacobian or None]
        self._seen: dict[int, np.ndarray | None] = {}  # the rows measured, by width

    def seen(self, rows: int) -> np.ndarray | None:
        """Which data rows ``(m, rows)`` were measured (None: all): a marker not seen has none."""
        if rows not in self._seen:
            seen_rows = getattr(self.data, "seen_rows", None)  # measured data (partial rows)
            self._seen[rows] = None if seen_rows is None else seen_rows(rows)
        return self._seen[rows]

    def state(self, x: np.ndarray):
        """The model's state at x."""
        return self._at(x)[1]

    def _at(self, x: np.ndarray) -> list:
        """[x, state, kinematics at the data's joints or None, Jacobian], once per x."""
        for kept in self._kept:
            if kept[0].shape == np.shape(x) and (kept[0] == x).all():  # np.array_equal's test
                return kept
        state = self.model.apply(self.start, x)
        kin = next((k[2] for k in self._kept if state.same_geometry(k[1])), None)
        if kin is None and self.start_kin is not None and state.same_geometry(self.start):
            kin = self.start_kin
        if kin is None:
            kin = state.step_kinematics(self.data, self.torque)
        self._kept = [[np.array(x, dtype=float), state, kin, None], *self._kept[:1]]
        for other in self._kept[1:]:  # another geometry's kinematics: made again if asked
            if other[2] is not kin:
                other[2] = None
        return self._kept[0]

    def data_rows(self, x: np.ndarray) -> np.ndarray:
        """Weighted model - measured of the data, configuration-major ``(m rows,)`` (measured)."""
        _, state, kin, _ = self._at(x)  # kin None: another geometry's made since
        r = state.residuals(self.data, self.torque, kin)
        seen = self.seen(r.shape[1])
        return -r.ravel() if seen is None else -r[seen]

    def fun(self, x: np.ndarray) -> np.ndarray:
        """Data rows, then the prior rows ``prior * x``."""
        f = self.data_rows(x)
        return f if self.prior is None else np.r_[f, self.prior * x]

    def data_jac(self, x: np.ndarray) -> np.ndarray:
        """Jacobian of :meth:`data_rows`, ``(m rows, p)`` (not to be written to)."""
        kept = self._at(x)
        if kept[3] is None:
            for other in self._kept:  # asked for at one x at a time: one Jacobian kept
                if other is not kept:
                    other[3] = None
            _, state, kin, _ = kept
            J = self.model.jacobian(self.start, x, self.data, self.torque, state, kin)
            seen = self.seen(J.shape[1])
            kept[3] = J.reshape(-1, J.shape[2]) if seen is None else J[seen]
        return kept[3]

    def jac(self, x: np.ndarray) -> np.ndarray:
        """Jacobian of :meth:`fun` (a copy for a robust loss, which SciPy scales in place)."""
        J = self.data_jac(x)
        if self.prior is not None:
            return np.vstack([J, np.diag(self.prior)])
        return J.copy() if self.robust else J


def fit(
    model: _Model,
    start: _State,
    data,
    torque: np.ndarray | None,
    *,
    prior: np.ndarray | None = None,
    loss: str = "linear",
    scale: float = 1e-3,
    max_iterations: int = 100,
    kin: Any = None,
) -> Fit[_Model, _State]:
    """Levenberg-Marquardt (least squares) or trust-region (robust loss) from x = 0.

    ``torque``: gravity torques ``(m, n)``, or None; ``prior``: weights of x in extra rows
    ``prior * x`` (a Gaussian prior toward the start), or None; ``loss``: one of ``LOSSES``,
    ``scale`` its residual scale [m]; ``max_iterations``: most residual evaluations; ``kin``:
    the start's kinematics at the data's joints, if made.
    """
    import scipy.optimize  # here: importing it costs every calib command 0.1 s at start-up

    problem = Problem(model, start, data, torque, prior, loss != "linear", kin)
    p = model.size()
    if p == 0:
        x = np.zeros(0)
        status, message, njev, nfev = 1, "nothing to fit", 0, 1
    elif loss == "linear":
        x, status, message, njev, nfev = _levenberg_marquardt(problem, p, max_iterations)
    else:
        sol = scipy.optimize.least_squares(
            problem.fun,
            np.zeros(p),
            jac=problem.jac,
            method="trf",
            loss=loss,
            f_scale=scale,
            max_nfev=max_iterations,
            **_TOLERANCES,
        )
        x, status, message = sol.x, int(sol.status), str(sol.message)
        njev = int(sol.njev if sol.njev is not None else sol.nfev)
        nfev = int(sol.nfev)
    f = problem.data_rows(x)
    J = problem.data_jac(x) if p else np.zeros((f.size, 0))
    _, state, kin, _ = problem._at(x)
    return solved(model, start, state, x, J, f, status, message, (njev, nfev), kin)


def solved(model, start, state, x, J, f, status: int, message: str, counts, kin=None) -> Fit:
    """The :class:`Fit`, converged with a positive ``status`` and finite numbers."""
    finite = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(f)) and np.all(np.isfinite(J)))
    if not finite:
        message = "non-finite parameters or residuals"
    converged = status > 0 and finite
    njev, nfev = counts
    return Fit(model, start, state, x, J, f, converged, status, message, njev, nfev, kin)


def gauss_newton_finish(fitted: Fit[_Model, _State], data, steps: int = 2) -> Fit[_Model, _State]:
    """A converged linear-loss fit finished by undamped Gauss-Newton steps on its data rows.

    Each step kept only if it lowers the cost (``fitted`` itself when none does).
    Rationale: docs/developers/engine.md#solve
    """
    problem = Problem(fitted.model, fitted.start, data, None, None, robust=False)
    x, f, best = fitted.x, fitted.f, fitted
    for k in range(1, steps + 1):
        step = np.linalg.lstsq(problem.data_jac(x), -f, rcond=None)[0]
        trial = problem.data_rows(x + step)
        if not (np.all(np.isfinite(trial)) and trial @ trial < f @ f):
            break
        x, f = x + step, trial
        best = dataclasses.replace(
            fitted,
            state=problem.state(x),
            x=x,
            J=problem.data_jac(x),
            f=f,
            iterations=fitted.iterations + k,
            evaluations=fitted.evaluations + k,
        )
    return best


_MINPACK_STATUS = {0: -1, 1: 2, 2: 3, 3: 4, 4: 1, 5: 0}  # MINPACK's info as least_squares' status
_STATUS_MESSAGES = {  # least_squares' message of each status (the results read as they did)
    -1: "Improper input parameters status returned from `leastsq`",
    0: "The maximum number of function evaluations is exceeded.",
    1: "`gtol` termination condition is satisfied.",
    2: "`ftol` termination condition is satisfied.",
    3: "`xtol` termination condition is satisfied.",
    4: "Both `ftol` and `xtol` termination conditions are satisfied.",
}


def _levenberg_marquardt(problem: Problem, p: int, max_iterations: int):
    """MINPACK's Levenberg-Marquardt through ``leastsq``, as ``least_squares(method='lm')``.

    Measurements: docs/developers/performance.md#_levenberg_marquardt-solve
    """
    import scipy.optimize

    x, _, info, _, code = scipy.optimize.leastsq(
        problem.fun,
        np.zeros(p),
        Dfun=problem.jac,
        full_output=True,
        maxfev=max_iterations,
        **_TOLERANCES,
    )
    status = _MINPACK_STATUS.get(int(code), -1)
    nfev = int(info["nfev"])
    return x, status, _STATUS_MESSAGES[status], int(info.get("njev", nfev)), nfev


def covariance(J: np.ndarray, rss: float, prior: np.ndarray | None = None):
    """Covariance ``sigma^2 (J^T J + P^2)^-1`` (inf: singular) and sigma = sqrt(RSS / (r - p))."""
    r, p = J.shape
    sigma = math.sqrt(rss / (r - p)) if r > p else math.nan
    A = J if prior is None else np.vstack([J, np.diag(prior)])
    if p == 0:
        return np.zeros((0, 0)), sigma
    R = scipy.linalg.qr(A, mode="r", check_finite=False)[0][:p]
    if not np.all(np.isfinite(R)) or np.any(np.abs(np.diag(R)) <= 1e-14 * np.max(np.abs(R))):
        return np.full((p, p), math.inf), sigma
    Rinv = scipy.linalg.solve_triangular(R, np.eye(p), check_finite=False)
    return sigma**2 * (Rinv @ Rinv.T), sigma


def condition(J: np.ndarray) -> float:
    """Condition number of J with its columns scaled to unit norm."""
    if J.shape[1] == 0:
        return 1.0
    norms = np.linalg.norm(J, axis=0)
    if np.any(norms == 0):
        return math.inf
    s = np.linalg.svd(J / norms, compute_uv=False)
    return float(s[0] / s[-1]) if s[-1] > 0 else math.inf


def fitted_values(fitted: Fit, cov: np.ndarray) -> dict:
    """Keys ``fitted``, ``estimate``, ``std`` (NaN: undefined), ``solver`` past ``model.fixed``."""
    fixed = fitted.model.fixed
    with np.errstate(invalid="ignore"):
        std = np.sqrt(np.diag(cov))[fixed:] if fitted.x.size else np.zeros(0)
    return {
        "fitted": tuple(fitted.model.names()[fixed:]),
        "estimate": fitted.x[fixed:].copy(),
        "std": std,
        "solver": (fitted.converged, fitted.message, fitted.iterations),
    }
