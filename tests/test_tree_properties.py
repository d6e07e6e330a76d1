"""Property tests on random trees with deliberately nasty geometry.

Each tree is a set of joint lines (point, direction, revolute/prismatic) hanging from the base
or from another joint, each child related to its antecedent's line in a chosen way (parallel,
intersecting, coincident, ... also at links that carry several children), and tools on the
leaves and on some inner joints, all in the base frame at q = 0. calib reads it from a URDF
written here (negative axes included); the reference is a Pinocchio model built joint by
joint, and the complete rank comes from finite differences of its placements.
"""

from __future__ import annotations

import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import scipy.linalg
from conftest import CI
from hypothesis import example, given, settings
from hypothesis import strategies as st
from pinref import PinTree, own_random_q

import calib
from calib import Measurement, analyze, from_tree
from calib.identification.identifiability import analyze_model
from calib.identification.tree_jacobian import tree_jacobian
from calib.kinematics.tree import load_tree

RELATIONS = ("generic", "parallel", "intersecting", "coincident", "perpendicular_intersecting")
MARKER = (0.011, 0.023, 0.037)
TREES = settings(CI, max_examples=CI.max_examples * 2 // 3)  # 40 in CI


@dataclass
class RandomTree:
    parent: list[int]  # antecedent joint, -1 for the base
    points: np.ndarray  # (n, 3)
    directions: np.ndarray  # (n, 3), unit, any sign
    sigma: np.ndarray  # (n,)
    tools: list[tuple[int, np.ndarray]]  # (joint, pose (4, 4) in the base at q = 0)
    relations: tuple[str, ...]
    tool_on_axis: tuple[bool, ...]

    @property
    def n(self) -> int:
        return len(self.sigma)

    @property
    def generic(self) -> bool:
        return all(r == "generic" for r in self.relations) and not any(self.tool_on_axis)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def perpendicular(u: np.ndarray, rng) -> np.ndarray:
    v = rng.normal(size=3)
    return unit(v - np.dot(v, u) * u)


def random_rotation(rng) -> np.ndarray:
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(R)))
    return Q if np.linalg.det(Q) > 0 else -Q


def line_of(rel: str, prev_p, prev_u, rng, L=0.5):
    sign = rng.choice([-1.0, 1.0])
    if rel == "generic":
        return rng.uniform(-L, L, 3), sign * unit(rng.normal(size=3))
    if rel == "parallel":
        return rng.uniform(-L, L, 3), sign * prev_u
    if rel == "intersecting":
        return prev_p + rng.uniform(-L, L) * prev_u, sign * unit(rng.normal(size=3))
    if rel == "coincident":
        return prev_p + rng.uniform(-L, L) * prev_u, sign * prev_u
    return prev_p + rng.uniform(-L, L) * prev_u, sign * perpendicular(prev_u, rng)


def build_tree(seed: int, parent, relations, sigma, extra_tools, on_axis) -> RandomTree:
    rng = np.random.default_rng(seed)
    n = len(parent)
    points, dirs = np.zeros((n, 3)), np.zeros((n, 3))
    for k in range(n):
        a = parent[k]
        prev = (np.zeros(3), np.array([0.0, 0.0, 1.0])) if a < 0 else (points[a], dirs[a])
        points[k], dirs[k] = line_of(relations[k], *prev, rng)
    leaves = [k for k in range(n) if k not in parent]
    carriers = leaves + [int(j) % n for j in extra_tools]
    if len(carriers) < 2:
        carriers.append(carriers[0])  # two tools on one link
    tools, flags = [], []
    for i, k in enumerate(carriers):
        pose = np.eye(4)
        pose[:3, :3] = random_rotation(rng)
        pose[:3, 3] = rng.uniform(-0.5, 0.5, 3)
        flag = bool(on_axis[i % len(on_axis)])
        if flag:
            pose[:3, 3] = points[k] + rng.uniform(-0.5, 0.5) * dirs[k]
        tools.append((k, pose))
        flags.append(flag)
    return RandomTree(
        list(parent), points, dirs, np.asarray(sigma), tools, tuple(relations), tuple(flags)
    )


@st.composite
def trees(draw, max_joints: int = 6, nasty: bool = True):
    n = draw(st.integers(2, max_joints))
    parent = [-1] + [draw(st.integers(-1, k - 1)) for k in range(1, n)]
    rel = st.sampled_from(RELATIONS if nasty else ("generic",))
    relations = draw(st.lists(rel, min_size=n, max_size=n))
    sigma = draw(st.lists(st.sampled_from([0, 0, 0, 1]), min_size=n, max_size=n))
    extra = draw(st.lists(st.integers(0, 100), max_size=2))
    on_axis = draw(st.lists(st.booleans() if nasty else st.just(False), min_size=1, max_size=4))
    seed = draw(st.integers(0, 2**32 - 1))
    return build_tree(seed, parent, relations, sigma, extra, on_axis)


def urdf_text(tr: RandomTree) -> str:
    """The tree as a URDF: every link frame parallel to the base at q = 0."""
    parts = ['<robot name="random_tree">', '<link name="base"/>']
    for k in range(tr.n):
        a = tr.parent[k]
        offset = tr.points[k] - (tr.points[a] if a >= 0 else np.zeros(3))
        kind, lim = ("prismatic", 0.5) if tr.sigma[k] == 1 else ("revolute", 3.1)
        parts += [
            f'<link name="l{k}"/>',
            f'<joint name="j{k}" type="{kind}">',
            f'<parent link="{"base" if a < 0 else f"l{a}"}"/><child link="l{k}"/>',
            f'<origin xyz="{" ".join(repr(float(v)) for v in offset)}" rpy="0 0 0"/>',
            f'<axis xyz="{" ".join(repr(float(v)) for v in tr.directions[k])}"/>',
            f'<limit lower="{-lim}" upper="{lim}" effort="1" velocity="1"/></joint>',
        ]
    for i, (k, pose) in enumerate(tr.tools):
        rpy = pin.rpy.matrixToRpy(pose[:3, :3])
        xyz = pose[:3, 3] - tr.points[k]
        parts += [
            f'<link name="t{i}"/>',
            f'<joint name="tj{i}" type="fixed"><parent link="l{k}"/><child link="t{i}"/>',
            f'<origin xyz="{" ".join(repr(float(v)) for v in xyz)}" '
            f'rpy="{" ".join(repr(float(v)) for v in rpy)}"/></joint>',
        ]
    return "\n".join([*parts, "</robot>"])


def pin_reference(tr: RandomTree) -> PinTree:
    """Pinocchio model built joint by joint (no URDF): unaligned joints at the given lines."""
    model = pin.Model()
    ids = []
    for k in range(tr.n):
        a = tr.parent[k]
        joint = (
            pin.JointModelPrismaticUnaligned(tr.directions[k])
            if tr.sigma[k] == 1
            else pin.JointModelRevoluteUnaligned(tr.directions[k])
        )
        offset = tr.points[k] - (tr.points[a] if a >= 0 else np.zeros(3))
        ids.append(
            model.addJoint(ids[a] if a >= 0 else 0, joint, pin.SE3(np.eye(3), offset), f"j{k}")
        )
    base = model.addFrame(pin.Frame("base", 0, pin.SE3.Identity(), pin.OP_FRAME))
    tools = []
    for i, (k, pose) in enumerate(tr.tools):
        placement = pin.SE3(np.eye(3), tr.points[k]).inverse() * pin.SE3(pose)
        tools.append(model.addFrame(pin.Frame(f"t{i}", ids[k], placement, pin.OP_FRAME)))
    return PinTree(model, base, tools)


def loaded(tr: RandomTree):
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "random_tree.urdf"
        path.write_text(urdf_text(tr))
        return load_tree(path, "base", [f"t{i}" for i in range(len(tr.tools))])


def quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        return fn(*args, **kwargs)


def theory(tr: RandomTree, per_tool: int) -> int:
    R, P = int(np.sum(tr.sigma == 0)), int(np.sum(tr.sigma == 1))
    return 4 * R + 2 * P + per_tool * len(tr.tools)


# --------------------------------------------------------------------------------------
# Properties
# --------------------------------------------------------------------------------------


@TREES
@given(trees())
def test_forward_of_every_tool_equals_pinocchio(tr):
    tree, ref = loaded(tr), pin_reference(tr)
    assert sorted(tree.joint_names) == sorted(ref.joint_names)  # both antecedents first
    q = own_random_q(tree.sigma, 20, seed=1)
    T, T_ref = from_tree(tree).forward(q), ref.poses(tree.joint_names, q)
    assert np.abs(T - T_ref).max() <= 1e-9


# Always tried: a link carrying a parallel, an intersecting and a coincident child, and a
# prismatic joint on the base z axis whose children are parallel and perpendicular-intersecting,
# with a tool on its last axis.
BRANCHING = (
    build_tree(
        1,
        [-1, 0, 0, 0],
        ("generic", "parallel", "intersecting", "coincident"),
        [0, 0, 1, 0],
        [],
        [False],
    ),
    build_tree(
        2,
        [-1, 0, 1, 1],
        ("coincident", "parallel", "perpendicular_intersecting", "parallel"),
        [1, 0, 0, 0],
        [1],
        [True, False],
    ),
)


@TREES
@given(trees())
@example(BRANCHING[0])
@example(BRANCHING[1])
def test_complete_set_reaches_the_pinocchio_complete_rank(tr):
    tree, ref = loaded(tr), pin_reference(tr)
    q = own_random_q(tree.sigma, 25, seed=2)
    W_ref = ref.placement_jacobian(tree.joint_names, q, MARKER)
    position = np.concatenate([6 * k + np.arange(3) for k in range(len(W_ref) // 6)])
    for rows, measure in ((slice(None), "pose"), (position, "position")):
        s = np.linalg.svd(W_ref[rows], compute_uv=False)
        ref_rank = int(np.sum(s > 1e-7 * s[0]))
        res = quiet(analyze, tree, measure=measure, marker=MARKER, params="complete", configs=40)
        paper = quiet(analyze, tree, measure=measure, marker=MARKER, params="paper", configs=40)
        assert res.n_complete == ref_rank, (tr.parent, tr.relations, measure)
        assert res.n_base == ref_rank, (tr.parent, tr.relations, tr.sigma, measure, res.base)
        assert paper.n_base <= res.n_base
        if tr.generic:
            assert ref_rank == res.n_theory == theory(tr, 6 if measure == "pose" else 3)


@TREES
@given(trees(), st.sampled_from(["pose", "position"]), st.sampled_from(["paper", "complete"]))
def test_base_count_is_the_numerical_rank(tr, measure, params):
    tree = loaded(tr)
    q = own_random_q(tree.sigma, 25, seed=3)
    meas = Measurement.of(measure, MARKER)
    model = from_tree(tree).idealized()
    res = quiet(analyze_model, model, params, meas, q)
    W = tree_jacobian(model, res.params, q, meas)
    R = scipy.linalg.qr(W, mode="r", pivoting=True)[0]
    diag = np.abs(np.diag(R))
    assert res.n_base == int(np.sum(diag > W.shape[0] * np.finfo(float).eps * diag[0]))


@TREES
@given(trees(nasty=False))
def test_generic_trees_have_the_theoretical_count(tr):
    res = quiet(analyze, loaded(tr), measure="pose", params="complete", configs=40)
    assert res.n_base == res.n_complete == res.n_theory == theory(tr, 6)
