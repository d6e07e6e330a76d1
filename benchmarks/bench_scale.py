"""Scale without waiting (issue 31): long contact recordings, many objects, big candidate sets.

Whole ``calib`` processes on one BLAS thread, each case ``CALIB_BENCH_REPEATS`` times (default
3): the median wall time, the median CPU time (user + system: the steadier on a shared machine)
and the peak resident memory of the process.

- Contacts, TALOS from the left sole to the left gripper touching planes (simulated, 0.01 mrad
  joint noise): 20,000 touches of one plane, and 500 planes of 4 touches, with ``--params
  complete`` and the default ``--params auto``.
- Design, TIAGo, 30 configurations of 20,000 and of 100,000 candidates, collision checks on
  (the default).

Run: .venv/bin/python benchmarks/bench_scale.py   (CALIB_BENCH_REPEATS, default 3)
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import CALIB, one_core, table

one_core()

REPEATS = int(os.environ.get("CALIB_BENCH_REPEATS", "3"))
TALOS = ["talos", "--base", "left_sole_link", "--tool", "gripper_left_base_link"]


def run(args: list[str]) -> tuple[float, float, float, int]:
    """Wall [s], CPU [s], peak memory [MB] and exit status of one calib process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([str(CALIB), *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    cpu = usage.ru_utime + usage.ru_stime
    return wall, cpu, usage.ru_maxrss / 1024, proc.returncode


def medians(args: list[str]) -> list[str]:
    """The row of a case: median wall, CPU, peak memory, exit status."""
    runs = [run(args) for _ in range(REPEATS)]
    wall, cpu, mem = (statistics.median(r[k] for r in runs) for k in range(3))
    return [f"{wall:.2f}", f"{cpu:.2f}", f"{mem:.0f}", str(runs[-1][3])]


def contact_file(folder: Path, touches: int, planes: int) -> Path:
    """A simulated plane campaign of TALOS sole to gripper."""
    path = folder / f"talos_{touches}_{planes}.csv"
    subprocess.run(
        [str(CALIB), "simulate", *TALOS, "--measure", "plane", "--configs", str(touches),
         "--contacts", str(planes), "--noise-mrad", "0.01", "--out", str(path)],
        check=True, capture_output=True,
    )  # fmt: skip
    return path


def main() -> None:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for touches, planes in ((20000, 1), (2000, 500)):
            data = contact_file(folder, touches, planes)
            for params in ("complete", "auto"):
                args = ["calibrate", *TALOS, "--measure", "plane", "--data", str(data),
                        "--params", params, "--out", str(folder / "out.urdf")]  # fmt: skip
                name = f"contacts: {touches} touches of {planes} plane(s), params {params}"
                rows.append([name, *medians(args)])
                print(rows[-1], flush=True)
        for candidates in (20000, 100000):
            args = ["design", "tiago", "--configs", "30", "--candidates", str(candidates)]
            rows.append([f"design: TIAGo 30 of {candidates}, collisions", *medians(args)])
            print(rows[-1], flush=True)
    print(table(["case", "wall [s]", "CPU [s]", "peak [MB]", "exit"], rows))


if __name__ == "__main__":
    main()
