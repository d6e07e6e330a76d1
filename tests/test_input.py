"""Hostile and careless input (issue 11, items 5-8 and 10-11): every number checked, every
URDF Pinocchio reads is read, sizes bounded, one clear CalibError for the rest.

References are independent of calib: Pinocchio built directly from a file (hand-fixed where
Pinocchio itself refuses the original), the theory, and the strict ``json`` parser.
"""

from __future__ import annotations

import errno
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import ANALYSABLE, chain_of
from hypothesis import event, given, settings
from hypothesis import strategies as st
from pinref import file_chain_poses, own_random_q

import calib
from calib import (
    CalibError,
    InvalidArgumentError,
    analyze,
    from_chain,
    load_chain,
)
from calib.cli.commands import main
from calib.core.fileio import read_bytes_limited, read_text_limited
from calib.exceptions import URDFError
from calib.identification.identifiability import analyze_model
from calib.identification.jacobian import complete_jacobian, identification_jacobian
from calib.identification.parameters import complete_parameters, paper_parameters
from calib.kinematics.mdh import from_lines
from calib.kinematics.urdf_export import measurement_to_base, write_calibrated_urdf
from calib.kinematics.urdf_xml import MAX_COORDINATE, MAX_URDF_BYTES

DATA = Path(__file__).parent / "data"

JOINT = """  <joint name="{name}" type="{type}">
    <parent link="{parent}"/><child link="{child}"/>
    <origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>
    {limit}
  </joint>
"""
LIMIT = '<limit lower="-2" upper="2" effort="1" velocity="1"/>'


def two_joint_urdf(
    axis2="0 1 0", xyz2="0.4 0 0.1", rpy2="0 0 0", limit2=LIMIT, extra="", head=""
) -> str:
    """base -> j1 (z) -> j2 -> fixed tool: a small chain whose second joint is varied."""
    j1 = JOINT.format(
        name="j1",
        type="revolute",
        parent="base",
        child="l1",
        xyz="0 0 0.1",
        rpy="0 0 0",
        axis="0 0 1",
        limit=LIMIT,
    )
    j2 = JOINT.format(
        name="j2",
        type="revolute",
        parent="l1",
        child="l2",
        xyz=xyz2,
        rpy=rpy2,
        axis=axis2,
        limit=limit2,
    )
    tool = (
        '  <joint name="t" type="fixed"><parent link="l2"/><child link="tool"/>'
        '<origin xyz="0.1 0.05 0.2" rpy="0 0 0"/></joint>\n'
    )
    return (
        f'<?xml version="1.0"?>\n{head}<robot name="two">\n'
        '  <link name="base"/><link name="l1"/><link name="l2"/><link name="tool"/>\n'
        f"{j1}{j2}{tool}{extra}</robot>\n"
    )


def write(tmp_path: Path, text: str, name: str = "r.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def run_cli(capfd, *argv) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capfd.readouterr()
    return code, out, err


def assert_one_error_line(code: int, out: str, err: str, *facts: str) -> None:
    assert code != 0
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("calib: error:"), err
    for fact in facts:
        assert fact in lines[0], (fact, err)


def pin_tool_in_base(path: Path, base: str, tool: str, q: np.ndarray) -> np.ndarray:
    """Reference: Pinocchio builds the file itself and computes the tool in the base."""
    return np.array([T.homogeneous for _, T, _ in file_chain_poses(path, base, tool, q)])


# --------------------------------------------------------------------------------------
# Item 5: every number that enters is checked
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("change", "fact"),
    [
        ({"axis2": "0 0 1e-300"}, "zero axis"),
        ({"axis2": "0 0 0"}, "zero axis"),
        ({"axis2": "0 nan 1"}, "axis"),
        ({"axis2": "0 1"}, "axis"),
        ({"xyz2": "1e300 0 0.1"}, "origin xyz"),
        ({"xyz2": f"{2 * MAX_COORDINATE:g} 0 0.1"}, "origin xyz"),
        ({"xyz2": "0.4 inf 0.1"}, "origin xyz"),
        ({"xyz2": "1_0 0 0.1"}, "origin xyz"),
        ({"rpy2": "0 NaN 0"}, "origin rpy"),
        ({"rpy2": "0 1e300 0"}, "origin rpy"),
        ({"limit2": '<limit lower="2" upper="-2" effort="1" velocity="1"/>'}, "lower limit"),
        ({"limit2": '<limit lower="x" upper="2" effort="1" velocity="1"/>'}, "lower limit"),
    ],
)
def test_bad_numbers_in_a_urdf_are_one_error_naming_the_joint(tmp_path, capfd, change, fact):
    path = write(tmp_path, two_joint_urdf(**change))
    with pytest.raises(URDFError) as info:
        load_chain(path, tool="tool")
    message = str(info.value)
    assert "\n" not in message
    assert "'j2'" in message and fact in message, message
    for command in ("show", "analyze"):
        code, out, err = run_cli(capfd, command, str(path), "--tool", "tool", "--json")
        assert_one_error_line(code, out, err, "'j2'")


def test_sane_but_unusual_numbers_are_accepted(tmp_path):
    """Unnormalised axes, coordinates up to the bound, exponents: the same geometry as
    Pinocchio's own reading of the file."""
    text = two_joint_urdf(axis2="0 3e2 0", xyz2=f"{MAX_COORDINATE / 2:g} -0 1E-1", rpy2="+.5 0 0")
    path = write(tmp_path, text)
    chain = load_chain(path, tool="tool")
    q = own_random_q(chain.sigma, 10, seed=1)
    T = from_chain(chain).forward(q)
    assert np.allclose(T, pin_tool_in_base(path, "base", "tool", q), atol=1e-9 * MAX_COORDINATE)


def test_show_and_analyze_json_of_every_catalog_chain_are_strict_json(capfd):
    def refuse(name):
        raise AssertionError(f"{name} in JSON output")

    for name in ANALYSABLE[:: max(1, len(ANALYSABLE) // 12)]:
        for argv in (["show", name, "--json"], ["analyze", name, "--json", "--configs", "30"]):
            code, out, _ = run_cli(capfd, *argv)
            assert code == 0, argv
            json.loads(out, parse_constant=refuse)


def test_from_lines_refuses_a_zero_direction_and_bad_arrays():
    p, u, tool = np.zeros((2, 3)), np.array([[0, 0, 1.0], [0, 0, 0]]), np.eye(4)
    with pytest.raises(InvalidArgumentError, match="direction 2 is zero"):
        from_lines(p, u, [0, 0], tool)
    with pytest.raises(InvalidArgumentError, match="direction 1 is zero"):
        from_lines(p, [[0, 0, 1e-300], [1, 0, 0]], [0, 0], tool)
    good_u = [[0, 0, 1.0], [1, 0, 0]]
    bad_cases = [  # each refused for its own fault
        ((np.full((2, 3), np.nan), good_u, [0, 0], tool), "finite numbers, got NaN"),
        (
            (np.zeros((3, 3)), good_u, [0, 0], tool),
            r"sigma's 2\) must have shape \(2, 3\), got \(3, 3\)",
        ),
        ((np.full((2, 3), 1e300), good_u, [0, 0], tool), "within 10000"),
        ((p, good_u, [0, 2], tool), r"sigma holds 0 .* got \[0.0, 2.0\]"),
        ((p, good_u, [0, 0], 2 * np.eye(4)), "rigid homogeneous transform"),
        ((p, np.eye(3), [0, 0], tool), r"joint directions \(one per joint of sigma's 2\)"),
        ((p, good_u, [0, 0], np.eye(3)), r"tool pose must have shape \(4, 4\), got \(3, 3\)"),
        ((p, good_u, [], tool), r"at least one joint: sigma .* is empty"),  # not the points
        (("x", good_u, [0, 0], tool), "must be numbers, got 'x'"),
    ]
    for args, why in bad_cases:
        with pytest.raises(InvalidArgumentError, match=why):
            from_lines(*args)


def test_nan_joint_values_through_the_api_are_errors():
    chain, mdh = chain_of("ur5"), from_chain(chain_of("ur5"))
    q = np.zeros((3, 6))
    q[1, 2] = np.nan
    calls = [
        lambda: chain.check_configurations(q),
        lambda: chain.tool_placements(q),
        lambda: mdh.kinematics(q),
        lambda: mdh.forward(q),
        lambda: analyze_model(mdh, "paper", None, q),
        lambda: identification_jacobian(mdh, paper_parameters(mdh), q),
        lambda: complete_jacobian(mdh, q),
        lambda: mdh.forward(np.full((2, 6), 1e300)),
    ]
    for call in calls:
        with pytest.raises(InvalidArgumentError, match="joint positions"):
            call()


# --------------------------------------------------------------------------------------
# Item 6: memory and time are bounded
# --------------------------------------------------------------------------------------


def long_chain_urdf(n: int) -> str:
    parts = ['<?xml version="1.0"?>', '<robot name="long">', '<link name="l0"/>']
    for k in range(1, n + 1):
        axis = ("0 0 1", "0 1 0", "1 0 0")[k % 3]
        parts.append(
            f'<link name="l{k}"/><joint name="j{k}" type="revolute"><parent link="l{k - 1}"/>'
            f'<child link="l{k}"/><origin xyz="0.01 0.002 0.003" rpy="0.1 0.2 0.3"/>'
            f'<axis xyz="{axis}"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint>'
        )
    parts.append(
        f'<link name="tool"/><joint name="t" type="fixed"><parent link="l{n}"/>'
        '<child link="tool"/><origin xyz="0.1 0 0"/></joint></robot>'
    )
    return "\n".join(parts)


_PEAK_SCRIPT = """
import resource, sys
from calib.cli.commands import main
code = main(sys.argv[1:])
print(code, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
"""


def peak_kb(*argv: str) -> tuple[int, int]:
    """Exit code and peak resident memory [kB] of a CLI run in a fresh process."""
    proc = subprocess.run(
        [sys.executable, "-c", _PEAK_SCRIPT, *argv], capture_output=True, text=True, timeout=300
    )
    code, kb = proc.stdout.split()[-2:]
    return int(code), int(kb)


def test_show_of_a_1000_joint_chain_needs_little_memory(tmp_path):
    """It was killed at 24 GB (Pinocchio's Data grows as the cube of the joints)."""
    path = write(tmp_path, long_chain_urdf(1000))
    code, kb = peak_kb("show", str(path), "--json")
    assert code == 0
    assert kb < 1_000_000, kb


def test_memory_estimate_of_an_analysis_is_an_upper_bound(tmp_path):
    """calib refuses what needs more than its estimate; the estimate must cover the real
    peak (measured here) of an analysis it accepts."""
    base_code, base_kb = peak_kb("analyze", "ur5", "--configs", "10")
    m = 20000
    code, kb = peak_kb("analyze", "ur5", "--configs", str(m))
    assert base_code == code == 0
    estimate_kb = m * 6 * calib.core.checks.BYTES_PER_CONFIG_JOINT / 1024
    assert kb - base_kb <= estimate_kb, (kb - base_kb, estimate_kb)


def test_memory_estimate_of_a_design_is_an_upper_bound():
    """The design's own estimate (smaller than an analysis's) covers its real peak."""
    argv = ["design", "tiago", "--configs", "30", "--no-collision", "--quiet", "--candidates"]
    base_code, base_kb = peak_kb(*argv, "200")
    m = 20000
    code, kb = peak_kb(*argv, str(m))
    assert base_code == code == 0
    estimate_kb = m * 8 * calib.core.checks.DESIGN_BYTES_PER_CANDIDATE_JOINT / 1024
    assert kb - base_kb <= estimate_kb, (kb - base_kb, estimate_kb)


@pytest.mark.parametrize("configs", ["1e12", "1000000000000", "100000000"])
@pytest.mark.parametrize("command", ["analyze", "simulate", "sweep"])
def test_huge_configs_are_refused_at_once(tmp_path, capfd, command, configs):
    argv = [command, "--configs", configs]
    argv += [] if command == "sweep" else ["ur5"]
    argv += ["--out", str(tmp_path / "s.csv")] if command == "simulate" else []
    t0 = time.perf_counter()
    code, out, err = run_cli(capfd, *argv)
    assert time.perf_counter() - t0 < 10
    assert_one_error_line(code, out, err, "configs" if configs == "1e12" else "configurations")
    assert list(tmp_path.iterdir()) == []


def test_analyze_refuses_configs_beyond_the_memory_budget():
    with pytest.raises(InvalidArgumentError, match="GB"):
        analyze("ur5", configs=10**9, measure="pose", params="paper")
    with pytest.raises(InvalidArgumentError, match="GB"):
        chain_of("ur5").random_configurations(10**12, seed=0)


def test_reading_is_size_limited(tmp_path):
    t0 = time.perf_counter()
    sparse = tmp_path / "sparse.csv"
    with open(sparse, "wb") as f:
        f.truncate(300 << 20)
    with pytest.raises(OSError) as info:
        read_bytes_limited(sparse, 1 << 20)
    assert info.value.errno == errno.EFBIG and "1 MB" in info.value.strerror
    assert time.perf_counter() - t0 < 5
    with pytest.raises(OSError) as info:  # a device is not read at all (issue 29, item 7)
        read_bytes_limited("/dev/zero", 1 << 20)
    assert "character device" in info.value.strerror
    small = write(tmp_path, "a,b\n1,2\n", "d.csv")
    assert read_text_limited(small, 8) == "a,b\n1,2\n"
    with pytest.raises(OSError) as info:
        read_text_limited(small, 7)
    assert info.value.errno == errno.EFBIG
    (tmp_path / "bin.csv").write_bytes(b"a\xff\n")
    with pytest.raises(OSError) as info:
        read_text_limited(tmp_path / "bin.csv", 100)
    assert info.value.errno == errno.EILSEQ
    with pytest.raises(IsADirectoryError):
        read_text_limited(tmp_path, 100)


def test_a_huge_urdf_is_refused_quickly(tmp_path, capfd):
    """A 300 MB comment (a sparse file) and /dev/zero: one line, no parse, no hang."""
    big = tmp_path / "big.urdf"
    with open(big, "wb") as f:
        f.write(b'<?xml version="1.0"?>\n<robot name="big"><!-- ')
        f.truncate(300 << 20)
    assert big.stat().st_size > MAX_URDF_BYTES
    for robot, says in ((str(big), "larger than 64 MB"), ("/dev/zero", "character device")):
        t0 = time.perf_counter()
        code, out, err = run_cli(capfd, "show", robot)
        assert time.perf_counter() - t0 < 10
        assert_one_error_line(code, out, err, robot, says)


# --------------------------------------------------------------------------------------
# Item 8: namespace prefixes that no xmlns declares
# --------------------------------------------------------------------------------------

GAZEBO = """  <gazebo reference="l2">
    <sensor:camera name="cam"><sensor:imageSize>640 480</sensor:imageSize></sensor:camera>
    <controller:gazebo_ros_camera name="c" plugin="x.so"/>
  </gazebo>
"""


def test_undeclared_namespace_prefix_is_read_as_pinocchio_reads_it(tmp_path):
    path = write(tmp_path, two_joint_urdf(extra=GAZEBO))
    chain = load_chain(path, tool="tool")
    q = own_random_q(chain.sigma, 10, seed=2)
    assert np.allclose(
        from_chain(chain).forward(q), pin_tool_in_base(path, "base", "tool", q), atol=1e-10
    )
    res = analyze(path, tool="tool", measure="position", params="complete")
    assert res.n_base == res.n_complete == 4 * 2 + 3


def test_calibrated_export_of_a_file_with_undeclared_prefixes(tmp_path):
    head = "<!-- a comment before the root -->\n"
    path = write(tmp_path, two_joint_urdf(extra=GAZEBO, head=head))
    chain = load_chain(path, tool="tool")
    nominal = from_chain(chain)
    pset = complete_parameters(nominal)
    delta = np.random.default_rng(3).normal(scale=1e-3, size=len(pset))
    calibrated = pset.apply(nominal, delta)
    out = tmp_path / "cal.urdf"
    write_calibrated_urdf(out, chain, nominal, calibrated)
    text = out.read_text()
    assert "<sensor:camera" in text and "<sensor:imageSize>640 480</sensor:imageSize>" in text
    assert text.startswith('<?xml version="1.0"?>\n' + head)
    # Pinocchio reads the export itself: its kinematics is the calibrated model's.
    q = own_random_q(chain.sigma, 10, seed=4)
    T = pin_tool_in_base(out, "base", "tool", q)
    M = measurement_to_base(nominal, calibrated)
    assert np.allclose(M @ T, calibrated.forward(q), atol=1e-9)


def test_default_namespace_and_entities_are_fine(tmp_path):
    head = '<!DOCTYPE robot [<!ENTITY off "0.4 0 0.1">]>\n'
    text = two_joint_urdf(xyz2="&off;", head=head).replace(
        '<robot name="two">', '<robot name="two" xmlns="http://example.org/urdf">'
    )
    path = write(tmp_path, text)
    chain = load_chain(path, tool="tool")
    reference = write(tmp_path, two_joint_urdf(), "ref.urdf")
    q = own_random_q(chain.sigma, 5, seed=5)
    assert np.allclose(chain.tool_placements(q), pin_tool_in_base(reference, "base", "tool", q))


# --------------------------------------------------------------------------------------
# Item 10: what calib does not use cannot make Pinocchio refuse the file or talk
# --------------------------------------------------------------------------------------

UNUSED_LIMITS = [
    '<limit lower="-2" upper="2" effort="-1" velocity="1"/>',
    '<limit lower="-2" upper="2" effort="1"/>',
    '<limit lower="-2" upper="2"/>',
    '<limit lower="-2" upper="2" effort="abc" velocity="-3"/>',
]
MATERIALS = """  <link name="extra">
    <visual><geometry><mesh filename="package://nowhere/m.dae"/></geometry>
      <material name="undefined_material"/></visual>
    <inertial><mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>
    </inertial>
  </link>
  <joint name="e" type="fixed"><parent link="base"/><child link="extra"/></joint>
"""


@pytest.mark.parametrize("limit", UNUSED_LIMITS)
def test_unused_limit_fields_are_sanitised(tmp_path, limit):
    path = write(tmp_path, two_joint_urdf(limit2=limit))
    with pytest.raises((ValueError, RuntimeError)):
        pin.buildModelFromUrdf(str(path))  # the premise: Pinocchio refuses the original
    fixed = write(tmp_path, two_joint_urdf(), "fixed.urdf")
    chain = load_chain(path, tool="tool")
    assert (chain.lower[1], chain.upper[1]) == (-2.0, 2.0)
    q = own_random_q(chain.sigma, 10, seed=6)
    assert np.allclose(from_chain(chain).forward(q), pin_tool_in_base(fixed, "base", "tool", q))


def test_revolute_joint_without_limit_tag_is_sampled_over_a_turn(tmp_path):
    path = write(tmp_path, two_joint_urdf(limit2=""))
    with pytest.raises((ValueError, RuntimeError)):
        pin.buildModelFromUrdf(str(path))
    chain = load_chain(path, tool="tool")
    assert (chain.lower[1], chain.upper[1]) == (-math.pi, math.pi)
    assert analyze(chain, measure="pose", params="complete").n_base == 4 * 2 + 6


def test_pinocchio_messages_are_hidden_unless_verbose(tmp_path, capfd):
    path = write(tmp_path, two_joint_urdf(extra=MATERIALS))
    code, out, err = run_cli(capfd, "show", str(path), "--tool", "tool")
    assert code == 0 and err == ""
    # A file urdfdom refuses (two roots): one calib line; --verbose adds urdfdom's own.
    text = two_joint_urdf().replace('<link name="base"/>', '<link name="base"/><link name="x"/>')
    bad = write(tmp_path, text, "bad.urdf")
    code, out, err = run_cli(capfd, "show", str(bad), "--tool", "tool")
    assert_one_error_line(code, out, err, "bad.urdf", "root")
    code, out, err = run_cli(capfd, "--verbose", "show", str(bad), "--tool", "tool")
    assert code != 0 and len(err.splitlines()) > 1 and "urdfdom" in err
    assert err.splitlines()[-1].startswith("calib: error:")
    code, out, err = run_cli(capfd, "show", str(bad), "--tool", "tool", "--verbose")
    assert code != 0 and "urdfdom" in err


# --------------------------------------------------------------------------------------
# Item 11: directories and mimic joints
# --------------------------------------------------------------------------------------


def test_a_directory_is_not_a_urdf(tmp_path, capfd, monkeypatch):
    (tmp_path / "robotdir").mkdir()
    monkeypatch.chdir(tmp_path)
    for robot in (tmp_path / "robotdir", "robotdir", str(tmp_path / "robotdir")):
        with pytest.raises(URDFError, match="is a directory"):
            load_chain(robot)
    code, out, err = run_cli(capfd, "show", "robotdir")
    assert_one_error_line(code, out, err, "robotdir", "is a directory")


def test_mimic_joint_behind_an_entity_name_is_still_a_mimic_joint(tmp_path):
    head = '<!DOCTYPE robot [<!ENTITY jn "j2">]>\n'
    text = two_joint_urdf(head=head).replace('name="j2"', 'name="&jn;"')
    end_of_j2 = LIMIT + '\n  </joint>\n  <joint name="t"'
    text = text.replace(end_of_j2, LIMIT + '<mimic joint="j1"/>' + end_of_j2[len(LIMIT) :])
    assert "<mimic" in text
    path = write(tmp_path, text)
    for tool in ("tool", "joint:j2", "l2", "link:tool"):
        chain = load_chain(path, tool=tool)
        assert chain.joint_names == ("j1", "j2")
        assert chain.variable_names == ("j1",)  # j2 follows j1: one independent joint
        assert [mj.name for mj in chain.coupling.mimic] == ["j2"]
    assert load_chain(path, tool="l1").coupling is None  # the chain before it has none


# --------------------------------------------------------------------------------------
# Must show: every URDF Pinocchio loads, with a serial chain, is analysed (or refused
# with the reason)
# --------------------------------------------------------------------------------------

VARIANTS = {
    "plain": two_joint_urdf(),
    "gazebo_prefixes": two_joint_urdf(extra=GAZEBO),
    "materials_and_bad_inertia": two_joint_urdf(extra=MATERIALS),
    "negative_effort": two_joint_urdf(limit2=UNUSED_LIMITS[0]),
    "no_velocity": two_joint_urdf(limit2=UNUSED_LIMITS[1]),
    "no_limit_tag": two_joint_urdf(limit2=""),
    "unnormalised_axis": two_joint_urdf(axis2="0 -7 0"),
    "equal_limits": two_joint_urdf(limit2=LIMIT.replace('"-2"', '"0"').replace('"2"', '"0"')),
    "huge_limits": two_joint_urdf(limit2=LIMIT.replace('"-2"', '"-1e9"').replace('"2"', '"1e9"')),
    "transmission": two_joint_urdf(
        extra='<transmission name="tr"><type>x</type><joint name="j2"/></transmission>\n'
    ),
    "continuous": two_joint_urdf().replace('"j2" type="revolute"', '"j2" type="continuous"'),
}


@pytest.mark.parametrize("variant", sorted(VARIANTS))
def test_every_urdf_pinocchio_loads_is_analysed(tmp_path, variant):
    path = write(tmp_path, VARIANTS[variant])
    try:
        pin.buildModelFromUrdf(str(path))
        pinocchio_loads = True
    except (ValueError, RuntimeError):
        pinocchio_loads = False
    try:
        res = analyze(path, tool="tool", measure="pose", params="complete")
    except CalibError as exc:
        assert not pinocchio_loads, f"Pinocchio loads {variant} but calib refuses it: {exc}"
        assert "\n" not in str(exc)
        return
    assert res.n_base == res.n_complete == 4 * 2 + 6


@pytest.mark.parametrize("name", ANALYSABLE)
def test_kinematic_copy_is_the_model_pinocchio_reads_from_the_file(name):
    """Pinocchio builds calib's model from calib's kinematic copy of the URDF: it must have
    the joints, frames and placements of the model Pinocchio builds from the file."""
    chain = chain_of(name)
    ref = pin.buildModelFromUrdf(str(chain.urdf_path))
    model = chain.model
    assert list(model.names) == list(ref.names)
    assert [j.shortname() for j in model.joints] == [j.shortname() for j in ref.joints]
    assert [(f.name, f.type, f.parentJoint) for f in model.frames] == [
        (f.name, f.type, f.parentJoint) for f in ref.frames
    ]
    q = pin.randomConfiguration(ref, -np.ones(ref.nq), np.ones(ref.nq))
    data, ref_data = model.createData(), ref.createData()
    pin.framesForwardKinematics(model, data, q)
    pin.framesForwardKinematics(ref, ref_data, q)
    for a, b in zip(data.oMf, ref_data.oMf, strict=True):
        assert np.allclose(a.homogeneous, b.homogeneous, atol=1e-12)
    lower, upper = chain.lower, chain.upper
    for k, jid in enumerate(chain.joint_ids):
        joint = ref.joints[jid]
        lo, hi = ref.lowerPositionLimit[joint.idx_q], ref.upperPositionLimit[joint.idx_q]
        if joint.nq == 1 and hi > lo:
            assert (lower[k], upper[k]) == (lo, hi)


NUMBER_TEXT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-1e5, 1e5).map(lambda v: f"{v:.4e}"),
    st.text(alphabet="0123456789.eE+-_ naif", max_size=12),
)


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(
    field=st.sampled_from(["xyz2", "rpy2", "axis2", "lower", "upper"]),
    words=st.one_of(
        st.lists(NUMBER_TEXT, min_size=1, max_size=4),
        st.lists(st.floats(-20, 20).map(repr), min_size=1, max_size=3),
    ),
)
def test_fuzzed_numbers_give_a_finite_model_or_one_error_naming_the_joint(field, words):
    value = " ".join(words)
    if field in ("lower", "upper"):
        old = 'lower="-2"' if field == "lower" else 'upper="2"'
        text = two_joint_urdf(limit2=LIMIT.replace(old, f'{field}="{value}"'))
    else:
        text = two_joint_urdf(**{field: value})
    with tempfile.TemporaryDirectory() as tmp:
        path = write(Path(tmp), text)
        try:
            chain = load_chain(path, tool="tool")
        except URDFError as exc:
            assert "\n" not in str(exc) and "'j2'" in str(exc), str(exc)
            event("refused")
            return
        event("accepted")
        mdh = from_chain(chain)
        rows = [v for row in mdh.rows() for v in row.values() if isinstance(v, float)]
        assert all(map(math.isfinite, rows))
        assert np.all(np.isfinite(mdh.forward(chain.random_configurations(5, seed=0))))
