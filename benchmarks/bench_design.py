"""Speed of experiment design (issue 13: 30 configurations from 2,000 candidates of a
7-joint robot in under 1 s, 100 from 20,000 in under 10 s, one core).

The cases time :func:`calib.design.design.design` on the Panda (7 joints): candidates drawn, their
Jacobian, greedy start, exchanges, indices of the design and of 20 random sets; the
collision filter is timed apart (it depends on the meshes, not on the algorithm). Medians of
wall time and of process CPU time (the machine is shared: CPU time is what one core spends).

Run: .venv/bin/python benchmarks/bench_design.py
"""

from __future__ import annotations

import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import one_core, process_ms, table

one_core()

from calib import load_chain  # noqa: E402
from calib.design.constraints import Constraints, filter_candidates  # noqa: E402
from calib.design.design import candidate_configurations, design  # noqa: E402
from calib.kinematics.tree import load_tree  # noqa: E402

NO_COLLISION = Constraints(collision=False)


def timed(fn, repeats: int) -> tuple[float, float, object]:
    """Median wall and CPU time [s] of fn() and its last result."""
    wall, cpu, out = [], [], None
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return statistics.median(wall), statistics.median(cpu), out


def design_rows() -> list[list[str]]:
    chain = load_chain("panda")
    rows = []
    cases = [
        (30, 2000, "position", "D", 5, "< 1 s"),
        (100, 20000, "position", "D", 3, "< 10 s"),
        (30, 2000, "pose", "D", 3, ""),
        (100, 20000, "pose", "D", 3, ""),
        (30, 2000, "position", "A", 3, ""),
        (30, 2000, "position", "I", 3, ""),
        (100, 20000, "position", "A", 3, "< 10 s"),
        (100, 20000, "position", "I", 3, "< 10 s"),
    ]
    for k, n, measure, crit, repeats, target in cases:
        wall, cpu, d = timed(
            lambda k=k, n=n, m=measure, c=crit: design(
                chain, k, candidates=n, measure=m, criterion=c, constraints=NO_COLLISION
            ),
            repeats,
        )
        stages = ", ".join(f"{s} {v:.0f}" for s, v in d.timings_ms.items())
        rows.append(
            [
                f"Panda, {k} from {n}, {measure}, {crit}",
                f"{wall:.2f}",
                f"{cpu:.2f}",
                target,
                f"{d.exchanges} exchanges, {d.sweeps} sweeps; ms: {stages}",
            ]
        )
    return rows


def tree_rows() -> list[list[str]]:
    """TALOS's two hands (16 joints, 70 parameters, 6 rows per configuration)."""
    tree = load_tree("talos", tools=("wrist_left_ft_tool_link", "wrist_right_ft_tool_link"))
    rows = []
    for k, n, repeats in ((30, 2000, 3), (100, 20000, 1)):
        wall, cpu, d = timed(
            lambda k=k, n=n: design(tree, k, candidates=n, constraints=NO_COLLISION), repeats
        )
        stages = ", ".join(f"{s} {v:.0f}" for s, v in d.timings_ms.items())
        rows.append(
            [
                f"TALOS hands (tree), {k} from {n}, position, D",
                f"{wall:.2f}",
                f"{cpu:.2f}",
                "",
                f"{d.model.b} parameters; ms: {stages}",
            ]
        )
    return rows


def collision_rows() -> list[list[str]]:
    rows = []
    for name in ("ur5", "panda", "tiago"):
        chain = load_chain(name)
        q = candidate_configurations(chain, 2000, 0)
        wall, cpu, (_, report) = timed(
            lambda c=chain, q=q: filter_candidates(c, q, [[0.0, 0.0, 0.0]], Constraints()), 3
        )
        rows.append(
            [
                f"{name}: collision filter, 2000 candidates",
                f"{wall:.2f}",
                f"{cpu:.2f}",
                "",
                f"{report.kept} kept, {len(q) - report.kept} rejected",
            ]
        )
    return rows


if __name__ == "__main__":
    header = ["case", "wall [s]", "cpu [s]", "target", "detail"]
    print(table(header, design_rows() + tree_rows() + collision_rows()))
    ms = process_ms(["design", "panda", "--configs", "30"], repeats=3)
    print(f"\n`calib design panda --configs 30` (collision filter on), whole process: {ms:.0f} ms")
