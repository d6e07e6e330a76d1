"""``auto`` against ``complete`` on two feet touching one floor from the torso (simulated).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/auto_shared_joints.py``

The campaign of ``tests/test_feet_on_the_floor.py`` for seeds 0-4: one true TALOS
(:func:`calib.measurements.true_robot.true_robot`, seed ``7 + s``: every joint placement of the
torso and both legs moved, 1 mm / 1 mrad standard deviation), each sole touching the floor
given 5 cm above the stretched soles in ``torso_2_link``'s frame (140 touches, seed ``10 + 2 s``
left and ``11 + 2 s`` right, joint noise 0.2 mrad): the first 100 fitted, the last 40 held
out (each term's validation touches). Both legs in one fit, the floor shared. Printed per
seed and ``params``: the joint placement components fitted, the held-out RMS height [mm] of
each foot (calib's ``held_out``, which tests/test_feet_on_the_floor.py checks against
Pinocchio), and ``auto``'s selection (components kept, winner, prior strength,
cross-validated errors [mm]). Seed 0 is the test's campaign. Why ``auto`` keeps less than the
data support here: docs/developers/engine.md, "Several chains sharing joints".
"""

from __future__ import annotations

import tempfile
import warnings
from pathlib import Path

import numpy as np

import calib
from calib.measurements.contact_campaign import simulate_contacts
from calib.measurements.true_robot import true_robot

BASE = "torso_2_link"
SIDES = ("left", "right")
FLOOR = np.eye(4)
FLOOR[2, 3] = -1.105  # the test's floor: 5 cm above the stretched sole (z -1.155)
FITTED, FRESH = 100, 40
SEEDS = range(5)


def campaign(folder: Path, seed: int) -> tuple[calib.Term, ...]:
    """Each foot's term: the nominal leg, its fitted touches, its fresh ones (validation)."""
    urdf = calib.load_chain("talos_left_leg").urdf_path
    legs = [calib.load_chain(urdf, BASE, f"{side}_sole_link") for side in SIDES]
    truth = true_robot(legs, folder / "true.urdf", seed=7 + seed)
    terms = []
    for k, (side, leg) in enumerate(zip(SIDES, legs, strict=True)):
        touches = simulate_contacts(
            calib.load_chain(truth.urdf, BASE, f"{side}_sole_link"),
            FITTED + FRESH,
            "plane",
            objects={"floor": FLOOR},
            error_mm=0,
            error_mrad=0,
            noise_mrad=0.2,
            seed=10 + 2 * seed + k,
        ).data
        first, last = np.arange(FITTED), np.arange(FITTED, FITTED + FRESH)
        terms.append(calib.Term(leg, touches.subset(first), touches.subset(last)))
    return tuple(terms)


def fit(terms: tuple[calib.Term, ...], params: str | None) -> str:
    """One line: components fitted, held-out heights, and auto's selection."""
    result = calib.calibrate(calib.Problem(terms, shared_planes=True, params=params))
    lines = result.summary().splitlines()
    fitted = lines[0].split(",")[2].split()[0]
    held = "/".join(line.split()[1] for line in lines if line.strip().startswith("held_out "))
    out = f"{params or 'auto':8s} {fitted:>2s} components, held-out height {held} mm"
    s = result.selection
    if s is not None:
        out += (
            f" | kept {len(s.kept)}, {s.winner}, prior {s.strength:.2g}, cv registration "
            f"{1e3 * s.registration_cv:.3f} selection {1e3 * s.selection_cv:.3f} complete "
            f"{1e3 * s.complete_cv:.3f}"
        )
    return out


def main() -> None:
    warnings.simplefilter("ignore")
    for seed in SEEDS:
        terms = campaign(Path(tempfile.mkdtemp()), seed)
        for params in (None, "complete"):
            print(f"seed {seed} {fit(terms, params)}")


if __name__ == "__main__":
    main()
