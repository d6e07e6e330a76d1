"""Contact counts on planar and spatial chains: calib's theory against Pinocchio's rank alone.

A planar arm (every revolute axis parallel to one direction u) turns its tool about u only,
so the general contact formulas do not hold (``calib analyze twodof --measure plane-point``
counted 5 against a theory of 7). The independent count: the chain built joint by joint in
Pinocchio (tests/test_properties.py's ``PinReference``: unaligned axes, nothing of DH), the
gap of each touch written from its definition (tests/test_contacts.py's ``pin_gap``), and the
numerical rank of its central differences under 6-DOF errors of every joint placement, of
the tool (contact) frame and of the plane, point or pose, at the postures calib projected
onto the contact (checked to hold in Pinocchio). Where calib's theory gives a count it must
be that rank; where it gives none it must say why.
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
import pytest
from conftest import CI
from hypothesis import given, settings
from hypothesis import strategies as st
from test_contacts import pin_gap
from test_properties import PinReference, RandomChain, build_chain, convert, random_q, unit

import calib
from calib import InvalidArgumentError
from calib.identification.contact_postures import contact_configurations
from calib.identification.contacts import contact_kind
from calib.identification.identifiability import analyze_model

KINDS = ("plane", "plane-point", "fixed-point", "fixed-pose")
POSTURES = 60


def _frame_with_z(z: np.ndarray, rng) -> np.ndarray:
    """A rotation whose third column is z, turned about it at random."""
    x = unit(np.cross(z, rng.normal(size=3)))
    return np.column_stack([x, np.cross(z, x), z])


@st.composite
def planar_chains(draw, normal: bool) -> RandomChain:
    """Revolute axes along +-u, prismatic ones across u, along it or oblique; the tool's z
    along +-u (a plane touched across the axes) or not, its origin on the last axis or not."""
    n = draw(st.integers(1, 6))
    sigma = draw(st.lists(st.sampled_from([0, 0, 1]), min_size=n, max_size=n))
    slides = draw(
        st.lists(st.sampled_from(["across", "across", "along", "oblique"]), min_size=n, max_size=n)
    )
    on_axis = draw(st.booleans())
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    u = unit(rng.normal(size=3))
    points, dirs = rng.uniform(-0.5, 0.5, (n, 3)), []
    for s, slide in zip(sigma, slides, strict=True):
        sign = rng.choice([-1.0, 1.0])  # negative axes too
        if s == 0 or slide == "along":
            dirs.append(sign * u)
        elif slide == "across":
            dirs.append(unit(np.cross(u, rng.normal(size=3))))
        else:
            dirs.append(unit(rng.normal(size=3)))
    tool = np.eye(4)
    tool[:3, :3] = (
        _frame_with_z(rng.choice([-1.0, 1.0]) * u, rng)
        if normal
        else _frame_with_z(unit(rng.normal(size=3)), rng)
    )
    tool[:3, 3] = rng.uniform(-0.5, 0.5, 3)
    if on_axis and sigma[-1] == 0:
        tool[:3, 3] = points[-1] + rng.uniform(-0.5, 0.5) * u
    return RandomChain(points, np.array(dirs), np.asarray(sigma), tool, ("planar",) * n, "planar")


@st.composite
def spatial_chains(draw, kind: str) -> RandomChain:
    """Generic and parallel joint lines, revolute and prismatic (directions of either sign),
    the tool anywhere, its origin or its z axis on the last axis.

    Not two neighbouring prismatic joints along one direction: they are one joint (their
    strokes add), which no formula of calib counts (docs/method.md §6)."""
    n = draw(st.integers({"fixed-pose": 7, "plane-point": 2}.get(kind, 4), 8))
    relations = draw(
        st.lists(st.sampled_from(["generic", "generic", "parallel"]), min_size=n, max_size=n)
    )
    sigma = draw(st.lists(st.sampled_from([0, 0, 0, 1]), min_size=n, max_size=n))
    for k in range(1, n):
        if sigma[k] == sigma[k - 1] == 1:
            relations[k] = "generic"
    tool_kind = draw(st.sampled_from(["generic", "origin_on_last_axis", "along_last_axis"]))
    return build_chain(draw(st.integers(0, 2**32 - 1)), relations, sigma, tool_kind, -4.0)


def pinocchio_rank(ch: RandomChain, kind: str, q: np.ndarray, q0: np.ndarray) -> int:
    """Rank of the gaps' central differences under 6-DOF errors of every joint placement, the
    tool frame and the plane, point or pose (touch ``q0`` defines it): Pinocchio only."""
    ref = PinReference(ch)
    model, data = ref.model, ref.data

    def tool(qi):
        pin.framesForwardKinematics(model, data, qi)
        return data.oMf[ref.tool].homogeneous

    P0 = np.linalg.inv(tool(q0))

    def gaps(P=P0):
        return np.concatenate([pin_gap(kind, P @ tool(qi)) for qi in q])

    assert np.abs(gaps()).max() < 1e-9  # calib's postures hold the contact
    h, cols = 1e-6, []
    frame = model.frames[ref.tool]

    def placed(j, M):  # joint j's placement (j >= 1), or the tool frame's (j = 0)
        if j:
            model.jointPlacements[j] = M
        else:
            frame.placement = M
            model.frames[ref.tool] = frame

    for j in range(model.njoints):
        old = pin.SE3(model.jointPlacements[j] if j else frame.placement)
        for e in h * np.eye(6):
            placed(j, old * pin.exp6(pin.Motion(e)))
            plus = gaps()
            placed(j, old * pin.exp6(pin.Motion(-e)))
            cols.append((plus - gaps()) / (2 * h))
        placed(j, old)
    for e in h * np.eye(6):  # the plane, point or pose
        plus, minus = (gaps(pin.exp6(pin.Motion(s * e)).homogeneous @ P0) for s in (1, -1))
        cols.append((plus - minus) / (2 * h))
    s = np.linalg.svd(np.array(cols).T, compute_uv=False)
    return int(np.sum(s > 1e-6 * s[0]))


def _check(ch: RandomChain, kind: str) -> None:
    k = contact_kind(kind)
    draw = lambda count, r: random_q(ch, count, 1 + r)  # noqa: E731
    try:
        model, q = contact_configurations(convert(ch), k, draw, POSTURES)
    except InvalidArgumentError:  # the contact cannot hold often enough on this chain
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        res = analyze_model(model, "complete", k, q)
    if res.n_theory is None:
        assert res.theory_note
        return
    rank = pinocchio_rank(ch, kind, q, draw(1, 0)[0])
    assert (res.n_theory, res.n_complete) == (rank, rank), res.theory_note


@settings(CI, max_examples=10, deadline=None)
@pytest.mark.parametrize("normal", [True, False])
@pytest.mark.parametrize("kind", KINDS)
@given(data=st.data())
def test_planar_theory_is_the_pinocchio_rank(kind, normal, data):
    """Touching a plane across the axes (``normal``), the arm slides on it: a count."""
    _check(data.draw(planar_chains(normal)), kind)


@settings(CI, max_examples=10, deadline=None)
@pytest.mark.parametrize("kind", KINDS)
@given(data=st.data())
def test_spatial_theory_is_the_pinocchio_rank(kind, data):
    """Enough joints for the contact to move; parallel axes and prismatic joints anywhere."""
    _check(data.draw(spatial_chains(kind)), kind)
