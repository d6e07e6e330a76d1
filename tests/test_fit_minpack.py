"""The linear fit runs MINPACK as scipy.optimize.least_squares(method='lm') does, to the bit."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
import scipy.optimize

import calib.calibration.model as model
from calib import load_chain, simulate
from calib.calibration import calibrate
from calib.calibration.solve import TOLERANCE, Problem, fit


@pytest.mark.parametrize(
    ("measure", "params", "iterations"), [("pose", "auto", 100), ("position", "complete", 2)]
)
def test_the_fit_is_least_squares_lm(measure, params, iterations):
    chain = load_chain("ur5")
    data = simulate(chain, 300, measure, (0.01, 0.02, 0.05), noise_mm=0.05, seed=4).measurements
    r = calibrate(chain, data, params=params)
    prior = np.full(r.model.size(), 0.5) if params == "auto" else None  # prior rows or not
    args = (r.model, r.registration, r.data, None, r.orientation_weight)
    problem = Problem(*args, prior, robust=False)
    sol = scipy.optimize.least_squares(
        problem.fun, np.zeros(r.model.size()), jac=problem.jac, method="lm",
        ftol=TOLERANCE, xtol=TOLERANCE, gtol=TOLERANCE, max_nfev=iterations,
    )  # fmt: skip
    fitted = fit(*args, prior=prior, max_iterations=iterations)
    assert np.array_equal(fitted.x, sol.x)
    assert (fitted.status, fitted.message) == (sol.status, sol.message)
    assert (fitted.iterations, fitted.evaluations) == (sol.njev, sol.nfev)
    assert np.array_equal(fitted.J, sol.jac[: len(fitted.f)])
    assert (fitted.status == 0) == (iterations == 2)  # the evaluations' limit, reached


def test_the_fit_holds_few_copies_of_its_jacobian(monkeypatch):
    """5,000 poses: the fit's traced peak is under 6.5 Jacobians (5.4; before 7.7: three of
    them least_squares' copies, and the problem's Jacobian at two points)."""
    chain = load_chain("ur5")
    data = simulate(chain, 5000, "pose", (0.01, 0.02, 0.05), noise_mm=0.05, seed=4).measurements
    r = calibrate(chain, data, params="complete")
    args = (r.model, r.registration, r.data, None, r.orientation_weight)
    monkeypatch.setattr(model, "CONFIGURATION_BLOCK", 256)  # the blocks' temporaries small
    tracemalloc.start()
    try:
        fitted = fit(*args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 6.5 * fitted.J.nbytes, peak / fitted.J.nbytes
