"""--origins / result.origins(): the calibration carried into a xacro file.

tests/data/yarm.urdf.xacro takes its joint origins (and the links calib adds) from the origins
YAML; xacro (the registry package) expands it, Pinocchio loads the result, and its forward
kinematics of every frame equal those of the calibrated URDF calib wrote (1e-12).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import xacro  # the test extra installs it (the registry package, no ROS)

import calib
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.entry import calibrate as calibrate_tree
from calib.calibration.entry import calibrate_contacts
from calib.cli.commands import main
from calib.kinematics.origins import origins_yaml
from calib.kinematics.tree import load_tree
from calib.measurements.csvfile import write_measurements
from calib.measurements.tree_campaign import simulate_tree

XACRO = Path(__file__).parent / "data" / "yarm.urdf.xacro"


def expand(tmp_path: Path, origins: Path | None, name: str) -> Path:
    """The URDF xacro makes of the Y arm (with the origins file, if given)."""
    mappings = {} if origins is None else {"origins": str(origins)}
    doc = xacro.process_file(str(XACRO), mappings=mappings)
    path = tmp_path / name
    path.write_text(doc.toxml())
    return path


def same_kinematics(a: Path, b: Path, seed: int = 3) -> None:
    """Every frame of ``a`` at the place of the frame of that name in ``b``, at 20 postures."""
    ma, mb = pin.buildModelFromUrdf(str(a)), pin.buildModelFromUrdf(str(b))
    da, db = ma.createData(), mb.createData()
    assert sorted(f.name for f in ma.frames) == sorted(f.name for f in mb.frames)
    assert [ma.names[i] for i in range(ma.njoints)] == [mb.names[i] for i in range(mb.njoints)]
    rng = np.random.default_rng(seed)
    root = ma.frames[1].name  # the root link of both (the world link when added)
    for _ in range(20):
        q = rng.uniform(-2.5, 2.5, ma.nq)
        pin.framesForwardKinematics(ma, da, q)
        pin.framesForwardKinematics(mb, db, q)
        ra, rb = da.oMf[ma.getFrameId(root)], db.oMf[mb.getFrameId(root)]
        for f in ma.frames:
            Ta = ra.actInv(da.oMf[ma.getFrameId(f.name)]).homogeneous
            Tb = rb.actInv(db.oMf[mb.getFrameId(f.name)]).homogeneous
            np.testing.assert_allclose(Ta, Tb, atol=1e-12, rtol=0, err_msg=f.name)


def moved(a: Path, b: Path) -> float:
    """The largest difference of the two files' tool placements at the zero posture."""
    ma, mb = pin.buildModelFromUrdf(str(a)), pin.buildModelFromUrdf(str(b))
    da, db = ma.createData(), mb.createData()
    pin.framesForwardKinematics(ma, da, pin.neutral(ma))
    pin.framesForwardKinematics(mb, db, pin.neutral(mb))
    f = "tool_a"
    return float(
        np.abs(da.oMf[ma.getFrameId(f)].homogeneous - db.oMf[mb.getFrameId(f)].homogeneous).max()
    )


def test_chain_origins_in_the_xacro_reproduce_the_calibrated_urdf(tmp_path):
    nominal = expand(tmp_path, None, "yarm.urdf")
    chain = calib.load_chain(nominal, "base_link", "tool_a")
    campaign = calib.simulate(chain, 40, "position", marker=[0.01, 0.02, 0.03], seed=1)
    result = calib.calibrate(chain, campaign.measurements, params="complete")
    urdf = result.urdf(world_link="world")
    (tmp_path / "cal.urdf").write_bytes(urdf)
    doc = result.origins(urdf)
    joints = doc["joints"]
    assert {"tool_a_marker1_joint", "world_joint"} <= set(joints)  # the added links
    assert joints["world_joint"]["added"] and joints["world_joint"]["link"] == "world"
    assert joints["j3"]["nominal_xyz"] == "0 0 0.4" and not joints["j3"]["added"]
    assert not {"k3", "k4", "k5", "tool_b_joint"} & set(joints)  # the other branch: unmoved
    (tmp_path / "origins.yaml").write_text(origins_yaml(doc))
    assert moved(nominal, tmp_path / "cal.urdf") > 1e-4  # the calibration moved the tool
    same_kinematics(expand(tmp_path, tmp_path / "origins.yaml", "x.urdf"), tmp_path / "cal.urdf")


def test_tree_origins_in_the_xacro_reproduce_the_calibrated_urdf(tmp_path):
    nominal = expand(tmp_path, None, "yarm.urdf")
    tree = load_tree(nominal, "base_link", ["tool_a", "tool_b"])
    campaign = simulate_tree(tree, 40, markers=[0.01, 0.0, 0.02], seed=2)
    result = calibrate_tree(tree, campaign.measurements, params="complete")
    (tmp_path / "cal.urdf").write_bytes(result.urdf())
    doc = result.origins()
    assert {"k4", "k5", "j4", "j5"} <= set(doc["joints"])  # both branches
    (tmp_path / "origins.yaml").write_text(origins_yaml(doc))
    same_kinematics(expand(tmp_path, tmp_path / "origins.yaml", "x.urdf"), tmp_path / "cal.urdf")


def test_cli_writes_the_origins_beside_the_urdf(tmp_path, capsys):
    nominal = expand(tmp_path, None, "yarm.urdf")
    chain = calib.load_chain(nominal, "base_link", "tool_a")
    campaign = calib.simulate(chain, 40, "position", seed=1)
    write_measurements(tmp_path / "m.csv", campaign.measurements)
    out, origins = tmp_path / "cal.urdf", tmp_path / "o.yaml"
    argv = ["calibrate", str(nominal), "--base", "base_link", "--tool", "tool_a"]
    argv += ["--data", str(tmp_path / "m.csv"), "--out", str(out), "--params", "complete"]
    assert main([*argv, "--origins", str(origins), "--world-link", "meas"]) == 0
    assert str(origins) in capsys.readouterr().out  # "wrote ..."
    same_kinematics(expand(tmp_path, origins, "x.urdf"), out)


def test_cli_origins_over_an_input_is_refused_before_the_fit(tmp_path, capsys):
    nominal = expand(tmp_path, None, "yarm.urdf")
    data = tmp_path / "m.csv"
    chain = calib.load_chain(nominal, "base_link", "tool_a")
    write_measurements(data, calib.simulate(chain, 30, "position", seed=1).measurements)
    before = data.read_bytes()
    argv = ["calibrate", str(nominal), "--base", "base_link", "--tool", "tool_a"]
    argv += ["--data", str(data), "--out", str(tmp_path / "c.urdf"), "--origins", str(data)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("calib: error: ") and "--origins" in err[0], err
    assert data.read_bytes() == before and not (tmp_path / "c.urdf").exists()


def test_contact_origins_in_the_xacro_reproduce_the_calibrated_urdf(tmp_path):
    nominal = expand(tmp_path, None, "yarm.urdf")
    chain = calib.load_chain(nominal, "base_link", "tool_a")
    data = calib.simulate_contacts(chain, 40, "plane", seed=3).data
    result = calibrate_contacts(chain, data, params="complete")
    (tmp_path / "cal.urdf").write_bytes(result.urdf())
    doc = result.origins()
    assert doc["joints"] and not any(j["added"] for j in doc["joints"].values())
    (tmp_path / "origins.yaml").write_text(origins_yaml(doc))
    same_kinematics(expand(tmp_path, tmp_path / "origins.yaml", "x.urdf"), tmp_path / "cal.urdf")


def test_several_terms_origins_in_the_xacro_reproduce_the_calibrated_urdf(tmp_path):
    nominal = expand(tmp_path, None, "yarm.urdf")
    chains = [calib.load_chain(nominal, "base_link", t) for t in ("tool_a", "tool_b")]
    data = [calib.simulate_contacts(c, 30, "plane", seed=5 + k).data for k, c in enumerate(chains)]
    result = calibrate_contact_chains(chains, data, params="complete")
    (tmp_path / "cal.urdf").write_bytes(result.urdf())
    doc = result.origins()
    assert {"j4", "k4"} <= set(doc["joints"])  # both branches moved
    (tmp_path / "origins.yaml").write_text(origins_yaml(doc))
    same_kinematics(expand(tmp_path, tmp_path / "origins.yaml", "x.urdf"), tmp_path / "cal.urdf")
