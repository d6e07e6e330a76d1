"""Two held-out studies of `calib design` (issue 13; docs/howto/design.md, explanation/design.md).

1. Trees: TALOS's two hands (16 joints, 70 parameters, two markers), 40 configurations
   designed from 800 candidates against 40 random ones; simulate (1 mm, 1 mrad errors,
   0.05 mm noise) and calibrate; RMS error of both hands at 100 configurations the fit
   never saw, against the true points; 10 seeds.
2. Orientation weight: UR5 pose campaigns with 0.05 mm and 0.5 mrad of noise (ratio
   0.1 m/rad); 30 configurations designed at 0.1 and at 1 m/rad; calibrate (weight
   estimated); held-out position error at 200 configurations; 10 seeds.

3. Payoff after calibration (issue 22): ``calib design ROBOT --configs 30 --candidates 2000
   --marker 0.05 0.02 0.10`` against 30 random configurations (``calib simulate --configs
   30``), UR5, Panda and TIAGo measured in position; 1 mm / 1 mrad errors on every joint
   placement, 0.05 mm noise; both sets calibrated with the default options and scored
   against the true robot at 500 configurations neither saw; 10 seeds (true robot, noise,
   random set). Besides the default (criterion D, ``auto``) it shows criterion I and
   ``--params complete``, the predicted errors (I on the held-out configurations) and the
   least I any set of 30 of the design's candidates can reach (a convex relaxation with a
   duality certificate), which bounds the gain a design can buy.

Run: .venv/bin/python docs/design_studies.py [tree|weight|payoff]   (all: about 10 minutes)
"""

from __future__ import annotations

import sys

import numpy as np

from calib import calibrate, load_chain, simulate
from calib.calibration import residual_stats
from calib.calibration.instrument import tree_points
from calib.design.constraints import Constraints, filter_candidates
from calib.design.design import candidate_configurations, design, least_i
from calib.design.observability import reference
from calib.kinematics.tree import load_tree
from calib.measurements.tree_campaign import simulate_tree, true_points

SEEDS = range(10)
NO_COLLISION = Constraints(collision=False)


def tree_study() -> None:
    """Study 1: designed vs random sets of a tree."""
    tree = load_tree("talos", tools=("wrist_left_ft_tool_link", "wrist_right_ft_tool_link"))
    markers = np.array([[0.05, 0.02, 0.1], [0.03, -0.02, 0.08]])
    q_ref = tree.random_configurations(100, 99)
    errors: dict[str, list[float]] = {"designed": [], "random": []}
    for seed in SEEDS:
        d = design(
            tree,
            40,
            candidates=800,
            marker=markers,
            seed=seed,
            random_sets=10,
            constraints=NO_COLLISION,
        )
        sets = {"designed": d.q, "random": candidate_configurations(tree, 40, 100 + seed)}
        for name, q in sets.items():
            camp = simulate_tree(tree, q, markers, 1.0, 1.0, 0.05, seed)
            parts = calibrate(tree, camp.measurements).chains
            err = tree_points(parts, tree.paths, q_ref) - true_points(camp.true_mdh, q_ref, markers)
            errors[name].append(1e3 * float(np.sqrt(np.mean(np.sum(err**2, axis=2)))))
    for name, e in errors.items():
        print(f"TALOS hands, {name:8s}: median {np.median(e):.4f} mm  {np.round(e, 4)}")


def weight_study() -> None:
    """Study 2: the orientation weight a pose design assumes."""
    chain = load_chain("ur5")
    q_ref = candidate_configurations(chain, 200, seed=99)
    for weight in (0.1, 1.0):
        errors = []
        for seed in SEEDS:
            d = design(
                chain,
                30,
                candidates=1000,
                measure="pose",
                orientation_weight=weight,
                seed=seed,
                random_sets=1,
                constraints=NO_COLLISION,
            )
            data = simulate(chain, d.q, "pose", noise_mm=0.05, noise_mrad=0.5, seed=seed)
            truth = simulate(chain, q_ref, "position", noise_mm=0.0, seed=seed)
            result = calibrate(chain, data.measurements, params="complete")
            errors.append(1e3 * residual_stats(result, truth.measurements).position_rms)
        print(f"UR5 pose, designed at {weight:g} m/rad: median {np.median(errors):.4f} mm")


PAYOFF_MARKER = (0.05, 0.02, 0.10)


def heldout_i(model, q: np.ndarray, L: np.ndarray) -> float:
    """I of the configurations q on the reference information L: sqrt(trace(L M^-1))."""
    W = model.jacobian(q).reshape(-1, model.b)
    return float(np.sqrt(np.trace(L @ np.linalg.inv(W.T @ W))))


def payoff_study(robots=("ur5", "panda", "tiago")) -> None:
    """Study 3: designed vs random sets of 30, default calibration options."""
    k, noise = 30, 0.05
    for name in robots:
        chain = load_chain(name)
        designs = {
            c: design(chain, k, candidates=2000, marker=PAYOFF_MARKER, criterion=c)
            for c in ("D", "I")
        }
        model = designs["D"].model
        q_cand = candidate_configurations(chain, 2000, 0)  # the design's candidates
        q_cand = q_cand[filter_candidates(chain, q_cand, [PAYOFF_MARKER], Constraints())[0]]
        errors: dict[tuple[str, str], list[float]] = {}
        pred: dict[str, list[float]] = {"D": [], "I": [], "random": [], "least": []}
        for seed in SEEDS:
            q_ref = candidate_configurations(chain, 500, 1000 + seed)
            L = reference(model, q_ref).mean
            truth = simulate(chain, q_ref, "position", PAYOFF_MARKER, seed=seed).measurements
            sets = {c: d.q for c, d in designs.items()}
            sets["random"] = chain.random_configurations(k, seed)
            for set_name, q in sets.items():
                data = simulate(chain, q, "position", PAYOFF_MARKER, noise_mm=noise, seed=seed)
                pred[set_name].append(heldout_i(model, q, L))
                for level in ("auto", "complete"):
                    result = calibrate(chain, data.measurements, marker=PAYOFF_MARKER, params=level)
                    rms = residual_stats(result, truth).position_rms
                    errors.setdefault((set_name, level), []).append(1e3 * rms)
            if seed == 0:
                pred["least"].append(least_i(model.jacobian(q_cand), k, L))
        print(f"{name} (b = {model.b}), median held-out RMS error over {len(SEEDS)} seeds [mm]:")
        for level in ("auto", "complete"):
            rand = np.median(errors["random", level])
            cells = [f"random {rand:.4f}"] + [
                f"{c} {np.median(errors[c, level]):.4f} "
                f"({100 * (1 - np.median(errors[c, level]) / rand):.0f} % lower)"
                for c in ("D", "I")
            ]
            print(f"  {level:8s}: " + ", ".join(cells))
        r = np.median(pred["random"])
        print(
            f"  predicted x noise: random {noise * r:.4f}, D {noise * np.median(pred['D']):.4f}, "
            f"I {noise * np.median(pred['I']):.4f}; no set of {k} of the candidates below "
            f"{noise * pred['least'][0]:.4f} mm: the gain is at most "
            f"{100 * (1 - pred['least'][0] / r):.0f} %"
        )


STUDIES = {"tree": tree_study, "weight": weight_study, "payoff": payoff_study}

if __name__ == "__main__":
    for study in sys.argv[1:] or STUDIES:
        STUDIES[study]()
