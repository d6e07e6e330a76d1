"""A joint fit's chain frames (placements.chain_frames) against Pinocchio on the moved URDF.

The joint engine makes each chain's frames from arrays: the nominal transforms between the
joints' axis frames with the placement errors composed in, no model rebuilt. The reference
shares nothing with that route: the errors are written into the joints' ``<origin>`` of a
URDF file (``moved_origins_urdf``), Pinocchio reads that file itself and poses the tool in
the base frame, each joint set by its name. The chains cover joints traversed backwards
(TALOS from a sole to a hand), a prismatic joint, continuous joints and a mimic joint (the
PR2 from its base to a fingertip) and trees (TALOS's hands, the PR2's two fingertips: every
chain of the tree on one set of errors). The motion per unit error (``joint_twists``, the
fit's Jacobian) is checked against central differences of those frames.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from pinref import pin_frame

from calib import load_robot
from calib.calibration.placements import Placements, joint_twists
from calib.kinematics.catalog import resolve_urdf
from calib.kinematics.placement_export import moved_origins_urdf
from calib.kinematics.so3 import rotation_vector, skew

PR2 = resolve_urdf("erd:pr2_description/urdf/pr2.urdf")
CASES = {
    "talos_sole_to_hand": ("talos_full_v2.urdf", "left_sole_link", ("gripper_left_base_link",)),
    "pr2_base_to_fingertip": (PR2, "base_footprint", ("r_gripper_l_finger_tip_link",)),
    "talos_hands_tree": (
        "talos",
        "base_link",
        ("wrist_left_ft_tool_link", "wrist_right_ft_tool_link"),
    ),
    "pr2_fingertips_tree": (
        PR2,
        "base_footprint",
        ("r_gripper_l_finger_tip_link", "r_gripper_r_finger_tip_link"),
    ),
}


def _moved(case: str, seed: int, scale: float = 1e-2):
    """The case's chains and placements with every joint moved by ~1 cm / 10 mrad."""
    urdf, base, tools = CASES[case]
    chains = tuple(load_robot(urdf, base, tool) for tool in tools)
    pl = Placements.of(chains)
    return chains, pl.shifted(scale * np.random.default_rng(seed).standard_normal(pl.y.size))


def _pinocchio_tool(path, chain, q: np.ndarray) -> np.ndarray:
    """The tool frame in the base frame ``(m, 4, 4)``: Pinocchio on the URDF file, each joint
    set by its name (the other joints at Pinocchio's neutral)."""
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    b, t = pin_frame(model, chain.base_frame), pin_frame(model, chain.tool_frame)
    out = []
    for row in q:
        config = pin.neutral(model)
        for name, value in zip(chain.joint_names, row, strict=True):
            joint = model.joints[model.getJointId(name)]
            if joint.nq == 2:  # continuous: (cos, sin)
                config[joint.idx_q : joint.idx_q + 2] = (np.cos(value), np.sin(value))
            else:
                config[joint.idx_q] = value
        pin.framesForwardKinematics(model, data, config)
        out.append((data.oMf[b].inverse() * data.oMf[t]).homogeneous)
    return np.array(out)


def test_the_cases_hold_what_they_claim():
    """Backward, prismatic, continuous and mimic joints, and chains sharing joints."""
    talos = _moved("talos_sole_to_hand", 0)[0][0]
    assert np.any(talos.sign < 0) and np.any(talos.sign > 0)
    pr2 = _moved("pr2_base_to_fingertip", 0)[0][0]
    assert np.any(pr2.sigma == 1) and np.any(pr2.continuous)
    assert pr2.coupling is not None  # the fingertip's joint mimics the finger's
    for tree in ("talos_hands_tree", "pr2_fingertips_tree"):
        a, b = _moved(tree, 0)[0]
        assert set(a.joint_names) & set(b.joint_names)


@pytest.mark.parametrize("case", CASES)
def test_frames_equal_pinocchio_on_the_moved_urdf(case, tmp_path):
    chains, pl = _moved(case, 1)
    path = tmp_path / "moved.urdf"
    path.write_bytes(moved_origins_urdf(chains[0], pl.errors()))
    for k, chain in enumerate(chains):
        q = chain.random_configurations(9, 10 + k)
        kin = pl.frames(chain, q)
        T = _pinocchio_tool(path, chain, q)
        assert kin.R.shape == (9, chain.n + 1, 3, 3)
        assert np.max(np.abs(kin.R[:, -1] - T[:, :3, :3])) < 1e-12
        assert np.max(np.abs(kin.p[:, -1] - T[:, :3, 3])) < 1e-12  # [m]
        # the errors changed the tool by centimetres: a test that can fail
        nominal = Placements.of(chains).frames(chain, q)
        assert np.max(np.abs(nominal.p[:, -1] - T[:, :3, 3])) > 1e-3


@pytest.mark.parametrize("case", ["talos_sole_to_hand", "pr2_fingertips_tree"])
def test_errors_composed_on_a_fitted_robot(case, tmp_path):
    """A refinement's errors act on a robot already moved (``rebased``): the URDF holds both."""
    chains, pl = _moved(case, 2)
    more = pl.rebased().shifted(1e-2 * np.random.default_rng(3).standard_normal(pl.y.size))
    path = tmp_path / "moved.urdf"
    path.write_bytes(moved_origins_urdf(chains[0], more.errors()))
    for chain in chains:
        q = chain.random_configurations(6, 4)
        kin = more.frames(chain, q)
        T = _pinocchio_tool(path, chain, q)
        assert np.max(np.abs(kin.R[:, -1] - T[:, :3, :3])) < 1e-12
        assert np.max(np.abs(kin.p[:, -1] - T[:, :3, 3])) < 1e-12


@pytest.mark.parametrize("case", ["talos_sole_to_hand", "pr2_base_to_fingertip"])
def test_joint_twists_match_central_differences(case):
    """The tool's motion per unit error of every component of every joint (the frames the
    errors act at: before a forward joint's motion, after a backward one's)."""
    chains, pl = _moved(case, 5)
    chain = chains[0]
    q = chain.random_configurations(4, 6)
    kin = pl.frames(chain, q)
    ang, lin = joint_twists(pl, chain, kin)
    vel = lin - skew(kin.p[:, -1])[:, None] @ ang  # the tool origin's velocity
    columns = pl.path(chain).columns
    h, worst, scale = 1e-6, 0.0, 0.0
    for i, j in enumerate(columns):
        for c in range(6):
            dy = np.zeros(pl.y.size)
            dy[6 * j + c] = h
            up, down = pl.shifted(dy).frames(chain, q), pl.shifted(-dy).frames(chain, q)
            dp = (up.p[:, -1] - down.p[:, -1]) / (2 * h)
            dw = rotation_vector(up.R[:, -1] @ np.swapaxes(down.R[:, -1], 1, 2)) / (2 * h)
            worst = max(
                worst, np.abs(dp - vel[:, i, :, c]).max(), np.abs(dw - ang[:, i, :, c]).max()
            )
            scale = max(scale, np.abs(dp).max())
    assert worst < 1e-8 * max(scale, 1.0)


def test_start_models_are_the_chains_own_conversions_when_unmoved():
    """The registration's models (from_chain of each chain) are kept at zero errors: they are
    what chain_models makes there, array for array; another model or a moved robot's is not."""
    import dataclasses

    from calib.kinematics.mdh import from_chain

    hands = load_robot(
        "talos", "base_link", ["wrist_left_ft_tool_link", "wrist_right_ft_tool_link"]
    )
    chains = tuple(hands.chains)
    placements = Placements.of(chains)
    own = tuple(from_chain(c) for c in chains)
    states = [dataclasses.make_dataclass("S", [("mdh", object)])(m) for m in own]
    kept = placements.start_models(chains, states)
    assert all(a is b for a, b in zip(kept, own, strict=True))
    for a, b in zip(kept, placements.chain_models(chains), strict=True):
        for f in ("sigma", "beta", "alpha", "d", "theta", "r", "y", "sign"):
            assert np.array_equal(getattr(a, f), getattr(b, f)), f
    swapped = placements.start_models(chains, states[::-1])  # not these chains' models
    assert not any(a is b for a, b in zip(swapped, own[::-1], strict=True))
    y = placements.y.copy()
    y[0, 2] = 1e-3
    moved = dataclasses.replace(placements, y=y)
    assert not any(a is b for a, b in zip(moved.start_models(chains, states), own, strict=True))
