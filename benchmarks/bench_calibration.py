"""Speed of calibration (issue 10: the default fit on the TIAGo session, and the selection,
within 10x of the complete fit of issue 4, about 50 ms).

Cases: the real TIAGo session of data/realdata (37 postures: point 1, the four points,
the four points read as the plate's pose) at every parameter level, and simulated UR5 /
Panda campaigns (100 configurations).
Medians, in-process and whole-process (interpreter start and imports included).

Run: .venv/bin/python benchmarks/bench_calibration.py
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import ROOT, median_times_ms, one_core, process_ms, table

one_core()

import warnings  # noqa: E402

from calib import (  # noqa: E402
    Columns,
    calibrate,
    load_chain,
    read_measurements,
    simulate,
    write_measurements,
)

warnings.simplefilter("ignore")

TIAGO = ROOT / "data" / "realdata" / "tiago"
MARKER = (0.05, 0.02, 0.1)


def tiago_rows() -> list[list[str]]:
    if not TIAGO.is_dir():
        return [["TIAGo session", "-", "-", "-", f"{TIAGO} not found"]]
    chain = load_chain(TIAGO / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    four = read_measurements(TIAGO / "qualisys_2021-11-30_static_postures.csv", chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    plate = read_measurements(
        TIAGO / "qualisys_2021-11-30_static_postures.csv", chain, Columns("markers")
    )
    rows = []
    for label, data in (("point 1", one), ("4 points", four), ("plate pose", plate)):
        for level in ("auto", "frames", "offsets", "complete"):
            last = []
            ms, cpu = median_times_ms(
                lambda d=data, lv=level, r=last: r.append(calibrate(chain, d, params=lv)), 7, 1
            )
            res = last[-1]
            stages = ", ".join(f"{k} {v:.0f}" for k, v in res.timings_ms.items())
            rows.append(
                [
                    f"TIAGo, 37 postures, {label}, --params {level}",
                    f"{ms:.0f}",
                    f"{cpu:.0f}",
                    TARGETS.get((label, level), ""),
                    f"{len(res.names)} parameters; {stages}",
                ]
            )
    return rows


TARGETS = {("point 1", "auto"): "< 40 (issue 22)", ("4 points", "auto"): "< 500 (issue 18)"}
"""Targets of the TIAGo rows [ms]: (data, level) -> text."""


def simulated_rows() -> list[list[str]]:
    rows = []
    for robot, measure in (("ur5", "position"), ("ur5", "pose"), ("panda", "position")):
        chain = load_chain(robot)
        data = simulate(
            chain, configs=100, measure=measure, marker=MARKER, seed=0, noise_mm=0.1
        ).measurements
        for level in ("auto", "complete"):
            ms, cpu = median_times_ms(
                lambda d=data, lv=level, c=chain: calibrate(c, d, marker=MARKER, params=lv), 7, 1
            )
            label = f"{robot}, m=100, {measure}, --params {level}"
            rows.append([label, f"{ms:.0f}", f"{cpu:.0f}", "", ""])
    return rows


def whole_process_rows() -> list[list[str]]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        meas = out / "meas.csv"
        data = simulate(
            load_chain("ur5"), configs=100, measure="position", marker=MARKER, seed=0, noise_mm=0.1
        )
        write_measurements(meas, data.measurements)
        args = [
            "calibrate",
            "ur5",
            "--data",
            str(meas),
            "--out",
            str(out / "c.urdf"),
            "--report",
            str(out / "r.json"),
        ]
        return [
            [
                "`calib calibrate ur5` (100 positions, auto) whole process",
                f"{process_ms(args):.0f}",
                "",
                "",
                "start-up included",
            ],
            [
                "`calib list` whole process (start-up reference)",
                f"{process_ms(['list']):.0f}",
                "",
                "",
                "",
            ],
        ]


def main() -> None:
    rows = tiago_rows() + simulated_rows() + whole_process_rows()
    print(table(["case", "median [ms]", "cpu [ms]", "target [ms]", "notes"], rows))


if __name__ == "__main__":
    main()
