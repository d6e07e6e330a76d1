"""What a calibration changed in a URDF, as data a xacro file reads (``xacro.load_yaml``).

A robot's URDF is usually generated from xacro files, so the flattened calibrated URDF is not
what a ROS user ships. :func:`changed_origins` compares the calibrated URDF with the nominal
one: every joint whose ``<origin>`` moved, and every joint the calibration added (marker
links, a camera, the world link), with its calibrated ``xyz`` [m] and ``rpy`` [rad] as the
calibrated URDF writes them (so a xacro that takes them reproduces that URDF to the bit) and
its nominal values beside them. :func:`origins_yaml` writes them as YAML::

    joints:
      "shoulder_lift_joint":
        parent: "shoulder_link"
        child: "upper_arm_link"
        xyz: "0.0019 0.1335 -0.0003"
        rpy: "-1.588 1.568 -1.588"
        nominal_xyz: "0.0 0.13585 0.0"
        nominal_rpy: "0.0 1.57079632679 0.0"
        added: false
        link: null

PyYAML is no dependency: the writer is plain text (every string quoted as JSON, which YAML
reads).
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from ..exceptions import URDFError
from .urdf_xml import parse_xml

__all__ = ["ORIGINS_FORMAT", "JointOrigin", "changed_origins", "origins_document", "origins_yaml"]

ORIGINS_FORMAT = "1"
"""Version of the origins file's layout (``format_version``)."""


@dataclass(frozen=True)
class JointOrigin:
    """A joint's calibrated origin and its nominal one.

    Attributes:
        joint: The URDF joint's name.
        parent: Its parent link.
        child: Its child link.
        xyz: Calibrated translation [m], as the calibrated URDF writes it (three numbers).
        rpy: Calibrated roll, pitch, yaw [rad], as the calibrated URDF writes it.
        nominal_xyz: The nominal URDF's translation [m], or None for an added joint.
        nominal_rpy: The nominal URDF's roll, pitch, yaw [rad], or None for an added joint.
        link: The link the calibration added with this joint (a marker's, a camera's, a new
            root), or None.
    """

    joint: str
    parent: str
    child: str
    xyz: str
    rpy: str
    nominal_xyz: str | None
    nominal_rpy: str | None
    link: str | None = None

    @property
    def added(self) -> bool:
        """The calibration added this joint (a marker, a camera, the world link)."""
        return self.nominal_xyz is None

    def to_dict(self) -> dict:
        """The YAML entry: parent, child, xyz, rpy, nominal_xyz, nominal_rpy, added, link."""
        return {
            "parent": self.parent,
            "child": self.child,
            "xyz": self.xyz,
            "rpy": self.rpy,
            "nominal_xyz": self.nominal_xyz,
            "nominal_rpy": self.nominal_rpy,
            "added": self.added,
            "link": self.link,
        }


def _origin(joint: ET.Element) -> tuple[str, str]:
    """A joint's origin attributes as written (URDF's defaults: zeros)."""
    origin = joint.find("origin")
    if origin is None:
        return "0 0 0", "0 0 0"
    return origin.get("xyz", "0 0 0"), origin.get("rpy", "0 0 0")


def _numbers(text: str, joint: str, src: str) -> tuple[float, ...]:
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise URDFError(src, f"joint '{joint}': origin '{text:.60}' is not three finite numbers")
    return values


def _moved(xyz: str, rpy: str, nominal: tuple[str, str], joint: str) -> bool:
    """The origin differs from the nominal one (numbers compared, not their text)."""
    new = (_numbers(xyz, joint, "the calibrated URDF"), _numbers(rpy, joint, "the calibrated URDF"))
    old = tuple(_numbers(text, joint, "the nominal URDF") for text in nominal)
    return new != old


def _tree(raw: bytes, src: str) -> tuple[dict[str, ET.Element], set[str]]:
    """A URDF's joints by name and its link names."""
    root = parse_xml(raw, src)
    links = {e.get("name", "") for e in root.findall("link")}
    return {j.get("name", ""): j for j in root.findall("joint")}, links


def _link(joint: ET.Element, tag: str) -> str:
    element = joint.find(tag)
    return "" if element is None else element.get("link", "")


def changed_origins(nominal: bytes, calibrated: bytes) -> tuple[JointOrigin, ...]:
    """The joints whose origin the calibration moved or added, in the calibrated file's order.

    Args:
        nominal: The nominal URDF's text.
        calibrated: The calibrated URDF's text (as a result's ``urdf()`` returns it).

    Raises:
        URDFError: A file is not XML, or an origin is not three finite numbers.
    """
    before, links = _tree(nominal, "the nominal URDF")
    out = []
    for name, joint in _tree(calibrated, "the calibrated URDF")[0].items():
        xyz, rpy = _origin(joint)
        old = before.get(name)
        nxyz: str | None = None
        nrpy: str | None = None
        if old is not None:
            nxyz, nrpy = _origin(old)
            if not _moved(xyz, rpy, (nxyz, nrpy), name):
                continue
        parent, child = _link(joint, "parent"), _link(joint, "child")
        new = None if old is not None else child if child not in links else parent
        out.append(JointOrigin(name, parent, child, xyz, rpy, nxyz, nrpy, new))
    return tuple(out)


def origins_document(robot: str, nominal_urdf: str, origins: tuple[JointOrigin, ...]) -> dict:
    """The origins file's content: ``format_version``, ``robot``, ``urdf``, ``joints``.

    Args:
        robot: The robot's name.
        nominal_urdf: The nominal URDF's path (said in the file).
        origins: The changed joints (:func:`changed_origins`).
    """
    return {
        "format_version": ORIGINS_FORMAT,
        "robot": robot,
        "urdf": nominal_urdf,
        "joints": {o.joint: o.to_dict() for o in origins},
    }


def _scalar(value: object) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    return json.dumps(str(value))


def origins_yaml(doc: dict) -> str:
    """The origins document (:func:`origins_document`) as YAML that ``xacro.load_yaml`` reads."""
    lines = [
        "# Joint origins changed or added by calib's calibration: xyz [m], rpy [rad] as the",
        "# calibrated URDF writes them; the nominal ones beside them (null: a joint calib added).",
        '# In a xacro: <xacro:property name="cal" value="${xacro.load_yaml(\'origins.yaml\')}"/>',
    ]
    lines += [f"{key}: {_scalar(doc[key])}" for key in ("format_version", "robot", "urdf")]
    lines.append("joints:" if doc["joints"] else "joints: {}")
    for name, entry in doc["joints"].items():
        lines.append(f"  {_scalar(name)}:")
        lines += [f"    {key}: {_scalar(value)}" for key, value in entry.items()]
    return "\n".join(lines) + "\n"
