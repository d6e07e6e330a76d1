"""The kinematics primitives' own paths (issue 22's speed work), each against an independent
route: the conversion of lines traversed backwards (``sign``) against a Pinocchio model that
turns each joint by ``sign * q``; ``ParameterSet.apply`` against shifts added one by one in
plain Python; the tool pose's rigidity test at its documented tolerances.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import CI
from hypothesis import given
from hypothesis import strategies as st
from test_properties import PinReference, chains, random_q

import calib
from calib import from_tree
from calib.exceptions import InvalidArgumentError
from calib.identification.parameters import Kind, Parameter, ParameterSet, complete_parameters
from calib.kinematics.mdh import RIGID_TOL, from_lines
from calib.kinematics.tree import load_tree

FIELDS = ("beta", "alpha", "d", "theta", "r", "y")


@CI
@given(chains(), st.integers(0, 2**32 - 1))
def test_lines_traversed_backwards_follow_pinocchio_turned_by_the_sign(ch, seed):
    # Random signs and flipped directions on nasty chains (parallel, coincident, nearly
    # parallel, intersecting lines; prismatic joints): the model at q is the reference chain
    # (which knows neither DH nor signs) at sign * q, whatever the direction's orientation.
    rng = np.random.default_rng(seed)
    sign = rng.choice([-1, 1], ch.n)
    flip = rng.choice([-1.0, 1.0], (ch.n, 1))
    mdh = from_lines(ch.points, flip * ch.directions, ch.sigma, ch.tool, sign=sign)
    assert mdh.sign.tolist() == [1, *sign.tolist(), 1]
    ch.directions = flip * ch.directions  # the reference turns about the flipped axes too
    q = random_q(ch, 20, seed=3)
    T, T_ref = mdh.forward(q), PinReference(ch).forward(q * sign)
    assert np.abs(T[:, :3, :3] - T_ref[:, :3, :3]).max() <= 1e-9
    assert np.abs(T[:, :3, 3] - T_ref[:, :3, 3]).max() <= 1e-9 * ch.size


def shifted_by_hand(model, params: ParameterSet, delta: np.ndarray) -> dict[str, list[float]]:
    """Each parameter's shift added to its field, one after the other, in plain floats."""
    fields = {
        p.kind.value: [float(v) for v in getattr(model, p.kind.value)] for p in params.parameters
    }
    for p, dx in zip(params.parameters, delta.tolist(), strict=True):
        fields[p.kind.value][p.row] += dx
    return fields


@CI
@given(st.integers(0, 2**32 - 1), st.integers(1, 60))
def test_apply_adds_every_shift_in_set_order_repeated_parameters_too(seed, size):
    rng = np.random.default_rng(seed)
    mdh = calib.from_chain(calib.load_chain("stanford"))  # prismatic, parallel rows
    pool = complete_parameters(mdh).parameters
    params = ParameterSet("drawn", tuple(pool[i] for i in rng.integers(0, len(pool), size)))
    delta = rng.normal(0.0, 0.1, size)
    shifted = params.apply(mdh, delta)
    for field, values in shifted_by_hand(mdh, params, delta).items():
        assert getattr(shifted, field).tolist() == values, field
    untouched = set(FIELDS) - {p.kind.value for p in params.parameters}
    for field in untouched:
        assert np.array_equal(getattr(shifted, field), getattr(mdh, field))
    assert shifted.source is None and mdh.source is not None  # another robot; mdh unchanged


def test_apply_shifts_a_tree_s_branch_parameters():
    tree = from_tree(load_tree("simple_humanoid"))
    branches = [k for k in range(len(tree.sigma)) if tree.gamma[k] != 0 or tree.b[k] != 0]
    k = branches[0] if branches else 1
    kinds = (Kind.GAMMA, Kind.B, Kind.D, Kind.B)
    params = ParameterSet("branch", tuple(Parameter(k, kind) for kind in kinds))
    delta = np.array([0.01, -0.02, 0.003, 0.5])
    shifted = params.apply(tree, delta)
    assert type(shifted) is type(tree)
    for field, values in shifted_by_hand(tree, params, delta).items():
        assert getattr(shifted, field).tolist() == values, field


def rotation(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [a for a in range(3) if a != axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


@pytest.mark.parametrize(
    ("change", "rigid"),
    [
        (lambda T: T, True),
        (lambda T: T.__setitem__((slice(0, 3), 0), T[:3, 0] * (1 + 0.4 * RIGID_TOL)), True),
        (lambda T: T.__setitem__((slice(0, 3), 0), T[:3, 0] * (1 + 0.6 * RIGID_TOL)), False),
        (lambda T: T.__setitem__((slice(0, 3), 1), -T[:3, 1]), False),  # a reflection
        (lambda T: T.__setitem__((3, 0), 5e-9), True),  # np.allclose's atol 1e-8
        (lambda T: T.__setitem__((3, 0), 2e-8), False),
        (lambda T: T.__setitem__((3, 3), 1 + 1.5e-5), False),
        (lambda T: T.__setitem__((3, 3), 1 + 5e-6), True),  # rtol 1e-5 of the 1
    ],
)
def test_the_tool_must_be_a_rigid_transform_within_rigid_tol(change, rigid):
    T = np.eye(4)
    T[:3, :3] = rotation(2, 0.3) @ rotation(0, -1.1)
    T[:3, 3] = (0.1, -0.2, 0.3)
    change(T)
    args = (np.zeros((1, 3)), [[0.0, 0.0, 1.0]], [0], T)
    if rigid:
        assert from_lines(*args).n == 1
    else:
        with pytest.raises(InvalidArgumentError, match="rigid homogeneous transform"):
            from_lines(*args)
