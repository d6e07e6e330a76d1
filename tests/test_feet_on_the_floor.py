"""Two TALOS feet on one floor, fitted as two terms from the torso: docs/howto/contacts.md.

The campaign is made with Pinocchio alone (``calib simulate`` draws each term's truth and
plane on its own, so it cannot make one robot's two legs touch one floor): the true robot is
the URDF with every joint placement of the torso and both legs moved (1 mm, 1 mrad std), the
torso held (a robot on a stand), each touch a posture of the torso and one leg brought by
Gauss-Newton to the sole flat on the floor, its joints recorded with 0.2 mrad of noise. The
fresh touches of each foot are the validation files; the written URDF, the report's floor and
sole frames are scored by tests/contact_scorer.py (Pinocchio, no calib).
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from contact_scorer import plane_gaps, read_joints, rms

import calib

pytestmark = pytest.mark.filterwarnings("ignore")

BASE = "torso_2_link"
TORSO = ["torso_1_joint", "torso_2_joint"]
LEGS = {side: [f"leg_{side}_{k}_joint" for k in range(1, 7)] for side in ("left", "right")}


def _true_robot(urdf: Path, rng: np.random.Generator) -> pin.Model:
    model = pin.buildModelFromUrdf(str(urdf))
    for name in TORSO + LEGS["left"] + LEGS["right"]:
        j = model.getJointId(name)
        error = pin.exp6(pin.Motion(rng.normal(0.0, 1e-3, 6)))
        model.jointPlacements[j] = model.jointPlacements[j] * error
    return model


def _gap(model, data, q, sole: int, floor: pin.SE3) -> np.ndarray:
    """Height [m], roll and pitch [rad] of the sole in the floor's frame (a plane's gap)."""
    pin.framesForwardKinematics(model, data, q)
    rel = floor.actInv(data.oMf[model.getFrameId(BASE)].actInv(data.oMf[sole]))
    return np.r_[rel.translation[2], pin.rpy.matrixToRpy(rel.rotation)[:2]]


def _touch(model, data, side: str, floor: pin.SE3, rng) -> np.ndarray:
    """The torso's and one leg's joints at a posture with the sole flat on the floor."""
    sole = model.getFrameId(f"{side}_sole_link")
    idx = [model.joints[model.getJointId(n)].idx_q for n in TORSO + LEGS[side]]
    lo, hi = model.lowerPositionLimit[idx], model.upperPositionLimit[idx]
    while True:
        q = pin.neutral(model)
        q[idx] = lo + (hi - lo) * (0.3 + 0.4 * rng.random(len(idx)))
        for _ in range(30):
            g = _gap(model, data, q, sole, floor)
            J = np.empty((3, len(idx)))
            for k, i in enumerate(idx):
                step = np.zeros(model.nq)
                step[i] = 1e-7
                J[:, k] = (_gap(model, data, q + step, sole, floor) - g) / 1e-7
            q[idx] -= np.linalg.lstsq(J, g, rcond=None)[0]
        inside = np.all(q[idx] >= lo) and np.all(q[idx] <= hi)
        if np.abs(_gap(model, data, q, sole, floor)).max() < 1e-10 and inside:
            return q[idx] + rng.normal(0.0, 2e-4, len(idx))


def _campaign(urdf: Path, folder: Path) -> dict[str, tuple[Path, Path]]:
    """Each foot's 40 touches and 20 fresh ones, as contact CSVs of one plane 'floor'."""
    rng = np.random.default_rng(7)
    model = _true_robot(urdf, rng)
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    stretched = data.oMf[model.getFrameId(BASE)].actInv(
        data.oMf[model.getFrameId("left_sole_link")]
    )
    floor = pin.SE3(np.eye(3), np.r_[0.0, 0.0, stretched.translation[2] + 0.05])  # knees bent
    files = {}
    for side in ("left", "right"):
        rows = [_touch(model, data, side, floor, rng) for _ in range(60)]
        files[side] = (folder / f"{side}.csv", folder / f"{side}_fresh.csv")
        for path, part in zip(files[side], (rows[:40], rows[40:]), strict=True):
            with open(path, "w", newline="") as f:
                out = csv.writer(f)
                out.writerow(["plane", *TORSO, *LEGS[side]])
                out.writerows(["floor", *q] for q in part)
    return files


def test_two_feet_on_one_floor_from_the_torso(tmp_path):
    """Fitted together (the torso once, one floor), the written URDF predicts fresh touches
    of the true robot to the joint noise, 20 times better than the nominal one; calib's
    held-out gaps are the independent scorer's on the written files."""
    urdf = Path(calib.load_chain("talos_left_leg").urdf_path)  # talos_reduced.urdf
    files = _campaign(urdf, tmp_path)
    terms = []
    for side, (data, fresh) in files.items():
        chain = calib.load_chain(urdf, BASE, f"{side}_sole_link")
        touches = calib.read_contacts(data, chain, "plane")
        terms.append(calib.Term(chain, touches, calib.read_contacts(fresh, chain, "plane")))
    result = calib.calibrate(calib.Problem(tuple(terms), shared_planes=True))
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
        stats = result.chains[k].stats
        assert scored == pytest.approx(stats["held_out"].rms, abs=1e-6)  # mm, deg
        assert scored[0] < 0.1 and max(scored[1:]) < 0.05  # mm, deg: the joint noise's
        assert stats["held_out_registration"].rms[0] > 20 * scored[0]
