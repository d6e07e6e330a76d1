"""Two studies of the README's `calib design` section (issue 13), held-out errors.

1. Trees: TALOS's two hands (16 joints, 70 parameters, two markers), 40 configurations
   designed from 800 candidates against 40 random ones; simulate (1 mm, 1 mrad errors,
   0.05 mm noise) and calibrate_tree; RMS error of both hands at 100 configurations the fit
   never saw, against the true points; 10 seeds.
2. Orientation weight: UR5 pose campaigns with 0.05 mm and 0.5 mrad of noise (ratio
   0.1 m/rad); 30 configurations designed at 0.1 and at 1 m/rad; calibrate (weight
   estimated); held-out position error at 200 configurations; 10 seeds.

Run: .venv/bin/python docs/design_studies.py   (about a minute)
"""

from __future__ import annotations

import numpy as np

from calib import calibrate, load_chain, residual_stats, simulate
from calib.calibration.tree_pipeline import calibrate_tree
from calib.constraints import Constraints
from calib.design import candidate_configurations, design
from calib.tree import load_tree
from calib.tree_campaign import simulate_tree, true_points

SEEDS = range(10)
NO_COLLISION = Constraints(collision=False)


def tree_study() -> None:
    """Study 1: designed vs random sets of a tree."""
    tree = load_tree("talos", tools=("wrist_left_ft_tool_link", "wrist_right_ft_tool_link"))
    markers = np.array([[0.05, 0.02, 0.1], [0.03, -0.02, 0.08]])
    q_ref = tree.random_configurations(100, 99)
    errors: dict[str, list[float]] = {"designed": [], "random": []}
    for seed in SEEDS:
        d = design(tree, 40, candidates=800, markers=markers, seed=seed, random_sets=10,
                   constraints=NO_COLLISION)
        sets = {"designed": d.q, "random": candidate_configurations(tree, 40, 100 + seed)}
        for name, q in sets.items():
            camp = simulate_tree(tree, q, markers, 1.0, 1.0, 0.05, seed)
            state = calibrate_tree(tree, camp.measurements).state
            pred = true_points(state.mdh, q_ref, state.markers) @ state.frame[:3, :3].T
            err = pred + state.frame[:3, 3] - true_points(camp.true_mdh, q_ref, markers)
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
            d = design(chain, 30, candidates=1000, measure="pose", orientation_weight=weight,
                       seed=seed, random_sets=1, constraints=NO_COLLISION)
            data = simulate(chain, d.q, "pose", noise_mm=0.05, noise_mrad=0.5, seed=seed)
            truth = simulate(chain, q_ref, "position", noise_mm=0.0, seed=seed)
            result = calibrate(chain, data.measurements, params="complete")
            errors.append(1e3 * residual_stats(result, truth.measurements).position_rms)
        print(f"UR5 pose, designed at {weight:g} m/rad: median {np.median(errors):.4f} mm")


if __name__ == "__main__":
    tree_study()
    weight_study()
