"""Every number of the calibrations of calibration_stages.py, for two source trees compared.

A change meant to leave the results alone (a speed-up) is checked on the real cases: each
case's report (``to_dict()``) and joint placement errors, every number, dumped per tree, then
the largest difference per case:

    mkdir -p /tmp/before && git archive <commit> | tar -x -C /tmp/before
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/compare_estimates.py /tmp/before /tmp/a.pkl
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/compare_estimates.py . /tmp/b.pkl
    .venv/bin/python benchmarks/compare_estimates.py --diff /tmp/a.pkl /tmp/b.pkl
"""

from __future__ import annotations

import dataclasses
import math
import pickle
import sys
import warnings
from pathlib import Path

import numpy as np

SKIPPED = ("timings_ms", "timings", "created", "calib_version")
"""Report keys that differ between runs by nature."""


def leaves(x, path=""):
    """(path, number or text) of every leaf of a report."""
    if isinstance(x, dict):
        for k, v in x.items():
            if k not in SKIPPED:
                yield from leaves(v, f"{path}/{k}")
    elif isinstance(x, list | tuple):
        for i, v in enumerate(x):
            yield from leaves(v, f"{path}[{i}]")
    elif isinstance(x, int | float) and not isinstance(x, bool):
        yield path, float(x)
    elif isinstance(x, np.ndarray):
        for i, v in enumerate(x.ravel()):
            yield f"{path}<{i}>", float(v)
    else:
        yield path, repr(x)


def dump(root: Path, out: Path) -> None:
    """Every case's numbers, calib imported from ``root``."""
    sys.path.insert(0, str(root))
    warnings.simplefilter("ignore")
    import calib
    from calib import calibrate, load_chain, load_robot, read_measurements
    from calib.measurements.contact_campaign import read_contacts
    from calib.measurements.csvfile import Columns
    from calib.measurements.tree_campaign import simulate_tree

    if not Path(calib.__file__).is_relative_to(root):
        sys.exit(f"calib imported from {calib.__file__}, not from {root}")
    data = root / "data" / "realdata"
    tiago = data / "tiago"
    chain = load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    csv = tiago / "qualisys_2021-11-30_static_postures.csv"
    four = read_measurements(csv, chain)
    one = dataclasses.replace(four, position=four.position[:, :3])
    plate = read_measurements(csv, chain, Columns("markers"))
    talos = load_robot("talos_full_v2.urdf", "left_sole_link", "gripper_left_base_link")
    touches = read_contacts(data / "talos_contact" / "left_train.csv", talos, "plane")
    tools = ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    hands = load_robot("talos", "base_link", tools)
    seen = simulate_tree(hands, 30, markers=[0.05, 0.02, 0.1], noise_mm=0.05, seed=1)
    ur10 = load_chain(data / "ur10" / "ur10_robot.urdf", "universe", "wrist_3_link")
    ur10_data = read_measurements(data / "ur10" / "calibration.csv", ur10)
    marker = (0, 0, -0.12)
    cases = {
        "point1": lambda: calibrate(chain, one),
        "complete": lambda: calibrate(chain, one, params="complete"),
        "four": lambda: calibrate(chain, four),
        "plate": lambda: calibrate(chain, plate),
        "ur10": lambda: calibrate(ur10, ur10_data, holdout=0.25),
        "talos": lambda: calibrate(talos, touches, marker=marker),
        "talos_complete": lambda: calibrate(talos, touches, marker=marker, params="complete"),
        "tree": lambda: calibrate(hands, seen.measurements, holdout=0.25),
        "tree_complete": lambda: calibrate(
            hands, seen.measurements, holdout=0.25, params="complete"
        ),
    }
    found = {}
    for name, fn in cases.items():
        r = fn()
        numbers = dict(leaves(r.to_dict()))
        if hasattr(r, "placements"):
            for joint, E in r.placements.errors().items():
                for i, v in enumerate(E.ravel()):
                    numbers[f"E/{joint}<{i}>"] = float(v)
        found[name] = numbers
    out.write_bytes(pickle.dumps(found))


def compare(a: Path, b: Path) -> None:
    """The largest difference per case (numbers), and the texts that differ."""
    first, second = pickle.loads(a.read_bytes()), pickle.loads(b.read_bytes())
    for case, A in first.items():
        B = second[case]
        worst, where, texts = 0.0, None, []
        for k in set(A) | set(B):
            x, y = A.get(k), B.get(k)
            if isinstance(x, float) and isinstance(y, float):
                if not (math.isnan(x) and math.isnan(y)) and abs(x - y) > worst:
                    worst, where = abs(x - y), k
            elif x != y and not k.endswith(("/urdf", "/data")):  # the trees' own paths
                texts.append((k, x, y))
        placed = [abs(A[k] - B[k]) for k in A if k.startswith("E/") and k in B]
        print(
            f"{case:15s} largest difference {worst:.2e} at {where}; joint placement errors "
            f"{max(placed, default=0.0):.2e}; other texts: {texts[:3]}"
        )


if __name__ == "__main__":
    if sys.argv[1] == "--diff":
        compare(Path(sys.argv[2]), Path(sys.argv[3]))
    else:
        dump(Path(sys.argv[1]).resolve(), Path(sys.argv[2]))
