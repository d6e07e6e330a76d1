"""Held-out accuracy of ``--params auto`` against the registration alone (``frames``) on the
UR10 campaign of data/realdata/ur10 (23 poses), under several fold layouts (issue 18, item 3).

For each layout, every fold is held out in turn, calib calibrates on the rest (default
options) and the fold's positions are scored by the calibrated state; the table gives the
pooled held-out position RMS of ``auto`` and of ``frames`` and their ratio (above 1: ``auto``
is worse). Position data are the point x1, y1, z1 alone; pose data add the rpy columns.

Layouts: 5 contiguous folds, 5 interleaved folds (configuration i in fold i mod 5), 5 folds of
seeded random permutations (seeds 0-7, numpy default_rng), and leave-one-out.

Run: .venv/bin/python benchmarks/bench_ur10_folds.py [position|pose]
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from common import ROOT, one_core, table

one_core()

import numpy as np  # noqa: E402

from calib import Columns, calibrate, load_chain, read_measurements  # noqa: E402

warnings.simplefilter("ignore")

UR10 = ROOT / "data" / "realdata" / "ur10"


def layouts(m: int) -> dict[str, list[np.ndarray]]:
    """The fold layouts: name -> held-out configurations of each fold."""
    out = {
        "5 contiguous": np.array_split(np.arange(m), 5),
        "5 interleaved": [np.arange(f, m, 5) for f in range(5)],
    }
    for seed in range(8):
        perm = np.random.default_rng(seed).permutation(m)
        out[f"5 random, seed {seed}"] = np.array_split(perm, 5)
    out["leave-one-out"] = [np.array([i]) for i in range(m)]
    return out


def pooled(chain, data, folds, params: str) -> tuple[float, list[int]]:
    """Pooled held-out position RMS [m], and the parameters kept on each fold's complement."""
    errors, kept = [], []
    for test in folds:
        mask = np.zeros(data.m, dtype=bool)
        mask[test] = True
        res = calibrate(chain, data.subset(~mask), params=params)
        errors.append(np.linalg.norm(res.state.residuals(data.subset(mask))[:, :3], axis=1))
        kept.append(len(res.selection.kept) if res.selection is not None else 0)
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2))), kept


def main() -> None:
    which = sys.argv[1] if len(sys.argv) > 1 else "position"
    chain = load_chain(UR10 / "ur10_robot.urdf", "universe", "wrist_3_link")
    data = read_measurements(
        UR10 / "calibration.csv", chain, Columns("rpy", ("phix1", "phiy1", "phiz1"))
    )
    if which == "position":
        data = data.position_only()
    rows = []
    for name, folds in layouts(data.m).items():
        auto, kept = pooled(chain, data, folds, "auto")
        frames, _ = pooled(chain, data, folds, "frames")
        counts = "" if len(kept) > 5 else " ".join(map(str, kept))
        rows.append(
            [name, f"{1e3 * auto:.3f}", f"{1e3 * frames:.3f}", f"{auto / frames:.4f}", counts]
        )
    print(f"UR10 {which} data, {data.m} configurations: pooled held-out position RMS [mm]")
    print(table(["layout", "auto", "frames", "auto/frames", "kept per fold"], rows))


if __name__ == "__main__":
    main()
