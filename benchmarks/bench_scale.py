"""Scale without waiting (issue 31): long contact recordings, many objects, big candidate sets.

Whole ``calib`` processes on one BLAS thread, each case ``CALIB_BENCH_REPEATS`` times (default
3): the median wall time, the median CPU time (user + system: the steadier on a shared machine)
and the peak resident memory of the process. The contacts also in process: a fresh Python
process reads the file, then times :func:`calib.calibrate` alone (one plane: the joint engine;
500 planes: the single chain's block route; wall and CPU, medians) and prints its peak
resident memory (VmHWM) and that after reading the file.

- Contacts, TALOS from the left sole to the left gripper touching planes (simulated, 0.01 mrad
  joint noise): 20,000 touches of one plane, and 500 planes of 4 touches, with ``--params
  complete`` and the default ``--params auto``.
- Design, TIAGo, 30 configurations of 20,000 and of 100,000 candidates, collision checks on
  (the default).

Run: .venv/bin/python benchmarks/bench_scale.py   (CALIB_BENCH_REPEATS, default 3)
"""

from __future__ import annotations

import json
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
    """Wall [s], CPU [s], peak memory [MiB] and exit status of one calib process."""
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
        [
            str(CALIB),
            "simulate",
            *TALOS,
            "--measure",
            "plane",
            "--configs",
            str(touches),
            "--contacts",
            str(planes),
            "--noise-mrad",
            "0.01",
            "--out",
            str(path),
        ],
        check=True,
        capture_output=True,
    )
    return path


IN_PROCESS = """
import json, sys, time
from calib import load_chain
from calib import calibrate
from calib.measurements.contact_campaign import read_contacts
def hwm():
    return [int(x.split()[1]) for x in open("/proc/self/status") if x.startswith("VmHWM")][0]
chain = load_chain("talos", "left_sole_link", "gripper_left_base_link")
data = read_contacts(sys.argv[1], chain, "plane")
read = hwm()
t0, c0 = time.perf_counter(), time.process_time()
result = calibrate(chain, data, params=sys.argv[2])
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
print(json.dumps([wall, cpu, hwm() / 1024, read / 1024, len(result.free)]))
"""


def in_process(data: Path, params: str) -> list[str]:
    """The row of a contact case in process: median wall, CPU, peak, after reading, free."""
    runs = []
    for _ in range(REPEATS):
        command = [sys.executable, "-c", IN_PROCESS, str(data), params]
        out = subprocess.run(command, capture_output=True, text=True, check=True, env=os.environ)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    wall, cpu, mem, read = (statistics.median(r[k] for r in runs) for k in range(4))
    return [f"{wall:.2f}", f"{cpu:.2f}", f"{mem:.0f}", f"{read:.0f}", str(runs[-1][4])]


def main() -> None:
    rows, inside = [], []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for touches, planes in ((20000, 1), (2000, 500)):
            data = contact_file(folder, touches, planes)
            for params in ("complete", "auto"):
                args = [
                    "calibrate",
                    *TALOS,
                    "--measure",
                    "plane",
                    "--data",
                    str(data),
                    "--params",
                    params,
                    "--out",
                    str(folder / "out.urdf"),
                ]
                name = f"contacts: {touches} touches of {planes} plane(s), params {params}"
                rows.append([name, *medians(args)])
                print(rows[-1], flush=True)
                inside.append([name, *in_process(data, params)])
                print(inside[-1], flush=True)
        for candidates in (20000, 100000):
            args = ["design", "tiago", "--configs", "30", "--candidates", str(candidates)]
            rows.append([f"design: TIAGo 30 of {candidates}, collisions", *medians(args)])
            print(rows[-1], flush=True)
    print(table(["case", "wall [s]", "CPU [s]", "peak [MiB]", "exit"], rows))
    print("In process (the calibration alone; peak of the process, and after reading the file):")
    print(table(["case", "wall [s]", "CPU [s]", "peak [MiB]", "read [MiB]", "free"], inside))


if __name__ == "__main__":
    main()
