"""TALOS touching a table (data/realdata/talos_contact): registration baseline vs calibrations.

Pinocchio's placements of ``left_sole_link -> gripper_left_base_link`` (the right side
likewise), no MDH. Every number is a 5-fold cross-validated held-out RMS of the contact
frame's height [mm], roll and pitch [deg] in the fitted table frame (folds drawn with seed 0;
the ridge strength of each model is chosen inside each training set by an inner 4-fold CV).

- ``registration``: the table and the contact frame fitted on the nominal robot
  (:func:`calib.calibration.contact_checks.register_contacts`): no calibration.
- ``offsets``: + an offset on each of the 15 chain joints.
- ``offsets+legs``: + a compliance of each leg joint under its gravity torque (standing).
- ``geometry``: + a 6-vector error of every joint placement of the chain (ridge).
- ``geometry+legs``: both.

``both``: the two chains fitted together, sharing the torso's parameters (each side keeps its
table: the sessions are ten days apart and the base frames are different soles).
Every held-out gap is recomputed by a second route (a Pinocchio model with the fitted
placements and joint values) and the largest difference is printed.

Run: ``OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/talos_contact_study.py``
"""

from __future__ import annotations

import csv
import math
import time
from dataclasses import dataclass
from pathlib import Path

import contact_model as cm
import numpy as np
import pinocchio as pin

from calib.calibration.contact_checks import register_contacts
from calib.identification.contacts import PlaneContact
from calib.kinematics.catalog import resolve_urdf
from calib.kinematics.so3 import rotation_matrix

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT / "data" / "realdata" / "talos_contact"
URDF = resolve_urdf("erd:talos_data/robots/talos_full_v2.urdf")
SIDES = {
    "left": ("left_sole_link", "gripper_left_base_link", "left_train.csv", "leg_right_1_joint"),
    "right": ("right_sole_link", "gripper_right_base_link", "right_train.csv", "leg_left_1_joint"),
}
GUESS = np.eye(4)
GUESS[2, 3] = -0.12
FOLDS, INNER, SEED = 5, 4, 0
LAMBDAS = 10.0 ** np.arange(-6.0, 3.0)
ITERATIONS = 30
FIGAROH = {
    "left": ((9.26, 0.75, 0.52), (4.86, 0.44, 0.50)),
    "right": ((8.03, 0.98, 0.59), (7.91, 0.98, 0.59)),
}


@dataclass(frozen=True, eq=False)
class Side:
    """One side's touches: its chain, joint readings, gravity torques, Pinocchio configs."""

    name: str
    chain: cm.Chain
    q: np.ndarray  # (m, n) chain joint readings [rad]
    tau: np.ndarray  # (m, n) gravity torques [N m]
    Q: np.ndarray  # (m, nq) Pinocchio configurations (all joints as read)
    ids: tuple[str, ...]

    def take(self, rows: np.ndarray) -> Side:
        return Side(
            self.name,
            self.chain,
            self.q[rows],
            self.tau[rows],
            self.Q[rows],
            tuple(self.ids[i] for i in rows),
        )


def read_side(model: pin.Model, name: str) -> Side:
    base, tool, file, other = SIDES[name]
    with open(DATA / file, newline="") as f:
        rows = list(csv.DictReader(f))
    chain = cm.load(model, base, tool)
    Q = np.tile(pin.neutral(model), (len(rows), 1))
    for j in range(1, model.njoints):
        if model.names[j] in rows[0]:
            Q[:, model.joints[j].idx_q] = [float(r[model.names[j]]) for r in rows]
    q = np.column_stack([[float(r[j]) for r in rows] for j in chain.joints])
    return Side(name, chain, q, cm.torques(chain, Q, other), Q, tuple(r["plane"] for r in rows))


@dataclass(frozen=True)
class Spec:
    """Which robot errors are free: per chain joint, 'placement' (6), 'offset', 'compliance'."""

    name: str
    placement: bool = False
    offset: bool = False
    legs_compliance: bool = False


def robot_keys(sides: list[Side], spec: Spec) -> list[tuple[str, int]]:
    """The free robot errors as (joint, k): k < 6 placement, 6 offset, 7 compliance."""
    keys: list[tuple[str, int]] = []
    for side in sides:
        for j in side.chain.joints:
            ks = [*(range(6) if spec.placement else ()), *((6,) if spec.offset else ())]
            if spec.legs_compliance and j.startswith("leg_"):
                ks.append(7)
            keys += [(j, k) for k in ks if (j, k) not in keys]
    return keys


@dataclass(frozen=True, eq=False)
class Fitted:
    """A fit: the robot errors, and per side its plane and contact frame."""

    keys: tuple[tuple[str, int], ...]
    theta: np.ndarray
    planes: tuple[cm.Plane, ...]
    contacts: tuple[np.ndarray, ...]

    def errors(self, chain: cm.Chain) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Placement errors ``(n, 6)``, offsets ``(n,)`` and scaled compliances ``(n,)``."""
        E = np.zeros((chain.n, 8))
        for (j, k), v in zip(self.keys, self.theta, strict=True):
            if j in chain.joints:
                E[chain.joints.index(j), k] = v
        return E[:, :6], E[:, 6], E[:, 7]


def gaps(fitted: Fitted, k: int, side: Side, weight: float = 1.0):
    """Residuals ``(m, 3)`` of a side with a fit, and the pieces of the Jacobian."""
    xi, off, comp = fitted.errors(side.chain)
    q = side.q + off + comp * side.tau / cm.TORQUE_SCALE
    kin = cm.kinematics(side.chain, q, xi)
    tw, end = cm.contact_twists(side.chain, kin, fitted.contacts[k])
    return cm.plane_rows(end, tw, fitted.planes[k], weight)


def _jacobian(fitted: Fitted, sides: list[Side], weights):
    blocks, res = [], []
    nk = len(fitted.keys)
    for k, side in enumerate(sides):
        r, Jr, Jp, Jc = gaps(fitted, k, side, weights[k])
        J = np.zeros((len(r), 3, nk + 5 * len(sides)))
        for c, (j, kind) in enumerate(fitted.keys):
            if j in side.chain.joints:
                i = side.chain.joints.index(j)
                col = Jr[:, :, i, min(kind, 6)]
                J[:, :, c] = col * (side.tau[:, i, None] / cm.TORQUE_SCALE if kind == 7 else 1)
        J[:, :, nk + 5 * k : nk + 5 * k + 3] = Jp
        J[:, :, nk + 5 * k + 3 : nk + 5 * k + 5] = Jc
        blocks.append(J.reshape(-1, J.shape[2]))
        res.append(r.ravel())
    return np.concatenate(res), np.concatenate(blocks)


def fit(sides: list[Side], keys, lam: float, weights) -> Fitted:
    """Gauss-Newton with a ridge ``lam |theta|^2`` on the robot errors, from the registration."""
    planes, contacts = [], []
    for side, w in zip(sides, weights, strict=True):
        kin = cm.kinematics(side.chain, side.q)
        reg = register_contacts(
            PlaneContact(), kin.T[:, :3, :3], kin.T[:, :3, 3], side.ids, GUESS, w
        )
        P = reg.objects[0]
        planes.append(cm.Plane(P[:3, 2], float(P[:3, 2] @ P[:3, 3])))
        contacts.append(reg.contact)
    fitted = Fitted(tuple(keys), np.zeros(len(keys)), tuple(planes), tuple(contacts))
    nk = len(keys)
    for _ in range(ITERATIONS if nk else 0):
        r, J = _jacobian(fitted, sides, weights)
        A = np.vstack([J, math.sqrt(lam) * np.eye(nk, J.shape[1])])
        b = np.concatenate([r, math.sqrt(lam) * fitted.theta])
        step = np.linalg.lstsq(A, -b, rcond=None)[0]
        fitted = _moved(fitted, step)
        if np.max(np.abs(step)) < 1e-10:
            break
    return fitted


def _moved(f: Fitted, step: np.ndarray) -> Fitted:
    nk = len(f.keys)
    planes, contacts = [], []
    for k, (plane, C) in enumerate(zip(f.planes, f.contacts, strict=True)):
        s = step[nk + 5 * k : nk + 5 * k + 5]
        n = plane.normal + cm.tangent(plane.normal) @ s[:2]
        planes.append(cm.Plane(n / np.linalg.norm(n), plane.height + s[2]))
        C2 = C.copy()
        C2[:3, :3] = C[:3, :3] @ rotation_matrix(np.array([s[3], s[4], 0.0]))
        contacts.append(C2)
    return Fitted(f.keys, f.theta + step[:nk], tuple(planes), tuple(contacts))


def folds(m: int, count: int, seed: int) -> list[np.ndarray]:
    return np.array_split(np.random.default_rng(seed).permutation(m), count)


def tilt_weight(side: Side) -> float:
    """Weight [m/rad] of the tilt rows: height RMS / tilt RMS of the registration, settled."""
    kin = cm.kinematics(side.chain, side.q)
    w = 1.0
    for _ in range(5):
        T = kin.T
        reg = register_contacts(PlaneContact(), T[:, :3, :3], T[:, :3, 3], side.ids, GUESS, w)
        r = reg.gaps(T[:, :3, :3], T[:, :3, 3], reg.index(side.ids))
        w = float(np.sqrt(np.mean(r[:, 0] ** 2) / np.mean(r[:, 1:] ** 2)))
    return w


def choose_lambda(train: list[Side], keys, weights) -> float:
    """The ridge strength of least inner-CV weighted held-out error."""
    inner = [folds(len(s.q), INNER, SEED + 1) for s in train]
    scores = []
    for lam in LAMBDAS:
        total = 0.0
        for f in range(INNER):
            fit_on = [
                s.take(np.setdiff1d(np.arange(len(s.q)), inner[k][f])) for k, s in enumerate(train)
            ]
            fitted = fit(fit_on, keys, lam, weights)
            for k, s in enumerate(train):
                total += float(np.sum(gaps(fitted, k, s.take(inner[k][f]), weights[k])[0] ** 2))
        scores.append(total)
    return float(LAMBDAS[int(np.argmin(scores))])


def pinocchio_gaps(fitted: Fitted, k: int, side: Side) -> np.ndarray:
    """The same gaps by a second route: a Pinocchio model with the fitted errors."""
    model = pin.Model(side.chain.model)
    data = model.createData()
    xi, off, comp = fitted.errors(side.chain)
    Q = side.Q.copy()
    for i, name in enumerate(side.chain.joints):
        j = model.getJointId(name)
        model.jointPlacements[j] = model.jointPlacements[j] * pin.exp6(
            pin.Motion(xi[i, :3], xi[i, 3:])
        )
        Q[:, model.joints[j].idx_q] += off[i] + comp[i] * side.tau[:, i] / cm.TORQUE_SCALE
    P, C = pin.SE3(fitted.planes[k].matrix()), pin.SE3(fitted.contacts[k])
    out = []
    for q in Q:
        pin.framesForwardKinematics(model, data, q)
        rel = P.actInv(data.oMf[side.chain.base].actInv(data.oMf[side.chain.tool]) * C)
        out.append((rel.translation[2], *pin.rpy.matrixToRpy(rel.rotation)[:2]))
    return np.array(out)


@dataclass(frozen=True)
class Outcome:
    """Held-out gaps of a model, pooled over the outer folds, per side."""

    held: tuple[np.ndarray, ...]  # (m, 3) per side [m, rad, rad]
    lambdas: tuple[float, ...]
    second_route: float  # largest difference to the Pinocchio route [m or rad]


def cross_validate(sides: list[Side], spec: Spec, weights) -> Outcome:
    """5-fold CV (nested choice of the ridge) of a model on one or several sides."""
    outer = [folds(len(s.q), FOLDS, SEED) for s in sides]
    keys = robot_keys(sides, spec)
    held: list[list[np.ndarray]] = [[] for _ in sides]
    lambdas, worst = [], 0.0
    for f in range(FOLDS):
        train = [
            s.take(np.setdiff1d(np.arange(len(s.q)), outer[k][f])) for k, s in enumerate(sides)
        ]
        lam = choose_lambda(train, keys, weights) if keys else 0.0
        fitted = fit(train, keys, lam, weights)
        lambdas.append(lam)
        for k, s in enumerate(sides):
            test = s.take(outer[k][f])
            r = gaps(fitted, k, test)[0]
            worst = max(worst, float(np.max(np.abs(r - pinocchio_gaps(fitted, k, test)))))
            held[k].append(r)
    return Outcome(tuple(np.concatenate(h) for h in held), tuple(lambdas), worst)


def rms(r: np.ndarray) -> tuple[float, float, float]:
    v = np.sqrt(np.mean(r**2, axis=0))
    return 1e3 * v[0], math.degrees(v[1]), math.degrees(v[2])


SPECS = (
    Spec("registration"),
    Spec("offsets", offset=True),
    Spec("offsets+legs", offset=True, legs_compliance=True),
    Spec("geometry", placement=True, offset=True),
    Spec("geometry+legs", placement=True, offset=True, legs_compliance=True),
)


def compliance_report(sides: dict[str, Side], weights: dict[str, float]) -> None:
    """The legs' compliance fitted on all touches of each side (offsets+legs, ridge by CV)."""
    spec = SPECS[2]
    for name, side in sides.items():
        keys = robot_keys([side], spec)
        lam = choose_lambda([side], keys, [weights[name]])
        fitted = fit([side], keys, lam, [weights[name]])
        _, off, comp = fitted.errors(side.chain)
        legs = [i for i, j in enumerate(side.chain.joints) if j.startswith("leg_")]
        print(
            f"{name}: offsets+legs on all {len(side.q)} touches (ridge {lam:.0e}): deflection "
            "per 100 N m [mrad] "
            + " ".join(f"{side.chain.joints[i][4:-6]} {1e3 * comp[i]:+.2f}" for i in legs)
            + f"; |offset| max {1e3 * np.max(np.abs(off)):.1f} mrad"
            + "; gravity torque RMS [N m] "
            + " ".join(f"{np.sqrt(np.mean(side.tau[:, i] ** 2)):.0f}" for i in legs)
        )


def main() -> None:
    model = pin.buildModelFromUrdf(str(URDF))
    sides = {name: read_side(model, name) for name in SIDES}
    weights = {name: tilt_weight(s) for name, s in sides.items()}
    print(
        f"TALOS table contacts, {FOLDS}-fold CV (seed {SEED}), held-out RMS height [mm] / "
        f"roll / pitch [deg]; tilt weight [m/rad]: "
        + ", ".join(f"{k} {w:.3f}" for k, w in weights.items())
    )
    print(
        f"{'model':<15} {'fit':<6} {'side':<6} {'height':>7} {'roll':>6} {'pitch':>6}  "
        f"{'ridge (per fold)':<40} 2nd route"
    )
    for spec in SPECS:
        runs = [([n], [sides[n]]) for n in SIDES] + [(list(SIDES), list(sides.values()))]
        for names, group in runs:
            t0 = time.perf_counter()
            out = cross_validate(group, spec, [weights[n] for n in names])
            dt = time.perf_counter() - t0
            for n, r in zip(names, out.held, strict=True):
                h, ro, pi = rms(r)
                kind = "single" if len(names) == 1 else "both"
                lam = " ".join(f"{v:.0e}" for v in out.lambdas)
                print(
                    f"{spec.name:<15} {kind:<6} {n:<6} {h:7.2f} {ro:6.2f} {pi:6.2f}  "
                    f"{lam:<40} {out.second_route:.1e}  ({dt:.1f} s)"
                )
    compliance_report(sides, weights)
    for n, (single, both) in FIGAROH.items():
        print(
            f"{'FIGAROH (pub.)':<15} {'single':<6} {n:<6} {single[0]:7.2f} {single[1]:6.2f} "
            f"{single[2]:6.2f}  other-day sessions"
        )
        print(
            f"{'FIGAROH (pub.)':<15} {'both':<6} {n:<6} {both[0]:7.2f} {both[1]:6.2f} "
            f"{both[2]:6.2f}  other-day sessions"
        )


if __name__ == "__main__":
    main()
