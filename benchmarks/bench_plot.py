"""What --plot and --origins cost (issue 33): the figure of a UR5 calibration, its origins YAML.

One BLAS thread, in process; each case ``CALIB_BENCH_REPEATS`` times (default 7) after a
warm-up: the median wall and CPU times. The result: a UR5, 100 positions (marker 1, 2, 5 cm,
0.05 mm noise, seed 0), 20 % held out, the default level.

Run: .venv/bin/python benchmarks/bench_plot.py   (CALIB_BENCH_REPEATS, default 7)
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import median_times_ms, one_core, table

one_core()

import calib  # noqa: E402
from calib.kinematics.origins import origins_yaml  # noqa: E402
from calib.outputs.plots import calibration_figure, figure_bytes  # noqa: E402

REPEATS = int(os.environ.get("CALIB_BENCH_REPEATS", "7"))


def main() -> None:
    chain = calib.load_chain("ur5")
    campaign = calib.simulate(chain, 100, "position", marker=[0.01, 0.02, 0.05], noise_mm=0.05)
    result = calib.calibrate(chain, campaign.measurements, holdout=0.2)
    cases = {
        "--plot .png (figure + file bytes)": lambda: figure_bytes(
            calibration_figure(result), "png"
        ),
        "--plot .svg": lambda: figure_bytes(calibration_figure(result), "svg"),
        "--origins (YAML text)": lambda: origins_yaml(result.origins()),
    }
    rows = []
    for name, fn in cases.items():
        wall, cpu = median_times_ms(fn, REPEATS, warmup=1)
        rows.append((name, f"{wall:.0f}", f"{cpu:.0f}"))
    print(table(("case", "wall [ms]", "cpu [ms]"), rows))


if __name__ == "__main__":
    main()
