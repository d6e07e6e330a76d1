"""Several cameras in one fit: TIAGo's head camera and a camera in the cell see its hand.

The joint placements are shared (the arm's joints are on both chains, the torso on the cell
camera's, the head on the head camera's): one fit, one URDF with both camera links. Checked by
Pinocchio loading the written URDF and by the rank of central differences of Pinocchio's
placements (tests/pixel_scorer.py).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from pixel_scorer import moved_model, numerical_rank, seen_pixels
from pixel_setups import INTRINSICS, calibrated, grid, look_at, pixels

from calib import Problem, Term, calibrate, load_chain
from calib.calibration.pixel_chain import PixelCamera, PixelData, pixel_rows
from calib.measurements.pixel_simulation import simulate_cameras, simulate_pixels
from calib.measurements.pixels import PixelObservations, Target
from calib.measurements.true_robot import true_robot

K, DIST = INTRINSICS.camera.camera_matrix, INTRINSICS.camera.distortion
TARGET = grid(4, 3, 0.03)


def _merged(parts, joints) -> PixelObservations:
    """Each camera's observations with the union's joint columns."""
    q, camera, point, pixels = [], [], [], []
    for obs, full in parts:
        index = {
            tuple(row): i
            for i, row in enumerate(full[:, [joints.index(j) for j in obs.joint_names]])
        }
        q.append(full[[index[tuple(row)] for row in np.asarray(obs.q)]])
        camera += obs.camera
        point += obs.point
        pixels.append(obs.pixels)
    return PixelObservations(
        joints, np.concatenate(q), tuple(camera), tuple(point), np.concatenate(pixels)
    )


@pytest.fixture(scope="module")
def two(tmp_path_factory):
    folder = tmp_path_factory.mktemp("tiago2")
    head = load_chain("tiago", base="xtion_link", tool="arm_tool_link")
    cell = load_chain("tiago", base="base_footprint", tool="arm_tool_link")
    path = folder / "true.urdf"
    true_robot([head, cell], path, seed=4)
    truths = [load_chain(str(path), base=c.base_frame, tool="arm_tool_link") for c in (head, cell)]
    model = head.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    C_head = (
        data.oMf[model.getFrameId("xtion_link")].inverse()
        * data.oMf[model.getFrameId("xtion_optical_frame")]
    ).homogeneous
    C_cell = look_at(np.array([1.8, -0.6, 1.4]), [0.4, 0.0, 0.8])
    placements = (C_head, C_cell)
    joints = tuple(dict.fromkeys((*head.joint_names, *cell.joint_names)))
    qh, qc = head.random_configurations(3000, 5), cell.random_configurations(3000, 6)
    full = np.zeros((3000, len(joints)))
    for chain, q in ((cell, qc), (head, qh)):
        full[:, [joints.index(j) for j in chain.joint_names]] = q
    parts = []
    for name, truth, C in zip(("head", "cell"), truths, placements, strict=True):
        q = full[:, [joints.index(j) for j in truth.joint_names]]
        parts.append((simulate_pixels(truth, name, C, INTRINSICS, TARGET, q), full))
    seen = {tuple(r) for r in np.asarray(parts[0][0].q)}  # postures the head camera sees
    keep = [
        i
        for i, r in enumerate(full[:, [joints.index(j) for j in head.joint_names]])
        if tuple(r) in seen
    ][:150]
    full = full[keep]
    parts = [
        (
            simulate_pixels(
                t, n, C, INTRINSICS, TARGET, full[:, [joints.index(j) for j in t.joint_names]]
            ),
            full,
        )
        for n, t, C in zip(("head", "cell"), truths, placements, strict=True)
    ]
    obs = _merged(parts, joints)
    cameras = (
        PixelCamera("xtion_optical_frame", "xtion_link", INTRINSICS, None),
        PixelCamera("cell_camera", "base_footprint", INTRINSICS, C_cell),
    )
    renamed = PixelObservations(
        obs.joint_names,
        obs.q,
        tuple({"head": "xtion_optical_frame", "cell": "cell_camera"}[c] for c in obs.camera),
        obs.point,
        obs.pixels,
    )
    result = calibrated((head, cell), cameras, TARGET, renamed)
    return head, cell, renamed, result, placements


def test_two_cameras_one_urdf_reproduces_every_pixel(two, tmp_path):
    head, cell, obs, result, _ = two
    assert {o for o in obs.camera} == {"xtion_optical_frame", "cell_camera"}
    path = tmp_path / "cal.urdf"
    path.write_bytes(result.urdf())
    text = path.read_text()
    assert text.count('<link name="xtion_optical_frame"') == 1
    assert text.count('<link name="cell_camera"') == 1
    model = pin.buildModelFromUrdf(str(path))
    for name, chain in (("xtion_optical_frame", head), ("cell_camera", cell)):
        rows = pixel_rows(chain, obs, TARGET, name)
        assert rows.m > 100
        seen = seen_pixels(
            model,
            name,
            "arm_tool_link",
            chain.joint_names,
            rows.q,
            TARGET.position[rows.point],
            np.eye(4),
            K,
            DIST,
        )
        assert np.max(np.abs(seen - rows.pixels)) < 1e-9
    assert [c.name for c in result.chains] == ["xtion_optical_frame", "cell_camera"]
    assert pixels(result, "train_registration")["reprojection_rms_px"] > 0.3


def _fd_rank(chains, names, obs, Cs, every: int, target=TARGET, which=None) -> int:
    """Rank of central differences over each camera's 6 and every joint's 6 of the chains, on
    every ``every``-th row of each chain (Pinocchio + a textbook pinhole; nothing of calib's
    kinematics or camera). ``which``: each chain's camera in ``Cs`` (default: its own)."""
    h, model = 1e-6, chains[0].model
    which = range(len(chains)) if which is None else which
    rows = [pixel_rows(c, obs, target, n) for c, n in zip(chains, names, strict=True)]
    rows = [r.subset(np.arange(r.m) % every == 0) for r in rows]

    def px(model=model, Cs=Cs):
        return np.concatenate(
            [
                seen_pixels(
                    model,
                    ch.base_frame,
                    ch.tool_frame,
                    ch.joint_names,
                    r.q,
                    target.position[r.point],
                    Cs[i],
                    K,
                    DIST,
                ).ravel()
                for ch, r, i in zip(chains, rows, which, strict=True)
            ]
        )

    def moved(T, e):
        return T @ np.block([[pin.exp3(e[3:]), e[:3, None]], [np.zeros((1, 3)), 1]])

    cols = []
    for c in range(len(Cs)):
        for e in h * np.eye(6):
            up = [moved(T, e) if k == c else T for k, T in enumerate(Cs)]
            down = [moved(T, -e) if k == c else T for k, T in enumerate(Cs)]
            cols.append((px(Cs=up) - px(Cs=down)) / (2 * h))
    for name in dict.fromkeys(j for ch in chains for j in ch.joint_names):
        for e in h * np.eye(6):
            up, down = (moved_model(model, name, np.eye(3), s * e) for s in (1, -1))
            cols.append((px(model=up) - px(model=down)) / (2 * h))
    return numerical_rank(np.column_stack(cols))


def test_two_cameras_count_equals_an_independent_rank(two):
    """Central differences over both cameras' 6 and every joint's 6 on both chains' rows."""
    head, cell, obs, result, placements = two
    C = (result.chains[0].registered.camera, placements[1])
    rank = _fd_rank((head, cell), ("xtion_optical_frame", "cell_camera"), obs, C, 6)
    assert rank == result.identifiable
    assert result.identifiable > 38  # more than the head camera alone (test_pixel_calibration)


def test_simulate_and_analyze_take_two_cameras(two, tmp_path, capsys):
    """``simulate`` and ``analyze`` with --camera twice (TIAGo's head camera and one in the
    cell): one OBS.csv with both cameras' rows, every pixel of each seen by Pinocchio on the
    robot simulated (no error: the nominal one); analyze's count equals the rank of central
    differences on those rows (its postures: the same seed), more than either camera's."""
    import json

    from calib.cli import main
    from calib.measurements.intrinsics import write_intrinsics
    from calib.measurements.pixels import read_observations, write_target

    head, cell, _, _, placements = two
    write_target(tmp_path / "target.csv", TARGET)
    write_intrinsics(tmp_path / "intr.yaml", INTRINSICS)
    names = ("xtion_optical_frame", "cell_camera")
    cameras = []
    for name, chain, T in zip(names, (head, cell), placements, strict=True):
        numbers = [repr(float(v)) for v in (*T[:3, 3], *pin.rpy.matrixToRpy(T[:3, :3]))]
        cameras += ["--camera", name, chain.base_frame, tmp_path / "intr.yaml", *numbers]
    common = [
        *cameras,
        "--target",
        tmp_path / "target.csv",
        "--tool",
        "arm_tool_link",
        "--configs",
        1500,
        "--seed",
        3,
    ]
    argv = [
        "simulate",
        "tiago",
        "--measure",
        "pixels",
        *common,
        "--out",
        tmp_path / "obs.csv",
        "--error-mm",
        0,
        "--error-mrad",
        0,
    ]
    assert main([str(a) for a in argv]) == 0, capsys.readouterr().err
    assert "cameras xtion_optical_frame on xtion_link, cell_camera on base_footprint" in (
        capsys.readouterr().out
    )
    joints = tuple(dict.fromkeys((*head.joint_names, *cell.joint_names)))
    lenses = dict.fromkeys(names, INTRINSICS)
    obs = read_observations(tmp_path / "obs.csv", joints, lenses, TARGET)
    for name, chain, T in zip(names, (head, cell), placements, strict=True):
        rows = pixel_rows(chain, obs, TARGET, name)
        assert rows.m > 100
        seen = seen_pixels(
            chain.model,
            chain.base_frame,
            "arm_tool_link",
            chain.joint_names,
            rows.q,
            TARGET.position[rows.point],
            T,
            K,
            DIST,
        )
        assert np.max(np.abs(seen - rows.pixels)) < 1e-9
    argv = ["analyze", "tiago", "--measure", "pixels", *common, "--json"]
    assert main([str(a) for a in argv]) == 0
    counted = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in counted["cameras"]] == list(names)
    rank = _fd_rank((head, cell), names, obs, placements, 8)
    assert counted["n_base"] == rank and rank > 42  # the head camera alone: 38 (42 mounted)


def test_two_cameras_on_the_command_line(two, tmp_path, capsys):
    """--camera twice: one URDF with both camera links, the report's cameras and terms."""
    import json

    from calib.cli import main
    from calib.measurements.intrinsics import write_intrinsics
    from calib.measurements.pixels import write_observations, write_target

    _, _, obs, _, placements = two
    write_observations(tmp_path / "obs.csv", obs)
    write_target(tmp_path / "target.csv", TARGET)
    write_intrinsics(tmp_path / "intr.yaml", INTRINSICS)
    T = placements[1]
    numbers = [repr(float(v)) for v in (*T[:3, 3], *pin.rpy.matrixToRpy(T[:3, :3]))]
    argv = [
        "calibrate",
        "tiago",
        "--measure",
        "pixels",
        "--data",
        tmp_path / "obs.csv",
        "--camera",
        "xtion_optical_frame",
        "xtion_link",
        tmp_path / "intr.yaml",
        "--camera",
        "cell_camera",
        "base_footprint",
        tmp_path / "intr.yaml",
        *numbers,
        "--target",
        tmp_path / "target.csv",
        "--tool",
        "arm_tool_link",
        "--out",
        tmp_path / "cal.urdf",
        "--report",
        tmp_path / "r.json",
    ]
    assert main([str(a) for a in argv]) == 0, capsys.readouterr().err
    doc = json.loads((tmp_path / "r.json").read_text())
    assert set(doc["frames"]["cameras"]) == {"xtion_optical_frame", "cell_camera"}
    assert [(t["base"], t["kind"]) for t in doc["terms"]] == [
        ("xtion_link", "pixels"),
        ("base_footprint", "pixels"),
    ]
    for term in doc["errors"]["terms"]:
        assert term["train"]["pixels"]["calibrated"]["reprojection_max_px"] < 1e-9


def _hand_and_base() -> Target:
    """12 points on TIAGo's hand (arm_tool_link) and 12 on a board fixed to its base
    (base_footprint, 0.3 m up, in front), one target file's points."""
    board = grid(4, 3, 0.04, (0.5, -0.05))
    on_base = board.position + np.array([0.0, 0.0, 0.3])
    return Target(
        (*TARGET.point, *(f"b{i}" for i in range(len(board.point)))),
        np.vstack([TARGET.position, on_base]),
        ("arm_tool_link",) * len(TARGET.point) + ("base_footprint",) * len(board.point),
    )


@pytest.fixture(scope="module")
def two_links(tmp_path_factory):
    """TIAGo's head camera sees its hand and a board on its base: one camera, two terms (one
    per link: xtion_link -> arm_tool_link, xtion_link -> base_footprint), one truth."""
    folder = tmp_path_factory.mktemp("links")
    chains = [
        load_chain("tiago", base="xtion_link", tool=t) for t in ("arm_tool_link", "base_footprint")
    ]
    true_robot(chains, folder / "true.urdf", seed=6)
    truths = [
        load_chain(str(folder / "true.urdf"), base=c.base_frame, tool=c.tool_frame) for c in chains
    ]
    model = chains[0].model
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    C = (
        data.oMf[model.getFrameId("xtion_link")].inverse()
        * data.oMf[model.getFrameId("xtion_optical_frame")]
    ).homogeneous
    step = pin.SE3(pin.exp3(np.array([0.002, -0.001, 0.003])), np.array([0.003, -0.002, 0.001]))
    true_C = C @ step.homogeneous
    joints = tuple(dict.fromkeys(j for c in chains for j in c.joint_names))
    q = np.zeros((500, len(joints)))
    for chain in reversed(chains):
        q[:, [joints.index(j) for j in chain.joint_names]] = chain.random_configurations(500, 5)
    target = _hand_and_base()
    name = "xtion_optical_frame"
    obs = simulate_cameras(truths, [(name, true_C, INTRINSICS)] * 2, target, joints, q)
    camera = PixelCamera(name, "xtion_link", INTRINSICS, None)
    terms = tuple(Term(c, PixelData(camera, target, obs)) for c in chains)
    result = calibrate(Problem(terms, params="complete"))
    return chains, target, obs, result, C


def test_a_target_on_two_links_round_trip_on_the_written_urdf(two_links, tmp_path):
    """Noise-free: one camera link in the written URDF; Pinocchio sees every pixel of both
    links' points through it to 1e-9 px (the camera registered once, on both terms' rows)."""
    chains, target, obs, result, _ = two_links
    assert result.accepted, result.refusal
    path = tmp_path / "cal.urdf"
    result.write_urdf(path)
    assert path.read_text().count('<link name="xtion_optical_frame"') == 1
    model = pin.buildModelFromUrdf(str(path))
    for chain in chains:
        rows = pixel_rows(chain, obs, target, "xtion_optical_frame")
        assert rows.m > 500
        seen = seen_pixels(
            model,
            "xtion_optical_frame",
            chain.tool_frame,
            chain.joint_names,
            rows.q,
            target.position[rows.point],
            np.eye(4),
            K,
            DIST,
        )
        assert np.max(np.linalg.norm(seen - rows.pixels, axis=1)) < 1e-9
    cameras = [c.state.camera for c in result.chains]
    assert np.array_equal(cameras[0], cameras[1])
    assert not any(c.outliers for c in result.chains)  # round-off (1e-12 px) is no outlier
    assert pixels(result, "train_registration", 1)["reprojection_rms_px"] > 0.3


def test_a_target_on_two_links_count_equals_an_independent_rank(two_links):
    """The unknowns determined = the rank of central differences over the one camera's 6 and
    every joint's 6 of both chains (the torso's lift seen through the base's board), more than
    the hand alone (38, tests/test_pixel_calibration.py)."""
    chains, target, obs, result, C = two_links
    name = "xtion_optical_frame"
    rank = _fd_rank(chains, (name, name), obs, [C], 12, target, which=(0, 0))
    assert rank == result.identifiable == result.unknowns
    assert rank > 38


def test_a_target_on_two_links_on_the_command_line(two_links, tmp_path, capsys):
    """TARGET.csv with a link column (the hand's and the base's points): simulate, calibrate
    (one term per link, one camera) and analyze. Pinocchio sees every pixel of OBS.csv
    through the written URDF's camera link; analyze counts the fit's unknowns (the rank of
    central differences, test above)."""
    import json

    from calib.cli import main
    from calib.measurements.intrinsics import write_intrinsics
    from calib.measurements.pixels import read_observations, write_target

    chains, target, _, result, C = two_links
    write_target(tmp_path / "target.csv", target)
    write_intrinsics(tmp_path / "intr.yaml", INTRINSICS)
    name = "xtion_optical_frame"
    numbers = [repr(float(v)) for v in (*C[:3, 3], *pin.rpy.matrixToRpy(C[:3, :3]))]
    camera = ["--camera", name, "xtion_link", tmp_path / "intr.yaml"]
    common = ["--target", tmp_path / "target.csv", "--tool", "arm_tool_link"]
    argv = [
        "simulate",
        "tiago",
        "--measure",
        "pixels",
        *camera,
        *numbers,
        *common,
        "--configs",
        500,
        "--seed",
        5,
        "--out",
        tmp_path / "obs.csv",
    ]
    assert main([str(a) for a in argv]) == 0, capsys.readouterr().err
    out = tmp_path / "cal.urdf"
    argv = [
        "calibrate",
        "tiago",
        "--measure",
        "pixels",
        "--data",
        tmp_path / "obs.csv",
        *camera,
        *common,
        "--out",
        out,
        "--report",
        tmp_path / "r.json",
    ]
    assert main([str(a) for a in argv]) == 0, capsys.readouterr().err
    doc = json.loads((tmp_path / "r.json").read_text())
    assert [t["tool"] for t in doc["terms"]] == ["arm_tool_link", "base_footprint"]
    assert list(doc["frames"]["cameras"]) == [name]
    joints = tuple(dict.fromkeys(j for c in chains for j in c.joint_names))
    obs = read_observations(tmp_path / "obs.csv", joints, {name: INTRINSICS}, target)
    model = pin.buildModelFromUrdf(str(out))
    for chain in chains:
        rows = pixel_rows(chain, obs, target, name)
        seen = seen_pixels(
            model,
            name,
            chain.tool_frame,
            chain.joint_names,
            rows.q,
            target.position[rows.point],
            np.eye(4),
            K,
            DIST,
        )
        assert rows.m > 500 and np.max(np.linalg.norm(seen - rows.pixels, axis=1)) < 1e-9
    capsys.readouterr()
    argv = ["analyze", "tiago", "--measure", "pixels", *camera, *numbers, *common, "--json"]
    assert main([str(a) for a in argv]) == 0
    counted = json.loads(capsys.readouterr().out)
    assert counted["n_base"] == result.identifiable == 46


def test_a_target_on_two_links_as_two_pixel_terms(two_links, tmp_path, capsys):
    """``--term pixels NAME LINK OBS.csv`` once per link of the target, one camera: one
    placement fitted (frames.cameras once), every pixel through the written URDF to 1e-9 px;
    at --params complete (the target's mounting an unknown) refused in one line."""
    import json

    from calib.cli import main
    from calib.measurements.intrinsics import write_intrinsics
    from calib.measurements.pixels import write_observations, write_target

    chains, target, obs, _, _ = two_links
    write_target(tmp_path / "target.csv", target)
    write_intrinsics(tmp_path / "intr.yaml", INTRINSICS)
    write_observations(tmp_path / "obs.csv", obs)
    name, out = "xtion_optical_frame", tmp_path / "cal.urdf"
    argv = [
        "calibrate",
        "tiago",
        "--camera",
        name,
        "xtion_link",
        tmp_path / "intr.yaml",
        "--target",
        tmp_path / "target.csv",
        "--out",
        out,
        "--report",
        tmp_path / "r.json",
    ]
    for chain in chains:
        argv += ["--term", "pixels", name, chain.tool_frame, tmp_path / "obs.csv"]
    assert main([str(a) for a in [*argv, "--params", "complete"]]) != 0 and not out.exists()
    err = capsys.readouterr().err
    errors = [line for line in err.splitlines() if line.startswith("calib: error:")]
    assert len(errors) == 1 and "takes no mounting" in errors[0] and "Traceback" not in err
    assert main([str(a) for a in argv]) == 0, capsys.readouterr().err
    assert list(json.loads((tmp_path / "r.json").read_text())["frames"]["cameras"]) == [name]
    model = pin.buildModelFromUrdf(str(out))
    for chain in chains:
        rows = pixel_rows(chain, obs, target, name)
        seen = seen_pixels(
            model,
            name,
            chain.tool_frame,
            chain.joint_names,
            rows.q,
            target.position[rows.point],
            np.eye(4),
            K,
            DIST,
        )
        assert np.max(np.linalg.norm(seen - rows.pixels, axis=1)) < 1e-9
