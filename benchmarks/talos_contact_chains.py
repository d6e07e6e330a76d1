"""TALOS flush contacts, both arms in one fit: 5-fold cross-validated held-out gaps.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/talos_contact_chains.py``

The left chain (``left_sole_link`` -> ``gripper_left_base_link``, ``left_train.csv``) and the
right one (``right_sole_link`` -> ``gripper_right_base_link``, ``right_train.csv``) share the
torso joints. Each chain's touches are split into 5 folds (seeded 0, as
``talos_contact_calibration.py``); fold f of both chains is held out together, the rest fitted,
and the held folds' gaps pooled: RMS height [mm], roll and pitch [deg] per chain, for

* ``both``: :func:`calibrate_contact_chains` on the two chains (shared torso, a plane each);
  ``both, left sole``: the right chain from ``left_sole_link`` too (all joints are recorded):
  the left leg and the torso shared;
* ``alone``: the same function on one chain;
* ``offsets``: the same at ``params="offsets"``;
* ``baseline``: the registration (the nominal robot with its own plane and contact).

* ``left sole + soles' loop``: both arms from the left sole with the closed loop
  ``left_sole_link`` -> ``right_sole_link`` (both soles flat on the ground: one fixed pose,
  a ``fixed-pose`` chain whose touches are the postures of both files, one pose per file:
  the feet stood elsewhere ten days apart, :func:`~calib.measurements.contact_loops.read_loop`);
  fold f of the loop is the postures of fold f of the arms, held out with them; its rows
  weighted ``pose_weight`` 1, 10 and 100; ``left sole, offsets``: the same arms at
  ``offsets`` without the loop.

``fit`` is the calibrated model; ``delivered`` is what calib hands over (the registration
when the model is refused). Then the plane question: the two sessions, both expressed from
``left_sole_link`` (all joints are recorded), fitted with one shared table or a table each.
Last, the median time of the default joint fit on all touches (target ~2 s): CPU time of
this process (one thread), which a machine shared with other jobs does not inflate, and the
wall-clock time.
"""

from __future__ import annotations

import statistics
import time
import warnings
from pathlib import Path

import numpy as np

from calib import load_robot
from calib.calibration.engine import calibrate_contact_chains
from calib.measurements.contact_campaign import ContactData, read_contacts
from calib.measurements.contact_loops import join_loops, read_loop

DATA = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
URDF = "talos_full_v2.urdf"
CONTACT = (0.0, 0.0, -0.12)
FOLDS = 5
SEED = 0
SIDES = ("left", "right")
FIGAROH = {
    "single": {"left": (9.26, 0.75, 0.52), "right": (8.03, 0.98, 0.59)},
    "both": {"left": (4.86, 0.44, 0.50), "right": (7.91, 0.98, 0.59)},
}
"""FIGAROH's published held-out RMS (height mm, roll deg, pitch deg), sessions of another day."""


def _folds(data: ContactData) -> list[np.ndarray]:
    return np.array_split(np.random.default_rng(SEED).permutation(data.m), FOLDS)


class Pool:
    """Held-out gaps pooled over folds: fit, delivered, baseline; refused folds."""

    def __init__(self) -> None:
        self.fit: list[tuple] = []
        self.delivered: list[tuple] = []
        self.base: list[tuple] = []
        self.refused = 0
        self.loop: list[tuple] = []

    def add(self, stats: dict, accepted: bool) -> None:
        h, b = stats["held_out"], stats["held_out_registration"]
        self.loop.append((h.m, h.weighted_mm, b.weighted_mm))
        if "height" not in h.names:  # a loop: its weighted gaps only
            self.fit.append((h.m, 0.0, 0.0, 0.0))
            self.refused += not accepted
            return
        row = (h.m, h.height_rms_mm, h.roll_rms_deg, h.pitch_rms_deg)
        brow = (b.m, b.height_rms_mm, b.roll_rms_deg, b.pitch_rms_deg)
        self.fit.append(row)
        self.base.append(brow)
        self.delivered.append(row if accepted else brow)
        self.refused += not accepted

    @staticmethod
    def rms(parts: list[tuple]) -> tuple[float, float, float]:
        m = sum(p[0] for p in parts)
        return tuple(  # type: ignore[return-value]
            float(np.sqrt(sum(p[0] * p[k] ** 2 for p in parts) / m)) for k in (1, 2, 3)
        )

    def line(self, label: str) -> str:
        f, d, b = self.rms(self.fit), self.rms(self.delivered), self.rms(self.base)
        return (
            f"{label:22s} fit {f[0]:6.2f} mm {f[1]:.2f} {f[2]:.2f} deg | delivered {d[0]:6.2f} "
            f"{d[1]:.2f} {d[2]:.2f} | baseline {b[0]:6.2f} {b[1]:.2f} {b[2]:.2f} | "
            f"refused {self.refused}/{FOLDS}"
        )


def cross_validate(chains, data, shared_planes: bool = False, params=None) -> list[Pool]:
    """Pools per chain of the joint fit of ``chains`` (folds of every chain held out together)."""
    folds = [_folds(d) for d in data]
    pools = [Pool() for _ in chains]
    for f in range(FOLDS):
        train = [
            d.subset(np.setdiff1d(np.arange(d.m), fo[f])) for d, fo in zip(data, folds, strict=True)
        ]
        held = [d.subset(fo[f]) for d, fo in zip(data, folds, strict=True)]
        r = calibrate_contact_chains(
            chains,
            train,
            contact=CONTACT,
            validate=held,
            shared_planes=shared_planes,
            params=params,
        )
        for pool, part in zip(pools, r.chains, strict=True):
            pool.add(part.stats, r.accepted)
    return pools


def with_loop(chains, data, loop, loops, params=None, pose_weight=1.0) -> list[Pool]:
    """Pools per chain (the arms', then the loop's): the arms' folds, the loop's the same rows.

    ``loops[k]``: the loop's touches from the postures of ``data[k]`` (same rows, same order).
    """
    folds = [_folds(d) for d in data]
    pools = [Pool() for _ in range(len(chains) + 1)]
    for f in range(FOLDS):
        keep = [np.setdiff1d(np.arange(d.m), fo[f]) for d, fo in zip(data, folds, strict=True)]
        train = [d.subset(k) for d, k in zip(data, keep, strict=True)]
        held = [d.subset(fo[f]) for d, fo in zip(data, folds, strict=True)]
        train.append(join_loops([lp.subset(k) for lp, k in zip(loops, keep, strict=True)]))
        held.append(join_loops([lp.subset(fo[f]) for lp, fo in zip(loops, folds, strict=True)]))
        r = calibrate_contact_chains(
            [*chains, loop],
            train,
            contact=CONTACT,
            validate=held,
            params=params,
            pose_weight=pose_weight,
        )
        for pool, part in zip(pools, r.chains, strict=True):
            pool.add(part.stats, r.accepted)
    return pools


def loop_line(pool: Pool, label: str) -> str:
    """The loop's pooled held-out weighted gap [mm] (fit and registration)."""
    m = sum(p[0] for p in pool.fit)
    fit = float(np.sqrt(sum(p[0] * p[1] ** 2 for p in pool.loop) / m))
    base = float(np.sqrt(sum(p[0] * p[2] ** 2 for p in pool.loop) / m))
    return f"{label:22s} loop held-out weighted {fit:.3f} mm (registration {base:.3f})"


def loop_study(from_left, moved) -> None:
    """Both arms from the left sole with the soles' loop, and at ``offsets`` without it."""
    loop = load_robot(URDF, "left_sole_link", "right_sole_link")
    loops = [read_loop(DATA / f"{s}_train.csv", loop, s) for s in SIDES]  # a pose per session
    for params in (None, "offsets"):
        for weight in (1.0, 10.0, 100.0):
            pools = with_loop(from_left, moved, loop, loops, params, weight)
            label = f"+ loop w{weight:g} {params or 'auto'}"
            for side, pool in zip(SIDES, pools[:-1], strict=True):
                print(pool.line(f"{side} {label}"))
            print(loop_line(pools[-1], label), flush=True)
    left_offsets = cross_validate(from_left, moved, params="offsets")
    for side, pool in zip(SIDES, left_offsets, strict=True):
        print(pool.line(f"{side} left sole, offsets"))


def main() -> None:
    warnings.simplefilter("ignore")
    chains = [load_robot(URDF, f"{s}_sole_link", f"gripper_{s}_base_link") for s in SIDES]
    data = [
        read_contacts(DATA / f"{s}_train.csv", c, "plane")
        for s, c in zip(SIDES, chains, strict=True)
    ]
    both = cross_validate(chains, data)
    from_left = [load_robot(URDF, "left_sole_link", f"gripper_{s}_base_link") for s in SIDES]
    moved = [
        read_contacts(DATA / f"{s}_train.csv", c, "plane")
        for s, c in zip(SIDES, from_left, strict=True)
    ]
    left_sole = cross_validate(from_left, moved)
    loop_study(from_left, moved)
    both_offsets = cross_validate(chains, data, params="offsets")
    for k, side in enumerate(SIDES):
        alone = cross_validate([chains[k]], [data[k]])[0]
        print(both[k].line(f"{side} both"))
        print(left_sole[k].line(f"{side} both, left sole"))
        print(alone.line(f"{side} alone"))
        offsets = cross_validate([chains[k]], [data[k]], params="offsets")[0]
        print(both_offsets[k].line(f"{side} both, offsets"))
        print(offsets.line(f"{side} alone, offsets"))
        for what, anchor in FIGAROH.items():
            h, r, p = anchor[side]
            print(f"{side:5s} FIGAROH {what:6s} {h:6.2f} mm {r:.2f} {p:.2f} deg")
    # the plane question: both sessions from the left sole, one table for both (a table
    # each is "both, left sole" above)
    shared = cross_validate(from_left, moved, shared_planes=True)
    for side, pool in zip(SIDES, shared, strict=True):
        print(pool.line(f"{side} one table"))
    wall, cpu = [], []
    for _ in range(5):
        t, c = time.perf_counter(), time.process_time()
        calibrate_contact_chains(chains, data, contact=CONTACT)
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    print(
        f"both chains, default calibration on {sum(d.m for d in data)} touches: median "
        f"{1e3 * statistics.median(cpu):.0f} ms CPU ({1e3 * statistics.median(wall):.0f} ms wall)"
    )


if __name__ == "__main__":
    main()
