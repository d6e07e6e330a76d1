"""Round-off removal (issue 11, item 9): a rounded URDF gives the counts of the exact one.

The references are independent of calib's snapping: the theory (4R + 2P + 3, two fewer for a
point on the last axis) and a complete-model rank computed here from Pinocchio's frames of
the *unrounded* file (tests/pinref.py), with an SVD and a relative tolerance of 1e-8.
"""

from __future__ import annotations

import re
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import INDEPENDENT, chain_of
from pinref import file_chain_poses, own_random_q, rigid_error_columns

import calib
from calib import analyze, load_chain

MINIMAL = """<?xml version="1.0"?>
<robot name="minimal">
  <link name="base"/><link name="l1"/><link name="tool"/>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="t" type="fixed">
    <parent link="l1"/><child link="tool"/>
    <origin xyz="0 0 0.2" rpy="RPY"/>
  </joint>
</robot>
"""


def reference_rank(path: Path, base: str, tool: str, rows, q: np.ndarray) -> int:
    """Rank of a 6-DOF error on the base and on every moving link of the chain, from a
    Pinocchio model built from the file itself (Pinocchio's own Data, no calib code)."""
    blocks = []
    for _, tool_in_base, joints in file_chain_poses(path, base, tool, q):
        frames = [pin.SE3.Identity(), *joints]
        blocks.append(rigid_error_columns(frames, tool_in_base.translation)[list(rows)])
    s = np.linalg.svd(np.vstack(blocks), compute_uv=False)
    return int(np.sum(s > 1e-8 * s[0]))


@pytest.mark.parametrize("rpy", ["3.1416 0 0", "3.14159265358979 0 0", "3.1416 0 -3.1416"])
def test_minimal_rounded_tool_on_the_axis_gives_five(tmp_path, rpy):
    """One revolute joint about z, the tool on its axis with a rounded half-turn: the point
    is on the last axis, so position gives 4R + 3 - 2 = 5 (not 7)."""
    path = tmp_path / "minimal.urdf"
    path.write_text(MINIMAL.replace("RPY", rpy))
    q = own_random_q([0], 30, seed=1)
    assert reference_rank(path, "base", "tool", (0, 1, 2), q) == 5
    for params in ("paper", "complete"):
        res = analyze(path, "base", "tool", measure="position", params=params)
        assert (res.n_base, res.n_complete, res.n_theory) == (5, 5, 5), params
        assert res.on_last_axis


def rounded_copy(src: Path, dst: Path, digits: int = 4) -> None:
    """The URDF with every joint's rpy and xyz rounded to ``digits`` decimals (text edit)."""
    text = src.read_text()

    def rounded(match: re.Match) -> str:
        try:
            values = [round(float(v), digits) for v in match.group(2).split()]
        except ValueError:  # a xacro expression left in a comment: not a number to round
            return match.group(0)
        return f'{match.group(1)}="{" ".join(f"{v:g}" for v in values)}"'

    dst.write_text(re.sub(r'\b(rpy|xyz)="([^"]*)"', rounded, text))


def counts(res) -> tuple:
    return res.n_base, res.n_complete, res.n_theory, res.on_axes


@pytest.mark.parametrize("name", INDEPENDENT)  # coupled chains: tests/test_mimic.py
def test_rounded_catalog_chain_has_the_counts_of_the_exact_one(name, tmp_path):
    chain = chain_of(name)
    entry = next(e for e in calib.catalog() if e.name == name)
    rounded = tmp_path / "rounded.urdf"
    rounded_copy(chain.urdf_path, rounded)
    other = load_chain(rounded, entry.base, entry.tool)
    q = own_random_q(chain.sigma, 40, seed=3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        for measure, rows in (("position", (0, 1, 2)), ("pose", tuple(range(6)))):
            exact = analyze(chain, measure=measure, params="complete")
            again = analyze(other, measure=measure, params="complete")
            assert counts(again) == counts(exact), (measure, again.snapped)
            ref = reference_rank(chain.urdf_path, chain.base_frame, chain.tool_frame, rows, q)
            assert exact.n_complete == ref, measure


ARM = """<?xml version="1.0"?>
<robot name="arm">
  <link name="b"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/>
  <link name="ee"/>
  <joint name="j1" type="continuous"><parent link="b"/><child link="l1"/>
    <origin rpy="-PI 0 0" xyz="0 0 0.15"/><axis xyz="0 0 1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin rpy="HALF 0 0" xyz="0 0.005 -0.13"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/>
    <origin rpy="PI 0 0" xyz="0 -0.4 0"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
  <joint name="j4" type="continuous"><parent link="l3"/><child link="l4"/>
    <origin rpy="HALF 0 0" xyz="0 0.2 -0.006"/><axis xyz="0 0 1"/></joint>
  <joint name="ee" type="fixed"><parent link="l4"/><child link="ee"/>
    <origin rpy="PI 0 -PI" xyz="0 0 -0.06"/></joint>
</robot>
"""


def test_arm_with_rounded_half_turns_has_the_counts_of_the_exact_one(tmp_path):
    """A Kinova-like arm (rpy 1.5708 and 3.1416 everywhere, tool rpy "3.1416 0 -3.1416" on
    the last axis): position gives 4R + 3 - 2 = 17, as the exact file and Pinocchio say."""
    exact, rounded = tmp_path / "exact.urdf", tmp_path / "rounded.urdf"
    exact.write_text(ARM.replace("HALF", repr(np.pi / 2)).replace("PI", repr(np.pi)))
    rounded.write_text(ARM.replace("HALF", "1.5708").replace("PI", "3.1416"))
    q = own_random_q([0, 0, 0, 0], 30, seed=2)
    assert reference_rank(exact, "b", "ee", (0, 1, 2), q) == 17
    for path in (exact, rounded):
        res = analyze(path, "b", "ee", measure="position", params="complete")
        assert (res.n_base, res.n_complete, res.n_theory, res.on_axes) == (17, 17, 17, (4,))
