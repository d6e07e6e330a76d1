"""Speed of the identifiability analysis of contacts (``calib analyze --measure plane|...``).

Medians of in-process calls on preloaded chains, 100 postures (the default): the whole
``analyze`` (conversion, projection of random configurations onto the contact, Jacobian,
QR) and its projection step alone. The chains: UR5, Panda, TIAGo's arm, and TALOS from the
left foot up the leg backwards to the left gripper (15 joints; issue 21's target: ``plane``
under 50 ms) and to the right foot (12 joints, the closed loop of two feet). The machine is
shared: the CPU time of the process (``time.process_time``, one BLAS thread) is reported beside
the wall time, which other processes inflate.

Run: .venv/bin/python benchmarks/bench_contacts.py
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import cpu_median_ns, median_ms, one_core, table

one_core()

from calib import analyze, from_chain, load_chain  # noqa: E402
from calib.identification.contact_postures import contact_configurations  # noqa: E402
from calib.identification.contacts import contact_kind  # noqa: E402

warnings.simplefilter("ignore")

ROBOTS = (
    ("ur5", None, None),
    ("panda", None, None),
    ("tiago", None, None),
    ("talos", "left_sole_link", "gripper_left_base_link"),
    ("talos", "left_sole_link", "right_sole_link"),
)
KINDS = ("plane", "plane-point", "fixed-point", "fixed-pose")
REPEATS = 11


def projection_ms(chain, mdh, kind: str) -> float:
    """Median time of the projection of 100 postures onto the contact [ms]."""
    contact = contact_kind(kind)

    def run():
        return contact_configurations(
            mdh, contact, lambda count, r: chain.random_configurations(count, r), 100
        )

    return median_ms(run, REPEATS, 1)


def cpu_ms(fn, repeats: int) -> float:
    """Median CPU time of ``fn()`` over ``repeats`` calls [ms], after one warm-up."""
    return cpu_median_ns(fn, repeats) / 1e6


def main() -> None:
    rows = []
    for name, base, tool in ROBOTS:
        chain = load_chain(name, base, tool)
        mdh = from_chain(chain).idealized()
        label = name if tool is None else f"{name} {base} -> {tool}"
        for kind in KINDS:
            run = lambda c=chain, k=kind: analyze(c, measure=k, params="paper")  # noqa: E731
            whole, cpu = median_ms(run, REPEATS, 1), cpu_ms(run, REPEATS)
            projection = projection_ms(chain, mdh, kind)
            rows.append((label, kind, f"{whole:.1f}", f"{cpu:.1f}", f"{projection:.1f}"))
    heads = ["chain", "measure", "analyze wall [ms]", "analyze CPU [ms]", "projection [ms]"]
    print(table(heads, rows))


if __name__ == "__main__":
    main()
