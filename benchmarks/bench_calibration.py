"""Speed of the calibration loop (issue: UR5, 100 position measurements, fit < 50 ms).

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
from calib.calibration import _Problem  # noqa: E402

warnings.simplefilter("ignore")

MARKER = (0.05, 0.02, 0.1)
NOISE_MM = 0.1


def finite_difference_fit(chain, data, marker) -> None:
    """The same problem solved with a 2-point finite-difference Jacobian (for comparison)."""
    res = calibrate(chain, data, marker=marker, max_iterations=1)
    problem = _Problem(res.nominal, res.analysis.params, res.lift, data, res.measurement, 1.0)
    scipy.optimize.least_squares(
        problem.fun,
        np.zeros(res.n_base),
        method="lm",
        jac="2-point",
        ftol=1e-10,
        xtol=1e-10,
        gtol=1e-10,
    )


def in_process_rows() -> list[list[str]]:
    rows = []
    cases = [
        ("ur5", "position", MARKER),
        ("ur5", "pose", None),
        ("panda", "position", MARKER),
        ("panda", "pose", None),
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
        rows.append(
            [
                f"{robot}, m=100, {measure}: calibrate() in-process",
                f"{t:.1f}",
                f"setup {setup:.1f} + fit {solve:.1f}; {last.iterations} iterations, "
                f"b={last.n_base}",
            ]
        )
        if (robot, measure) == ("ur5", "position"):
            fd = median_ms(
                lambda chain=chain, data=data: finite_difference_fit(chain, data, MARKER), 5, 1
            )
            rows.append(
                [
                    "ur5, m=100, position: same fit, 2-point finite differences",
                    f"{fd:.1f}",
                    "for comparison (scipy least_squares jac='2-point')",
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
