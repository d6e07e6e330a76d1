"""Two chains touching from their feet, sharing the torso: calib's count against Pinocchio's.

The independent rank uses nothing of calib: Pinocchio's ``oMf[base]^-1 oMf[tool]`` at the
real touches' postures, each made flush on its own table plane by Newton steps on its chain's
joints, and central differences of the gaps (height, and the contact normal's tilt in the
plane's frame) with respect to every joint placement (``jointPlacements[j] * exp6(e)``), each
plane's pose and each contact frame's pose. Its numerical rank is what the touches determine.
"""

from __future__ import annotations

import functools
import re
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
from contact_scorer import configurations, read_joints
from pinfit import _foot, _line_twist

import calib
from calib.kinematics.catalog import resolve_urdf

REAL = Path(__file__).resolve().parents[1] / "data" / "realdata" / "talos_contact"
URDF = resolve_urdf("erd:talos_data/robots/talos_full_v2.urdf")
ARMS = (("left", "gripper_left_base_link"), ("right", "gripper_right_base_link"))
CONTACT = pin.SE3(np.eye(3), np.array([0.0, 0.0, -0.12]))


def _tool(model, data, base, tool):
    return data.oMf[model.getFrameId(base)].inverse() * data.oMf[model.getFrameId(tool)]


def _gaps(model, data, base, tool, plane, contact, Q):
    """Each posture's height and tilt of ``contact`` on ``plane`` (base frame) ``(3 m,)``.

    ``data`` is the model's, made once (``createData`` of the full TALOS costs milliseconds:
    made per call, it was most of this file's time)."""
    b, t, out = model.getFrameId(base), model.getFrameId(tool), []
    for q in Q:
        pin.framesForwardKinematics(model, data, q)
        M = plane.actInv(data.oMf[b].inverse() * data.oMf[t] * contact)
        out += [M.translation[2], M.rotation[0, 2], M.rotation[1, 2]]
    return np.array(out)


def _flush(model, data, base, tool, plane, Q, joints):
    """The postures moved onto the plane (Newton, least-norm steps on ``joints``' q)."""
    Q = Q.copy()
    for k, q in enumerate(Q):
        for _ in range(8):
            g = _gaps(model, data, base, tool, plane, CONTACT, q[None])
            E = 1e-7 * np.eye(len(q))[joints]
            J = np.array(
                [_gaps(model, data, base, tool, plane, CONTACT, (q + e, q - e)) for e in E]
            )
            q[joints] -= np.linalg.pinv((J[:, :3] - J[:, 3:]).T / 2e-7) @ g
        Q[k] = q
    return Q


def _terms(model, data):
    """Each arm's base, tool, table plane, flush postures and its chain's joint ids."""
    terms = []
    for side, tool in ARMS:
        base = f"{side}_sole_link"
        Q = configurations(model, read_joints(REAL / f"{side}_train.csv")[1])
        pin.framesForwardKinematics(model, data, Q[0])
        plane = _tool(model, data, base, tool) * CONTACT
        ids = [model.getJointId(n) for n in calib.load_robot(URDF, base, tool).joint_names]
        joints = [model.joints[j].idx_q for j in ids]
        terms.append((base, tool, plane, _flush(model, data, base, tool, plane, Q, joints), ids))
    return terms


@functools.cache
def _placement_jacobian() -> tuple[np.ndarray, list[int], tuple]:
    """The gaps' central differences in every chain joint's placement error (6 each, in the
    order of ``joints``), then each term's plane and contact (12 each); ``joints``; terms."""
    model = pin.buildModelFromUrdf(str(URDF))
    data = model.createData()
    terms = _terms(model, data)
    joints = sorted({j for t in terms for j in t[4]})
    nominal = [pin.SE3(model.jointPlacements[j]) for j in joints]
    size = 6 * len(joints) + 12 * len(terms)

    def gaps(x):
        for j, M, e in zip(joints, nominal, x[: 6 * len(joints)].reshape(-1, 6), strict=True):
            model.jointPlacements[j] = M * pin.exp6(e)
        out = []
        for k, (base, tool, plane, Q, _) in enumerate(terms):
            y = x[6 * len(joints) + 12 * k :]
            moved = plane * pin.exp6(y[:6])
            out.append(_gaps(model, data, base, tool, moved, CONTACT * pin.exp6(y[6:12]), Q))
        return np.concatenate(out)

    h = 1e-6
    J = np.array([(gaps(e) - gaps(-e)) / (2 * h) for e in h * np.eye(size)]).T
    return J, joints, tuple((t[0], t[4]) for t in terms)


def _rank(A: np.ndarray) -> int:
    s = np.linalg.svd(A, compute_uv=False)
    return int(np.sum(s > 1e-6 * s[0]))


def independent_rank() -> int:
    """The rank of the gaps' central differences in every joint placement and object."""
    return _rank(_placement_jacobian()[0])


def _row_twists(model, base: str, joints) -> list[tuple[int, np.ndarray]]:
    """A chain's MDH rows 2..n (Khalil, Hayati's beta where two axes are parallel; lines
    and feet as tests/pinfit.py draws them, at the neutral posture) as twists of the joint
    placement in the link each row deforms: ``(joint id, twist in its placement's frame)``.
    Row 1 (the sole to the first joint) and the tool's row deform the plane's and the
    contact's poses, free anyway."""
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    frame = model.frames[model.getFrameId(base)]
    sole = data.oMf[model.getFrameId(base)]
    lines = [(sole.translation, sole.rotation[:, 2])]  # the sole's z
    for j in joints:
        S = np.ravel(data.joints[j].S)
        axis = S[3:] if np.linalg.norm(S[3:]) > 0 else S[:3]
        lines.append((data.oMi[j].translation, data.oMi[j].rotation @ axis))
    feet, out = [lines[0][0]], []
    below = [frame.parentJoint, *joints]
    for k in range(1, len(joints) + 1):
        (point, a), (p, u) = lines[k - 1], lines[k]
        foot, n = _foot(a, point, u, p, feet[-1])
        feet.append(foot)
        parallel = np.linalg.norm(np.cross(a, u)) < 1e-9
        kinds = ("beta", "alpha", "d", "theta") if parallel else ("alpha", "d", "theta", "r")
        reverse = joints[k - 1] in model.supports[below[k - 1]]
        carrier = joints[k - 2] if reverse else joints[k - 1]
        if k == 1:
            continue
        for kind in kinds:
            if kind in ("theta", "r"):
                twist = _line_twist(p, u, kind == "theta")
            else:
                twist = _line_twist(foot, np.cross(a, n) if kind == "beta" else n, kind != "d")
            out.append((carrier, data.oMi[carrier].actInv(pin.Motion(twist)).vector))
    return out


def independent_mdh_rank() -> int:
    """The rank the touches give the chains' MDH rows beyond the planes' and contacts' poses:
    each row's twist in the placement Jacobian's columns of its joint (first order)."""
    J, joints, terms = _placement_jacobian()
    model = pin.buildModelFromUrdf(str(URDF))
    objects = J[:, 6 * len(joints) :]
    columns = [
        J[:, 6 * joints.index(j) : 6 * joints.index(j) + 6] @ twist
        for base, ids in terms
        for j, twist in _row_twists(model, base, ids)
    ]
    return _rank(np.column_stack([objects, *columns])) - _rank(objects)


def _both_arms() -> tuple[calib.Term, ...]:
    """Each arm's real touches, its chain from its own sole."""
    terms = []
    for side, tool in ARMS:
        robot = calib.load_robot(URDF, f"{side}_sole_link", tool)
        touches = calib.read_contacts(REAL / f"{side}_train.csv", robot, "plane")
        terms.append(calib.Term(robot, touches))
    return tuple(terms)


def test_two_arms_touching_fit_every_unknown_pinocchio_finds_determined():
    """Both arms' touches, params complete: calib fits and counts the independent rank.

    Before the fix the MDH rows of the two chains missed three directions where they meet
    (the tilts of the first leg and arm joints beside the shared torso): 96 components
    fitted, "106 unknowns determined", while ``analyze`` and ``identifiable`` said 109
    (both arms from their soles, 150 rows: 109 is also this rank).
    """
    rank = independent_rank()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        problem = calib.Problem(_both_arms(), params="complete")
        result = calib.calibrate(problem)
        n_base = calib.analyze(problem).n_base
    printed = re.search(r"(\d+) unknowns determined", result.summary())
    assert printed is not None
    counts = (int(printed.group(1)), result.unknowns, result.identifiable, n_base)
    assert counts == (rank,) * 4


def test_auto_offers_each_chains_mdh_rows_not_the_components_where_chains_meet():
    """Both arms from their soles at ``auto``: 111 directions offered, 96 determined.

    ``complete`` also offers the components of the shared joints and their neighbours (132
    offered, 99 determined: the rank above, 109, less the 10 unknowns of the two planes and
    contact frames, 3 + 2 each). ``auto`` does not, on purpose (measured
    2026-11-29, offered after the MDH rows so that only the 3 missing tilts were new):
    5-fold held-out heights from the left sole 4.54 / 6.84 mm -> 5.41 / 7.56 (left / right),
    simulated arms (``benchmarks/self_measure.py``) 1.128 / 0.333 -> 1.596 / 0.394. The
    greedy selection takes the weakly determined tilts on per-touch gains: from the left sole
    ``arm_left_1_joint:ry`` came out -16.8 +- 5.7 mrad in one fold, +17.6 +- 4.6 in another.
    """
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = calib.calibrate(calib.Problem(_both_arms()))
    # 96: the touches' rank in the chains' MDH rows, by Pinocchio alone (independent_mdh_rank);
    # 111 is the count of names calib offers (its MDH rows, the rows two chains share once):
    # calib's own number, not an independent one (_row_twists' rows 2..n of both chains give
    # 112 columns, 107 distinct: the rows calib offers beside them are not counted here).
    determined = independent_mdh_rank()
    assert f"the touches determine {determined} of the 111 parameters offered" in result.notes
    assert not any(n.endswith((":rx", ":ry")) for n in result.selection.kept)
