"""The README's study tables that the notebooks printed before they became tutorials.

Their checks are in tests/test_study_*.py; this script prints the numbers and draws the
design study's figure, as the notebooks did.

- ``realdata``: TIAGo (calibrate on 2021-11-30, score on 2021-11-26) at every ``--params``
  level, point 1, four points, the plate's pose and ``--elastic``; UR10 5 contiguous folds,
  position and pose data (the README's "Real data: held-out accuracy" tables).
- ``design [FIGURE.png]``: held-out error after ``--params complete`` calibrations, D-optimal
  sets against random sets of the same 1000 collision-free candidates, K = b, 2 b, 5 b, 10
  seeds, and the K at which designed sets match 100 random configurations; the criteria D, A
  and I (Panda, position, K = 2 b); the figure ``docs/design_study.png`` when a path is given.
- ``contacts``: TALOS's table touches, 5-fold cross-validation (seed 0): the nominal robot's
  table and contact frame (``register_contacts``, the README's 13.75 / 12.22 mm baseline), the
  calibration's registration and calibrated held-out gaps, ``--elastic``, both arms in one
  problem.

Run: ``OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/studies.py realdata|design|contacts``
(realdata about 10 s, contacts about 20 s, design a few minutes; measured at load 10 to 12
on 2 cores).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import warnings
from collections import defaultdict
from pathlib import Path

import numpy as np

import calib
from calib.calibration import residual_stats
from calib.design.constraints import Constraints, filter_candidates
from calib.design.design import candidate_configurations
from calib.design.observability import observation_model
from calib.kinematics.catalog import resolve_urdf

ROOT = Path(__file__).resolve().parent.parent
REAL = ROOT / "data" / "realdata"
LEVELS = ("frames", "offsets", "paper", "complete", "auto")


def mm(x: float) -> str:
    return f"{1e3 * x:.2f}"


def first_point(data):
    return dataclasses.replace(data, position=data.position[:, :3])


def realdata() -> None:
    """The TIAGo and UR10 tables: train and held-out RMS / max [mm] per level."""
    warnings.simplefilter("ignore", calib.DataWarning)
    tiago = REAL / "tiago"
    chain = calib.load_chain(tiago / "tiago_48_schunk.urdf", "base_footprint", "wrist_ft_tool_link")
    files = [tiago / f"qualisys_2021-11-{d}_static_postures.csv" for d in (30, 26)]
    train4, test4 = (calib.read_measurements(f, chain) for f in files)
    plate = [calib.read_measurements(f, chain, calib.Columns("markers")) for f in files]
    sets = {
        "point 1": (first_point(train4), first_point(test4)),
        "4 points": (train4, test4),
        "4 points as the plate's pose": tuple(plate),
    }
    print("TIAGo | --params | parameters | train RMS / max | held out | held out, point 1 [mm]")
    for label, (train, test) in sets.items():
        for level in LEVELS:
            r = calib.calibrate(chain, train, params=level, validate=test)
            v = r.validation.calibrated
            p1 = residual_stats(r, first_point(test4)) if label == "4 points" else v
            print(
                f"{label} | {level} | {len(r.names)} | {mm(r.after.position_rms)} / "
                f"{mm(r.after.position_max)} | {mm(v.position_rms)} / {mm(v.position_max)} | "
                f"{mm(p1.position_rms)} / {mm(p1.position_max)}"
                + ("" if r.accepted else " | REFUSED")
            )
    elastic = calib.calibrate(chain, sets["point 1"][0], validate=sets["point 1"][1], elastic=True)
    v = elastic.validation.calibrated
    held = f"{mm(v.position_rms)} / {mm(v.position_max)}"
    print(f"point 1 | --elastic | {len(elastic.names)} | held out {held}")
    ur10 = REAL / "ur10"
    uchain = calib.load_chain(ur10 / "ur10_robot.urdf", "universe", "wrist_3_link")
    poses = calib.read_measurements(
        ur10 / "calibration.csv", uchain, calib.Columns("rpy", ("phix1", "phiy1", "phiz1"))
    )
    folds = np.array_split(np.arange(poses.m), 5)
    print("UR10 | data | --params | pooled held-out RMS / max [mm]")
    for name, data in (("position", poses.position_only()), ("pose", poses)):
        for level in LEVELS:
            errors = []
            for test in folds:
                held = np.zeros(data.m, dtype=bool)
                held[test] = True
                r = calib.calibrate(uchain, data.subset(~held), params=level)
                sub = data.subset(held)
                torque = uchain.gravity_torques(sub.q) if np.any(r.state.compliance) else None
                errors.append(np.linalg.norm(r.state.residuals(sub, torque)[:, :3], axis=1))
            e = np.concatenate(errors)
            print(f"UR10 | {name} | {level} | {mm(np.sqrt(np.mean(e**2)))} / {mm(e.max())}")


NOISE_MM, SEEDS, FACTORS = 0.05, range(10), (1, 2, 5)
DESIGN_ROBOTS, MEASURES = ("ur5", "panda", "tiago"), ("position", "pose")


def _heldout_mm(chain, q, measure, seed) -> float:
    data = calib.simulate(chain, q, measure, noise_mm=NOISE_MM, seed=seed).measurements
    ref = candidate_configurations(chain, 100, seed=123)
    truth = calib.simulate(chain, ref, measure, noise_mm=0.0, seed=seed).measurements
    result = calib.calibrate(chain, data, params="complete")
    return 1e3 * residual_stats(result, truth).position_rms


def _k_matching(errors, b, key) -> str:
    """K at which the designed median reaches the random-100 median (log-log interpolation)."""
    target = np.median(errors[(*key, 100, "random 100")])
    ks = [f * b for f in FACTORS]
    med = [np.median(errors[(*key, k, "designed")]) for k in ks]
    if med[0] <= target:
        return f"<= {ks[0]}"
    for (k0, e0), (k1, e1) in zip(
        zip(ks, med, strict=True), zip(ks[1:], med[1:], strict=True), strict=False
    ):
        if e1 <= target:
            return f"{k0 * (k1 / k0) ** (np.log(e0 / target) / np.log(e0 / e1)):.0f}"
    return f"> {ks[-1]}"


def design(figure: str | None) -> None:
    """Designed against random sets, the table, the criteria and (optionally) the figure."""
    warnings.simplefilter("ignore")  # RankWarning of the smallest random sets
    free = Constraints(collision=False)
    errors, B, cands = defaultdict(list), {}, {}
    for name in DESIGN_ROBOTS:
        chain = calib.load_chain(name)
        q = candidate_configurations(chain, 1000, seed=0)
        cand = cands[name] = q[filter_candidates(chain, q, np.zeros((1, 3)), Constraints())[0]]
        for measure in MEASURES:
            b = B[name, measure] = observation_model(chain, measure).b
            for k in (f * b for f in FACTORS):
                d = calib.design(chain, k, candidates=cand, measure=measure, constraints=free)
                for seed in SEEDS:
                    pick = np.random.default_rng([seed, 7]).choice(len(cand), k, replace=False)
                    errors[name, measure, k, "designed"].append(
                        _heldout_mm(chain, d.q, measure, seed)
                    )
                    errors[name, measure, k, "random"].append(
                        _heldout_mm(chain, cand[pick], measure, seed)
                    )
            for seed in SEEDS:
                pick = np.random.default_rng([seed, 8]).choice(len(cand), 100, replace=False)
                errors[name, measure, 100, "random 100"].append(
                    _heldout_mm(chain, cand[pick], measure, seed)
                )
    print(
        "robot | measure | b | designed / random, K = b [mm] | K = 2 b | K = 5 b "
        "| match 100 random at K ="
    )
    for (name, measure), b in B.items():
        cells = [
            " / ".join(
                f"{np.median(errors[name, measure, f * b, kind]):.4f}"
                for kind in ("designed", "random")
            )
            for f in FACTORS
        ]
        match = _k_matching(errors, b, (name, measure))
        print(f"{name} | {measure} | {b} | {' | '.join(cells)} | {match}")
    panda = calib.load_chain("panda")
    k = 2 * B["panda", "position"]
    for criterion in ("D", "A", "I"):
        d = calib.design(
            panda,
            k,
            candidates=cands["panda"],
            measure="position",
            criterion=criterion,
            constraints=free,
        )
        e = np.median([_heldout_mm(panda, d.q, "position", s) for s in SEEDS])
        print(f"criterion {criterion} (Panda, position, K = {k}): held-out median {e:.4f} mm")
    print(f"random sets of {k}: {np.median(errors['panda', 'position', k, 'random']):.4f} mm")
    if figure:
        _design_figure(errors, B).savefig(figure, dpi=110)
        print(f"wrote {figure}")


def _design_figure(errors, B):
    from matplotlib.figure import Figure
    from matplotlib.ticker import FormatStrFormatter, NullLocator

    fig = Figure(figsize=(11, 6.2), layout="constrained")
    axes = fig.subplots(2, 3, sharex=False)
    for col, name in enumerate(DESIGN_ROBOTS):
        for row, measure in enumerate(MEASURES):
            ax, ks = axes[row, col], [f * B[name, measure] for f in FACTORS]
            for kind, color in (("random", "tab:gray"), ("designed", "tab:blue")):
                e = np.array([errors[name, measure, k, kind] for k in ks])
                q25, q50, q75 = np.percentile(e, [25, 50, 75], axis=1)
                ax.fill_between(ks, q25, q75, color=color, alpha=0.25, lw=0)
                ax.plot(
                    ks,
                    q50,
                    "o-",
                    color=color,
                    label="designed (D)" if kind == "designed" else "random K",
                )
            r100 = np.percentile(errors[name, measure, 100, "random 100"], [25, 50, 75])
            ax.axhspan(r100[0], r100[2], color="tab:orange", alpha=0.15, lw=0)
            ax.axhline(r100[1], color="tab:orange", ls="--", label="100 random")
            ax.set_xscale("log")
            ax.xaxis.set_minor_locator(NullLocator())
            ax.yaxis.set_major_formatter(FormatStrFormatter("%.3f"))
            ax.set_xticks(ks, [f"{k}" for k in ks])
            ax.set_title(f"{name}, {measure} (b = {B[name, measure]})", fontsize=10)
            if col == 0:
                ax.set_ylabel("held-out RMS error [mm]")
            if row == 1:
                ax.set_xlabel("configurations K")
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(
        "Held-out position error after calibration: median and quartiles of 10 seeds, "
        "noise 0.05 mm",
        fontsize=11,
    )
    return fig


def _nominal_baseline(chain, data, folds) -> str:
    """The table and contact frame fitted on the nominal robot (contact guessed 0.12 m along
    -z of the gripper), pooled held-out RMS height [mm] / roll / pitch [deg]."""
    from calib.calibration.contact_checks import register_contacts
    from calib.identification.contacts import PlaneContact

    guess = np.eye(4)
    guess[2, 3] = -0.12
    T = calib.from_chain(chain).forward(data.q)
    ids = np.array(data.ids)
    gaps = []
    for test in folds(data.m):
        train = np.setdiff1d(np.arange(data.m), test)
        reg = register_contacts(
            PlaneContact(), T[train, :3, :3], T[train, :3, 3], ids[train], guess
        )
        gaps.append(reg.gaps(T[test, :3, :3], T[test, :3, 3], reg.index(ids[test])))
    rms = np.sqrt(np.mean(np.vstack(gaps) ** 2, axis=0))
    return f"{1e3 * rms[0]:.2f} / {math.degrees(rms[1]):.2f} / {math.degrees(rms[2]):.2f}"


def contacts() -> None:
    """TALOS: 5-fold held-out gaps, height [mm] / roll / pitch [deg], pooled."""
    warnings.simplefilter("ignore")
    urdf = resolve_urdf("erd:talos_data/robots/talos_full_v2.urdf")
    sides = {
        "left": ("left_sole_link", "gripper_left_base_link", "left_train.csv"),
        "right": ("right_sole_link", "gripper_right_base_link", "right_train.csv"),
    }

    def take(data, rows):
        ids = tuple(data.ids[i] for i in rows)
        return calib.ContactData(data.joint_names, data.q[rows], ids, data.kind, data.source)

    def pooled(rows):
        m = sum(r.m for r in rows)
        return " / ".join(
            f"{math.sqrt(sum(r.m * getattr(r, k) ** 2 for r in rows) / m):.2f}"
            for k in ("height_rms_mm", "roll_rms_deg", "pitch_rms_deg")
        )

    def folds(m):
        return np.array_split(np.random.default_rng(0).permutation(m), 5)

    for side, (base, tool, name) in sides.items():
        chain = calib.load_chain(urdf, base, tool)
        data = calib.read_contacts(REAL / "talos_contact" / name, chain, "plane")
        print(f"{side}: {_nominal_baseline(chain, data, folds)} (register_contacts, held out)")
        for elastic in (False, True):
            before, after = [], []
            for test in folds(data.m):
                train = np.setdiff1d(np.arange(data.m), test)
                r = calib.calibrate(
                    chain,
                    take(data, train),
                    marker=(0.0, 0.0, -0.12),
                    validate=take(data, test),
                    seed=0,
                    elastic=elastic,
                )
                before.append(r.stats["held_out_registration"])
                after.append(
                    r.stats["held_out"] if r.accepted else r.stats["held_out_registration"]
                )
            label = "--elastic" if elastic else "calibrated"
            print(f"{side}: registration {pooled(before)} -> {label} {pooled(after)} (held out)")
    for label, pairs in (
        ("each from its foot", [(b, t) for b, t, _ in sides.values()]),
        ("both from the left foot", [("left_sole_link", t) for _, t, _ in sides.values()]),
    ):
        chains = [calib.load_chain(urdf, *p) for p in pairs]
        data = [
            calib.read_contacts(REAL / "talos_contact" / n, c, "plane")
            for c, (_, _, n) in zip(chains, sides.values(), strict=True)
        ]
        parts = [folds(d.m) for d in data]
        after = defaultdict(list)
        for f in range(5):
            terms = tuple(
                calib.Term(
                    c, take(d, np.setdiff1d(np.arange(d.m), p[f])), take(d, p[f]), (0, 0, -0.12)
                )
                for c, d, p in zip(chains, data, parts, strict=True)
            )
            r = calib.calibrate(calib.Problem(terms))
            for side, part in zip(sides, r.chains, strict=True):
                key = "held_out" if r.accepted else "held_out_registration"
                after[side].append(part.stats[key])
        print(f"{label}: " + "; ".join(f"{s} {pooled(after[s])}" for s in sides))


if __name__ == "__main__":
    job = sys.argv[1] if len(sys.argv) > 1 else ""
    if job == "realdata":
        realdata()
    elif job == "design":
        design(sys.argv[2] if len(sys.argv) > 2 else None)
    elif job == "contacts":
        contacts()
    else:
        sys.exit("usage: studies.py realdata | design [FIGURE.png] | contacts")
