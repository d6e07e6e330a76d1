"""The linear fit runs MINPACK as scipy.optimize.least_squares(method='lm') does, to the bit.

The fit is the joint engine's (a chain measured by an instrument: ``calibrate`` routes it
there); its arguments are caught on their way to :func:`calib.calibration.solve.fit`.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import scipy.optimize

import calib.calibration.engine as engine
from calib import load_chain, simulate
from calib.calibration import calibrate
from calib.calibration.solve import TOLERANCE, Problem, fit


def engine_fit(monkeypatch, chain, data, **options) -> dict:
    """The arguments and the result of the engine's fit of ``calibrate(chain, data)``."""
    seen: dict = {}

    def spy(model, start, rows, torque, **kwargs):
        seen.update(model=model, start=start, data=rows, torque=torque, **kwargs)
        seen["fitted"] = fit(model, start, rows, torque, **kwargs)
        return seen["fitted"]

    monkeypatch.setattr(engine, "fit", spy)
    calibrate(chain, data, **options)
    return seen


@pytest.mark.parametrize(
    ("measure", "params", "iterations"), [("pose", "auto", 100), ("position", "complete", 2)]
)
def test_the_fit_is_least_squares_lm(monkeypatch, measure, params, iterations):
    chain = load_chain("ur5")
    data = simulate(chain, 300, measure, (0.01, 0.02, 0.05), noise_mm=0.05, seed=4).measurements
    seen = engine_fit(monkeypatch, chain, data, params=params, max_iterations=iterations)
    size = seen["model"].size()
    prior = np.full(size, 0.5) if params == "auto" else None  # prior rows or not
    args = (seen["model"], seen["start"], seen["data"], seen["torque"])
    problem = Problem(*args, prior, robust=False)
    sol = scipy.optimize.least_squares(
        problem.fun,
        np.zeros(size),
        jac=problem.jac,
        method="lm",
        ftol=TOLERANCE,
        xtol=TOLERANCE,
        gtol=TOLERANCE,
        max_nfev=iterations,
    )
    fitted = fit(*args, prior=prior, max_iterations=iterations)
    assert np.array_equal(fitted.x, sol.x)
    assert (fitted.status, fitted.message) == (sol.status, sol.message)
    assert (fitted.iterations, fitted.evaluations) == (sol.njev, sol.nfev)
    assert np.array_equal(fitted.J, sol.jac[: len(fitted.f)])
    assert (fitted.status == 0) == (iterations == 2)  # the evaluations' limit, reached


def test_a_robust_loss_is_least_squares_trf_with_the_noise_as_scale(monkeypatch):
    """``loss`` and ``noise_mm`` reach the engine's fit: scipy's trf, f_scale the noise [m]."""
    chain = load_chain("ur5")
    data = simulate(chain, 60, "position", (0.01, 0.02, 0.05), noise_mm=0.1, seed=3).measurements
    seen = engine_fit(monkeypatch, chain, data, params="complete", loss="huber", noise_mm=0.2)
    assert (seen["loss"], seen["scale"]) == ("huber", 2e-4)
    size = seen["model"].size()
    args = (seen["model"], seen["start"], seen["data"], seen["torque"])
    problem = Problem(*args, None, robust=True)
    sol = scipy.optimize.least_squares(
        problem.fun,
        np.zeros(size),
        jac=problem.jac,
        method="trf",
        loss="huber",
        f_scale=2e-4,
        ftol=TOLERANCE,
        xtol=TOLERANCE,
        gtol=TOLERANCE,
        max_nfev=100,
    )
    assert np.array_equal(seen["fitted"].x, sol.x)


def test_the_fit_holds_few_copies_of_its_jacobian(monkeypatch):
    """5,000 poses: the fit's traced peak is under 6.5 Jacobians (5.4; before 7.7: three of
    them least_squares' copies, and the problem's Jacobian at two points)."""
    chain = load_chain("ur5")
    data = simulate(chain, 5000, "pose", (0.01, 0.02, 0.05), noise_mm=0.05, seed=4).measurements
    seen = engine_fit(monkeypatch, chain, data, params="complete")
    args = (seen["model"], seen["start"], seen["data"], seen["torque"])
    tracemalloc.start()
    try:
        fitted = fit(*args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 6.5 * fitted.J.nbytes, peak / fitted.J.nbytes
