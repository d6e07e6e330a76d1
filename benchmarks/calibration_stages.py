"""CPU-time medians of the TIAGo default calibration's stages, for one source tree of calib.

Run it on two trees alternately (the machine's load drifts):

    mkdir -p /tmp/before && git archive <commit> | tar -x -C /tmp/before
    for i in 1 2 3; do for r in /tmp/before .; do
        OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/calibration_stages.py $r
    done; done

One line per run [ms of process CPU time, medians]: the TIAGo session (37 postures, point 1,
``auto``) whole and by the joint engine's stages (``registration``, ``selection``, ``fit``,
``validation``: the result's ``timings_ms``, wall clock, medians), then point 1 ``complete``, the
four points and the plate's pose (``auto``), the UR10 with ``holdout=0.25``, the TALOS
left contact calibration (default, through ``calibrate``) and the TALOS hands as a tree (30
simulated configurations of both hands, 0.05 mm of noise, ``holdout=0.25``: the README's
trees).
"""

from __future__ import annotations

import dataclasses
import sys
import warnings
from pathlib import Path

ROOT = Path(sys.argv[1] if len(sys.argv) > 1 else ".").resolve()
sys.path.insert(0, str(ROOT))

from common import cpu_median_ns  # noqa: E402 (the benchmarks' folder, not ROOT)

warnings.simplefilter("ignore")

import calib  # noqa: E402
from calib import calibrate, load_chain, load_robot, read_measurements  # noqa: E402
from calib.measurements.contact_campaign import read_contacts  # noqa: E402
from calib.measurements.csvfile import Columns  # noqa: E402
from calib.measurements.tree_campaign import simulate_tree  # noqa: E402

DATA = Path(__file__).resolve().parent.parent / "data" / "realdata"
STAGES = ("registration", "selection", "fit", "validation")
"""The joint engine's stages (its result's ``timings_ms``)."""


def cpu_ms(fn, repeats: int) -> float:
    """Median process CPU time of ``fn()`` [ms], after one warm-up call."""
    return cpu_median_ns(fn, repeats) / 1e6


def main() -> None:
    tiago = DATA / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    csv = tiago / "qualisys_2021-11-30_static_postures.csv"
    four = read_measurements(csv, chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    plate = read_measurements(csv, chain, Columns("markers"))
    ur10 = load_chain(DATA / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link")
    ur10_data = read_measurements(DATA / "ur10" / "calibration.csv", ur10)
    talos = load_robot("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
    touches = read_contacts(DATA / "talos_contact" / "left_train.csv", talos, "plane")
    hands = load_robot(
        "talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    )
    seen = simulate_tree(hands, 30, markers=[0.05, 0.02, 0.1], noise_mm=0.05, seed=1)
    spent: dict[str, list[float]] = {}

    def run():
        for name, ms in calibrate(chain, one).timings_ms.items():
            spent.setdefault(name, []).append(ms)

    whole = cpu_ms(run, 21)
    stage = {n: sorted(t)[len(t) // 2] for n, t in spent.items()}
    others = [
        cpu_ms(lambda: calibrate(chain, one, params="complete"), 11),
        cpu_ms(lambda: calibrate(chain, four), 5),
        cpu_ms(lambda: calibrate(chain, plate), 5),
        cpu_ms(lambda: calibrate(ur10, ur10_data, holdout=0.25), 11),
        cpu_ms(lambda: calibrate(talos, touches, marker=(0, 0, -0.12)), 5),
        cpu_ms(lambda: calibrate(hands, seen.measurements, holdout=0.25), 11),
    ]
    print(
        f"{ROOT.name} point1 {whole:.1f} ["
        + " ".join(f"{n} {stage[n]:.1f}" for n in STAGES)
        + "] complete {:.1f} four {:.1f} plate {:.1f} ur10 {:.1f} talos {:.1f} tree {:.1f}".format(
            *others
        ),
        flush=True,
    )


if __name__ == "__main__":
    if not Path(calib.__file__).is_relative_to(ROOT):
        sys.exit(f"calib imported from {calib.__file__}, not from {ROOT}")
    main()
