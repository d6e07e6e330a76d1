"""Helpers shared by the benchmarks: medians of repeated timings, in-process and whole-process."""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CALIB = Path(sys.executable).with_name("calib")


def one_core() -> None:
    """Pin BLAS to one thread (call before importing numpy): the targets are per core."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def cpu_median_ns(fn: Callable[[], object], repeats: int) -> float:
    """Median process CPU time of ``fn()`` over ``repeats`` calls [ns], after one warm-up."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.process_time_ns()
        fn()
        times.append(time.process_time_ns() - t0)
    return float(statistics.median(times))


def median_ms(fn: Callable[[], object], repeats: int, warmup: int = 3) -> float:
    """Median wall time of ``fn()`` over ``repeats`` calls [ms], after a warm-up."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def median_times_ms(fn: Callable[[], object], repeats: int, warmup: int = 3) -> tuple[float, float]:
    """Median wall and process CPU times of ``fn()`` over ``repeats`` calls [ms], after a
    warm-up (on a busy machine the CPU time is the steadier)."""
    for _ in range(warmup):
        fn()
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return 1e3 * statistics.median(wall), 1e3 * statistics.median(cpu)


def process_ms(args: Sequence[str], repeats: int = 5) -> float:
    """Median wall time of a whole ``calib`` process [ms] (interpreter start included).

    ``["--python"]`` times the bare interpreter (``python -c pass``) instead, for reference;
    ``["--python", CODE]`` times ``python -c CODE``.
    """
    return 1e3 * statistics.median(process_times(args, repeats))


def process_times(args: Sequence[str], repeats: int) -> list[float]:
    """Wall times [s] of ``repeats`` whole processes (see :func:`process_ms` for ``args``)."""
    return [wall for wall, _ in process_cpu_times(args, repeats)]


def _command(args: Sequence[str]) -> list[str]:
    """The process :func:`process_ms` describes: ``calib ARGS``, or ``python -c CODE``."""
    args = list(args)
    if args[:1] == ["--python"]:
        return [sys.executable, "-c", args[1] if len(args) > 1 else "pass"]
    return [str(CALIB), *args]


def process_cpu_times(args: Sequence[str], repeats: int) -> list[tuple[float, float]]:
    """Wall and CPU (user + system) times [s] of ``repeats`` whole processes (``args`` as in
    :func:`process_ms`): on a busy machine the CPU time is the steadier of the two."""
    command = _command(args)
    times = []
    for _ in range(repeats):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
        times.append((wall, cpu))
    return times


def compile_calib() -> None:
    """Write calib's bytecode caches, as an installation does: with ``PYTHONDONTWRITEBYTECODE``
    set (or before the first run), every start would otherwise compile calib's sources
    (about 90 ms for ``calib analyze``)."""
    import compileall

    compileall.compile_dir(ROOT / "calib", quiet=1)


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A plain-text table."""
    cells = [[str(h) for h in header], *[[str(c) for c in r] for r in rows]]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    return "\n".join("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)) for r in cells)
