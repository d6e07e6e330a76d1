"""CPU-time medians of one measured chain through either route (issue 28): pipeline and engine.

``calibrate`` fits one chain measured by an instrument with the MDH chart's pipeline
(:func:`calib.calibration.pipeline.calibrate_chain`) unless the internal switch
``calib.calibration.entry.ENGINE_CHAIN`` sends it to the joint engine as a one-term problem
(:func:`calib.calibration.entry.measured_chain`). One line per route [ms of process CPU time,
medians]: the TIAGo session (37 postures, point 1, ``auto``: the target is under 40 ms), point
1 ``complete``, the UR10 with ``holdout=0.25``. Run it a few times (the machine's load drifts):

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/chain_routes.py
"""

from __future__ import annotations

import dataclasses
import warnings
from pathlib import Path

from common import cpu_median_ns, one_core

one_core()
warnings.simplefilter("ignore")

import calib.calibration.entry as entry  # noqa: E402
from calib import calibrate, load_chain, read_measurements  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "data" / "realdata"


def main() -> None:
    tiago = DATA / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    four = read_measurements(tiago / "qualisys_2021-11-30_static_postures.csv", chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    ur10 = load_chain(DATA / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link")
    ur10_data = read_measurements(DATA / "ur10" / "calibration.csv", ur10)
    cases = {
        "point1": (lambda: calibrate(chain, one), 21),
        "complete": (lambda: calibrate(chain, one, params="complete"), 11),
        "ur10": (lambda: calibrate(ur10, ur10_data, holdout=0.25), 11),
    }
    for engine in (False, True):
        entry.ENGINE_CHAIN = engine
        ms = {name: cpu_median_ns(fn, n) / 1e6 for name, (fn, n) in cases.items()}
        route = "engine" if engine else "pipeline"
        print(f"{route:8s} " + " ".join(f"{k} {v:.1f}" for k, v in ms.items()), flush=True)


if __name__ == "__main__":
    main()
