"""CPU time of the default calibration on large campaigns (issue 19: 20,000 configurations or
50 markers within 60 s on one core, or a refusal up front that says what to do).

Whole ``calib calibrate`` processes on one BLAS thread; the time is the child's user + system
CPU time (the machine is shared: wall time says more about the other jobs than about calib).
Cases: a UR5 with 20,000 simulated positions, 20,000 poses, and 50 markers at 1000
configurations (points from Pinocchio's tool placements), with the default ``--params auto``
and with ``--params complete``.

Run: .venv/bin/python benchmarks/bench_large_campaigns.py   (CALIB_BENCH_REPEATS, default 3)
"""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import CALIB, one_core, table

one_core()

import numpy as np  # noqa: E402

from calib import load_chain, simulate, write_measurements  # noqa: E402

REPEATS = int(os.environ.get("CALIB_BENCH_REPEATS", "3"))


def markers_csv(path: Path, m: int, k: int) -> None:
    """A UR5 campaign of k markers at m configurations, 0.05 mm noise."""
    chain = load_chain("ur5")
    q = chain.random_configurations(m, 1)
    F = chain.tool_placements(q)
    rng = np.random.default_rng(2)
    markers = rng.uniform(-0.1, 0.1, (k, 3))
    points = F[:, None, :3, 3] + np.einsum("mij,kj->mki", F[:, :3, :3], markers)
    points += rng.normal(0.0, 5e-5, points.shape)
    header = [*chain.joint_names, *(f"{a}{i + 1}" for i in range(k) for a in "xyz")]
    np.savetxt(
        path, np.c_[q, points.reshape(m, -1)], delimiter=",", header=",".join(header), comments=""
    )


def cpu_s(args: list[str]) -> tuple[float, int]:
    """Median CPU time [s] of a whole calib process, and its exit status."""
    times, code = [], 0
    for _ in range(REPEATS):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        code = subprocess.run([str(CALIB), *args], capture_output=True).returncode
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        times.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return statistics.median(times), code


def main() -> None:
    chain = load_chain("ur5")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        data = {
            "20000 positions": folder / "pos.csv",
            "20000 poses": folder / "pose.csv",
            "50 markers x 1000": folder / "k50.csv",
        }
        for measure, key in (("position", "20000 positions"), ("pose", "20000 poses")):
            mrad = {"noise_mrad": 0.1} if measure == "pose" else {}
            camp = simulate(chain, 20000, measure, noise_mm=0.05, seed=0, **mrad)
            write_measurements(data[key], camp.measurements)
        markers_csv(data["50 markers x 1000"], 1000, 50)
        for label, path in data.items():
            for level in ("auto", "complete"):
                out = folder / "c.urdf"
                args = ["calibrate", "ur5", "--data", str(path), "--out", str(out)]
                seconds, code = cpu_s([*args, "--params", level])
                verdict = "done" if code == 0 else "refused up front" if code == 2 else code
                rows.append([label, level, f"{seconds:.1f}", verdict])
    print(table(["campaign", "--params", "CPU [s]", "result"], rows))


if __name__ == "__main__":
    main()
