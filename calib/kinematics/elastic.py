"""The calibrated URDF plus joint compliance: a model a user applies outside calib.

A URDF holds geometry only. When a calibration fits joint compliance (``--elastic``), the
whole model is the calibrated URDF whose joints see

    q' = q + c * tau(q)

``c`` the compliance of each chain joint [rad/(N m) or m/N] and ``tau(q)`` the gravity torque
it carries [N m or N], as in the fit: the URDF's masses on the nominal joint placements (the
file records them: ``nominal_origins``), the other joints at their neutral position,
gravity as recorded (a vector in the base frame). calib writes ``c`` and the gravity next to
the URDF (:func:`compliance_document`, ``<out>.compliance.json``); :func:`load_calibrated`
reads the URDF with that file (or the report) back as an :class:`ElasticModel`, which
predicts measured points and gives the deflected or the compensating joint positions.

A calibration from contacts of a robot standing on its base frame (a sole) records its load
too (``load``: ``{"kind": "standing", "support": {...}}``, :mod:`.standing`): the torques are
then those of the robot standing on the base frame, gravity along ``-z`` of it; and its
contact frame and plane (``contact``: ``{"frame", "plane"}``), which
:meth:`ElasticModel.contact_placements` uses.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..core.fileio import read_bytes_limited, read_failure, read_text_limited
from ..core.words import counted
from ..exceptions import (
    AmbiguousFrameError,
    CalibError,
    DataError,
    FrameNotFoundError,
    InvalidArgumentError,
    URDFError,
    warn_user,
)
from .frames import frame_placement, joint_placements, resolve_frame
from .limits import refuse_far_past_limits
from .mdh import MDHModel, from_chain
from .report_view import check_pairing, compliance_fields
from .robot import Chain, load_chain, pin_configurations, robot_source
from .standing import JointReadings, StandingLoad, Support, standing_load
from .urdf_model import build_model, read_urdf_file
from .urdf_xml import MAX_URDF_BYTES, URDFInfo, kinematic_xml

__all__ = [
    "COMMAND_ITERATIONS",
    "COMMAND_STEP",
    "COMPLIANCE_FORMAT",
    "MAX_JSON_BYTES",
    "ElasticModel",
    "compliance_document",
    "gravity_in_base",
    "load_calibrated",
    "nominal_masses",
    "nominal_origins",
    "predictions_csv",
]

COMPLIANCE_FORMAT = "1"
"""Version of the compliance file's layout (its ``format_version``)."""

MAX_JSON_BYTES = 64 << 20
"""Largest report or compliance file read [B]."""

COMMAND_ITERATIONS = 50
"""Most Newton steps :meth:`ElasticModel.command` takes."""

COMMAND_STEP = 1e-6
"""Step of the central differences of the torques in :meth:`ElasticModel.command` [rad or m]."""


def gravity_in_base(chain: Chain) -> np.ndarray:
    """Gravity ``(3,)`` [m/s^2] in the chain's base frame (Pinocchio's, -z of the URDF root).

    The base frame is placed with every joint at its reference position (``q_ref``).
    """
    model = chain.model
    q0 = chain.pin_configurations(np.zeros((1, chain.n)))[0]
    oMb = frame_placement(model, joint_placements(model, q0), chain.base_id)
    return np.array(oMb.rotation.T @ model.gravity.linear)


@dataclass(frozen=True, eq=False)
class ElasticModel:
    """A calibrated URDF with joint compliance under gravity, in the measurement frame.

    Attributes:
        chain: The calibrated URDF's chain (base and tool frames of the calibration).
        measurement_to_base: Pose of the base frame in the measurement frame ``(4, 4)``.
        markers: Measured points in the URDF's tool frame ``(K, 3)`` [m].
        compliance: Compliance of each chain joint ``(n,)`` [rad/(N m) or m/N].
        gravity: Gravity in the base frame ``(3,)`` [m/s^2].
        mdh: The URDF's geometry as an MDH model (base to tool; vectorised kinematics).
        torque_model: The gravity model (the URDF's masses on the nominal placements).
        load: The standing load (contacts of a standing robot), or None: the chain hangs
            from its base frame.
        contact: The contact frame in the tool frame ``(4, 4)`` (contacts), or None.
        plane: The contact plane in the base frame ``(4, 4)``, z its normal, or None.
        readings: The joints off the chain the standing load took at their recorded positions
            in the fit: pass their readings (:class:`~calib.kinematics.standing.JointReadings`)
            to reproduce it.
    """

    chain: Chain
    measurement_to_base: np.ndarray
    markers: np.ndarray
    compliance: np.ndarray
    gravity: np.ndarray
    mdh: MDHModel
    torque_model: pin.Model
    load: StandingLoad | None = None
    contact: np.ndarray | None = None
    plane: np.ndarray | None = None
    readings: tuple[str, ...] = ()

    def __repr__(self) -> str:
        """One line: ``<ElasticModel ur5: base_link -> tool0, 6 joints, 2 compliant, ...>``."""
        chain = self.chain
        extra = ", standing" if self.load is not None else ""
        extra += ", contact" if self.contact is not None else ""
        return (
            f"<ElasticModel {chain.name}: {chain.base_frame} -> {chain.tool_frame}, "
            f"{chain.n} joints, {int(np.count_nonzero(self.compliance))} compliant, "
            f"{counted(len(self.markers), 'markers')}{extra}>"
        )

    def torques(self, q: np.ndarray, readings: JointReadings | None = None) -> np.ndarray:
        """Gravity torque of each chain joint ``(m, n)`` [N m or N] at configurations ``(m, n)``.

        As in the fit: the URDF's masses on the nominal joint placements (``torque_model``,
        whose gravity is set from ``gravity``), the other joints at their neutral position or,
        standing on the base frame (``load``), at ``readings`` where given (a warning when the
        fit had readings and none are given).

        Raises:
            InvalidArgumentError: ``readings`` for a hanging chain (no standing load).
        """
        self._check_readings(readings)
        return self._torques(self._configurations(q), readings)

    def _configurations(self, q: np.ndarray) -> np.ndarray:
        """Commanded ``q`` ``(m, n)``, refused far past a limit as a configurations file is."""
        q = self.chain.check_configurations(q)
        refuse_far_past_limits(self.chain, q, "the configurations", np.arange(1, len(q) + 1))
        return q

    def _check_readings(self, readings: JointReadings | None) -> None:
        if self.load is None and readings is not None:
            raise InvalidArgumentError("joint readings load a standing robot (contacts) only")
        if self.load is not None and self.readings and readings is None:
            warn_user(
                f"the fit took {len(self.readings)} joints off the chain at their recorded "
                f"positions ({', '.join(self.readings[:3])}, ...); without readings they are "
                f"at their neutral positions",
                UserWarning,
            )

    def _torques(self, q: np.ndarray, readings: JointReadings | None) -> np.ndarray:
        if self.load is not None:
            return self.load.torques(q, readings)
        model = self.torque_model
        ids = tuple(model.getJointId(name) for name in self.chain.joint_names)
        q = self.chain.check_configurations(q)
        data = model.createData()
        idx = [model.joints[j].idx_v for j in ids]
        qp = pin_configurations(model, pin.neutral(model), ids, q)
        tau = [pin.computeGeneralizedGravity(model, data, row)[idx] for row in qp]
        return np.array(tau).reshape(-1, self.chain.n)

    def deflected(self, q: np.ndarray, readings: JointReadings | None = None) -> np.ndarray:
        """Joint positions the geometry sees at commanded ``q`` ``(m, n)``: ``q + c tau(q)``.

        ``readings``: the joints off the chain, as :meth:`torques` takes them.
        """
        self._check_readings(readings)
        q = self._configurations(q)
        return q + self.compliance * self._torques(q, readings)

    def command(
        self, target: np.ndarray, tol: float = 1e-12, readings: JointReadings | None = None
    ) -> np.ndarray:
        """The commanded positions whose deflected positions are ``target`` ``(m, n)``.

        Newton's method on ``q + c tau(q) = target`` from ``q = target``, ``d tau / dq`` by
        central differences, stopped at ``tol`` [rad or m]; ``readings`` as :meth:`torques`
        takes them.

        Raises:
            InvalidArgumentError: It does not settle in ``COMMAND_ITERATIONS`` iterations.
        """
        self._check_readings(readings)
        target = self._configurations(target)
        q = target.copy()
        for _ in range(COMMAND_ITERATIONS):
            r = q + self.compliance * self._torques(q, readings) - target
            if np.max(np.abs(r), initial=0.0) <= tol:
                return q
            try:
                step = np.linalg.solve(self._deflection_jacobian(q, readings), r[..., None])
            except np.linalg.LinAlgError:
                break  # a deflection that no commanded position undoes locally
            q = q - step[..., 0]
        raise InvalidArgumentError("the compensating joint positions do not settle")

    def _deflection_jacobian(self, q: np.ndarray, readings) -> np.ndarray:
        """``d(q + c tau(q))/dq`` ``(m, n, n)`` by central differences of the torques."""
        n, h = self.chain.n, COMMAND_STEP
        J = np.repeat(np.eye(n)[None], len(q), axis=0)
        for j in range(n):
            step = h * np.eye(n)[j]
            dtau = self._torques(q + step, readings) - self._torques(q - step, readings)
            J[:, :, j] += self.compliance * dtau / (2 * h)
        return J

    def tool_placements(self, q: np.ndarray, readings: JointReadings | None = None) -> np.ndarray:
        """Tool frame in the measurement frame ``(m, 4, 4)`` at commanded ``q`` ``(m, n)``.

        ``readings``: the joints off the chain, as :meth:`torques` takes them.
        """
        return self.measurement_to_base @ self._tool_in_base(self.deflected(q, readings))

    def _tool_in_base(self, deflected: np.ndarray) -> np.ndarray:
        """Tool frame in the base frame ``(m, 4, 4)`` at the joints the geometry sees."""
        kin = self.mdh.kinematics(deflected)
        T = np.zeros((len(kin.p), 4, 4))
        T[:, :3, :3], T[:, :3, 3], T[:, 3, 3] = kin.R[:, -1], kin.p[:, -1], 1.0
        return T

    def contact_placements(
        self, q: np.ndarray, readings: JointReadings | None = None
    ) -> np.ndarray:
        """The contact frame in the plane's frame ``(m, 4, 4)`` at commanded ``q`` ``(m, n)``.

        Flush: its height ``[:, 2, 3]`` [m] and its z axis's tilt from the normal are zero.
        ``readings``: the joints off the chain, as :meth:`torques` takes them.

        Raises:
            InvalidArgumentError: The model holds no contact (not from a contact calibration).
        """
        if self.contact is None or self.plane is None:
            raise InvalidArgumentError("this calibrated model holds no contact frame and plane")
        T = self._tool_in_base(self.deflected(q, readings))
        return np.linalg.inv(self.plane) @ T @ self.contact

    def points(self, q: np.ndarray, readings: JointReadings | None = None) -> np.ndarray:
        """Measured points predicted at commanded ``q`` ``(m, K, 3)`` [m, measurement frame].

        ``readings``: the joints off the chain, as :meth:`torques` takes them.
        """
        return self._points(self.tool_placements(q, readings))

    def _points(self, T: np.ndarray) -> np.ndarray:
        """The markers ``(m, K, 3)`` [m] on tool frames ``T`` ``(m, 4, 4)`` (measurement frame)."""
        return T[:, None, :3, 3] + np.einsum("mij,kj->mki", T[:, :3, :3], self.markers)


def compliance_document(
    chain: Chain,
    compliance: np.ndarray,
    urdf: str,
    *,
    tool_frame: str,
    measured: tuple[np.ndarray, np.ndarray, tuple[str, ...]],
    touching: tuple[dict | None, dict] | None = None,
) -> dict:
    """The compliance file of a calibration with fitted compliance (JSON-ready).

    Args:
        chain: The nominal chain (its URDF, base frame and joints).
        compliance: The fitted compliance of each joint ``(n,)`` [rad/(N m) or m/N].
        urdf: The calibrated URDF it goes with (as written).
        tool_frame: The written URDF's tool frame.
        measured: The base frame's pose in the measurement frame ``(4, 4)``, the measured
            points in the tool frame ``(K, 3)`` [m] and their links in the URDF.
        touching: A chain touching a plane, standing on its base frame (gravity along -z of
            it): its load record and its contact (``{"plane_id", "frame", "plane"}``);
            None: a chain measured (the URDF's gravity).
    """
    nominal = read_urdf_file(chain.urdf_resolved)
    frame, markers, links = measured
    if touching is None:
        gravity, torques = gravity_in_base(chain), " (other joints at their neutral position)"
    else:
        gravity = np.array([0.0, 0.0, -np.linalg.norm(chain.model.gravity.linear)])
        torques = (
            ", the robot standing on the base frame (gravity along its -z; load), the joints "
            "off the chain at their recorded positions (load.readings; the others at their "
            "neutral position)"
        )
    document = {
        "format_version": COMPLIANCE_FORMAT,
        "model": "q' = q + c * tau(q): the URDF's joints see q' at commanded q; tau = gravity "
        f"torques of the URDF's masses{torques}",
        "robot": chain.name,
        "urdf": urdf,
        "base_frame": chain.base_frame,
        "tool_frame": tool_frame,
        "joints": list(chain.joint_names),
        "compliance": compliance.tolist(),
        "units": ["rad/(N m)" if s == 0 else "m/N" for s in chain.sigma],
        "gravity": {"frame": chain.base_frame, "vector": gravity.tolist()},
    }
    if touching is not None:
        document |= {"load": touching[0], "contact": touching[1]}
    return document | {
        "measurement_to_base": np.asarray(frame).tolist(),
        "markers": np.asarray(markers).tolist(),
        "marker_links": list(links),
        "nominal_origins": nominal_origins(nominal),
        "nominal_masses": nominal_masses(nominal),
    }


def nominal_origins(info: URDFInfo) -> dict[str, dict[str, list[float]]]:
    """Every joint's ``<origin>`` in a URDF: name -> ``{xyz [m], rpy [rad]}``."""
    return {j.name: {"xyz": list(j.xyz), "rpy": list(j.rpy)} for j in info.joints}


def nominal_masses(info: URDFInfo) -> dict[str, dict]:
    """Every link's mass and centre of mass in a URDF: name -> ``{mass [kg], com [m]}``.

    The calibrated URDF may move a link's frame (a segment traversed backwards is written
    inverted) and its ``<inertial>`` with it; the gravity model restores the nominal ones.
    """
    return {name: {"mass": mass, "com": list(com)} for name, mass, com in info.masses}


def torque_model(
    urdf: str | Path, origins: dict, base: str, gravity: np.ndarray, masses: dict | None = None
) -> pin.Model:
    """The gravity model of a fit: the URDF's masses on the nominal placements.

    Args:
        urdf: The calibrated URDF.
        origins: Nominal joint origins (:func:`nominal_origins`); joints it does not name
            (the added marker and world links) keep theirs.
        base: The base frame (``gravity`` is given in it).
        gravity: Gravity in the base frame ``(3,)`` [m/s^2].
        masses: Nominal link masses (:func:`nominal_masses`), or None: the calibrated URDF's.
    """
    info = read_urdf_file(urdf)
    if masses is not None:
        kept = tuple(m for m in info.masses if m[0] not in masses)
        nominal = tuple((k, float(v["mass"]), tuple(v["com"])) for k, v in masses.items())
        info = dataclasses.replace(info, masses=kept + nominal)
    joints = []
    for j in info.joints:
        o = origins.get(j.name)
        if o is not None:
            j = dataclasses.replace(j, xyz=tuple(o["xyz"]), rpy=tuple(o["rpy"]))
        joints.append(j)
    model = build_model(kinematic_xml(dataclasses.replace(info, joints=tuple(joints))), str(urdf))
    oMi = joint_placements(model, pin.neutral(model))
    oMb = frame_placement(model, oMi, resolve_frame(model, base))
    model.gravity = pin.Motion(np.r_[oMb.rotation @ gravity, np.zeros(3)])
    return model


def _origins(doc: dict, src: str) -> dict:
    """The nominal joint origins of a compliance file, or of a report's nominal URDF."""
    origins = doc.get("nominal_origins")
    if origins is None and isinstance(doc.get("urdf"), str):  # a report
        try:
            return nominal_origins(read_urdf_file(doc["urdf"]))
        except URDFError as exc:
            raise DataError(
                src, f"its nominal URDF (the gravity model) cannot be read: {exc}"
            ) from None
    ok = isinstance(origins, dict) and all(
        isinstance(o, dict)
        and all(
            isinstance(o.get(k), list)
            and len(o[k]) == 3
            and all(isinstance(v, (int, float)) and math.isfinite(v) for v in o[k])
            for k in ("xyz", "rpy")
        )
        for o in origins.values()
    )
    if not ok or not isinstance(origins, dict):
        raise DataError(src, "'nominal_origins' is missing or not {joint: {xyz, rpy}}")
    return origins


def _masses(doc: dict, src: str) -> dict | None:
    """The nominal link masses of a compliance file (None where it has none: older files)."""
    masses = doc.get("nominal_masses")
    if masses is None:
        return None
    ok = isinstance(masses, dict) and all(
        isinstance(v, dict)
        and isinstance(v.get("mass"), (int, float))
        and math.isfinite(v["mass"])
        and v["mass"] > 0
        and isinstance(v.get("com"), list)
        and len(v["com"]) == 3
        and all(isinstance(c, (int, float)) and math.isfinite(c) for c in v["com"])
        for v in masses.values()
    )
    if not ok:
        raise DataError(src, "'nominal_masses' is not {link: {mass, com}}")
    return masses


def _read_json(path: str | Path) -> dict:
    try:
        doc = json.loads(read_text_limited(path, MAX_JSON_BYTES))
    except OSError as exc:
        raise DataError(str(path), read_failure(exc)) from None
    except (ValueError, UnicodeDecodeError) as exc:
        raise DataError(str(path), f"not a JSON file: {exc}") from None
    if not isinstance(doc, dict):
        raise DataError(str(path), "not a calib report or compliance file")
    return doc


def _numbers(doc: dict, key: str, shape: tuple[int, ...], src: str) -> np.ndarray:
    value = doc.get(key)
    if isinstance(value, dict) and "matrix" in value:  # a report's pose
        value = value["matrix"]
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.ndim != len(shape) or any(s >= 0 and s != d for s, d in zip(shape, a.shape, strict=True)):
        raise DataError(src, f"'{key}' is missing or not {shape} numbers")
    if not np.all(np.isfinite(a)):
        raise DataError(src, f"'{key}' holds a number that is not finite")
    return a


def _fields(doc: dict, src: str) -> tuple[str, str, list[str], np.ndarray]:
    """Base and tool frames, joint names and compliances of a report or compliance file."""
    comp = doc.get("compliance")
    joints: object
    values: object
    if isinstance(comp, dict):  # a report: joint -> compliance
        joints, values = list(comp), list(comp.values())
    else:
        joints, values = doc.get("joints"), comp
    base, tool = doc.get("base_frame"), doc.get("tool_frame")
    if not isinstance(base, str) or not isinstance(tool, str) or not isinstance(joints, list):
        raise DataError(src, "not a calib report or compliance file (base_frame, tool_frame)")
    c = _numbers({"compliance": values}, "compliance", (len(joints),), src)
    return base, tool, [str(j) for j in joints], c


def load_calibrated(
    urdf: str | Path, compliance: str | Path, tool: str | None = None, term: int | None = None
) -> ElasticModel:
    """The calibrated URDF with its compliance file or its calibration report.

    Args:
        urdf: The calibrated URDF (as ``calib calibrate`` wrote it).
        compliance: Its ``.compliance.json``, or the report (``--report``).
        tool: The tool frame of the term to read in a report of several (a tree's tools,
            several terms; ``terms[k].tool``); None for a report of one term.
        term: The index (from 0) in the report's ``terms`` of the term to read: two terms of
            one tool (a hand measured by a camera and touching a table); None: ``tool``'s.

    Raises:
        InvalidArgumentError: ``term`` is not an integer (a bool is not one).
        DataError: The file is not a report or compliance file, does not match the URDF
            (a report written with another URDF: its ``model.urdf_sha256``), or is a report
            of several terms and ``tool`` names none of them (or two: give ``term``), or
            has no term ``term``.
        CalibError: The URDF cannot be loaded with the recorded frames.
    """
    src = str(compliance)
    raw = _read_json(compliance)
    doc = compliance_fields(raw, src, tool, term)  # its format first
    _check_urdf(raw, urdf, src)
    chain = None
    several = doc.get("term_compliance")
    if isinstance(several, dict):  # one term of several: its chain's joints, rigid if absent
        chain = load_chain(urdf, str(doc.get("base_frame")), str(doc.get("tool_frame")))
        doc = {**doc, "compliance": {j: several.get(j, 0.0) for j in chain.joint_names}}
    base, tool, joints, c = _fields(doc, src)
    chain = chain or load_chain(urdf, base, tool)
    if tuple(joints) != tuple(chain.joint_names):
        raise DataError(
            src,
            f"its joints ({', '.join(joints)}) are not the chain's of {urdf} "
            f"({', '.join(chain.joint_names)})",
        )
    gravity = doc.get("gravity")
    vec = _numbers(gravity if isinstance(gravity, dict) else {}, "vector", (3,), src)
    if isinstance(gravity, dict) and gravity.get("frame") not in (None, base):
        raise DataError(src, f"the gravity is given in '{gravity.get('frame')}', not the base")
    T = _numbers(doc, "measurement_to_base", (4, 4), src)
    markers = _numbers(doc, "markers", (-1, 3), src)
    model = torque_model(urdf, _origins(doc, src), base, vec, _masses(doc, src))
    load = _standing(doc.get("load"), chain, model, src)
    readings = _readings(doc.get("load"), src)
    contact = doc.get("contact")
    frames: tuple[np.ndarray | None, np.ndarray | None] = (None, None)
    if contact is not None:
        if not isinstance(contact, dict):
            raise DataError(src, "'contact' is not {frame, plane}")
        frames = (
            _numbers(contact, "frame", (4, 4), src),
            _numbers(contact, "plane", (4, 4), src),
        )
    return ElasticModel(
        chain, T, markers, c, vec, from_chain(chain), model, load, *frames, readings=readings
    )


def _check_urdf(doc: dict, urdf: str | Path, src: str) -> None:
    """Refuse a URDF other than the one the report was written with (a readable one)."""
    try:
        text = read_bytes_limited(robot_source(urdf)[1], MAX_URDF_BYTES)
    except (OSError, CalibError):  # loading the chain says why
        return
    check_pairing(doc, text, str(urdf), src)


def _readings(load, src: str) -> tuple[str, ...]:
    """The joints a compliance file's load read off the chain (none in older files)."""
    names = load.get("readings", []) if isinstance(load, dict) else []
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise DataError(src, "'load.readings' is not a list of joint names")
    return tuple(names)


def _standing(load, chain: Chain, model: pin.Model, src: str) -> StandingLoad | None:
    """The standing load a compliance file records (``load``), on the gravity model."""
    if load is None:
        return None
    support = load.get("support") if isinstance(load, dict) else None
    if (
        not isinstance(load, dict)
        or load.get("kind") != "standing"
        or not isinstance(support, dict)
    ):
        raise DataError(src, "'load' is not {kind: standing, support: {foot, share}}")
    same = [model.names[j] for j in chain.joint_ids] == list(chain.joint_names) and [
        model.frames[f].name for f in (chain.base_id, chain.tool_id)
    ] == [chain.base_frame, chain.tool_frame]
    if not same:
        raise DataError(src, "the gravity model's joints and frames are not the URDF's")
    try:
        return standing_load(
            dataclasses.replace(chain, model=model),
            Support(support.get("foot"), support.get("share")),
        )
    except (InvalidArgumentError, FrameNotFoundError, AmbiguousFrameError) as exc:
        raise DataError(src, f"its load does not fit the URDF: {exc}") from None


def predictions_csv(
    model: ElasticModel, q: np.ndarray, readings: JointReadings | None = None
) -> str:
    """CSV of predictions at configurations ``(m, n)``.

    Columns: the commanded joints, the predicted points ``x1, y1, z1, ...`` [m, measurement
    frame], and the deflected joints ``deflected_<joint>`` (``q + c tau(q)``); ``readings``:
    the joints off the chain, as :meth:`ElasticModel.torques` takes them.
    """
    names = list(model.chain.joint_names)
    k = len(model.markers)
    header = names + [f"{a}{i + 1}" for i in range(k) for a in "xyz"]
    header += [f"deflected_{n}" for n in names]
    deflected = model.deflected(q, readings)  # the torques once, for both
    T = model.measurement_to_base @ model._tool_in_base(deflected)
    pts = model._points(T).reshape(len(q), -1)
    rows = np.hstack([q, pts, deflected])
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([repr(float(v)) if math.isfinite(v) else "nan" for v in row])
    return out.getvalue()
