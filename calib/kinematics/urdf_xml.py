"""calib's own reading of URDF XML: parsing, checked numbers, and Pinocchio's kinematic copy.

calib parses the file once, with expat and without namespace processing, so a prefix that
no ``xmlns`` declares (``<sensor:camera>`` in a Gazebo block) is just part of a name, as it is
for Pinocchio's own parser. Every number calib uses is checked here (strict decimal grammar,
finite, within :data:`MAX_COORDINATE` or :data:`MAX_ANGLE`, non-zero axes), with an error that
names the joint. Pinocchio then builds its model from a *kinematic copy* written by calib:
links and joints with their origins, axes and position limits only. What calib does not use
(visuals, materials, inertias, effort and velocity limits, dynamics, Gazebo blocks) cannot
make Pinocchio refuse the file or print messages, and both parsers see the same names.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
import xml.parsers.expat
from dataclasses import dataclass

from ..exceptions import URDFError

__all__ = [
    "JOINT_TYPES",
    "MAX_ANGLE",
    "MAX_COORDINATE",
    "MAX_URDF_BYTES",
    "MIN_AXIS_NORM",
    "SNAP_ANGLE",
    "SNAP_LENGTH",
    "URDFInfo",
    "URDFJoint",
    "URDFMimic",
    "kinematic_xml",
    "parse_xml",
    "read_urdf_info",
]

MAX_URDF_BYTES = 64 << 20
"""Largest URDF file calib reads [B] (64 MB; real robot descriptions are under 1 MB)."""

MAX_COORDINATE = 1e4
"""Largest joint-origin coordinate [m] accepted from a URDF or the API (10 km).

Coordinates beyond it are certainly not a robot's geometry, and at 1e300 the rank
tolerance of the analysis overflows and the counts are silently wrong.
"""

MAX_ANGLE = 1e3
"""Largest ``rpy`` angle [rad] accepted from a URDF.

Position limits beyond it (revolute) or beyond :data:`MAX_COORDINATE` (prismatic) are read
as "no usable limits", as infinite ones are.
"""

MIN_AXIS_NORM = 1e-6
"""A joint axis shorter than this has no direction (``0 0 0``, ``0 0 1e-300``)."""

SNAP_ANGLE = 1e-5
"""Angle [rad] within which round-off removal snaps to a multiple of 90 degrees.

URDF files round pi/2 to 1.5708 (3.7e-6 rad off), 1.57079 or 1.57079632679 (5e-12 off).
"""

SNAP_LENGTH = 1e-6
"""Length [m] under which round-off removal snaps a distance to zero."""

JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
"""The joint types of the URDF specification."""

_WITH_AXIS = ("revolute", "continuous", "prismatic")
_WITH_LIMIT = ("revolute", "prismatic")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")


@dataclass(frozen=True)
class URDFMimic:
    """A ``<mimic>`` tag: the joint's position is ``multiplier * q[joint] + offset``.

    Attributes:
        joint: Name of the joint followed (it may be missing from the file: the chain that
            needs it says so).
        multiplier: Factor (default 1).
        offset: Offset [rad or m] (default 0).
    """

    joint: str
    multiplier: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class URDFJoint:
    """One ``<joint>`` as calib reads it (checked numbers).

    Attributes:
        name: Joint name.
        type: One of :data:`JOINT_TYPES`.
        parent: Parent link.
        child: Child link.
        xyz: Origin translation [m].
        rpy: Origin roll, pitch, yaw [rad].
        axis: Unit axis (``(1, 0, 0)`` when the joint has none).
        lower: Lower position limit [rad or m], None if not given.
        upper: Upper position limit [rad or m], None if not given.
        mimic: The joint's ``<mimic>`` tag, or None.
    """

    name: str
    type: str
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]
    axis: tuple[float, float, float]
    lower: float | None
    upper: float | None
    mimic: URDFMimic | None


@dataclass(frozen=True)
class URDFInfo:
    """What calib reads from the URDF XML itself.

    Attributes:
        name: The robot's name.
        root_link: Name of the root link.
        links: Link names, in file order.
        joints: The joints, in file order.
        mimic_joints: Names of joints carrying a ``<mimic>`` tag.
        mimics: Each joint with a ``<mimic>`` tag and the joint its tag names.
        masses: ``(link, mass [kg], centre of mass [m])`` of the links with a usable
            ``<inertial>`` (for gravity torques; rotational inertia is not kept).
    """

    name: str
    root_link: str
    links: tuple[str, ...]
    joints: tuple[URDFJoint, ...]
    masses: tuple[tuple[str, float, tuple[float, float, float]], ...] = ()

    @property
    def mimic_joints(self) -> frozenset[str]:
        """Names of the joints carrying a ``<mimic>`` tag."""
        return frozenset(j.name for j in self.joints if j.mimic)

    @property
    def mimics(self) -> dict[str, str]:
        """Each joint with a ``<mimic>`` tag and the joint its tag names."""
        return {j.name: j.mimic.joint for j in self.joints if j.mimic}


def parse_xml(raw: bytes, src: str) -> ET.Element:
    """Parse XML without namespace processing (comments and processing instructions kept).

    A prefixed name such as ``sensor:camera`` stays a plain name whether or not an ``xmlns``
    declares the prefix, and ``xmlns`` declarations stay plain attributes: the tree is
    written back as it was read.

    Raises:
        URDFError: The bytes are not well-formed XML.
    """
    builder = ET.TreeBuilder(insert_comments=True, insert_pis=True)
    parser = xml.parsers.expat.ParserCreate()  # no namespace_separator: no namespaces
    parser.buffer_text = True
    parser.StartElementHandler = builder.start
    parser.EndElementHandler = builder.end
    parser.CharacterDataHandler = builder.data
    parser.CommentHandler = builder.comment
    parser.ProcessingInstructionHandler = builder.pi
    try:
        parser.Parse(raw, True)
    except xml.parsers.expat.ExpatError as exc:
        raise URDFError(src, f"malformed XML: {exc}") from None
    return builder.close()


def _numbers(text: str | None, default: tuple[float, ...], what: str, where: str, src: str):
    if text is None:
        return default
    words = text.split()
    if len(words) != len(default) or not all(_NUMBER.fullmatch(w) for w in words):
        raise URDFError(src, f"{where} has {what} '{text}': expected {len(default)} numbers")
    values = tuple(float(w) for w in words)
    if not all(map(math.isfinite, values)):
        raise URDFError(src, f"{where} has {what} '{text}': numbers must be finite")
    return values


def _bounded(values, bound: float, unit: str, what: str, where: str, src: str):
    if any(abs(v) > bound for v in values):
        shown = " ".join(f"{v:g}" for v in values)
        raise URDFError(
            src, f"{where} has {what} '{shown}': beyond {bound:g} {unit}, not a robot's geometry"
        )
    return values


def _unit_axis(element: ET.Element | None, where: str, src: str) -> tuple[float, float, float]:
    text = None if element is None else element.get("xyz")
    a = _numbers(text, (1.0, 0.0, 0.0), "axis", where, src)
    scale = max(map(abs, a))
    if scale < MIN_AXIS_NORM:
        raise URDFError(src, f"{where} has a zero axis '{text}': it gives no direction")
    a = tuple(v / scale for v in a)  # no underflow or overflow in the norm
    norm = math.sqrt(sum(v * v for v in a))
    return (a[0] / norm, a[1] / norm, a[2] / norm)


def _limits(joint: ET.Element, kind: str, where: str, src: str):
    """Checked position limits; limits beyond the sane bounds count as no limits."""
    limit = joint.find("limit")
    if kind not in _WITH_LIMIT or limit is None:
        return None, None
    out: list[float | None] = []
    for side in ("lower", "upper"):
        text = limit.get(side)
        out.append(None if text is None else _numbers(text, (0.0,), f"{side} limit", where, src)[0])
    lower, upper = out
    if lower is not None and upper is not None and lower > upper:
        raise URDFError(src, f"{where} has lower limit {lower:g} > upper limit {upper:g}")
    bound = MAX_ANGLE if kind == "revolute" else MAX_COORDINATE
    if any(v is not None and abs(v) > bound for v in out):
        return None, None
    return lower, upper


def _link_of(joint: ET.Element, tag: str, links: set[str], where: str, src: str) -> str:
    e = joint.find(tag)
    link = e.get("link") if e is not None else None
    if link not in links:
        raise URDFError(src, f"{where} names a missing {tag} link '{link}'")
    return link


def _joint(j: ET.Element, links: set[str], src: str) -> URDFJoint:
    name = j.get("name")
    if not name:
        raise URDFError(src, "a <joint> has no name")
    where = f"joint '{name}'"
    kind = j.get("type", "")
    if kind not in JOINT_TYPES:
        raise URDFError(src, f"{where} has unknown type '{kind}' (URDF: {', '.join(JOINT_TYPES)})")
    parent = _link_of(j, "parent", links, where, src)
    child = _link_of(j, "child", links, where, src)
    origin = j.find("origin")
    get = (lambda key: None) if origin is None else origin.get
    xyz = _numbers(get("xyz"), (0.0, 0.0, 0.0), "origin xyz", where, src)
    rpy = _numbers(get("rpy"), (0.0, 0.0, 0.0), "origin rpy", where, src)
    _bounded(xyz, MAX_COORDINATE, "m", "origin xyz", where, src)
    _bounded(rpy, MAX_ANGLE, "rad", "origin rpy", where, src)
    axis = _unit_axis(j.find("axis"), where, src) if kind in _WITH_AXIS else (1.0, 0.0, 0.0)
    lower, upper = _limits(j, kind, where, src)
    return URDFJoint(name, kind, parent, child, xyz, rpy, axis, lower, upper, _mimic(j, where, src))


def _mimic(joint: ET.Element, where: str, src: str) -> URDFMimic | None:
    """The checked ``<mimic joint multiplier offset>`` of a joint, or None."""
    tag = joint.find("mimic")
    if tag is None:
        return None
    master = (tag.get("joint") or "").strip()
    if not master:
        raise URDFError(src, f"{where} has a <mimic> without a joint name")
    (factor,) = _numbers(tag.get("multiplier"), (1.0,), "mimic multiplier", where, src)
    (offset,) = _numbers(tag.get("offset"), (0.0,), "mimic offset", where, src)
    _bounded((factor,), MAX_ANGLE, "", "mimic multiplier", where, src)
    _bounded((offset,), MAX_COORDINATE, "rad or m", "mimic offset", where, src)
    return URDFMimic(master, factor, offset)


def _unique(names: list[str], what: str, src: str) -> None:
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise URDFError(src, f"two {what}s are named '{name}'")
        seen.add(name)


def read_urdf_info(raw: bytes, src: str) -> URDFInfo:
    """Parse and check a URDF document.

    Args:
        raw: The file's bytes.
        src: The file name, for error messages.

    Returns:
        The links and joints, with checked numbers.

    Raises:
        URDFError: Malformed XML, not a ``<robot>``, a missing or duplicate name, a joint
            naming a missing link, or a bad number (the error names the joint).
    """
    root = parse_xml(raw, src)
    if root.tag != "robot":
        raise URDFError(src, f"root element is <{root.tag}>, not <robot>")
    links = [e.get("name", "") for e in root.findall("link")]
    if not links:
        raise URDFError(src, "no <link> element")
    if not all(links):
        raise URDFError(src, "a <link> has no name")
    _unique(links, "link", src)
    link_set = set(links)
    joints = tuple(_joint(j, link_set, src) for j in root.findall("joint"))
    _unique([j.name for j in joints], "joint", src)
    children = {j.child for j in joints}
    roots = [name for name in links if name not in children]
    root_link = roots[0] if roots else links[0]
    masses = tuple(m for e in root.findall("link") if (m := _mass(e)) is not None)
    return URDFInfo(root.get("name", "robot"), root_link, tuple(links), joints, masses)


def _mass(link: ET.Element) -> tuple[str, float, tuple[float, float, float]] | None:
    """A link's mass and centre of mass, or None where absent or not usable.

    Never an error: calib uses masses only for the optional joint compliance of a calibration.
    """
    inertial = link.find("inertial")
    element = None if inertial is None else inertial.find("mass")
    origin = None if inertial is None else inertial.find("origin")
    try:
        mass = _numbers(None if element is None else element.get("value"), (0.0,), "", "", "")[0]
        com = _numbers(None if origin is None else origin.get("xyz"), (0.0,) * 3, "", "", "")
    except URDFError:
        return None
    if not (0.0 < mass < 1e6) or max(map(abs, com)) > 1e3:
        return None
    return link.get("name", ""), mass, com


def _snap_angle(a: float) -> float:
    quarter = math.pi / 2
    target = round(a / quarter) * quarter + 0.0  # no negative zero
    return target if abs(a - target) < SNAP_ANGLE else a


def _snap_length(v: float) -> float:
    return 0.0 if abs(v) < SNAP_LENGTH else v


def _snap_axis(axis: tuple[float, float, float]) -> tuple[float, float, float]:
    a = [0.0 if abs(c) < SNAP_ANGLE else c for c in axis]
    norm = math.sqrt(sum(c * c for c in a))
    return (a[0] / norm, a[1] / norm, a[2] / norm)


def _text(values) -> str:
    return " ".join(repr(float(v)) for v in values)


def kinematic_xml(info: URDFInfo, snap: bool = False) -> str:
    """The kinematic copy of a URDF that Pinocchio builds calib's model from.

    Links (names, and mass and centre of mass where usable) and joints (type, parent, child,
    origin, unit axis, position limits) of the checked document; effort and velocity limits
    are written as 0 (calib does not use them) and a revolute or prismatic joint without
    limits gets ``lower = upper = 0``, which calib reads as "no usable limits".

    Args:
        info: The checked document.
        snap: Remove round-off (:data:`SNAP_ANGLE`, :data:`SNAP_LENGTH`): each ``rpy`` angle
            within it of a multiple of 90 degrees is snapped to it, each ``xyz`` coordinate
            under it to zero, and each axis component under it to zero. The analysis then
            sees the ideal geometry the file's rounded numbers stand for.

    Returns:
        The URDF text.
    """
    robot = ET.Element("robot", {"name": info.name})
    masses = {name: (mass, com) for name, mass, com in info.masses}
    for link in info.links:
        e = ET.SubElement(robot, "link", {"name": link})
        if link in masses:
            inertial = ET.SubElement(e, "inertial")
            ET.SubElement(inertial, "origin", {"xyz": _text(masses[link][1]), "rpy": "0 0 0"})
            ET.SubElement(inertial, "mass", {"value": repr(masses[link][0])})
            zero = dict.fromkeys(("ixx", "ixy", "ixz", "iyy", "iyz", "izz"), "0")
            ET.SubElement(inertial, "inertia", zero)
    xyz: tuple[float, ...]
    rpy: tuple[float, ...]
    for j in info.joints:
        xyz, rpy, axis = j.xyz, j.rpy, j.axis
        if snap:
            xyz = tuple(map(_snap_length, xyz))
            rpy = tuple(map(_snap_angle, rpy))
            axis = _snap_axis(axis)
        e = ET.SubElement(robot, "joint", {"name": j.name, "type": j.type})
        ET.SubElement(e, "parent", {"link": j.parent})
        ET.SubElement(e, "child", {"link": j.child})
        ET.SubElement(e, "origin", {"xyz": _text(xyz), "rpy": _text(rpy)})
        if j.type in _WITH_AXIS:
            ET.SubElement(e, "axis", {"xyz": _text(axis)})
        if j.type in _WITH_LIMIT:
            lower = 0.0 if j.lower is None else j.lower
            upper = 0.0 if j.upper is None else j.upper
            limit = {"lower": repr(lower), "upper": repr(upper), "effort": "0", "velocity": "0"}
            ET.SubElement(e, "limit", limit)
    return ET.tostring(robot, encoding="unicode")
