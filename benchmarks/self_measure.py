"""The robot measuring itself, one term among others: TALOS's head camera and the arms' table.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/self_measure.py``

One true TALOS (:func:`calib.measurements.true_robot.true_robot`, seed 3: every joint origin
of the three chains and the head camera's placement ``rgbd_optical_joint`` moved by 1 mm /
1 mrad standard deviation). Its terms, simulated on it:

* both arms touching a table from their soles (``left_sole_link`` ->
  ``gripper_left_base_link``, ``right_sole_link`` -> ``gripper_right_base_link``), 40 touches
  each, joint noise ``NOISE_MRAD``;
* the head camera (``rgbd_optical_frame``) seeing a marker on the left gripper
  (``MARKER`` in ``gripper_left_base_link``), 40 configurations (:func:`calib.simulate` on
  the true chain), position noise ``NOISE_MM`` per axis.

Fitted by :func:`calib.calibration.engine.calibrate_contact_chains` (``auto`` and ``complete``, 25 %
held out, seed 0): the arms alone, the camera alone, and all three terms together. Printed: each
term's held-out RMS (height [mm] / roll / pitch [deg] for a plane; x / y / z [mm] for the camera)
against its registration's, then the noise-free round trip (largest held-out error of every
term), and the median time of the joint fit (5 runs, CPU of this process and wall clock).
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from calib import load_robot, simulate
from calib.calibration.engine import calibrate_contact_chains
from calib.measurements.contact_campaign import simulate_contacts
from calib.measurements.true_robot import true_robot

URDF = "talos_full_v2.urdf"
PAIRS = (
    ("left_sole_link", "gripper_left_base_link"),
    ("right_sole_link", "gripper_right_base_link"),
    ("rgbd_optical_frame", "gripper_left_base_link"),
)
MARKER = (0.02, 0.01, 0.05)
NOISE_MM = 0.5
NOISE_MRAD = 0.2
TOUCHES = 40


def campaign(folder: Path, noisy: bool):
    """The nominal chains and each term's data on one true robot."""
    nominal = [load_robot(URDF, *p) for p in PAIRS]
    truth = true_robot(nominal, folder / "true.urdf", measuring=nominal[2:], seed=3)
    true = [load_robot(str(truth.urdf), *p) for p in PAIRS]
    zero = {"error_mm": 0.0, "error_mrad": 0.0}
    joints = NOISE_MRAD if noisy else 0.0
    data = [
        simulate_contacts(c, TOUCHES, "plane", seed=1 + k, noise_mrad=joints, **zero).data
        for k, c in enumerate(true[:2])
    ]
    noise = NOISE_MM if noisy else 0.0
    camera = simulate(true[2], TOUCHES, "position", marker=MARKER, seed=2, noise_mm=noise, **zero)
    data.append(camera.measurements)
    return nominal, data


def line(label: str, part) -> str:
    held, reg = part.stats["held_out"], part.stats["held_out_registration"]
    fmt = " / ".join(f"{v:.3f}" for v in held.rms)
    was = " / ".join(f"{v:.3f}" for v in reg.rms)
    return f"  {label:28s} {fmt:26s} (registration {was})"


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        nominal, data = campaign(Path(tmp), noisy=True)
        sets = {"arms": [0, 1], "camera alone": [2], "arms + camera": [0, 1, 2]}
        for params in ("auto", "complete"):
            print(f"held-out RMS, params={params} (noise {NOISE_MM} mm, joints {NOISE_MRAD} mrad)")
            for name, idx in sets.items():
                r = calibrate_contact_chains(
                    [nominal[i] for i in idx],
                    [data[i] for i in idx],
                    params=params,
                    holdout=0.25,
                    seed=0,
                )
                verdict = "accepted" if r.accepted else f"REFUSED ({r.refusal})"
                print(f" {name}: {len(r.free)} placement directions, {verdict}")
                for i, part in zip(idx, r.chains, strict=True):
                    print(line(f"{PAIRS[i][0]} -> {PAIRS[i][1]}", part))
        nominal, exact = campaign(Path(tmp), noisy=False)
        r = calibrate_contact_chains(nominal, exact, params="complete", holdout=0.25, seed=0)
        worst = [max(p.stats["held_out"].max) for p in r.chains]
        print(f"noise-free round trip (complete): largest held-out error per term {worst} (mm/deg)")
        print(f"identifiable {r.identifiable}, fitted at complete {r.unknowns}")
        wall, cpu = [], []
        for _ in range(5):
            t, c = time.perf_counter(), time.process_time()
            calibrate_contact_chains(nominal, data)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
        print(
            f"arms + camera, default calibration ({sum(d.m for d in data)} rows): median "
            f"{1e3 * statistics.median(cpu):.0f} ms CPU ({1e3 * statistics.median(wall):.0f} ms "
            f"wall)"
        )


if __name__ == "__main__":
    main()
