"""Links a calibrated URDF gains: the measured points (markers) and the measurement frame.

A marker is written as a fixed link under the tool link (``<tool>_marker<k>``, joint
``<tool>_marker<k>_joint``), so that any URDF user (Pinocchio, MoveIt, a TF tree) can ask
for the measured point. The measurement frame is written, on request, as a new root link
(``--world-link NAME``, joint ``NAME_joint``) whose fixed joint places the URDF's old root
link in it: forward kinematics from that link gives measured coordinates.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from ..exceptions import CalibError, InvalidArgumentError

__all__ = [
    "add_marker_links",
    "add_world_link",
    "calibrated_tool_name",
    "check_new_names",
    "marker_joints",
    "marker_link_names",
    "root_link",
    "set_fixed_link",
]


def marker_link_names(tool: str, k: int) -> tuple[str, ...]:
    """Names of the links of ``k`` markers on ``tool``: ``<tool>_marker1``, ..."""
    return tuple(f"{tool}_marker{i + 1}" for i in range(k))


def root_link(root: ET.Element) -> str:
    """The URDF's root link: the one link that is no joint's child.

    Raises:
        CalibError: No single root link.
    """
    links = [link.get("name", "") for link in root.findall("link")]
    children = {c.get("link", "") for c in root.findall("joint/child")}
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise CalibError(f"the URDF has {len(roots)} root links, not 1: {', '.join(roots)}")
    return roots[0]


def check_new_names(root: ET.Element, links: tuple[str, ...], option: str) -> None:
    """Raise if a new link (or its joint ``<link>_joint``) already has a name in the URDF.

    Raises:
        InvalidArgumentError: A name is taken (one line, naming ``option``).
    """
    taken = {e.get("name", "") for e in (*root.findall("link"), *root.findall("joint"))}
    for name in links:
        if not name or not name.strip() or any(c in name for c in "<>&\"'"):
            raise InvalidArgumentError(f"{option}: '{name}' is not a valid URDF link name")
        for new in (name, f"{name}_joint"):
            if new in taken:
                raise InvalidArgumentError(
                    f"{option}: the URDF already has a link or joint named '{new}'"
                )


def _element(tag: str, text: str, tail: str, **attrs: str) -> ET.Element:
    e = ET.Element(tag, attrs)
    e.text, e.tail = text, tail
    return e


def _fixed_joint(name: str, parent: str, child: str, T: np.ndarray, indent: str) -> ET.Element:
    from .urdf_export import set_origin  # the one place origins are written

    inner = indent + "  "
    joint = _element("joint", "\n" + inner, "\n" + indent, name=name, type="fixed")
    joint.append(_element("parent", "", "\n" + inner, link=parent))
    joint.append(_element("child", "", "\n" + indent, link=child))
    set_origin(joint, T)
    return joint


def _append(root: ET.Element, elements: list[ET.Element]) -> None:
    """Append elements at the end of the root, each on its own line, indented by two spaces."""
    last_tail = root[-1].tail if len(root) else "\n"
    if len(root):
        root[-1].tail = "\n  "
    else:
        root.text = "\n  "
    for e in elements:
        e.tail = "\n  "
    elements[-1].tail = last_tail
    root.extend(elements)


def add_marker_links(root: ET.Element, tool: str, tool_link: str, markers: np.ndarray) -> None:
    """Add a fixed link per marker under ``tool_link``, at the marker ``(K, 3)`` [m].

    Args:
        root: The URDF's ``<robot>`` element (edited).
        tool: The tool frame's name (the links' prefix).
        tool_link: The link the markers are fixed to (the tool frame's link).
        markers: The points in the tool frame ``(K, 3)`` [m].

    Raises:
        InvalidArgumentError: A link or joint of that name exists.
    """
    from .urdf_export import set_origin

    names = marker_link_names(tool, len(markers))
    existing = marker_joints(root, tool, tool_link, len(markers))
    check_new_names(root, tuple(n for n in names if n not in existing), "marker links")
    elements: list[ET.Element] = []
    for name, mk in zip(names, np.asarray(markers, dtype=float), strict=True):
        T = np.eye(4)
        T[:3, 3] = mk
        if name in existing:  # a calibrated URDF calibrated again: the link is moved
            set_origin(existing[name], T)
            continue
        elements.append(_element("link", "", "", name=name))
        elements.append(_fixed_joint(f"{name}_joint", tool_link, name, T, "  "))
    if elements:
        _append(root, elements)


def calibrated_tool_name(tool: str) -> str:
    """The link added for a tool frame carried by a moving joint: ``<tool>_calibrated``."""
    return f"{tool}_calibrated"


def set_fixed_link(root: ET.Element, name: str, parent: str, T: np.ndarray) -> None:
    """Place link ``name`` on ``parent`` by a fixed joint ``<name>_joint`` at ``T`` ``(4, 4)``.

    A link of that name already fixed to ``parent`` (a calibrated URDF calibrated again) is
    moved; a new one is added.

    Raises:
        InvalidArgumentError: A link or joint of that name exists elsewhere.
    """
    from .urdf_export import child_link, parent_link, set_origin

    for joint in root.findall("joint"):
        placed = child_link(joint) == name and parent_link(joint) == parent
        if placed and joint.get("type") == "fixed":
            set_origin(joint, T)
            return
    check_new_names(root, (name,), "the calibrated tool link")
    _append(
        root,
        [_element("link", "", "", name=name), _fixed_joint(f"{name}_joint", parent, name, T, "  ")],
    )


def marker_joints(root: ET.Element, tool: str, tool_link: str, k: int) -> dict[str, ET.Element]:
    """Marker links a previous calibration wrote (name -> its fixed joint under the tool)."""
    joints = {j.get("name", ""): j for j in root.findall("joint")}
    links = {link.get("name", "") for link in root.findall("link")}
    found = {}
    for name in marker_link_names(tool, k):
        joint = joints.get(f"{name}_joint")
        if name in links and joint is not None and joint.get("type") == "fixed":
            parent, child = joint.find("parent"), joint.find("child")
            if (parent is not None and parent.get("link") == tool_link) and (
                child is not None and child.get("link") == name
            ):
                found[name] = joint
    return found


def add_world_link(root: ET.Element, name: str, world_to_root: np.ndarray) -> None:
    """Add ``name`` as the parent of the URDF's root link, at ``world_to_root`` ``(4, 4)``.

    Args:
        root: The URDF's ``<robot>`` element (edited).
        name: The new root link (the measurement frame).
        world_to_root: Pose of the old root link in the new one.

    Raises:
        InvalidArgumentError: ``name`` (or ``name_joint``) is taken.
        CalibError: The URDF has no single root link.
    """
    check_new_names(root, (name,), "world_link")
    old = root_link(root)
    _append(
        root,
        [
            _element("link", "", "", name=name),
            _fixed_joint(f"{name}_joint", name, old, world_to_root, "  "),
        ],
    )
