"""Speed of the calibration loop (issue: UR5, 100 position measurements, fit < 50 ms).

The analytic and finite-difference Jacobians are compared on the same least-squares problem
(same base set, lift and start): only the ``least_squares`` call is timed for both, the
setup (identifiability, lift) is done once beforehand.

Run: .venv/bin/python benchmarks/bench_calibration.py
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import median_ms, one_core, process_ms, table

one_core()

import statistics  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402
import scipy.optimize  # noqa: E402

from calib import (  # noqa: E402
    calibrate,
    calibrated_urdf,
    load_chain,
    simulate,
    write_measurements,
)
from calib.calibration import TOLERANCE, _Problem  # noqa: E402

warnings.simplefilter("ignore")

MARKER = (0.05, 0.02, 0.1)
NOISE_MM = 0.1


def least_squares_fit(res, data, jac: str) -> tuple[object, int, int]:
    """The fit of ``calibrate`` alone, on its problem (base set, lift) from the nominal model.

    ``jac="analytic"`` is what ``calibrate`` runs; ``"2-point"`` lets scipy difference the
    residuals instead. A fresh problem each time (no cached state), built at no cost.

    Returns:
        scipy's result, the residual evaluations and the Jacobian evaluations (counted here).
    """
    problem = _Problem(
        res.nominal, res.analysis.params, res.lift, data, res.measurement, res.orientation_weight
    )
    calls = {"fun": 0, "jac": 0}

    def fun(x):
        calls["fun"] += 1
        return problem.fun(x)

    def jacobian(x):
        calls["jac"] += 1
        return problem.jac(x)

    analytic = jac == "analytic"
    sol = scipy.optimize.least_squares(
        fun,
        np.zeros(res.n_base),
        jac=jacobian if analytic else jac,
        method="lm",
        ftol=TOLERANCE,
        xtol=TOLERANCE,
        gtol=TOLERANCE,
        # calibrate's limit; scipy counts the finite-difference evaluations too, so none.
        max_nfev=100 if analytic else None,
    )
    return sol, calls["fun"], calls["jac"]


def in_process_rows() -> list[list[str]]:
    rows = []
    cases = [
        ("ur5", "position", MARKER),
        ("ur5", "pose", None),
        ("panda", "position", MARKER),
        ("panda", "pose", None),
        ("ur5", "position", None),  # the tool origin, on the last axis: first fit + refit
    ]
    for robot, measure, marker in cases:
        chain = load_chain(robot)
        data = simulate(
            chain, configs=100, measure=measure, marker=marker, seed=0, noise_mm=NOISE_MM
        ).measurements
        results = []

        def fit(chain=chain, data=data, marker=marker, results=results):
            results.append(calibrate(chain, data, marker=marker))

        t = median_ms(fit, 30)
        last = results[-1]
        setup = statistics.median(r.timings_ms["setup"] for r in results)
        solve = statistics.median(r.timings_ms["fit"] for r in results)
        refit = statistics.median(r.timings_ms["refit"] for r in results)
        where = "tool origin on the last axis" if marker is None and measure == "position" else ""
        rows.append(
            [
                f"{robot}, m=100, {measure}{f' ({where})' if where else ''}: "
                "calibrate() in-process",
                f"{t:.1f}",
                f"setup {setup:.1f} + fit {solve:.1f}"
                + (
                    f" + refit {refit:.1f} ({'kept' if last.refitted else 'rejected'})"
                    if refit > 0.5
                    else ""
                )
                + f"; {last.iterations} iterations, b={last.n_base}",
            ]
        )
        if (robot, measure, marker) == ("ur5", "position", MARKER):
            for jac, label in (("analytic", "analytic Jacobian"), ("2-point", "2-point FD")):
                sols = []

                def solve_only(res=last, data=data, jac=jac, sols=sols):
                    sols.append(least_squares_fit(res, data, jac))

                ms = median_ms(solve_only, 30 if jac == "analytic" else 10, 1)
                sol, nfun, njac = sols[-1]
                rows.append(
                    [
                        f"ur5, m=100, position: least_squares only, {label}",
                        f"{ms:.1f}",
                        f"setup excluded; {nfun} residual + {njac} Jacobian evaluations, "
                        f"final cost {sol.cost:.4g} m^2",
                    ]
                )
            urdf = median_ms(
                lambda chain=chain, res=last: calibrated_urdf(chain, res.nominal, res.calibrated),
                30,
            )
            rows.append(["ur5: calibrated URDF text (parse + edit + serialise)", f"{urdf:.1f}", ""])
    return rows


def whole_process_rows() -> list[list[str]]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        meas = out / "meas.csv"
        chain = load_chain("ur5")
        data = simulate(
            chain, configs=100, measure="position", marker=MARKER, seed=0, noise_mm=NOISE_MM
        ).measurements
        write_measurements(meas, data)
        calibrate_args = [
            "calibrate",
            "ur5",
            "--data",
            str(meas),
            "--out",
            str(out / "c.urdf"),
            "--report",
            str(out / "r.json"),
            "--marker",
            *map(str, MARKER),
        ]
        simulate_args = ["simulate", "ur5", "--out", str(out / "s.csv")]
        return [
            [
                "`calib calibrate ur5` (100 positions) whole process",
                f"{process_ms(calibrate_args):.0f}",
                "interpreter start and imports included",
            ],
            [
                "`calib simulate ur5` (100 poses) whole process",
                f"{process_ms(simulate_args):.0f}",
                "",
            ],
            ["`calib list` whole process (start-up reference)", f"{process_ms(['list']):.0f}", ""],
        ]


def main() -> None:
    rows = in_process_rows() + whole_process_rows()
    print(table(["case", "median [ms]", "notes"], rows))


if __name__ == "__main__":
    main()
