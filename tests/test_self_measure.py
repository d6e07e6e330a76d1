"""The robot measuring itself as one term among others: a head camera measures the hand.

A measured term of :func:`calib.calibration.engine.calibrate_contact_chains` (``Measurements`` in
the chain's base frame, a frame on the robot) fitted with contact chains: one truth, one fit, one
URDF. Checked by routes that share nothing with the fit: central differences of the rows,
Pinocchio's forward kinematics of the written URDF, and the rank of central differences of
Pinocchio's placements under a small twist of every joint placement, of the camera frame's
placement, of the planes and contact frames (Pinocchio alone).
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest
from contact_scorer import configurations, plane_gaps, relative_placements
from contact_states import plane_state
from test_contact_chains import central_differences, moved_chains

from calib import load_chain, load_robot, simulate
from calib.calibration.chain_registration import MeasuredState
from calib.calibration.engine import calibrate_contact_chains
from calib.calibration.engine_model import ChainsData, ChainsModel, ChainsState
from calib.calibration.measured_view import MeasuredChain
from calib.calibration.model import registration_state
from calib.calibration.report import REPORT_KEYS
from calib.exceptions import CalibError, CalibrationRefusedError, DataError, InvalidArgumentError
from calib.identification.contacts import PlaneContact
from calib.kinematics.so3 import matrix_to_quaternion, rotation_matrix
from calib.measurements.contact_campaign import ContactData, simulate_contacts
from calib.measurements.data import Measurements
from calib.measurements.true_robot import true_robot

URDF = "talos_full_v2.urdf"
PAIRS = (
    ("left_sole_link", "gripper_left_base_link"),
    ("right_sole_link", "gripper_right_base_link"),
)
CAMERA = ("rgbd_optical_frame", "gripper_left_base_link")
CAMERA_TIAGO = ("xtion_optical_frame", "arm_tool_link")
MARKER = (0.02, 0.01, 0.05)


def _talos(urdf=URDF):
    return [load_robot(urdf, *p) for p in (*PAIRS, CAMERA)]


@pytest.mark.parametrize("pose", [False, True])
def test_jacobian_matches_central_differences(pose):
    """Every column: a plane chain's, the camera term's own (frame, 2 markers, tool rotation)
    and every joint's six placement components, at a moved robot and off the solution."""
    chains = (load_robot(URDF, *PAIRS[0]), load_robot(URDF, *CAMERA))
    rng = np.random.default_rng(1)
    pl, models, C, n = moved_chains(chains, rng)
    F = np.eye(4)
    F[:3, :3], F[:3, 3] = rotation_matrix([0.1, -0.2, 0.05]), [0.02, -0.01, 0.03]
    tool = rotation_matrix([0.2, 0.1, -0.3]) if pose else None
    markers = np.array([[0.01, 0.02, 0.1], [-0.03, 0.0, 0.05]])
    term = MeasuredState(registration_state(models[1], F, markers, tool), 0.3)
    start = ChainsState(chains, pl, (plane_state(models[0], C, n, 0.7, 0.3, "t"), term))
    q = [c.random_configurations(k, 3 + k) for c, k in zip(chains, (5, 6), strict=True)]
    quat = None
    if pose:
        quat = matrix_to_quaternion(rotation_matrix(rng.normal(size=(6, 3))))
    data = ChainsData(
        (
            ContactData(chains[0].joint_names, q[0], ("t",) * 5, PlaneContact()),
            Measurements(chains[1].joint_names, q[1], rng.normal(size=(6, 2, 3)), quat),
        )
    )
    kinds = (PlaneContact(), term.kind)
    model = ChainsModel((0, 1), 2, tuple(range(pl.y.size)), pl.names(), None, kinds, (1, 1))
    assert model.size() == 3 + 2 + 6 + 6 + 3 * pose + pl.y.size
    x = 1e-3 * rng.standard_normal(model.size())
    J = model.jacobian(start, x, data)
    num = central_differences(model, start, x, data)
    assert np.max(np.abs(J - num)) < 1e-6 * np.max(np.abs(num))


@pytest.fixture(scope="module")
def joint_fit(tmp_path_factory):
    """One true TALOS (every joint of the three chains and the camera's placement moved by
    ~1 mm / 1 mrad): both arms' table touches from the soles and the head camera's points on
    the left hand, fitted together."""
    folder = tmp_path_factory.mktemp("self")
    nominal = _talos()
    truth = true_robot(nominal, folder / "true.urdf", measuring=nominal[2:], seed=3)
    true = _talos(str(truth.urdf))
    zero = {"error_mm": 0.0, "error_mrad": 0.0}
    data = [simulate_contacts(c, 40, "plane", seed=1, **zero).data for c in true[:2]]
    data.append(simulate(true[2], 40, "position", marker=MARKER, seed=2, **zero).measurements)
    r = calibrate_contact_chains(nominal, data, params="complete", holdout=0.25, seed=0)
    out = folder / "cal.urdf"
    r.write_urdf(out)
    return nominal, data, truth, r, out


def test_joint_round_trip_on_the_written_urdf(joint_fit):
    """Pinocchio on the written URDF: the camera's measurements (every row, held out too) to
    1e-9 m, and both arms' touches flush on the fitted planes to 1e-9."""
    nominal, data, _, r, out = joint_fit
    assert r.accepted
    camera = r.chains[2]
    assert isinstance(camera, MeasuredChain) and camera.joint == "rgbd_optical_joint"
    assert camera.stats["held_out"].m == 10
    assert camera.stats["held_out_registration"].length_rms_mm > 1.0  # something to fix
    d = data[2]
    joints = {n: d.q[:, k] for k, n in enumerate(nominal[2].joint_names)}
    T = relative_placements(out, *CAMERA, joints)
    marker = camera.state.inner.markers[0]
    seen = np.array([M.rotation @ marker + M.translation for M in T])
    assert np.max(np.abs(seen - d.position)) < 1e-9
    before = relative_placements(nominal[0].urdf_path, *CAMERA, joints)
    assert (
        np.max(np.abs([a.translation - b.translation for a, b in zip(T, before, strict=True)]))
        > 1e-3
    )
    for chain, d, part in zip(nominal[:2], data[:2], r.chains[:2], strict=True):
        joints = {n: d.q[:, k] for k, n in enumerate(chain.joint_names)}
        g = plane_gaps(out, chain.base_frame, chain.tool_frame, part.contact, part.plane, joints)
        assert np.max(np.abs(g)) < 1e-9


def test_the_camera_joint_is_what_moved(joint_fit):
    """The camera's fixed joint takes the measuring frame's correction (E = frame^-1); every
    other edited joint is a joint of the chains (the camera alone is not told apart from the
    head joints' placements: its joint need not be the truth's, the camera -> hand path is)."""
    nominal, _, _, r, out = joint_fit
    urdf = pin.buildModelFromUrdf(str(out))
    start = pin.buildModelFromUrdf(str(nominal[0].urdf_path))
    fid = next(i for i, f in enumerate(urdf.frames) if f.name == "rgbd_optical_joint")
    got, was = urdf.frames[fid].placement.homogeneous, start.frames[fid].placement.homogeneous
    E = np.linalg.inv(r.chains[2].state.inner.frame)
    assert np.allclose(got, was @ E, atol=1e-12) and not np.allclose(got, was, atol=1e-5)
    moved = set(r.joint_errors())
    assert "rgbd_optical_joint" in moved
    assert moved - {"rgbd_optical_joint"} <= {n for c in nominal for n in c.joint_names}


def test_report_lists_the_term(joint_fit):
    _, _, _, r, _ = joint_fit
    doc = json.loads(json.dumps(r.to_dict()))
    assert list(doc)[: len(REPORT_KEYS)] == list(REPORT_KEYS) and doc["format_version"] == "3"
    assert [t["kind"] for t in doc["terms"]] == ["plane", "plane", "position"]
    frame = [p for p in doc["parameters"] if p["name"].startswith("term3.frame.")]
    assert len(frame) == 6 and {p["joint"] for p in frame} == {"rgbd_optical_joint"}
    markers = [p for p in doc["parameters"] if p["name"].startswith("term3.marker1.")]
    assert len(markers) == 3 and {p["joint"] for p in markers} == {None}
    held = doc["errors"]["terms"][2]["held_out"]
    assert held["calibrated"]["x_rms_mm"] < 1e-6 and held["registration"]["x_rms_mm"] > 0.1
    assert doc["frames"]["on_robot"] is True
    assert "rgbd_optical_joint" in doc["model"]["joint_origins"]


def _frame(model: pin.Model, name: str) -> int:
    ids = [i for i, f in enumerate(model.frames) if f.name == name]
    bodies = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
    return bodies[0] if bodies else ids[0]


class _Robot:
    """A Pinocchio model whose joint and frame placements, planes, contact frames and marker
    take small twists, and every term's rows at given configurations (Pinocchio alone)."""

    def __init__(self, urdf, terms):
        self.model = pin.buildModelFromUrdf(str(urdf))
        self.data = self.model.createData()
        self.terms = terms  # (base, tool, joints {name: values}, kind)
        self.extra = {}  # plane k / contact k -> pin.SE3, "marker" -> (3,)

    def rel(self, base, tool, joints):
        Q = configurations(self.model, joints)
        b, t = _frame(self.model, base), _frame(self.model, tool)
        out = []
        for q in Q:
            pin.framesForwardKinematics(self.model, self.data, q)
            out.append(self.data.oMf[b].inverse() * self.data.oMf[t])
        return out

    def rows(self) -> np.ndarray:
        out = []
        for k, (base, tool, joints, kind) in enumerate(self.terms):
            for M in self.rel(base, tool, joints):
                if kind == "position":
                    out.append(M.rotation @ self.extra["marker"] + M.translation)
                else:  # a plane touch: height, roll, pitch of the contact in the plane
                    G = self.extra[("plane", k)].inverse() * M * self.extra[("contact", k)]
                    out.append(np.r_[G.translation[2], pin.rpy.matrixToRpy(G.rotation)[:2]])
        return np.concatenate(out)

    def handles(self, joint_names, frames):
        """(get, set) of every placement perturbed: joints, frames, planes, contacts."""
        m = self.model
        out = []
        for j in dict.fromkeys(m.getJointId(n) for n in joint_names):
            out.append(
                (
                    lambda j=j: m.jointPlacements[j].copy(),
                    lambda M, j=j: m.jointPlacements.__setitem__(j, M),
                )
            )
        for f in frames:

            def put(M, f=f):
                frame = m.frames[f]
                frame.placement = M
                m.frames[f] = frame

            out.append((lambda f=f: m.frames[f].placement.copy(), put))
        for key in [k for k in self.extra if k != "marker"]:
            out.append(
                (
                    lambda key=key: self.extra[key].copy(),
                    lambda M, key=key: self.extra.__setitem__(key, M),
                )
            )
        return out

    def rank(self, joint_names, frames, eps=1e-6, tol=1e-7) -> int:
        """Rank of the central differences of every row under a twist of every placement
        (6 each) and a shift of the marker (3), singular values above ``tol`` of the largest."""
        cols = []
        for get, put in self.handles(joint_names, frames):
            nominal = get()
            for i in range(6):
                steps = []
                for sign in (1.0, -1.0):
                    put(nominal * pin.exp6(pin.Motion(sign * eps * np.eye(6)[i])))
                    steps.append(self.rows())
                put(nominal)
                cols.append((steps[0] - steps[1]) / (2 * eps))
        if "marker" in self.extra:
            marker = self.extra["marker"].copy()
            for i in range(3):
                steps = []
                for sign in (1.0, -1.0):
                    self.extra["marker"] = marker + sign * eps * np.eye(3)[i]
                    steps.append(self.rows())
                self.extra["marker"] = marker
                cols.append((steps[0] - steps[1]) / (2 * eps))
        s = np.linalg.svd(np.array(cols).T, compute_uv=False)
        return int(np.sum(s > tol * s[0]))


def _joints(chain, q):
    return {n: q[:, k] for k, n in enumerate(chain.joint_names)}


def test_tiago_head_to_hand_count_equals_a_pinocchio_rank():
    """TIAGo's camera measuring a point on the hand, alone through the joint engine: the
    unknowns it determines (camera 6, marker 3, joint placement directions) are the rank of
    Pinocchio's finite differences (singular values above 1e-7 of the largest: the same from
    1e-5 to 1e-9)."""
    chain = load_chain("tiago", "xtion_optical_frame", "arm_tool_link")
    data = simulate(chain, 40, "position", marker=MARKER, seed=5).measurements
    r = calibrate_contact_chains([chain], [data], params="complete")
    robot = _Robot(
        chain.urdf_path,
        [("xtion_optical_frame", "arm_tool_link", _joints(chain, data.q), "position")],
    )
    robot.extra["marker"] = np.array(MARKER)
    camera = _frame(robot.model, "xtion_optical_frame")
    assert r.unknowns == r.identifiable == robot.rank(chain.joint_names, [camera])
    assert r.unknowns == 4 * chain.n + 3  # Everett: 4R + 2P + 3 (the marker off the last axis)


def test_talos_head_and_contacts_count_equals_a_pinocchio_rank():
    """TALOS's camera on the left hand and both arms' table touches (flush on the nominal
    robot), one problem: its determined unknowns (planes, contact tilts, camera, marker, joint
    placement directions) are the rank of Pinocchio's finite differences of every term's rows."""
    nominal = _talos()
    zero = {"error_mm": 0.0, "error_mrad": 0.0}
    data = [simulate_contacts(c, 24, "plane", seed=1, **zero).data for c in nominal[:2]]
    data.append(simulate(nominal[2], 24, "position", marker=MARKER, seed=2, **zero).measurements)
    r = calibrate_contact_chains(nominal, data, params="complete")
    terms = [
        (c.base_frame, c.tool_frame, _joints(c, d.q), "plane" if k < 2 else "position")
        for k, (c, d) in enumerate(zip(nominal, data, strict=True))
    ]
    robot = _Robot(nominal[0].urdf_path, terms)
    for k in range(2):
        first = {n: v[:1] for n, v in terms[k][2].items()}
        robot.extra[("plane", k)] = robot.rel(*terms[k][:2], first)[0]  # touches flush on it
        robot.extra[("contact", k)] = pin.SE3.Identity()
    robot.extra["marker"] = np.array(MARKER)
    assert np.max(np.abs(robot.rows()[: 3 * 48])) < 1e-9  # flush: the planes are right
    names = [n for c in nominal for n in c.joint_names]
    assert r.identifiable == robot.rank(names, [_frame(robot.model, CAMERA[0])])
    # the complete level's offer (each chain's MDH rows, then the components where the
    # chains meet) holds every combination of the shared joints the data determine
    assert r.unknowns == r.identifiable


@pytest.fixture(scope="module")
def talos_data():
    """Noise-free touches of both arms and the camera's points, on the nominal TALOS."""
    nominal = _talos()
    zero = {"error_mm": 0.0, "error_mrad": 0.0}
    data = [simulate_contacts(c, 24, "plane", seed=1, **zero).data for c in nominal[:2]]
    data.append(simulate(nominal[2], 24, "position", marker=MARKER, seed=2, **zero).measurements)
    return nominal, data


def _one_line_error(error, match, *args, **kwargs):
    with pytest.raises(error, match=match) as info:
        calibrate_contact_chains(*args, **kwargs)
    assert isinstance(info.value, CalibError) and "\n" not in str(info.value)


def test_a_measured_term_must_measure_from_the_robot(talos_data):
    """An instrument frame that is not fixed to a link (the root link) beside contacts."""
    nominal, data = talos_data
    off = load_robot(URDF, "base_link", CAMERA[1])
    rows = simulate(off, 12, "position", seed=1).measurements
    what = "base frame 'base_link' is the robot's root link, not fixed to a link"
    _one_line_error(InvalidArgumentError, what, [*nominal[:2], off], [*data[:2], rows])
    moved = load_robot(URDF, "head_2_link", CAMERA[1])  # the camera's link, a joint moves it
    rows = simulate(moved, 12, "position", seed=1).measurements
    what = "base frame 'head_2_link' is the link of the moving joint head_2_joint, not fixed"
    _one_line_error(InvalidArgumentError, what, [*nominal[:2], moved], [*data[:2], rows])
    joint = load_robot(URDF, "head_2_joint", CAMERA[1])  # the moving joint's own frame
    rows = simulate(joint, 12, "position", seed=1).measurements
    what = "base frame 'head_2_joint' is the frame of the moving joint head_2_joint, not fixed"
    _one_line_error(InvalidArgumentError, what, [*nominal[:2], joint], [*data[:2], rows])


def test_rows_of_the_wrong_kind_are_refused(talos_data):
    nominal, data = talos_data
    camera = nominal[2]
    pose = simulate(camera, 12, "pose", seed=3).measurements
    touches = simulate_contacts(nominal[0], 12, "plane", seed=3).data
    other = simulate(nominal[0], 12, "position", seed=3).measurements  # the sole's joints
    cases = [
        ({"validate": [None, None, pose]}, data, InvalidArgumentError, "another kind"),
        ({"validate": [None, None, touches]}, data, InvalidArgumentError, "must be Measurements"),
        ({}, [*data[:2], other], DataError, "joints are not those"),
        ({"validate": [pose, None, None]}, data, InvalidArgumentError, "validation rows must"),
        ({}, [data[0], data[1], "rows.csv"], InvalidArgumentError, "data must be touches"),
    ]
    for kwargs, rows, error, match in cases:
        _one_line_error(error, match, nominal, rows, **kwargs)


def test_a_term_worse_than_its_registration_is_refused(tmp_path):
    """The camera's validation rows taken on the nominal robot (the fit learnt another one,
    moved by ~3 mm / 3 mrad): its held-out errors grow, the model is refused, and no URDF is
    written, though both arms' touches fit."""
    nominal = _talos()
    truth = true_robot(
        nominal, tmp_path / "t.urdf", measuring=nominal[2:], seed=3, error_mm=3.0, error_mrad=3.0
    )
    true = _talos(str(truth.urdf))
    zero = {"error_mm": 0.0, "error_mrad": 0.0}
    data = [simulate_contacts(c, 30, "plane", seed=1, **zero).data for c in true[:2]]
    data.append(simulate(true[2], 30, "position", marker=MARKER, seed=2, **zero).measurements)
    held = simulate(nominal[2], 30, "position", marker=MARKER, seed=9, **zero).measurements
    r = calibrate_contact_chains(nominal, data, params="complete", validate=[None, None, held])
    stats = r.chains[2].stats
    assert stats["held_out"].weighted_mm > stats["held_out_registration"].weighted_mm
    assert not r.accepted and "rgbd_optical_frame -> gripper_left_base_link" in r.refusal
    with pytest.raises(CalibrationRefusedError):
        r.write_urdf(tmp_path / "cal.urdf")
    assert not (tmp_path / "cal.urdf").exists()


def _camera_rows(urdf, chain, q, markers, pose: bool) -> Measurements:
    """What the camera of a URDF sees (Pinocchio alone): markers ``(K, 3)`` on the hand and,
    for pose data, the hand frame's orientation."""
    T = relative_placements(urdf, chain.base_frame, chain.tool_frame, _joints(chain, q))
    points = np.array([[M.rotation @ mk + M.translation for mk in markers] for M in T])
    quat = matrix_to_quaternion(np.array([M.rotation for M in T])) if pose else None
    return Measurements(chain.joint_names, q, points, quat)


@pytest.mark.parametrize("pose", [False, True])
def test_two_markers_or_a_pose_round_trip(pose, tmp_path):
    """TIAGo's camera sees two markers on the hand (or the hand's pose) on a true robot
    (joints and camera moved): the written URDF reproduces every row to 1e-9 (Pinocchio), the
    markers (or the measured frame) in the hand frame as fitted."""
    chain = load_chain("tiago", "xtion_optical_frame", "arm_tool_link")
    truth = true_robot([chain], tmp_path / "t.urdf", measuring=[chain], seed=4)
    markers = np.array([[0.03, -0.02, 0.05], [-0.01, 0.04, 0.02]])[: 1 if pose else 2]
    q = chain.random_configurations(50, 6)
    data = _camera_rows(truth.urdf, chain, q, markers, pose)
    r = calibrate_contact_chains([chain], [data], params="complete", holdout=0.2, seed=1)
    assert r.accepted and r.chains[0].stats["held_out_registration"].length_rms_mm > 0.5
    r.write_urdf(tmp_path / "cal.urdf")
    s = r.chains[0].state.inner
    seen = _camera_rows(tmp_path / "cal.urdf", chain, q, s.markers, pose)
    assert np.max(np.abs(seen.points - data.points)) < 1e-9
    if pose:  # the measured frame's rotation in the written hand frame
        T = relative_placements(tmp_path / "cal.urdf", *CAMERA_TIAGO, _joints(chain, q))
        R = np.array([M.rotation @ s.tool_rotation for M in T])
        want = np.array([pin.Quaternion(*c[[3, 0, 1, 2]]).matrix() for c in data.quaternion])
        assert np.max(np.abs(R - want)) < 1e-9


def test_the_chain_pipeline_moves_the_camera_joint_on_robot(tmp_path):
    """One chain (``calibrate(..., on_robot)``): the written URDF edits the camera's fixed
    joint, the chain's joints and the tool's fixed joint, nothing else (and adds the marker's
    link)."""
    import xml.etree.ElementTree as ET

    from calib import calibrate
    from calib.kinematics.urdf_export import origin_of

    chain = load_chain("tiago", *CAMERA_TIAGO)
    data = simulate(chain, 60, "position", params="complete", seed=4).measurements
    res = calibrate(chain, data, params="complete")
    raw = res.urdf(on_robot=True)
    before = {j.get("name"): j for j in ET.parse(chain.urdf_path).getroot().findall("joint")}
    after = {j.get("name"): j for j in ET.fromstring(raw).findall("joint")}
    assert set(after) - set(before) == {f"{CAMERA_TIAGO[1]}_marker1_joint"}  # the marker
    changed = {n for n in before if not np.array_equal(origin_of(before[n]), origin_of(after[n]))}
    assert "xtion_optical_joint" in changed
    tool = next(n for n, j in after.items() if j.find("child").get("link") == CAMERA_TIAGO[1])
    assert changed <= {*chain.joint_names, "xtion_optical_joint", tool}


def test_a_measured_term_gets_a_chains_checks(talos_data):
    """The camera's rows are checked as one chain's: a gross outlier (50 mm on row 8) is set
    aside and named in the report with its term, a held-out one too; joints in degrees, two
    joint columns swapped, validation rows that are the data, too few rows: one-line
    DataErrors naming the mistake."""
    nominal, data = talos_data
    cam = simulate(nominal[2], 30, "position", marker=MARKER, seed=2).measurements
    pos = cam.position.copy()
    pos[7, 0] += 0.05
    bad = Measurements(cam.joint_names, cam.q, pos, None, "cam.csv")
    r = calibrate_contact_chains(nominal, [*data[:2], bad], params="complete")
    assert [o.row for o in r.chains[2].outliers] == [8]
    assert [(o["term"], o["row"]) for o in r.to_dict()["outliers"]] == [(2, 8)]
    held = simulate(nominal[2], 20, "position", marker=MARKER, seed=7).measurements
    pos = held.position.copy()
    pos[3, 1] -= 0.05
    held = Measurements(held.joint_names, held.q, pos, None, "held.csv")
    r = calibrate_contact_chains(nominal, [*data[:2], bad], validate=[None, None, held])
    assert r.chains[2].stats["held_out"].m == 19  # its outlier set aside, as a chain's
    assert any("held" in n and "row 4" in n for n in r.notes), r.notes
    q = cam.q.copy()
    q[:, [4, 6]] = q[:, [6, 4]]  # within the limits (+- 2.43 and 2.51 rad): the diagnosis
    far = "outside the joint limits .* degrees for radians"  # the limits first, as calibrate's
    cases = [(np.degrees(cam.q), far), (q, "arm_left_3_joint and arm_left_5_joint")]
    for joints, what in cases:
        wrong = Measurements(cam.joint_names, joints, cam.position, None, "wrong.csv")
        _one_line_error(DataError, what, nominal, [*data[:2], wrong])
    # validation rows that are the data; too few rows for the camera's 9 unknowns
    _one_line_error(
        DataError,
        "held out must mean held out",
        nominal,
        [*data[:2], cam],
        validate=[None, None, cam],
    )
    few = cam.subset(np.arange(3))
    _one_line_error(DataError, "equations", nominal, [*data[:2], few])


def test_summary_names_the_measured_term(joint_fit):
    text = joint_fit[3].summary()
    assert "2 planes, 1 measured term" in text.splitlines()[0]
    assert "rgbd_optical_frame -> gripper_left_base_link, measured position" in text
    assert "the measuring frame in joint 'rgbd_optical_joint'" in text


def test_the_one_entry_takes_a_measured_term(joint_fit):
    """``calib.calibrate(Problem(...))``: the head camera's term beside both arms' touches
    gives the joint fit's result (the same function underneath)."""
    from calib import Problem, Term, calibrate

    nominal, data, _, direct, _ = joint_fit
    terms = tuple(Term(c, d) for c, d in zip(nominal, data, strict=True))
    r = calibrate(Problem(terms, params="complete", holdout=0.25, seed=0))
    assert r.accepted and isinstance(r.chains[2], MeasuredChain)
    assert r.chains[2].stats["held_out"].length_rms_mm < 1e-6
    assert np.array_equal(r.estimate, direct.estimate)


def test_the_command_line_takes_the_measured_term(joint_fit, tmp_path, capsys):
    """``--term plane ... --term position CAMERA HAND head.csv``: one problem of three terms;
    Pinocchio sees the camera's rows on the written URDF (the report's marker) to 1e-9."""
    from calib import write_measurements
    from calib.cli.commands import main
    from calib.measurements.contact_campaign import write_contacts

    nominal, data, _, _, _ = joint_fit
    files = [tmp_path / name for name in ("left.csv", "right.csv", "head.csv")]
    write_contacts(files[0], data[0])
    write_contacts(files[1], data[1])
    write_measurements(files[2], data[2])
    argv = ["calibrate", URDF, "--params", "complete", "--holdout", "0.25"]
    for kind, chain, path in zip(("plane", "plane", "position"), nominal, files, strict=True):
        argv += ["--term", kind, chain.base_frame, chain.tool_frame, str(path)]
    cli = tmp_path / "cli.urdf"
    code = main([*argv, "--out", str(cli), "--report", str(tmp_path / "r.json")])
    assert code == 0, capsys.readouterr().err
    report = json.loads((tmp_path / "r.json").read_text())
    assert [t["kind"] for t in report["terms"]] == ["plane", "plane", "position"]
    d = data[2]
    joints = {n: d.q[:, k] for k, n in enumerate(nominal[2].joint_names)}
    T = relative_placements(cli, *CAMERA, joints)
    marker = np.array(report["frames"]["markers"][CAMERA[1]][0])  # [m], in the hand's frame
    seen = np.array([M.rotation @ marker + M.translation for M in T])
    assert np.max(np.abs(seen - d.position)) < 1e-9  # every row, held out too [m]
    names = [p["name"] for p in report["parameters"] if p["name"].startswith("term3.")]
    assert names[:6] == [f"term3.frame.{c}" for c in ("rx", "ry", "rz", "x", "y", "z")]


def test_each_term_of_one_tool_is_read_as_what_it_is(joint_fit, tmp_path, capsys):
    """The head camera's measured term and the left arm's touching term share the tool
    ``gripper_left_base_link``: ``tool=`` alone is refused in one line naming how to choose
    (``term=``, ``--term``); ``term=2`` reads the measured term (it was read as touching when
    ``frames.contacts`` had its tool), whose points are the camera's rows on the written URDF
    (noise-free, 1e-9 m); ``term=1`` the right arm's touches; a term of another tool is
    refused."""
    from calib import load_calibrated, write_measurements
    from calib.cli.commands import main

    nominal, data, _, r, _ = joint_fit
    out, report = tmp_path / "cal.urdf", tmp_path / "cal.json"
    r.write(out, report)
    tool = CAMERA[1]
    assert nominal[0].tool_frame == tool
    with pytest.raises(DataError, match=r"terms 0, 2 have the tool .*\(term=\)") as info:
        load_calibrated(out, report, tool)
    assert "\n" not in str(info.value)
    d = data[2]
    for model in (load_calibrated(out, report, term=2), load_calibrated(out, report, tool, 2)):
        assert model.contact is None and model.chain.base_frame == CAMERA[0]
        assert np.max(np.abs(model.points(d.q)[:, 0] - d.position[:, :3])) < 1e-9
    touching = load_calibrated(out, report, term=1)
    assert touching.contact is not None and touching.chain.tool_frame == PAIRS[1][1]
    with pytest.raises(DataError, match=f"term 1's tool is {PAIRS[1][1]}, not {tool}"):
        load_calibrated(out, report, tool, 1)
    with pytest.raises(DataError, match="no term 3: its terms are 0 to 2"):
        load_calibrated(out, report, term=3)
    configs, pred = tmp_path / "q.csv", tmp_path / "p.csv"
    write_measurements(configs, d)
    args = ["predict", str(out), "--compliance", str(report), "--configs", str(configs)]
    assert main([*args, "--tool", tool, "--term-index", "2", "--out", str(pred)]) == 0
    header = pred.read_text().splitlines()[0].split(",")
    rows = np.loadtxt(pred, delimiter=",", skiprows=1)
    xyz = rows[:, [header.index(c) for c in ("x1", "y1", "z1")]]
    assert np.max(np.abs(xyz - d.position[:, :3])) < 1e-9
    assert main([*args, "--tool", tool, "--out", str(pred)]) == 2
    assert "choose one by its index (--term-index)" in capsys.readouterr().err


def test_two_terms_own_planes_of_one_id_are_both_reported_and_read(joint_fit, tmp_path):
    """Both arms touch a plane each (not shared), both named alike by their touches: the
    report's ``objects`` kept one (the last term's overwrote the first's), so
    ``load_calibrated(term=0)`` read the right arm's plane, or was refused when the bases
    differ ("not in its base's frame"). Each is now ``<id>@<tool>``, listed in its term."""
    from calib import load_calibrated

    _, _, _, r, _ = joint_fit
    out, report = tmp_path / "cal.urdf", tmp_path / "cal.json"
    r.write(out, report)
    doc = json.loads(report.read_text())
    ids = [next(iter(c.objects())) for c in r.chains[:2]]
    assert ids[0] == ids[1]  # one id, two planes
    names = [f"{ids[0]}@{tool}" for _, tool in PAIRS]
    assert sorted(doc["objects"]["planes"]) == sorted(names)
    for k, part in enumerate(r.chains[:2]):
        assert doc["terms"][k]["objects"] == [names[k]]
        model = load_calibrated(out, report, term=k)
        assert model.chain.base_frame == PAIRS[k][0]
        assert np.max(np.abs(model.plane - part.objects()[ids[0]])) < 1e-12


def test_auto_on_both_arms_and_the_camera_is_accepted(tmp_path):
    """``auto`` on the self-measure campaign (benchmarks/self_measure.py): both arms' MDH rows
    name the torso's shared joint alike (``torso_1_joint:d7``, two directions, one per chain:
    each named with its chain's tool, ``torso_1_joint:d7@gripper_left_base_link``);
    the selection keeps both, and the fit frees both (not the first twice, a rank-deficient
    Jacobian the engine refused, the user getting the registration). Accepted, every term's
    held-out error below its registration's."""
    nominal = _talos()
    truth = true_robot(nominal, tmp_path / "true.urdf", measuring=nominal[2:], seed=3)
    true = _talos(str(truth.urdf))
    zero = {"error_mm": 0.0, "error_mrad": 0.0}
    data = [
        simulate_contacts(c, 40, "plane", seed=1 + k, noise_mrad=0.2, **zero).data
        for k, c in enumerate(true[:2])
    ]
    camera = simulate(true[2], 40, "position", marker=MARKER, seed=2, noise_mm=0.5, **zero)
    data.append(camera.measurements)
    r = calibrate_contact_chains(nominal, data, params="auto", holdout=0.25, seed=0)
    free = r.solution.fit.model.free
    assert len(set(free)) == len(free) and len(set(r.free)) == len(r.free)  # a name each
    shared = {f"torso_1_joint:d7@gripper_{side}_base_link" for side in ("left", "right")}
    assert shared <= set(r.free) and "torso_1_joint:d7" not in r.free
    entries = {p["name"]: p for p in r.to_dict()["parameters"]}
    assert all(entries[n]["joint"] == "torso_1_joint" and entries[n]["unit"] == "m" for n in shared)
    assert r.accepted, r.refusal
    for part in r.chains:
        held, reg = part.stats["held_out"].rms, part.stats["held_out_registration"].rms
        assert held[0] < 0.5 * reg[0] and held[1] < reg[1]


def test_two_measured_terms_keep_their_own_frames_and_markers_in_the_report():
    """The report merges the measured terms' parameters by name (a tree's tools share the
    instrument's frame): two terms measured from two frames of the head name theirs apart
    (``term1.frame.x``, ``term2.frame.x``), so none is lost."""
    from calib import Problem, Term, calibrate

    a = load_robot(URDF, "rgbd_optical_frame", "gripper_left_base_link")
    b = load_robot(URDF, "rgbd_link", "gripper_right_base_link")
    terms = tuple(
        Term(c, simulate(c, 40, "position", marker=MARKER, seed=k).measurements)
        for k, c in ((1, a), (2, b))
    )
    result = calibrate(Problem(terms, params="frames"))
    names = [p["name"] for p in result.to_dict()["parameters"]]
    assert len(names) == len(set(names)) == 2 * (6 + 3)
    assert {"term1.frame.x", "term2.frame.x", "term1.marker1.z", "term2.marker1.z"} <= set(names)


def test_a_fit_that_keeps_no_joint_placement_says_where_the_camera_goes(talos_data):
    """Noise-free touches and camera points of the nominal TALOS: nothing to fit, so the note
    says what the URDF gets: the camera's frame in its fixed joint (rgbd_optical_joint, the
    URDF's), not with world_link (an instrument's, which a term on the robot does not take)."""
    nominal, data = talos_data
    result = calibrate_contact_chains(nominal, data)
    (note,) = [n for n in result.notes if n.startswith("no joint placement was fitted")]
    joints = ET.parse(nominal[2].urdf_path).getroot().iter("joint")
    joint = [j for j in joints if j.find(f"child[@link='{CAMERA[0]}']") is not None]
    assert [j.get("type") for j in joint] == ["fixed"]
    assert f"the measurement frame in its fixed joint {joint[0].get('name')})" in note
    assert "world_link" not in note
