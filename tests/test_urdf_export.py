"""Calibrated URDF: reloaded by Pinocchio and by yourdfpy it reproduces the calibrated model;
nothing but the calibrated origins changes; errors leave no file behind.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yourdfpy
from conftest import chain_of, mdh_of

from calib import CalibError, calibrate, from_chain, load_chain, simulate
from calib.identification.parameters import complete_parameters
from calib.kinematics.urdf_export import calibrated_urdf, measurement_to_base, write_calibrated_urdf

DATA = Path(__file__).parent / "data"
CHAINS = ["ur5", "panda", "stanford", str(DATA / "negative_axes.urdf")]


def chain_named(name: str):
    return load_chain(name) if "/" in name else chain_of(name)


def perturbed(chain, seed: int, mm: float = 2.0, mrad: float = 3.0):
    """Nominal and a randomly perturbed MDH model (every complete-set parameter)."""
    nominal = from_chain(chain)
    pset = complete_parameters(nominal)
    rng = np.random.default_rng(seed)
    scale = np.array([1e-3 * (mrad if p.kind.is_rotation else mm) for p in pset.parameters])
    return nominal, pset.apply(nominal, scale * rng.standard_normal(len(pset)))


def pin_tool_placements(path: Path, chain, q: np.ndarray) -> np.ndarray:
    """Tool in base by Pinocchio on the written file, joints addressed by name."""
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()

    def frame(name):
        return (
            model.getFrameId(name, pin.FrameType.BODY)
            if model.existBodyName(name)
            else model.getFrameId(name)
        )

    base, tool = frame(chain.base_frame), frame(chain.tool_frame)
    out = []
    for row in q:
        qp = pin.neutral(model)
        for name, v in zip(chain.joint_names, row, strict=True):
            joint = model.joints[model.getJointId(name)]
            if joint.nq == 2:
                qp[joint.idx_q : joint.idx_q + 2] = (math.cos(v), math.sin(v))
            else:
                qp[joint.idx_q] = v
        pin.framesForwardKinematics(model, data, qp)
        out.append(data.oMf[base].actInv(data.oMf[tool]).homogeneous)
    return np.array(out)


def yourdfpy_tool_placements(path: Path, chain, q: np.ndarray) -> np.ndarray:
    urdf = yourdfpy.URDF.load(
        str(path),
        load_meshes=False,
        build_scene_graph=True,
        build_collision_scene_graph=False,
        load_collision_meshes=False,
    )
    out = []
    for row in q:
        urdf.update_cfg(dict(zip(chain.joint_names, row, strict=True)))
        out.append(urdf.get_transform(chain.tool_frame, chain.base_frame))
    return np.array(out)


@pytest.mark.parametrize("name", CHAINS, ids=lambda n: Path(n).stem)
def test_reloaded_urdf_reproduces_the_calibrated_model(name, tmp_path):
    chain = chain_named(name)
    nominal, calibrated = perturbed(chain, seed=len(name))
    path = tmp_path / "cal.urdf"
    write_calibrated_urdf(path, chain, nominal, calibrated)
    q = chain.random_configurations(40, 5)
    expected = calibrated.forward(q)
    T = measurement_to_base(nominal, calibrated)
    assert np.abs(T @ pin_tool_placements(path, chain, q) - expected).max() < 1e-9
    assert np.abs(T @ yourdfpy_tool_placements(path, chain, q) - expected).max() < 1e-9
    # The nominal file and model agree (the reference the edit starts from).
    assert np.abs(pin_tool_placements(chain.urdf_path, chain, q) - nominal.forward(q)).max() < 1e-9


def test_calibrated_urdf_of_a_calibration_predicts_the_true_robot(tmp_path):
    chain = chain_of("panda")
    marker = np.array([0.05, 0.02, 0.1])
    campaign = simulate(chain, configs=50, measure="position", marker=marker, seed=2)
    res = calibrate(chain, campaign.measurements, marker=marker, params="complete")
    fitted = res.state.markers[0]  # the fitted marker, in the calibrated tool frame
    q = chain.random_configurations(100, 77)
    true_points = campaign.truth.true_mdh.forward(q)
    true_points = true_points[:, :3, :3] @ marker + true_points[:, :3, 3]
    # The result's URDF (the joint origins moved, the base kept: measurement_to_base is the
    # base frame in the instrument's), and the MDH writer's from the calibrated MDH model
    # (joint 1's nominal placement kept: the change of rows 0 and 1 joins the frame).
    written, mdh = tmp_path / "panda_cal.urdf", tmp_path / "panda_mdh.urdf"
    res.write_urdf(written)
    write_calibrated_urdf(mdh, chain, res.nominal, res.calibrated)
    frame = res.measurement_to_base
    moved = frame @ measurement_to_base(res.nominal, res.calibrated)
    for path, T in ((written, frame), (mdh, moved)):
        for placements in (
            pin_tool_placements(path, chain, q),
            yourdfpy_tool_placements(path, chain, q),
        ):
            world = T @ placements
            points = world[:, :3, :3] @ fitted + world[:, :3, 3]
            assert np.abs(points - true_points).max() < 1e-9


def _parse(path_or_bytes) -> ET.Element:
    parser = ET.XMLParser(target=ET.TreeBuilder(insert_comments=True))
    if isinstance(path_or_bytes, bytes):
        return ET.fromstring(path_or_bytes, parser=parser)
    return ET.parse(path_or_bytes, parser=parser).getroot()


def _tool_joint(chain) -> str:
    return {
        "ur5": "wrist_3_link-tool0_fixed_joint",
        "panda": "panda_hand_joint",
        "stanford": "tool0_joint",
        "negative_axes": "tool_joint",
    }[Path(chain.name).stem]


@pytest.mark.parametrize("name", CHAINS, ids=lambda n: Path(n).stem)
def test_only_the_calibrated_origins_change(name):
    chain = chain_named(name)
    nominal, calibrated = perturbed(chain, seed=3)
    raw = chain.urdf_path.read_bytes()
    new = calibrated_urdf(chain, nominal, calibrated)
    before, after = _parse(raw), _parse(new)
    changed = {*chain.joint_names[1:], _tool_joint(chain)}
    seen = set()
    pairs = list(zip(before.iter(), after.iter(), strict=True))  # same elements, same order
    parents = {c: p for p in before.iter() for c in p}
    for old, cur in pairs:
        assert old.tag == cur.tag
        assert (old.text or "").strip() == (cur.text or "").strip()
        parent = parents.get(old)
        in_changed_joint = (
            parent is not None
            and parent.tag == "joint"
            and parent.get("name") in changed
            and parents.get(parent) is before
        )
        if old.tag == "origin" and in_changed_joint:
            seen.add(parent.get("name"))
            assert set(cur.attrib) == {"xyz", "rpy"}
        else:
            assert old.attrib == cur.attrib
    assert seen == changed
    # Bytes before the root element (declaration, header comments) are kept as they were.
    start = raw.index(b"<robot")
    assert new[:start] == raw[:start]
    comments = [e.text for e in before.iter() if e.tag is ET.Comment]
    assert comments == [e.text for e in after.iter() if e.tag is ET.Comment]


def test_ur5_and_panda_specifics_are_kept():
    for name, needles in {
        "ur5": [
            b'xmlns:xacro="http://wiki.ros.org/xacro"',
            b"<transmission",
            b"package://example-robot-data/robots/ur_description/meshes/ur5/visual/base.dae",
            b"EDITING THIS FILE BY HAND IS NOT RECOMMENDED",
        ],
        "panda": [b'<mimic joint="panda_finger_joint1"', b'lower="-3.0718" upper="-0.0698"'],
    }.items():
        chain = chain_of(name)
        nominal, calibrated = perturbed(chain, seed=1)
        new = calibrated_urdf(chain, nominal, calibrated)
        for needle in needles:
            assert needle in new
        joint1 = _parse(new).find(f"joint[@name='{chain.joint_names[0]}']/origin")
        assert (
            joint1.attrib
            == _parse(chain.urdf_path.read_bytes())
            .find(f"joint[@name='{chain.joint_names[0]}']/origin")
            .attrib
        )


def test_nominal_export_keeps_the_geometry():
    chain = chain_of("stanford")
    nominal = mdh_of("stanford")
    before, after = (
        _parse(chain.urdf_path.read_bytes()),
        _parse(calibrated_urdf(chain, nominal, nominal)),
    )
    for joint in [*chain.joint_names[1:], "tool0_joint"]:
        old = before.find(f"joint[@name='{joint}']/origin")
        cur = after.find(f"joint[@name='{joint}']/origin")
        for key in ("xyz", "rpy"):
            a = np.array(old.get(key, "0 0 0").split(), dtype=float)
            b = np.array(cur.get(key).split(), dtype=float)
            assert np.allclose(a, b, atol=1e-12), (joint, key)


def test_tool_without_fixed_joint_gets_a_calibrated_tool_link(tmp_path):
    """The tool link is the child of the last joint (continuous j3): the calibrated tool is a
    link ``<tool>_calibrated`` fixed to it, and Pinocchio's kinematics of the written file to
    it is the calibrated model; a tree's tool there is still refused (its fixed joint is
    where a tree writes each tool)."""
    import pinocchio as pin

    from calib.kinematics.urdf_export import check_exportable

    chain = load_chain(DATA / "fixed_middle.urdf")
    nominal, calibrated = perturbed(chain, seed=0)
    path = tmp_path / "out.urdf"
    write_calibrated_urdf(path, chain, nominal, calibrated)
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    q = np.random.default_rng(3).uniform(-3.0, 3.0, (10, chain.n))
    T = measurement_to_base(nominal, calibrated)
    base = model.getFrameId(chain.base_frame)
    tool = model.getFrameId(f"{chain.tool_frame}_calibrated")
    for qi, expected in zip(q, calibrated.forward(q), strict=True):
        x = pin.neutral(model)
        for name, v in zip(chain.joint_names, qi, strict=True):
            joint = model.joints[model.getJointId(name)]
            if joint.nq == 2:
                x[joint.idx_q : joint.idx_q + 2] = np.cos(v), np.sin(v)
            else:
                x[joint.idx_q] = v
        pin.framesForwardKinematics(model, data, x)
        got = T @ (data.oMf[base].inverse() * data.oMf[tool]).homogeneous
        assert np.abs(got - expected).max() < 1e-9
    with pytest.raises(CalibError, match="continuous joint 'j3', not by a fixed joint"):
        check_exportable(chain)  # as a tree's tool


def test_a_failed_write_leaves_no_file(tmp_path, monkeypatch):
    import calib.core.fileio

    chain = chain_of("ur5")
    nominal, calibrated = perturbed(chain, seed=0)

    def broken(src, dst):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(calib.core.fileio.os, "replace", broken)
    with pytest.raises(CalibError, match="Input/output error"):
        write_calibrated_urdf(tmp_path / "cal.urdf", chain, nominal, calibrated)
    assert list(tmp_path.iterdir()) == []
