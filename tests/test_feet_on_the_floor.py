"""TALOS feet on a floor given: docs/howto/contacts.md "Feet on the ground".

The campaigns are calib's, the scores Pinocchio's. Two feet from the torso: one true robot
(:func:`calib.measurements.true_robot.true_robot`: every joint placement of the torso and both
legs moved, 1 mm, 1 mrad std), each foot's touches simulated on its chain of the true URDF on
one floor given in the torso's frame (``simulate_contacts(..., objects=)``, no further error),
0.2 mrad of joint noise; the fresh touches of each foot are the validation files. Both feet on
the floor: the floor is the left sole's plane, known, held in the fit (``known_planes``). The
written URDF, the report's floor and sole frames (or the floor given) are scored by
tests/contact_scorer.py (Pinocchio, no calib), as are the true URDF's own touches.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from contact_scorer import plane_gaps, read_joints, rms

import calib
from calib.measurements.contact_campaign import simulate_contacts, write_contacts
from calib.measurements.true_robot import true_robot

pytestmark = pytest.mark.filterwarnings("ignore")

BASE = "torso_2_link"
TORSO = ["torso_1_joint", "torso_2_joint"]
FLOOR = np.eye(4)
FLOOR[2, 3] = -1.105  # in the torso's frame: 5 cm above the stretched sole (z -1.155)
SIDES = ("left", "right")


def _campaign(folder: Path, noise_mrad: float = 0.2) -> dict[str, tuple[Path, Path]]:
    """Each foot's 100 touches and 40 fresh ones of one true robot, on the floor given."""
    urdf = calib.load_chain("talos_left_leg").urdf_path  # talos_reduced.urdf
    chains = [calib.load_chain(urdf, BASE, f"{side}_sole_link") for side in SIDES]
    truth = true_robot(chains, folder / "true.urdf", seed=7)
    files = {}
    for k, side in enumerate(SIDES):
        true = calib.load_chain(truth.urdf, BASE, f"{side}_sole_link")
        touches = simulate_contacts(
            true,
            140,
            "plane",
            objects={"floor": FLOOR},
            error_mm=0,
            error_mrad=0,
            noise_mrad=noise_mrad,
            seed=10 + k,
        ).data
        files[side] = (folder / f"{side}.csv", folder / f"{side}_fresh.csv")
        write_contacts(files[side][0], touches.subset(np.arange(100)))
        write_contacts(files[side][1], touches.subset(np.arange(100, 140)))
    return files


def test_the_simulated_soles_are_flat_on_the_given_floor(tmp_path):
    """Without noise, every simulated touch of the true URDF is on the floor given (Pinocchio)."""
    files = _campaign(tmp_path, noise_mrad=0.0)
    for side in SIDES:
        for path in files[side]:
            _, joints = read_joints(path)
            gaps = plane_gaps(
                tmp_path / "true.urdf", BASE, f"{side}_sole_link", np.eye(4), FLOOR, joints
            )
            assert np.abs(gaps).max() < 1e-9  # m, rad


def test_two_feet_on_one_floor_from_the_torso(tmp_path):
    """Fitted together (the torso once, one floor, ``complete``), the written URDF predicts
    fresh touches of the true robot within twice the true URDF's own gaps (the joint noise),
    20 times better than the nominal one; calib's held-out gaps are the independent scorer's
    on the written files."""
    files = _campaign(tmp_path)
    urdf = calib.load_chain("talos_left_leg").urdf_path
    terms = []
    for side, (data, fresh) in files.items():
        chain = calib.load_chain(urdf, BASE, f"{side}_sole_link")
        touches = calib.read_contacts(data, chain, "plane")
        terms.append(calib.Term(chain, touches, calib.read_contacts(fresh, chain, "plane")))
    result = calib.calibrate(calib.Problem(tuple(terms), shared_planes=True, params="complete"))
    result.write(tmp_path / "feet.urdf", report=tmp_path / "feet.json")
    report = json.loads((tmp_path / "feet.json").read_text())
    assert result.accepted and list(report["objects"]["planes"]) == ["floor"]
    assert set(TORSO) <= set(report["model"]["shared_joints"])
    plane = np.array(report["objects"]["planes"]["floor"]["matrix"])
    for k, (side, (_, fresh)) in enumerate(files.items()):
        tool = f"{side}_sole_link"
        contact = np.array(report["frames"]["contacts"][tool]["matrix"])
        _, joints = read_joints(fresh)
        scored = rms(plane_gaps(tmp_path / "feet.urdf", BASE, tool, contact, plane, joints))
        true = rms(plane_gaps(tmp_path / "true.urdf", BASE, tool, np.eye(4), FLOOR, joints))
        stats = result.chains[k].stats
        assert scored == pytest.approx(stats["held_out"].rms, abs=1e-6)  # mm, deg
        assert scored[0] < 2 * true[0] and max(scored[1:]) < 2 * max(true[1:])
        assert stats["held_out_registration"].rms[0] > 20 * scored[0]


def _sole_to_sole(folder: Path, seed: int, known: bool) -> tuple[float, int]:
    """Both soles on the floor, the floor the left sole's plane, fitted or held: the written
    URDF's held-out heights [mm] scored by Pinocchio, and the unknowns counted."""
    chain = calib.load_chain("talos", "left_sole_link", "right_sole_link")
    floor = {"floor": (0.0, 0.0, 0.0, 0.0, 0.0, 1.0)}
    campaign = simulate_contacts(chain, 350, "plane", objects=floor, noise_mrad=0.2, seed=seed)
    write_contacts(folder / "fit.csv", campaign.data.subset(np.arange(150)))
    write_contacts(folder / "fresh.csv", campaign.data.subset(np.arange(150, 350)))
    data, fresh = (
        calib.read_contacts(folder / f, chain, "plane") for f in ("fit.csv", "fresh.csv")
    )
    problem = calib.Problem(
        (calib.Term(chain, data, fresh),), known_planes=floor if known else None
    )
    calib.calibrate(problem).write(folder / "feet.urdf", report=folder / "feet.json")
    report = json.loads((folder / "feet.json").read_text())
    plane = np.eye(4) if known else np.array(report["objects"]["planes"]["floor"]["matrix"])
    contact = np.array(report["frames"]["contacts"]["right_sole_link"]["matrix"])
    _, joints = read_joints(folder / "fresh.csv")
    gaps = plane_gaps(
        folder / "feet.urdf", "left_sole_link", "right_sole_link", contact, plane, joints
    )
    return float(rms(gaps)[0]), calib.analyze(problem).n_unknowns


def test_the_known_floor_under_the_base_sole_fits_as_well(tmp_path):
    """Held, the floor (the left sole's plane) leaves 3 unknowns and adds the sole's height
    (1): the fit's held-out heights, scored by Pinocchio on the written URDF and the floor
    given, are no worse than the fitted floor's, pooled over seeds."""
    fitted, held = [], []
    for seed in range(3):
        fitted.append(_sole_to_sole(tmp_path, seed, known=False))
        held.append(_sole_to_sole(tmp_path, seed, known=True))
    assert all(h[1] == f[1] - 3 + 1 for f, h in zip(fitted, held, strict=True))
    pooled = [np.sqrt(np.mean(np.square([r[0] for r in runs]))) for runs in (fitted, held)]
    assert pooled[1] <= pooled[0]
