"""A calibration that fits no joint placement says so (checks47): the URDF it writes is the
nominal robot's, with only the registered frames, which a user who expected a fit is told in a
warning of the report (a note), with the option that fits; ``frames`` asked is not warned."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from calib import calibrate, load_chain, simulate, simulate_contacts

NONE = "no joint placement was fitted"


def _tool_placements(urdf: str, q: np.ndarray) -> np.ndarray:
    """tool0 in base_link at ``q`` (Pinocchio on the URDF ``urdf``, a path or its text)."""
    text = urdf.lstrip().startswith("<")
    model = pin.buildModelFromXML(urdf) if text else pin.buildModelFromUrdf(urdf)
    data, tool = model.createData(), model.getFrameId("tool0")
    base = model.getFrameId("base_link")
    out = []
    for qk in q:
        pin.framesForwardKinematics(model, data, qk)
        out.append((data.oMf[base].inverse() * data.oMf[tool]).homogeneous)
    return np.array(out)


@pytest.fixture(scope="module")
def ur5():
    return load_chain("ur5")


def test_auto_choosing_none_on_a_chain_is_warned_and_its_urdf_is_the_nominal_one(ur5):
    """2 mm of noise on 15 postures: ``auto`` keeps no parameter. Before, the fit was accepted
    with no warning (only "parameters: none fitted" in the summary); the URDF it writes moves
    no joint (Pinocchio: tool0 where the nominal URDF puts it) and adds the marker link."""
    data = simulate(ur5, 15, "position", marker=(0.01, 0.02, 0.05), noise_mm=2.0, seed=1)
    r = calibrate(ur5, data.measurements, params="auto", noise_mm=2.0)
    assert r.accepted and not r.free
    warned = [n for n in r.to_dict()["warnings"] if n.startswith(NONE)]
    assert len(warned) == 1, r.notes
    assert "params='complete' fits" in warned[0] and "more or more varied postures" in warned[0]
    assert "the markers as links on the tool" in warned[0]
    q = ur5.random_configurations(5, 3)
    written = r.urdf().decode()
    got, nominal = _tool_placements(written, q), _tool_placements(str(ur5.urdf_path), q)
    assert np.abs(got - nominal).max() < 1e-12
    assert "tool0_marker1" in written
    frames = calibrate(ur5, data.measurements, params="frames", noise_mm=2.0)
    assert frames.accepted and not [n for n in frames.notes if n.startswith(NONE)]


def test_every_parameter_fixed_is_warned_with_fix_named(ur5):
    """``offsets`` with every offset fixed: nothing fitted, the warning names ``fix``."""
    data = simulate(ur5, 15, "position", marker=(0.01, 0.02, 0.05), noise_mm=0.05, seed=1)
    offsets = calibrate(ur5, data.measurements, params="offsets").free
    r = calibrate(ur5, data.measurements, params="offsets", fix=offsets)
    assert r.accepted and not r.free
    warned = [n for n in r.notes if n.startswith(NONE)]
    assert len(warned) == 1 and "with fix left none" in warned[0], r.notes
    assert warned[0].endswith("if you expected a fit, name fewer parameters in fix")


def test_auto_choosing_none_on_touches_is_warned_and_its_urdf_is_the_nominal_one(ur5):
    """Touches of a robot that is its URDF (no error): ``auto`` keeps none; the warning says
    the URDF is the nominal one as is (the planes are not in it), which Pinocchio confirms."""
    touches = simulate_contacts(ur5, 12, "plane", seed=2, error_mm=0.0, error_mrad=0.0).data
    r = calibrate(ur5, touches, params="auto")
    assert r.accepted and not r.free
    warned = [n for n in r.to_dict()["warnings"] if n.startswith(NONE)]
    assert len(warned) == 1 and "the nominal robot's as is" in warned[0], r.notes
    q = ur5.random_configurations(5, 4)
    got = _tool_placements(r.urdf().decode(), q)
    assert np.abs(got - _tool_placements(str(ur5.urdf_path), q)).max() < 1e-12
    frames = calibrate(ur5, touches, params="frames")
    assert not [n for n in frames.notes if n.startswith(NONE)]
