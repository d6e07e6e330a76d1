"""CPU-time medians of one measured chain through the joint engine, its only route (issue 28).

``calibrate`` fits one chain measured by an instrument with the joint engine as a one-term
problem (:func:`calib.calibration.entry.measured_chain`; until issue 28 the MDH chart's own
pipeline did, the figures it gave are in the issue's notes). One line [ms of process CPU time,
medians]: the TIAGo session (37 postures, point 1, ``auto``: the target is under 40 ms), point
1 ``complete``, the UR10 with ``holdout=0.25``. Run it a few times (the machine's load drifts):

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/chain_routes.py

``accuracy``: held-out errors [mm, RMS / max], scored on what calib writes (the
URDF read by Pinocchio, its marker link placed in the instrument's frame by the report;
``tests/pinref.instrument_points``): the TIAGo (fit on 2021-11-30, scored on 2021-11-26's point
1) at every level, four points and the plate's pose; the UR10 (5 contiguous folds, pooled);
simulated UR5 and Panda (30 configurations, 0.05 mm noise, 3 seeds, 50 noise-free unseen ones).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/chain_routes.py accuracy
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import warnings
from pathlib import Path

from common import cpu_median_ns, one_core

one_core()
warnings.simplefilter("ignore")

import numpy as np  # noqa: E402

import calib  # noqa: E402
from calib import calibrate, load_chain, read_measurements  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "data" / "realdata"
sys.path.insert(0, str(ROOT / "tests"))
from pinref import instrument_points  # noqa: E402  (Pinocchio alone)

ROUTES = ("engine",)


def held_out(result, chain, data, tmp: Path) -> np.ndarray:
    """Point 1's errors [mm] of the written URDF on ``data`` (Pinocchio alone)."""
    path = tmp / "cal.urdf"
    path.write_bytes(result.urdf())
    got = instrument_points(
        path, result.to_dict(), chain.base_frame, chain.tool_frame, chain.joint_names, data.q
    )
    return 1e3 * np.linalg.norm(got - data.position[:, :3], axis=1)


def line(label: str, errors: list[np.ndarray]) -> None:
    """One row: each route's RMS / max [mm]."""
    cells = [f"{np.sqrt(np.mean(e**2)):.3f} / {e.max():.3f}" for e in errors]
    print(f"| {label} | " + " | ".join(cells) + " |", flush=True)


def both(fit, score) -> list[np.ndarray]:
    """``[score(fit())]``: the one route's (the pipeline's column is gone with it)."""
    return [score(fit())]


def tiago(tmp: Path) -> None:
    folder = DATA / "tiago"
    chain = load_chain(folder / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    files = [folder / f"qualisys_2021-11-{d}_static_postures.csv" for d in (30, 26)]
    train4, test4 = (read_measurements(f, chain) for f in files)
    one, test = (dataclasses.replace(d, position=d.position[:, :3]) for d in (train4, test4))
    plate = read_measurements(files[0], chain, calib.Columns("markers"))
    for level in ("frames", "offsets", "complete", "auto"):
        fit = lambda level=level: calibrate(chain, one, validate=test, params=level)  # noqa: E731
        line(f"TIAGo point 1, {level}", both(fit, lambda r: held_out(r, chain, test, tmp)))
    for label, data in (("4 points", train4), ("plate pose", plate)):
        fit = lambda data=data: calibrate(chain, data)  # noqa: E731
        line(f"TIAGo {label}, auto", both(fit, lambda r: held_out(r, chain, test, tmp)))


def ur10(tmp: Path) -> None:
    chain = load_chain(DATA / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link")
    columns = calib.Columns("rpy", ("phix1", "phiy1", "phiz1"))
    poses = read_measurements(DATA / "ur10" / "calibration.csv", chain, columns)
    folds = np.array_split(np.arange(poses.m), 5)
    for name, data in (("position", poses.position_only()), ("pose", poses)):
        for level in ("frames", "offsets", "complete", "auto"):
            pooled: list[list[np.ndarray]] = [[], []]
            for test in folds:
                held = np.zeros(data.m, dtype=bool)
                held[test] = True
                train, seen = data.subset(~held), data.subset(held)
                fit = lambda t=train, lv=level: calibrate(chain, t, params=lv)  # noqa: E731
                score = lambda r, s=seen: held_out(r, chain, s, tmp)  # noqa: E731
                for k, e in enumerate(both(fit, score)):
                    pooled[k].append(e)
            line(f"UR10 {name}, {level}", [np.concatenate(p) for p in pooled])


def simulated(tmp: Path) -> None:
    marker = (0.05, 0.02, 0.1)
    for robot in ("ur5", "panda"):
        chain = load_chain(robot)
        for measure in ("position", "pose"):
            for level in ("auto", "complete"):
                pooled: list[list[np.ndarray]] = [[], []]
                for seed in range(3):
                    seen = calib.simulate(
                        chain, 30, measure, marker=marker, noise_mm=0.05, seed=seed
                    ).measurements
                    q = calib.simulate(chain, 50, seed=100 + seed).measurements.q
                    truth = calib.simulate(chain, q, measure, marker=marker, seed=seed).measurements
                    fit = lambda c=chain, s=seen, lv=level: calibrate(c, s, params=lv)  # noqa: E731
                    score = lambda r, c=chain, t=truth: held_out(r, c, t, tmp)  # noqa: E731
                    for k, e in enumerate(both(fit, score)):
                        pooled[k].append(e)
                line(f"{robot} {measure}, {level}", [np.concatenate(p) for p in pooled])


def accuracy() -> None:
    print("| case | " + " | ".join(ROUTES) + " |")
    with tempfile.TemporaryDirectory() as folder:
        for study in (tiago, ur10, simulated):
            study(Path(folder))


def main() -> None:
    tiago = DATA / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    four = read_measurements(tiago / "qualisys_2021-11-30_static_postures.csv", chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    ur10 = load_chain(DATA / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link")
    ur10_data = read_measurements(DATA / "ur10" / "calibration.csv", ur10)
    cases = {
        "point1": (lambda: calibrate(chain, one), 21),
        "complete": (lambda: calibrate(chain, one, params="complete"), 11),
        "ur10": (lambda: calibrate(ur10, ur10_data, holdout=0.25), 11),
    }
    ms = {name: cpu_median_ns(fn, n) / 1e6 for name, (fn, n) in cases.items()}
    print("engine   " + " ".join(f"{k} {v:.1f}" for k, v in ms.items()), flush=True)


if __name__ == "__main__":
    accuracy() if sys.argv[1:] == ["accuracy"] else main()
