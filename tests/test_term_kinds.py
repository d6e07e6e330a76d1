"""Every kind is a term of one problem, in Python and on the command line alike.

Point feet (``plane-point``), fixed points and fixed poses, several objects per chain, beside
each other and beside a head camera's markers, poses or pixels: a noise-free campaign on a
true TALOS (every joint of the torso, both legs and the left arm moved, and the head camera,
calib.measurements.true_robot) fitted as one problem, then checked by Pinocchio alone on the
written URDF (tests/contact_scorer.py: each touch's contact frame on its fitted object;
tests/pixel_scorer.py: the pixels), exact to 1e-9. What a problem of two point feet
determines is the rank of Pinocchio's central differences (tests/test_self_measure.py's
``_Robot``, its rows those of a point on a plane). What does not apply to several terms is a
one-line error, in Python and on the command line.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from contact_scorer import contact_gaps, relative_placements
from pixel_scorer import seen_pixels
from pixel_setups import INTRINSICS, grid
from test_pixel_terms import _optical, _seen_postures
from test_self_measure import _camera_rows, _joints, _Robot

import calib
from calib import Problem, Term, calibrate, load_robot
from calib.calibration.pixel_chain import PixelCamera, PixelData, pixel_rows
from calib.cli.commands import main
from calib.cli.contact_chains_cli import TERM_KINDS
from calib.core.choices import CONTACT_MEASURES
from calib.exceptions import InvalidArgumentError
from calib.measurements.contact_campaign import simulate_contacts, write_contacts
from calib.measurements.pixel_simulation import simulate_pixels
from calib.measurements.true_robot import true_robot

URDF = "talos_full_v2.urdf"
FEET = (("torso_2_link", "left_sole_link"), ("torso_2_link", "right_sole_link"))
CAMERA = ("rgbd_optical_frame", "gripper_left_base_link")
ZERO = {"error_mm": 0.0, "error_mrad": 0.0}
ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def truth(tmp_path_factory):
    """A true TALOS: the torso's, both legs' and the left arm's joints and the head camera's
    placement moved (~1 mm / 1 mrad); its URDF path."""
    folder = tmp_path_factory.mktemp("truth")
    chains = [load_robot(URDF, *p) for p in (*FEET, CAMERA)]
    return true_robot(chains, folder / "true.urdf", measuring=chains[2:], seed=3).urdf


def _touches(urdf, pair, kind, seed, contacts=1, m=80):
    """Noise-free touches of a chain of ``urdf`` (its objects: the truth's)."""
    return simulate_contacts(
        load_robot(str(urdf), *pair), m, kind, contacts=contacts, seed=seed, **ZERO
    ).data


def _flush(out: Path, chain, data, part) -> float:
    """The largest gap [m, rad] Pinocchio sees on the written URDF: every touch's contact
    frame on its fitted object."""
    objects = [part.objects()[i] for i in data.ids]
    ends = (chain.base_frame, chain.tool_frame)
    gaps = contact_gaps(data.kind.label, out, *ends, part.contact, objects, _joints(chain, data.q))
    return float(np.abs(gaps).max())


CASES = [
    (("plane-point", "plane-point"), 1),
    (("fixed-point", "fixed-point"), 1),
    (("fixed-pose", "fixed-pose"), 1),
    (("plane", "plane-point"), 1),
    (("plane-point", "fixed-point"), 1),
    (("plane-point", "plane-point"), 2),
    (("fixed-point", "fixed-point"), 2),
    (("plane", "plane"), 2),
]


@pytest.mark.parametrize(("kinds", "objects"), CASES, ids=[f"{'+'.join(k)}x{n}" for k, n in CASES])
def test_contact_terms_of_every_kind_round_trip_on_the_written_urdf(
    truth, kinds, objects, tmp_path
):
    """Both feet touching from the torso, any contact kind each (one or several objects per
    chain): one problem, one URDF on which every touch, held out too, is flush to 1e-9."""
    nominal = [load_robot(URDF, *p) for p in FEET]
    pairs = enumerate(zip(FEET, kinds, strict=True))
    data = [_touches(truth, p, k, seed, objects) for seed, (p, k) in pairs]
    terms = tuple(Term(c, d) for c, d in zip(nominal, data, strict=True))
    result = calibrate(Problem(terms, params="complete", holdout=0.25, seed=0))
    assert result.accepted, result.refusal
    assert [t["kind"] for t in result.to_dict()["terms"]] == list(kinds)
    out = tmp_path / "cal.urdf"
    result.write(out)
    for chain, d, part in zip(nominal, data, result.chains, strict=True):
        assert len(part.objects()) == objects
        assert _flush(out, chain, d, part) < 1e-9
        assert part.stats["held_out_registration"].weighted_mm > 0.05  # something to fix


@pytest.mark.parametrize("pose", [False, True], ids=["markers", "pose"])
def test_a_camera_term_beside_a_point_foot_round_trips(truth, pose, tmp_path):
    """The head camera sees two markers on the left hand (or its pose) while the left foot
    touches a plane as a point: one problem, one URDF that reproduces the camera's rows
    (Pinocchio) and puts every touch on the fitted plane, to 1e-9."""
    foot, camera = load_robot(URDF, *FEET[0]), load_robot(URDF, *CAMERA)
    touches = _touches(truth, FEET[0], "plane-point", 1)
    markers = np.array([[0.03, -0.02, 0.05], [-0.01, 0.04, 0.02]])[: 1 if pose else 2]
    q = camera.random_configurations(60, 6)
    seen = _camera_rows(truth, camera, q, markers, pose)
    problem = Problem((Term(foot, touches), Term(camera, seen)), params="complete")
    result = calibrate(problem)
    assert result.accepted and result.to_dict()["terms"][1]["kind"] == (
        "pose" if pose else "position"
    )
    out = tmp_path / "cal.urdf"
    result.write(out)
    assert _flush(out, foot, touches, result.chains[0]) < 1e-9
    fitted = result.chains[1].state.inner
    again = _camera_rows(out, camera, q, fitted.markers, pose)
    assert np.max(np.abs(again.points - seen.points)) < 1e-9
    if pose:  # the measured frame's rotation in the written hand frame
        T = relative_placements(out, *CAMERA, _joints(camera, q))
        R = np.array([M.rotation @ fitted.tool_rotation for M in T])
        want = np.array([pin.Quaternion(*c[[3, 0, 1, 2]]).matrix() for c in seen.quaternion])
        assert np.max(np.abs(R - want)) < 1e-9


def test_a_camera_seeing_the_hand_beside_a_point_foot_round_trips(truth, tmp_path):
    """The head camera's pixels of a grid on the left hand (its placement on ``rgbd_link``
    unknown) while the left foot touches a plane as a point: every pixel through the written
    URDF's camera link (Pinocchio, a textbook pinhole) to 1e-9 px, every touch on its plane."""
    foot, head = load_robot(URDF, *FEET[0]), load_robot(URDF, "rgbd_link", CAMERA[1])
    target, C = grid(4, 3, 0.03), _optical(head)
    true_head = load_robot(str(truth), "rgbd_link", CAMERA[1])
    q = _seen_postures(head, true_head, C, 40)
    obs = simulate_pixels(true_head, CAMERA[0], C, INTRINSICS, target, q)
    camera = PixelCamera(CAMERA[0], "rgbd_link", INTRINSICS, None)
    touches = _touches(truth, FEET[0], "plane-point", 1)
    terms = (Term(foot, touches), Term(head, PixelData(camera, target, obs)))
    result = calibrate(Problem(terms, params="complete"))
    assert result.accepted, result.refusal
    out = tmp_path / "cal.urdf"
    result.write(out)
    assert _flush(out, foot, touches, result.chains[0]) < 1e-9
    rows = pixel_rows(head, obs, target, CAMERA[0])
    K, dist = INTRINSICS.camera.camera_matrix, INTRINSICS.camera.distortion
    X = target.position[rows.point]
    worst = []
    for urdf in (out, head.urdf_path):  # the written URDF, and the nominal one: something to fix
        model = pin.buildModelFromUrdf(str(urdf))
        seen = seen_pixels(
            model, CAMERA[0], CAMERA[1], head.joint_names, rows.q, X, np.eye(4), K, dist
        )
        worst.append(np.max(np.linalg.norm(seen - rows.pixels, axis=1)))
    assert rows.m > 200 and worst[0] < 1e-9 and worst[1] > 1.0


class _PointFeet(_Robot):
    """``_Robot`` whose touches are points on planes: each row the height alone."""

    def rows(self) -> np.ndarray:
        out = []
        for k, (base, tool, joints, _) in enumerate(self.terms):
            for M in self.rel(base, tool, joints):
                G = self.extra[("plane", k)].inverse() * M * self.extra[("contact", k)]
                out.append(G.translation[2:])
        return np.concatenate(out)


def test_two_point_feet_count_the_pinocchio_rank():
    """Both feet touching planes as points from the torso, on the nominal TALOS: what the
    problem determines (``calib.analyze``, and the unknowns ``calibrate`` fits at
    ``complete``) is the rank of Pinocchio's central differences of the heights under a twist
    of every joint placement, plane and contact frame."""
    chains = [load_robot(URDF, *p) for p in FEET]
    campaigns = [
        simulate_contacts(c, 50, "plane-point", seed=k, **ZERO) for k, c in enumerate(chains)
    ]
    data = [c.data for c in campaigns]
    terms = [
        (c.base_frame, c.tool_frame, _joints(c, d.q), "plane-point")
        for c, d in zip(chains, data, strict=True)
    ]
    robot = _PointFeet(chains[0].urdf_path, terms)
    for k, campaign in enumerate(campaigns):
        robot.extra[("plane", k)] = pin.SE3(campaign.truth.frames["table1"])
        robot.extra[("contact", k)] = pin.SE3.Identity()
    assert np.max(np.abs(robot.rows())) < 1e-9  # flush: the planes are right
    rank = robot.rank(list(dict.fromkeys(n for c in chains for n in c.joint_names)), [])
    assert rank < 100  # fewer than the rows: the rank is not the rows'
    problem = Problem(tuple(Term(c, d) for c, d in zip(chains, data, strict=True)))
    assert calib.analyze(problem).n_base == rank
    assert calibrate(Problem(problem.terms, params="complete")).unknowns == rank


@pytest.mark.parametrize(
    "option", [{"elastic": True}, {"fix": ("frame",)}, {"free": ("c1",)}, {"loss": "huber"}]
)
def test_what_several_terms_do_not_take_is_one_line(option):
    chains = [load_robot(URDF, *p) for p in FEET]
    data = [simulate_contacts(c, 12, "plane-point", seed=k).data for k, c in enumerate(chains)]
    with pytest.raises(InvalidArgumentError) as info:
        Problem(tuple(Term(c, d) for c, d in zip(chains, data, strict=True)), **option)
    said = str(info.value)
    assert said.startswith(f"{next(iter(option))} is for ") and "several terms" in said
    assert "\n" not in said


def _report_objects(doc: dict) -> tuple[list[dict[str, np.ndarray]], list[np.ndarray]]:
    """Each term's objects by touch id, and its contact frame, as the report gives them."""
    every = {k: np.array(v["matrix"]) for kind in doc["objects"].values() for k, v in kind.items()}
    contacts = doc["frames"]["contacts"]
    objects = []
    for term in doc["terms"]:
        ids = [o.split("@")[0] for o in term["objects"]]
        objects.append(dict(zip(ids, (every[o] for o in term["objects"]), strict=True)))
    return objects, [np.array(contacts[t["tool"]]["matrix"]) for t in doc["terms"]]


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize("kind", ["plane-point", "fixed-point", "fixed-pose"])
def test_the_command_line_takes_every_contact_kind_as_a_term(truth, kind, tmp_path, capsys):
    """``calib calibrate URDF --term KIND ... --term KIND ...``: the written URDF and the
    report's objects and contact frames put every touch in place (Pinocchio, 1e-9); ``calib
    analyze --term`` counts what ``calib.analyze`` of the same files counts."""
    chains = [load_robot(URDF, *p) for p in FEET]
    argv, read = [URDF], []
    for k, (pair, chain) in enumerate(zip(FEET, chains, strict=True)):
        path = tmp_path / f"{k}.csv"
        write_contacts(path, _touches(truth, pair, kind, k, m=60))
        argv += ["--term", kind, *pair, str(path)]
        read.append(calib.read_contacts(path, chain, kind))
    weight = ["--pose-weight", "2"] if kind == "fixed-pose" else []  # it weighs fixed poses
    out, report = tmp_path / "cal.urdf", tmp_path / "r.json"
    code = main(
        [
            "calibrate",
            *argv,
            *weight,
            "--params",
            "complete",
            "--quiet",
            "--out",
            str(out),
            "--report",
            str(report),
        ]
    )
    assert code == 0, capsys.readouterr().err
    objects, contacts = _report_objects(json.loads(report.read_text()))
    for chain, d, F, C in zip(chains, read, objects, contacts, strict=True):
        g = contact_gaps(
            kind,
            out,
            chain.base_frame,
            chain.tool_frame,
            C,
            [F[i] for i in d.ids],
            _joints(chain, d.q),
        )
        assert np.abs(g).max() < 1e-9
    capsys.readouterr()
    assert main(["analyze", *argv, "--json"]) == 0
    problem = Problem(tuple(Term(c, d) for c, d in zip(chains, read, strict=True)))
    assert json.loads(capsys.readouterr().out) == calib.analyze(problem).to_dict()


BAD = [
    (["--term", "plane-pointy", *FEET[0], "DATA"], "KIND one of " + ", ".join(TERM_KINDS)),
    (["--elastic"], "--elastic is for "),
    (["--fix", "frame"], "--fix is for "),
    (["--free", "c1"], "--free is for "),
    (["--loss", "huber"], "--loss is for "),
    (["--noise-mm", "0.1"], "--noise-mm is for "),
    (["--pose-weight", "2"], "--pose-weight weighs the rows of --loop"),
]


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(("extra", "said"), BAD)
def test_the_command_lines_refusals_are_one_line(extra, said, tmp_path, capsys):
    chain = load_robot(URDF, *FEET[0])
    write_contacts(tmp_path / "DATA", simulate_contacts(chain, 20, "plane-point", seed=1).data)
    data = str(tmp_path / "DATA")
    extra = [data if e == "DATA" else e for e in extra]
    argv = [
        "calibrate",
        URDF,
        "--term",
        "plane-point",
        *FEET[0],
        data,
        "--term",
        "plane-point",
        *FEET[0],
        data,
        *extra,
        "--out",
        str(tmp_path / "o.urdf"),
    ]
    assert main(argv) == 2
    err = [x for x in capsys.readouterr().err.splitlines() if not x.startswith("calib: warning")]
    assert len(err) == 1 and said in err[0], err
    assert not (tmp_path / "o.urdf").exists()


ONE_CHAIN = [["--loss", "huber"], ["--noise-mm", "0.1"]]


@pytest.mark.parametrize("extra", ONE_CHAIN, ids=[e[0] for e in ONE_CHAIN])
def test_one_chain_touching_takes_none_of_them_either(extra, tmp_path, capsys):
    """As contacts.md says: options of one chain measured by an instrument, for touches too
    (``--fix`` and ``--free`` name one chain touching's parameters: tests/test_weakly_seen.py)."""
    chain = load_robot(URDF, *FEET[0])
    write_contacts(tmp_path / "D.csv", simulate_contacts(chain, 20, "plane-point", seed=1).data)
    argv = ["calibrate", URDF, "--base", FEET[0][0], "--tool", FEET[0][1], "--measure"]
    argv += ["plane-point", "--data", str(tmp_path / "D.csv"), *extra]
    assert main([*argv, "--out", str(tmp_path / "o.urdf")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{extra[0]} is for one chain measured by an instrument" in err[0]


@pytest.mark.filterwarnings("ignore")
def test_loops_alone_are_terms_and_take_no_contact_frame(tmp_path, capsys):
    """Two ``--term loop`` make a problem (as two fixed-pose terms do in Python); ``--contact``
    is the touching terms' contact frame guess: with loops alone (a loop's contact frame is
    its tool frame) it would be dropped, so it is an error."""
    argv = ["calibrate", URDF, "--quiet", "--out", str(tmp_path / "o.urdf")]
    for k, pair in enumerate(FEET):
        path = tmp_path / f"{k}.csv"
        write_contacts(path, simulate_contacts(load_robot(URDF, *pair), 30, "fixed-pose").data)
        argv += ["--term", "loop", *pair, str(path)]
    assert main([*argv, "--contact", "0", "0", "0.1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--contact is the contact frame of the touching terms" in err[0]
    assert not (tmp_path / "o.urdf").exists()
    assert main([*argv, "--report", str(tmp_path / "r.json")]) == 0, capsys.readouterr().err
    doc = json.loads((tmp_path / "r.json").read_text())
    assert [t["kind"] for t in doc["terms"]] == ["fixed-pose", "fixed-pose"]
    assert (tmp_path / "o.urdf").exists() == doc["accepted"]


KIND_NAMED = r"--term ([a-z][a-z-]*)(?=[`|)]|\s+(?:[A-Z]|\S*_|\.\.\.))"
"""``--term KIND`` on a page: the kind then the code's end, a frame, a placeholder or ``...``
(not prose: "one per --term with several chains")."""


def test_every_term_kind_a_page_names_is_one_the_command_takes():
    """A page's ``--term KIND`` (a command line or a sentence) names a kind ``--term`` takes,
    and ``--term`` takes every contact kind ``--measure`` takes."""
    assert set(CONTACT_MEASURES) <= set(TERM_KINDS)
    pages = [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]
    named = {
        (page.name, kind) for page in pages for kind in re.findall(KIND_NAMED, page.read_text())
    }
    assert named and not {(page, kind) for page, kind in named if kind not in TERM_KINDS}
