"""Time and peak memory of the default calibration on large simulated campaigns (issue 31).

Each case runs in a fresh process (one BLAS thread) that reads a CSV written beforehand: a
UR5 measured in position (marker at (10, 20, 50) mm) or in pose, 0.05 mm noise, default
options (``params='auto'``). Printed: the median wall time of the calibration, the process's
peak resident memory (VmHWM: ru_maxrss would carry the parent's over the fork), that of a
process that only reads the file (the difference is the calibration's), the winner of the
selection, the whole process's wall time (start-up and reading included), and the slope of
the calibration's memory per configuration between sizes.

Run: .venv/bin/python benchmarks/bench_selection_memory.py [m ...]
(CALIB_BENCH_REPEATS, default 1; CALIB_BENCH_MEASURES, default position,pose;
CALIB_BENCH_BEYOND=1 lifts the stated maximum of rows, ``MAX_ROWS``, in the measured
processes, to measure campaigns larger than calib accepts)
"""

from __future__ import annotations

import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import one_core

one_core()

from calib import load_chain, simulate, write_measurements  # noqa: E402

REPEATS = int(os.environ.get("CALIB_BENCH_REPEATS", "1"))
CHILD = """
import json, os, sys, time
from calib import load_chain, read_measurements
from calib.calibration import calibrate
if os.environ.get("CALIB_BENCH_BEYOND") == "1":  # every module that holds the maximum
    import importlib
    for name in ("entry",):
        try:
            module = importlib.import_module("calib.calibration." + name)
        except ImportError:
            continue
        if hasattr(module, "MAX_ROWS"):
            module.MAX_ROWS = 10**7
    import calib.measurements.csvfile
    calib.measurements.csvfile.MAX_ROWS = 10**7
path, run = sys.argv[1], sys.argv[2] == "1"
chain = load_chain("ur5")
data = read_measurements(path, chain)
t0 = time.perf_counter()
try:
    kept = calibrate(chain, data).selection.winner if run else ""
except Exception as error:  # the refusal of a selection too long to wait for
    kept = "refused: " + str(error)[:60]
wall = time.perf_counter() - t0
peak = [int(line.split()[1]) for line in open("/proc/self/status") if line.startswith("VmHWM")]
print(json.dumps([wall, peak[0], kept]))
"""


def child(path: Path, run: bool) -> tuple[float, float, str, float]:
    """Wall time [s], peak RSS [MiB], the winner and the whole process's wall time [s]."""
    tic = time.perf_counter()
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(path), "1" if run else "0"],
        capture_output=True,
        text=True,
        check=True,
        env=os.environ,
    )
    whole = time.perf_counter() - tic
    wall, rss, winner = json.loads(out.stdout.strip().splitlines()[-1])
    return wall, rss / 1024.0, winner, whole


@contextlib.contextmanager
def _beyond():
    """The stated maximum of rows lifted while writing (``CALIB_BENCH_BEYOND=1``)."""
    import calib.measurements.csvfile as csvfile

    kept = csvfile.MAX_ROWS
    if os.environ.get("CALIB_BENCH_BEYOND") == "1":
        csvfile.MAX_ROWS = 10**7
    try:
        yield
    finally:
        csvfile.MAX_ROWS = kept


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [1000, 10_000, 100_000]
    print("measure       m   time [s]  process [s]  peak [MiB]  data only [MiB]  winner")
    chain = load_chain("ur5")
    for measure in os.environ.get("CALIB_BENCH_MEASURES", "position,pose").split(","):
        prev = None
        for m in sizes:
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / "campaign.csv"
                camp = simulate(chain, m, measure, (0.01, 0.02, 0.05), noise_mm=0.05, seed=0)
                with _beyond():
                    write_measurements(path, camp.measurements)
                del camp
                runs = [child(path, True) for _ in range(REPEATS)]
                base = child(path, False)[1]
            wall = statistics.median(r[0] for r in runs)
            whole = statistics.median(r[3] for r in runs)
            peak = statistics.median(r[1] for r in runs)
            print(
                f"{measure:8s} {m:7d} {wall:9.2f} {whole:12.2f} {peak:11.0f} {base:16.0f}  "
                f"{runs[0][2]}"
            )
            if prev is not None:
                slope = (peak - base - prev[1]) * 1024.0 / (m - prev[0])
                print(f"   slope of the calibration's memory: {slope:.1f} KiB per configuration")
            prev = (m, peak - base)


if __name__ == "__main__":
    main()
