"""Coupled (mimic) joints in a chain, against Pinocchio.

References computed without calib: Pinocchio builds its model from the URDF file itself, and
the test applies the ``<mimic>`` relation it reads with ElementTree (``tests/pinref.py``,
:class:`MimicChain`); where Pinocchio's own mimic joints load (``mimic=True``), they are
checked too. The identifiable counts are compared with the rank of finite differences of
Pinocchio's tool placement under a generic 6-DOF error on every joint placement, the base
and the tool.
"""

from __future__ import annotations

import json
import re
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import ANALYSABLE, COUPLED, chain_of
from pinref import MimicChain

import calib
from calib import DataError, analyze, from_chain, load_chain
from calib.cli.commands import main
from calib.exceptions import ChainError, URDFError
from calib.kinematics.urdf_export import calibrated_urdf, measurement_to_base
from calib.measurements.csvfile import measurements_csv, parse_measurements, simulate

DATA = Path(__file__).parent / "data"
NESTED = str(DATA / "mimic_of_mimic.urdf")
CHAINS = (*COUPLED, NESTED)
PIN_MIMIC_FAILS = {"romeo_left_finger", NESTED}
"""Pinocchio 4.1's mimic=True refuses these files (a master after its mimic joint)."""


def chain_for(name: str) -> calib.Chain:
    return load_chain(name) if name == NESTED else chain_of(name)


def reference(chain: calib.Chain, pin_mimic: bool = False) -> MimicChain:
    return MimicChain(chain.urdf_path, chain.base_frame, chain.tool_frame, pin_mimic)


def own_variables(chain: calib.Chain, m: int, seed: int) -> np.ndarray:
    """Independent joint positions drawn by the test: +-1 rad, +-0.02 m for prismatic joints."""
    ref = reference(chain)
    rng = np.random.default_rng(seed)
    values = rng.uniform(-1.0, 1.0, (m, len(chain.variable_names)))
    for i, name in enumerate(chain.variable_names):
        if ref.model.joints[ref.model.getJointId(name)].shortname().startswith("JointModelP"):
            values[:, i] *= 0.02
    return values


def test_the_coupled_list_is_every_catalog_chain_with_mimic_joints():
    coupled = {name for name in ANALYSABLE if chain_of(name).coupling is not None}
    assert coupled == set(COUPLED)


@pytest.mark.parametrize("name", CHAINS)
def test_variables_are_the_independent_joints_that_move_the_chain(name):
    chain = chain_for(name)
    ref = reference(chain)
    assert set(chain.variable_names) == ref.variables
    mimic = {mj.name for mj in chain.coupling.mimic}
    assert mimic and not mimic & set(chain.variable_names)
    in_chain = [n for n in chain.joint_names if n not in mimic]
    assert list(chain.variable_names[: len(in_chain)]) == in_chain  # chain order first


@pytest.mark.parametrize("name", CHAINS)
def test_forward_kinematics_equals_pinocchio_with_the_mimic_relation(name):
    chain = chain_for(name)
    qv = own_variables(chain, 20, seed=1)
    T = from_chain(chain).forward(chain.joint_values(qv))
    refs = [reference(chain)]
    if name not in PIN_MIMIC_FAILS:
        refs.append(reference(chain, pin_mimic=True))
    for ref in refs:
        T_ref = [ref.pose(ref.config(chain.variable_names, v)).homogeneous for v in qv]
        assert np.abs(T - np.array(T_ref)).max() < 1e-10


def test_pinocchio_refuses_the_files_said_to_fail():
    for name in PIN_MIMIC_FAILS:
        with pytest.raises(ValueError):
            reference(chain_for(name), pin_mimic=True)


def test_mimic_of_a_mimic_composes_the_relations():
    chain = load_chain(NESTED)
    qv = np.array([[0.3, -1.2], [-0.7, 2.0]])
    q = chain.joint_values(qv)
    q1 = qv[:, 0]
    expected = np.column_stack([q1, 2 * q1 + 0.1, -0.05 * (2 * q1 + 0.1) + 0.02, qv[:, 1]])
    assert np.allclose(q, expected, atol=1e-15)
    assert np.allclose(chain.coupling.variables(q), qv, atol=1e-15)


@pytest.mark.parametrize("measure", ["pose", "position"])
@pytest.mark.parametrize("name", CHAINS)
def test_identifiable_count_equals_the_rank_of_the_independent_reference(name, measure):
    chain = chain_for(name)
    ref = reference(chain)
    configs = [ref.config(chain.variable_names, v) for v in own_variables(chain, 24, seed=2)]
    rows = tuple(range(6)) if measure == "pose" else (0, 1, 2)
    rank, s = ref.error_rank(configs, rows)
    assert s[rank - 1] / s[0] > 1e-7 > 1e-9 > s[rank] / s[0]  # a clear gap
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        full = analyze(chain, measure=measure, params="complete")
        paper = analyze(chain, measure=measure, params="paper")
    assert full.n_base == full.n_complete == paper.n_complete == rank
    assert paper.n_base <= rank
    assert full.n_theory is None and paper.n_theory is None
    assert [mj.name for mj in full.mimic] == [mj.name for mj in chain.coupling.mimic]


def test_a_parallel_linkage_loses_directions_that_independent_joints_have():
    """mimic_arm: joint3 = -joint2 + 0.1 on a parallel axis keeps the forearm's attitude."""
    chain = chain_of("mimic_arm")
    ref = reference(chain)
    configs = [ref.config(chain.variable_names, v) for v in own_variables(chain, 24, seed=3)]
    rank, _ = ref.error_rank(configs, tuple(range(6)))
    assert rank == 28 < 4 * 6 + 6  # 2 fewer than six independent revolute joints


def _with_mimic_offset(chain: calib.Chain, joint: str, delta: float, tmp_path: Path) -> Path:
    """A copy of the chain's URDF whose joint's mimic offset is moved by ``delta`` (by the test)."""
    tree = ET.parse(str(chain.urdf_path))
    for element in tree.getroot().iter("joint"):
        if element.get("name") == joint:
            tag = element.find("mimic")
            tag.set("offset", repr(float(tag.get("offset", "0")) + delta))
    path = tmp_path / "moved.urdf"
    tree.write(path)
    return path


@pytest.mark.parametrize("name", ["mimic_arm", "panda_right_finger", "pr2_left_fingertip"])
def test_the_mimic_offset_is_the_joint_offset_of_its_row(name, tmp_path):
    """Moving the offset of the mimic expression moves the tool exactly as moving theta_k
    (r_k for a prismatic joint) of the mimic joint's row: one parameter."""
    chain = chain_of(name)
    delta = 1e-3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", calib.RankWarning)
        res = analyze(chain, measure="pose", params="complete")
    qv = own_variables(chain, 10, seed=4)
    mdh = from_chain(chain)
    for mj in chain.coupling.mimic:
        k = mj.joint + 1
        kind = "theta" if mdh.sigma[k] == 0 else "r"
        moved = getattr(mdh, kind).copy()
        moved[k] += delta
        T = mdh.replace(**{kind: moved}).forward(chain.joint_values(qv))
        path = _with_mimic_offset(chain, mj.name, delta, tmp_path)
        ref = MimicChain(path, chain.base_frame, chain.tool_frame)
        T_ref = np.array([ref.pose(ref.config(chain.variable_names, v)).homogeneous for v in qv])
        assert np.abs(T - T_ref).max() < 1e-12
        # The analysis: offset_k enters every base parameter theta_k enters, alike.
        joint_offset = f"{kind}{k}"
        assert res.mimic_offsets()[k] == joint_offset
        seen = 0
        for base, terms in res.regrouping_coefficients().items():
            c = 1.0 if base == joint_offset else terms.get(joint_offset)
            assert terms.get(f"offset{k}") == c
            seen += c is not None
        assert seen >= 1
        assert f"offset{k}" in "".join(res.regrouping().values())


def test_analyze_text_and_json_name_the_coupled_joints(capsys):
    assert main(["analyze", "mimic_arm"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^ +theta3 joint3 += theta3 \+ offset3$", out, re.M)  # row 3's joint
    assert "offset3 of joint3 = -1 joint2 + 0.1: with theta3" in out
    assert "offset5 of joint5 = 0.5 joint4 - 0.2: with theta5" in out
    assert "theory n/a" in out
    assert main(["show", "mimic_arm", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out)
    assert shown["variables"] == ["joint1", "joint2", "joint4", "joint6"]
    assert [(m["row"], m["master"], m["multiplier"], m["offset"]) for m in shown["mimic"]] == [
        (3, "joint2", -1.0, 0.1),
        (5, "joint4", 0.5, -0.2),
    ]


# --------------------------------------------------------------------------------------
# Bad mimic tags: one-line errors
# --------------------------------------------------------------------------------------


def _two_joints(mimic: str, j1_type: str = "revolute") -> str:
    limit = '<limit lower="-1" upper="1" effort="1" velocity="1"/>'
    return f"""<?xml version="1.0"?>
<robot name="r"><link name="b"/><link name="l1"/><link name="l2"/>
  <joint name="j1" type="{j1_type}"><parent link="b"/><child link="l1"/>
    <origin xyz="0 0 0.1"/><axis xyz="0 0 1"/>{limit if j1_type != "fixed" else ""}</joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 1 0"/>{limit}{mimic}</joint>
</robot>"""


@pytest.mark.parametrize(
    ("mimic", "j1_type", "error", "fact"),
    [
        ('<mimic joint="nosuch"/>', "revolute", ChainError, "'nosuch', which is not a joint"),
        ('<mimic joint="j2"/>', "revolute", ChainError, "cycle"),
        ('<mimic joint="j1"/>', "fixed", ChainError, "not a revolute, continuous or prismatic"),
        ('<mimic joint="j1" multiplier="two"/>', "revolute", URDFError, "mimic multiplier"),
        ('<mimic joint="j1" offset="nan"/>', "revolute", URDFError, "mimic offset"),
        ("<mimic/>", "revolute", URDFError, "without a joint name"),
    ],
)
def test_bad_mimic_tags_are_one_line_errors(tmp_path, capsys, mimic, j1_type, error, fact):
    path = tmp_path / "bad.urdf"
    path.write_text(_two_joints(mimic, j1_type))
    with pytest.raises(error, match=fact) as info:
        load_chain(path, base="b", tool="l2")
    assert "\n" not in str(info.value)
    assert main(["show", str(path), "--base", "b", "--tool", "l2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("calib: error:") and fact in err


def test_a_zero_multiplier_holds_the_joint_at_its_offset(tmp_path):
    path = tmp_path / "zero.urdf"
    path.write_text(_two_joints('<mimic joint="j1" multiplier="0" offset="0.4"/>'))
    chain = load_chain(path, base="b", tool="l2")
    assert chain.variable_names == ("j1",)
    assert np.allclose(chain.joint_values([[0.3], [-0.2]]), [[0.3, 0.4], [-0.2, 0.4]])


# --------------------------------------------------------------------------------------
# Measurements, calibration and the calibrated URDF
# --------------------------------------------------------------------------------------


def test_the_csv_holds_the_independent_joints_only():
    chain = chain_of("pr2_left_fingertip")  # its master is outside the chain
    campaign = simulate(chain, configs=6, measure="position", seed=1)
    text = measurements_csv(campaign.measurements)
    header = text.splitlines()[0].split(",")
    assert header[: len(chain.variable_names)] == list(chain.variable_names)
    assert "l_gripper_l_finger_joint" in header and "l_gripper_r_finger_joint" not in header
    back = parse_measurements(text, chain)
    assert np.abs(back.q - campaign.measurements.q).max() < 1e-15
    # The mimic joints follow the master column, read by the test from the CSV itself.
    rows = [dict(zip(header, line.split(","), strict=True)) for line in text.splitlines()[1:]]
    master = np.array([float(r["l_gripper_l_finger_joint"]) for r in rows])
    assert np.allclose(back.q[:, -2], master) and np.allclose(back.q[:, -1], master)
    missing = text.replace("l_gripper_l_finger_joint", "other_column")
    with pytest.raises(DataError, match="missing joint column"):
        parse_measurements(missing, chain)


def test_noise_free_calibration_of_a_coupled_arm_is_exact_and_keeps_the_mimic_tags(tmp_path):
    chain = chain_of("mimic_arm")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        campaign = simulate(chain, configs=60, measure="pose", seed=5)
        result = calib.calibrate(chain, campaign.measurements, params="complete")
    assert result.accepted, result.refusal
    qv = own_variables(chain, 15, seed=6)
    q = chain.joint_values(qv)
    true = campaign.truth.true_mdh.forward(q)
    assert np.abs(result.points(q)[:, 0] - true[:, :3, 3]).max() < 1e-9
    text = calibrated_urdf(chain, result.nominal, result.calibrated)
    tags = [
        {
            j.get("name"): j.find("mimic").attrib
            for j in root.iter("joint")
            if j.find("mimic") is not None
        }
        for root in (ET.parse(str(chain.urdf_path)).getroot(), ET.fromstring(text))
    ]
    assert (
        tags[0]
        == tags[1]
        == {
            "joint3": {"joint": "joint2", "multiplier": "-1", "offset": "0.1"},
            "joint5": {"joint": "joint4", "multiplier": "0.5", "offset": "-0.2"},
        }
    )
    path = tmp_path / "cal.urdf"
    path.write_bytes(text)
    # Pinocchio's own mimic joints, on the calibrated file.
    ref = MimicChain(path, chain.base_frame, chain.tool_frame, pin_mimic=True)
    to_base = measurement_to_base(result.nominal, result.calibrated)
    T_ref = np.array(
        [to_base @ ref.pose(ref.config(chain.variable_names, v)).homogeneous for v in qv]
    )
    assert np.abs(T_ref - result.calibrated.forward(q)).max() < 1e-9
