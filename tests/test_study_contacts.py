"""TALOS touching a table (real data): the checks of the contacts study.

Counts against their closed forms (plane 4R + 2P - 1, 4R - 2 without a prismatic joint;
the others 4R + 2P, 4R - 1 without one); the registration's held-out gaps recomputed from
Pinocchio's placements on the URDF (no MDH); the standing leg's gravity torques against
central differences of the potential energy summed body by body from Pinocchio; and every
calibration (one chain, ``--elastic``, both arms in one problem) must beat the
registration on touches it has not seen (5-fold cross-validation, seed 0).
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import calib
from calib import analyze, from_chain, load_chain
from calib.calibration.contact_checks import register_contacts
from calib.identification.contacts import PlaneContact
from calib.kinematics.catalog import resolve_urdf
from calib.kinematics.standing import standing_load

pytestmark = [
    pytest.mark.slow,
    pytest.mark.filterwarnings("ignore::calib.RankWarning"),
    pytest.mark.filterwarnings("ignore::calib.DataWarning"),
]

URDF = resolve_urdf("erd:talos_data/robots/talos_full_v2.urdf")
DATA = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
SIDES = {
    "left": ("left_sole_link", "gripper_left_base_link", "left_train.csv"),
    "right": ("right_sole_link", "gripper_right_base_link", "right_train.csv"),
}
CONTACT = (0.0, 0.0, -0.12)


def closed_form(kind, R, P):
    base = 4 * R + 2 * P
    return base - (1 if P else 2) if kind == "plane" else base - (0 if P else 1)


def folds(m, count=5, seed=0):
    return np.array_split(np.random.default_rng(seed).permutation(m), count)


def take(data, rows):
    ids = tuple(data.ids[i] for i in rows)
    return calib.ContactData(data.joint_names, data.q[rows], ids, data.kind, data.source)


def pooled(rows):
    m = sum(r[0] for r in rows)
    return [math.sqrt(sum(r[0] * r[k] ** 2 for r in rows) / m) for k in (1, 2, 3)]


def figures(s):
    return (s.m, s.height_rms_mm, s.roll_rms_deg, s.pitch_rms_deg)


@pytest.fixture(scope="module")
def sides():
    out = {}
    for side, (base, tool, name) in SIDES.items():
        chain = load_chain(URDF, base, tool)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out[side] = (chain, calib.read_contacts(DATA / name, chain, "plane"))
    return out


@pytest.mark.parametrize("side", SIDES)
@pytest.mark.parametrize("kind", ["plane", "plane-point", "fixed-point", "fixed-pose"])
def test_contact_counts_equal_their_closed_forms(side, kind):
    chain = load_chain(URDF, *SIDES[side][:2])
    res = analyze(chain, measure=kind, params="complete", configs=150)
    expected = closed_form(kind, chain.n_revolute, chain.n_prismatic)
    assert res.n_base == res.n_complete == res.n_theory == expected


def test_feet_loop_count():
    feet = load_chain(URDF, "left_sole_link", "right_sole_link")
    loop = analyze(feet, measure="fixed-pose", params="complete")
    assert loop.n_base == loop.n_theory == closed_form("fixed-pose", feet.n_revolute, 0)


def test_registration_held_out_gaps_recomputed_by_pinocchio(sides):
    guess = np.eye(4)
    guess[2, 3] = -0.12
    model = pin.buildModelFromUrdf(str(URDF))
    pdata = model.createData()
    for chain, data in sides.values():
        T = from_chain(chain).forward(data.q)  # nominal gripper placements in the sole frame
        ids = np.array(data.ids)
        base, tool = model.getFrameId(chain.base_frame), model.getFrameId(chain.tool_frame)
        worst = 0.0
        for test in folds(data.m):
            train = np.setdiff1d(np.arange(data.m), test)
            reg = register_contacts(
                PlaneContact(), T[train, :3, :3], T[train, :3, 3], ids[train], guess
            )
            gap = reg.gaps(T[test, :3, :3], T[test, :3, 3], reg.index(ids[test]))
            for i, g in zip(test, gap, strict=True):
                qp = pin.neutral(model)
                for joint, v in zip(data.joint_names, data.q[i], strict=True):
                    qp[model.joints[model.getJointId(joint)].idx_q] = v
                pin.framesForwardKinematics(model, pdata, qp)
                tip = pdata.oMf[base].actInv(pdata.oMf[tool]).homogeneous @ reg.contact
                Tt = np.linalg.inv(reg.objects[reg.ids.index("table")]) @ tip
                n = Tt[2, :3]  # the table's normal in the contact frame
                mine = np.array([Tt[2, 3], math.atan2(n[1], n[2]), -math.asin(n[0])])
                worst = max(worst, float(np.abs(mine - g).max()))
        assert worst < 1e-9


@pytest.mark.parametrize("elastic", [False, True], ids=["geometry", "elastic"])
def test_calibration_beats_the_registration_held_out(sides, elastic):
    for chain, data in sides.values():
        before, after = [], []
        for test in folds(data.m):
            train = np.setdiff1d(np.arange(data.m), test)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = calib.calibrate(
                    chain,
                    take(data, train),
                    marker=CONTACT,
                    validate=take(data, test),
                    seed=0,
                    elastic=elastic,
                )
            h, b = r.stats["held_out"], r.stats["held_out_registration"]
            before.append(figures(b))
            after.append(figures(h if r.accepted else b))
        b, a = pooled(before), pooled(after)
        assert a[0] < b[0]
        if elastic:
            assert a[1] < b[1]


def test_standing_torques_are_the_potential_energy_derivative():
    model = pin.buildModelFromUrdf(str(URDF))
    chain = load_chain(URDF, "left_sole_link", "gripper_left_base_link")
    q = chain.random_configurations(2, 0)
    tau = standing_load(chain).torques(q)
    g = np.linalg.norm(model.gravity.linear)

    def energy(qc):
        d = model.createData()
        pin.framesForwardKinematics(model, d, chain.pin_configurations(qc[None])[0])
        sole = d.oMf[chain.base_id]
        return sum(
            model.inertias[j].mass * g * sole.actInv(d.oMi[j].act(model.inertias[j].lever))[2]
            for j in range(1, model.njoints)
        )

    h = 1e-6
    fd = np.array(
        [[(energy(r + h * e) - energy(r - h * e)) / (2 * h) for e in np.eye(chain.n)] for r in q]
    )
    assert np.max(np.abs(tau - fd)) < 1e-5


@pytest.mark.parametrize("from_left_foot", [False, True], ids=["each-foot", "left-foot"])
def test_both_arms_in_one_problem_beat_each_registration(from_left_foot):
    pairs = [("left_sole_link" if from_left_foot else b, t) for b, t, _ in SIDES.values()]
    chains = [load_chain(URDF, *p) for p in pairs]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = [
            calib.read_contacts(DATA / name, c, "plane")
            for c, (_, _, name) in zip(chains, SIDES.values(), strict=True)
        ]
    parts = [folds(d.m) for d in data]
    before, after = {s: [] for s in SIDES}, {s: [] for s in SIDES}
    for f in range(5):
        terms = tuple(
            calib.Term(c, take(d, np.setdiff1d(np.arange(d.m), p[f])), take(d, p[f]), CONTACT)
            for c, d, p in zip(chains, data, parts, strict=True)
        )
        r = calib.calibrate(calib.Problem(terms))
        for side, part in zip(SIDES, r.chains, strict=True):
            h, b = part.stats["held_out"], part.stats["held_out_registration"]
            before[side].append(figures(b))
            after[side].append(figures(h if r.accepted else b))
    for side in SIDES:
        assert pooled(after[side])[0] < pooled(before[side])[0], side
