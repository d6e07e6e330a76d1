"""Property tests on random serial chains with deliberately nasty geometry.

Each chain is a list of joint lines (point, direction, revolute/prismatic) and a tool pose, all in
the base frame. calib converts it with ``calib.kinematics.mdh.from_lines``; the independent
reference is a Pinocchio model built here joint by joint (JointModelRevoluteUnaligned /
JointModelPrismaticUnaligned), which knows nothing about DH.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg
from conftest import CI
from hypothesis import given
from hypothesis import strategies as st
from pinref import rigid_error_columns

import calib
from calib import Measurement
from calib.identification.identifiability import analyze_model
from calib.identification.jacobian import complete_jacobian, identification_jacobian
from calib.kinematics.mdh import from_lines

RELATIONS = (
    "generic",
    "parallel",
    "intersecting",
    "coincident",
    "nearly_parallel",
    "perpendicular_intersecting",
)
TOOLS = ("generic", "origin_on_last_axis", "along_last_axis")
N_CONFIGS = 25


@dataclass
class RandomChain:
    points: np.ndarray  # (n, 3)
    directions: np.ndarray  # (n, 3)
    sigma: np.ndarray  # (n,)
    tool: np.ndarray  # (4, 4)
    relations: tuple[str, ...]
    tool_kind: str

    @property
    def n(self) -> int:
        return len(self.sigma)

    @property
    def size(self) -> float:
        return max(0.1, float(np.abs(self.points).max()), float(np.abs(self.tool[:3, 3]).max()))

    @property
    def generic(self) -> bool:
        return all(r == "generic" for r in self.relations)


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v)


def random_rotation(rng) -> np.ndarray:
    Q, R = np.linalg.qr(rng.normal(size=(3, 3)))
    Q = Q @ np.diag(np.sign(np.diag(R)))
    return Q if np.linalg.det(Q) > 0 else -Q


def perpendicular(u: np.ndarray, rng) -> np.ndarray:
    v = rng.normal(size=3)
    return unit(v - np.dot(v, u) * u)


def rotate(v: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    return pin.AngleAxis(angle, unit(axis)).matrix() @ v


def build_chain(seed: int, relations, sigma, tool_kind: str, tilt_exp: float) -> RandomChain:
    rng = np.random.default_rng(seed)
    L = 0.5
    prev_p, prev_u = np.zeros(3), np.array([0.0, 0.0, 1.0])  # the base z axis
    points, dirs = [], []
    for rel in relations:
        sign = rng.choice([-1.0, 1.0])
        if rel == "generic":
            p, u = rng.uniform(-L, L, 3), unit(rng.normal(size=3))
        elif rel == "parallel":
            p, u = rng.uniform(-L, L, 3), sign * prev_u
        elif rel == "intersecting":
            p, u = prev_p + rng.uniform(-L, L) * prev_u, unit(rng.normal(size=3))
        elif rel == "coincident":
            p, u = prev_p + rng.uniform(-L, L) * prev_u, sign * prev_u
        elif rel == "nearly_parallel":
            tilt = 10.0**tilt_exp
            u = sign * rotate(prev_u, perpendicular(prev_u, rng), tilt)
            p = rng.uniform(-L, L, 3)
        else:  # perpendicular_intersecting
            p, u = prev_p + rng.uniform(-L, L) * prev_u, sign * perpendicular(prev_u, rng)
        points.append(p)
        dirs.append(u)
        prev_p, prev_u = p, u
    tool = np.eye(4)
    tool[:3, :3] = random_rotation(rng)
    tool[:3, 3] = rng.uniform(-L, L, 3)
    if tool_kind in ("origin_on_last_axis", "along_last_axis"):
        tool[:3, 3] = prev_p + rng.uniform(-L, L) * prev_u
    if tool_kind == "along_last_axis":
        z = prev_u
        x = perpendicular(z, rng)
        tool[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return RandomChain(
        np.array(points),
        np.array(dirs),
        np.asarray(sigma, dtype=int),
        tool,
        tuple(relations),
        tool_kind,
    )


@st.composite
def chains(draw, max_joints: int = 7, nasty: bool = True):
    n = draw(st.integers(1, max_joints))
    relations = draw(
        st.lists(st.sampled_from(RELATIONS if nasty else ("generic",)), min_size=n, max_size=n)
    )
    sigma = draw(st.lists(st.sampled_from([0, 0, 0, 1]), min_size=n, max_size=n))
    tool_kind = draw(st.sampled_from(TOOLS if nasty else ("generic",)))
    tilt_exp = draw(st.floats(-6.0, -3.0))
    seed = draw(st.integers(0, 2**32 - 1))
    return build_chain(seed, relations, sigma, tool_kind, tilt_exp)


class PinReference:
    """A Pinocchio model of the chain: joint k at points[k], unaligned axis directions[k]."""

    def __init__(self, ch: RandomChain):
        model = pin.Model()
        parent, prev = 0, np.zeros(3)
        for k in range(ch.n):
            axis = ch.directions[k]
            jm = (
                pin.JointModelPrismaticUnaligned(axis)
                if ch.sigma[k] == 1
                else pin.JointModelRevoluteUnaligned(axis)
            )
            placement = pin.SE3(np.eye(3), ch.points[k] - prev)
            parent = model.addJoint(parent, jm, placement, f"j{k + 1}")
            prev = ch.points[k]
        tool_in_last = pin.SE3(np.eye(3), prev).inverse() * pin.SE3(ch.tool)
        self.tool = model.addFrame(pin.Frame("tool", parent, tool_in_last, pin.OP_FRAME))
        self.model = model
        self.data = model.createData()
        self.n = ch.n

    def forward(self, q: np.ndarray) -> np.ndarray:
        out = []
        for qi in q:
            pin.framesForwardKinematics(self.model, self.data, qi)
            out.append(self.data.oMf[self.tool].homogeneous)
        return np.array(out)

    def complete_rank(self, q: np.ndarray, rows=(0, 1, 2, 3, 4, 5), marker=(0.0, 0.0, 0.0)):
        """Rank of a generic 6-DOF rigid error on the base and on every moving link, from
        Pinocchio's frames (translations along and rotations about each frame's axes)."""
        blocks = []
        for qi in q:
            pin.framesForwardKinematics(self.model, self.data, qi)
            T = self.data.oMf[self.tool]
            E = T.translation + T.rotation @ np.asarray(marker, dtype=float)
            frames = [pin.SE3.Identity()] + [self.data.oMi[j] for j in range(1, self.n + 1)]
            blocks.append(rigid_error_columns(frames, E)[list(rows)])
        W = np.vstack(blocks)
        s = np.linalg.svd(W, compute_uv=False)
        return int(np.sum(s > 1e-8 * s[0]))


def random_q(ch: RandomChain, m: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    q = rng.uniform(-math.pi, math.pi, (m, ch.n))
    q[:, ch.sigma == 1] = rng.uniform(-0.5, 0.5, (m, int(np.sum(ch.sigma == 1))))
    return q


def convert(ch: RandomChain):
    return from_lines(ch.points, ch.directions, ch.sigma, ch.tool)


def theory(ch: RandomChain, measure: str) -> int:
    R, P = int(np.sum(ch.sigma == 0)), int(np.sum(ch.sigma == 1))
    return 4 * R + 2 * P + (6 if measure == "pose" else 3)


def analyse(mdh, params: str, q, measure="pose", marker=None):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        return analyze_model(mdh, params, Measurement.of(measure, marker), q)


# --------------------------------------------------------------------------------------
# Properties
# --------------------------------------------------------------------------------------


@CI
@given(chains())
def test_forward_kinematics_equals_pinocchio(ch):
    mdh = convert(ch)
    q = random_q(ch, 30, seed=1)
    T, T_ref = mdh.forward(q), PinReference(ch).forward(q)
    assert np.abs(T[:, :3, :3] - T_ref[:, :3, :3]).max() <= 1e-9
    assert np.abs(T[:, :3, 3] - T_ref[:, :3, 3]).max() <= 1e-9 * ch.size


@CI
@given(chains())
def test_mdh_values_do_not_blow_up(ch):
    mdh = convert(ch)
    bound = 100 * ch.size
    assert np.all(np.isfinite(mdh.d)) and np.all(np.isfinite(mdh.r))
    assert np.abs(mdh.d).max() < bound, (ch.relations, mdh.d)
    assert np.abs(mdh.r).max() < bound, (ch.relations, mdh.r)
    # Nearly parallel consecutive axes are Hayati rows (tilts here are <= 1e-3 rad).
    for k, rel in enumerate(ch.relations, start=1):
        if rel in ("parallel", "coincident", "nearly_parallel"):
            assert mdh.parallel[k], (k, ch.relations)


@CI
@given(chains())
def test_complete_set_reaches_the_complete_rank_pose(ch):
    mdh = convert(ch)
    q = random_q(ch, N_CONFIGS, seed=2)
    ref_rank = PinReference(ch).complete_rank(q)
    complete = analyse(mdh, "complete", q)
    paper = analyse(mdh, "paper", q)
    assert complete.n_complete == ref_rank
    assert complete.n_base == ref_rank, (ch.relations, ch.sigma, ch.tool_kind, complete.base)
    assert paper.n_base <= complete.n_base
    assert paper.n_complete == ref_rank
    if ch.generic:
        assert ref_rank == theory(ch, "pose")


@CI
@given(chains())
def test_complete_set_reaches_the_complete_rank_position_with_marker(ch):
    mdh = convert(ch)
    q = random_q(ch, N_CONFIGS, seed=3)
    marker = (0.011, 0.023, 0.037)
    ref_rank = PinReference(ch).complete_rank(q, rows=(0, 1, 2), marker=marker)
    complete = analyse(mdh, "complete", q, "position", marker)
    assert complete.n_complete == ref_rank
    assert complete.n_base == ref_rank, (ch.relations, ch.sigma, ch.tool_kind, complete.base)
    assert analyse(mdh, "paper", q, "position", marker).n_base <= complete.n_base
    if ch.generic:
        assert ref_rank == theory(ch, "position")


@CI
@given(chains(), st.sampled_from(["pose", "position"]), st.sampled_from(["paper", "complete"]))
def test_base_count_is_the_numerical_rank(ch, measure, params):
    """n_base is the rank b = #{|R_ii| > tau} of W (docs/method.md section 3), computed here with
    scipy's pivoted QR, and never more than the complete reference's rank."""
    mdh = convert(ch)
    q = random_q(ch, N_CONFIGS, seed=7)
    marker = (0.011, 0.023, 0.037) if measure == "position" else None
    res = analyse(mdh, params, q, measure, marker)
    W = identification_jacobian(mdh, res.params, q, res.measurement)
    R = scipy.linalg.qr(W, mode="r", pivoting=True)[0]
    diag = np.abs(np.diag(R))
    rank = int(np.sum(diag > W.shape[0] * np.finfo(float).eps * diag[0]))
    assert res.n_base == rank, (ch.relations, ch.sigma, ch.tool_kind, res.base)
    rows = (0, 1, 2, 3, 4, 5) if measure == "pose" else (0, 1, 2)
    assert res.n_base <= PinReference(ch).complete_rank(q, rows, marker or (0.0, 0.0, 0.0))


@CI
@given(chains(nasty=False))
def test_generic_chains_have_the_theoretical_count(ch):
    q = random_q(ch, N_CONFIGS, seed=4)
    res = analyse(convert(ch), "complete", q)
    assert res.n_base == res.n_complete == theory(ch, "pose")
    assert res.n_theory == theory(ch, "pose")


@CI
@given(chains())
def test_complete_jacobian_rank_is_the_pinocchio_reference(ch):
    mdh = convert(ch)
    q = random_q(ch, N_CONFIGS, seed=5)
    W = complete_jacobian(mdh, q, Measurement.of("pose"))
    s = np.linalg.svd(W, compute_uv=False)
    assert int(np.sum(s > 1e-8 * s[0])) == PinReference(ch).complete_rank(q)


@pytest.mark.parametrize("tilt", [1e-6, 1e-5, 1e-4, 1e-3])
def test_nearly_parallel_pair_stays_small_and_exact(tilt):
    """Two revolute axes 0.4 m apart, tilted by `tilt`: a common normal would sit 0.4/tilt
    away; the Hayati row keeps every length below the chain size."""
    u = np.array([0.0, 0.0, 1.0])
    u2 = rotate(u, np.array([1.0, 0.0, 0.0]), tilt)
    tool = np.eye(4)
    tool[:3, 3] = (0.4, 0.1, 0.3)
    ch = RandomChain(
        np.array([[0.0, 0.0, 0.1], [0.4, 0.0, 0.2]]),
        np.array([u, u2]),
        np.array([0, 0]),
        tool,
        ("coincident", "nearly_parallel"),
        "generic",
    )
    mdh = convert(ch)
    assert mdh.parallel[2]
    assert max(np.abs(mdh.d).max(), np.abs(mdh.r).max()) < 1.0
    q = random_q(ch, 50, seed=6)
    assert np.abs(mdh.forward(q) - PinReference(ch).forward(q)).max() <= 1e-9
