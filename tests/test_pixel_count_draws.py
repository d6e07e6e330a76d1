"""``calib analyze --measure pixels`` counts at enough seeing postures, however few see.

An eye-in-hand Panda (camera 10 cm past ``panda_hand``) and a 6 x 5 board on the floor: 5 of
the first 100 random postures see it. The count must be the generic one, the rank of
central differences of Pinocchio's placements projected by a textbook pinhole
(tests/pixel_scorer.py) at many postures that see the board (drawn by the test).
"""

from __future__ import annotations

import json
import re
import shlex

import numpy as np
import pinocchio as pin
import pytest
from pinref import pin_config, pin_frame
from pixel_scorer import moved_model, numerical_rank, seen_pixels, textbook_pixels

import calib
from calib import load_chain
from calib.cli import main

K = np.array([[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]])
DIST = np.array([-0.1, 0.05, 0.0, 0.0, 0.0])
BOARD = np.array([(0.35 + 0.06 * i, 0.06 * j - 0.12, 0.0) for i in range(6) for j in range(5)])
CAMERA = np.eye(4)
CAMERA[2, 3] = 0.1  # on panda_hand, looking along its z


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("eye_in_hand")
    (folder / "intr.yaml").write_text(
        "image_width: 640\nimage_height: 480\n"
        "camera_matrix: [[600.0, 0.0, 319.5], [0.0, 600.0, 239.5], [0.0, 0.0, 1.0]]\n"
        "distortion_coefficients: [-0.1, 0.05, 0.0, 0.0, 0.0]\n"
    )
    rows = [f"b{k},{x:.3f},{y:.3f},0" for k, (x, y, _) in enumerate(BOARD)]
    (folder / "board.csv").write_text("point,x,y,z\n" + "\n".join(rows) + "\n")
    return folder


def _analyze(capsys, files, *extra) -> tuple[int, str, str]:
    argv = ["analyze", "panda", "--measure", "pixels", "--camera", "cam", "panda_hand"]
    argv += [str(files / "intr.yaml"), "0", "0", "0.1", "0", "0", "0"]
    argv += ["--target", str(files / "board.csv"), "--tool", "panda_link0", *extra]
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _seeing_rows(model, joints, postures: int, seed: int):
    """Postures within the URDF limits where the board is in front and in the image, and
    the points seen at each (4 at most: the camera-board placement is 6 numbers)."""
    ids = [model.getJointId(n) for n in joints]
    lo = np.array([model.lowerPositionLimit[model.joints[i].idx_q] for i in ids])
    hi = np.array([model.upperPositionLimit[model.joints[i].idx_q] for i in ids])
    data = model.createData()
    hand, root = pin_frame(model, "panda_hand"), pin_frame(model, "panda_link0")
    rng = np.random.default_rng(seed)
    qs, Xs = [], []
    while len(qs) < postures:
        q = rng.uniform(lo, hi)
        pin.framesForwardKinematics(model, data, pin_config(model, ids, q))
        board = np.array([data.oMf[hand].actInv(data.oMf[root].act(x)) for x in BOARD])
        p = (board - CAMERA[:3, 3]) @ CAMERA[:3, :3]
        uv = textbook_pixels(p, K, DIST)
        inside = (p[:, 2] > 0.05) & (uv >= 0).all(axis=1) & (uv < (640, 480)).all(axis=1)
        if inside.sum() >= 4:
            seen = np.flatnonzero(inside)
            qs += [q] * 4
            Xs += list(BOARD[seen[np.linspace(0, len(seen) - 1, 4).astype(int)]])
    return np.array(qs), np.array(Xs)


def _fd_rank(postures: int = 30, h: float = 1e-6) -> int:
    """Rank of the pixels' central differences over the camera's 6 and every joint's 6."""
    chain = load_chain("panda", base="panda_hand", tool="panda_link0")
    model = pin.buildModelFromUrdf(str(chain.urdf_path))
    joints = [f"panda_joint{k}" for k in range(1, 8)]
    q, X = _seeing_rows(model, joints, postures, seed=5)

    def px(C=CAMERA, model=model):
        return seen_pixels(model, "panda_hand", "panda_link0", joints, q, X, C, K, DIST).ravel()

    cols = []
    for e in h * np.eye(6):
        up, down = np.eye(4), np.eye(4)
        up[:3, :3], up[:3, 3] = pin.exp3(e[3:]), e[:3]
        down[:3, :3], down[:3, 3] = pin.exp3(-e[3:]), -e[:3]
        cols.append((px(C=CAMERA @ up) - px(C=CAMERA @ down)) / (2 * h))
    for name in joints:
        for e in h * np.eye(6):
            moved = (moved_model(model, name, np.eye(3), s * e) for s in (1, -1))
            cols.append((px(model=next(moved)) - px(model=next(moved))) / (2 * h))
    return numerical_rank(np.column_stack(cols))


def test_the_count_is_the_rank_at_many_seeing_postures(capsys, files):
    """At the default 100 postures only 5 see the board (25 counted before): analyze draws
    more, and its count is the finite-difference rank at 30 seeing postures."""
    code, out, err = _analyze(capsys, files, "--json")
    assert code == 0, err
    found = json.loads(out)
    assert found["n_base"] == _fd_rank()
    assert found["configs"] > 100 and found["postures"] >= 16
    assert "5 of the first 100 random postures see the target" in found["notes"][0]
    code, text, _ = _analyze(capsys, files)
    assert f"unknowns determined: {found['n_base']} of 48" in text
    assert "note: 5 of the first 100 random postures see the target" in text


def test_too_few_seeing_postures_are_said_with_what_to_do(capsys, files):
    """2 configurations, doubled 5 times: 64, too few see the board: one note line."""
    code, out, err = _analyze(capsys, files, "--configs", "2")
    assert code == 0, err
    notes = [line for line in out.splitlines() if line.startswith("note:")]
    assert len(notes) == 1
    assert "of 64 random postures see the target: the count may be low" in notes[0]
    assert "give more --configs" in notes[0]


def test_a_python_caller_gets_the_generic_count(files):
    """``pixel_count`` without postures draws as ``calib analyze`` does (it counted 25 at the
    100 postures a caller drew, 34 is right); at a caller's own 100 postures it says the count
    may be low."""
    from calib import PixelCamera, read_intrinsics, read_target
    from calib.calibration.pixel_chain import pixel_count

    chain = load_chain("panda", base="panda_hand", tool="panda_link0")
    camera = PixelCamera("cam", "panda_hand", read_intrinsics(files / "intr.yaml"), CAMERA)
    target = read_target(files / "board.csv")
    found = pixel_count((chain,), (camera,), target)
    assert found["n_base"] == _fd_rank() and found["n_unknowns"] == 48
    assert found["configs"] > 100 and "5 of the first 100" in found["notes"][0]
    q = chain.random_configurations(100, 0)
    own = pixel_count((chain,), (camera,), target, chain.joint_names, q)
    assert own["postures"] == 5 and own["n_base"] < found["n_base"]
    assert "only 5 of 100 postures see the target: the count may be low" in own["notes"][0]
    with pytest.raises(calib.InvalidArgumentError, match=r"pixel_chain\.pixel_count"):
        calib.analyze(chain, measure="pixels")  # it said: unknown measure 'pixels'


def test_the_next_step_simulates_enough_seeing_postures_and_calibrates(
    capsys, files, tmp_path, monkeypatch
):
    """The closing line's simulate command draws the postures the count settled on: it sees
    the board at about as many postures as the line says, and its OBS.csv is one the
    line's calibrate command calibrates."""
    monkeypatch.chdir(tmp_path)
    code, out, err = _analyze(capsys, files)
    assert code == 0, err
    found = re.fullmatch(
        r"next: record the pixels .* \(calib (simulate .*) simulates them: (\d+) of the (\d+) "
        r"postures see it\), then calib (calibrate .*)",
        out.splitlines()[-1],
    )
    assert found is not None, out
    simulate, seeing, calibrate = shlex.split(found.group(1)), found.group(2), found.group(4)
    assert simulate[simulate.index("--configs") + 1] == found.group(3)
    assert main(simulate) == 0
    said = capsys.readouterr().out
    seen = int(re.search(r"in (\d+) of \d+ postures", said).group(1))
    assert abs(seen - int(seeing)) <= 3 and seen >= 16  # the true robot is perturbed
    words = shlex.split(calibrate)
    words[words.index("--data") + 1] = "obs.csv"
    assert main(words) == 0, capsys.readouterr().err
    assert "accepted" in capsys.readouterr().out
