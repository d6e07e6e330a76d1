"""Write a URDF whose joint origins are moved by given rigid errors: ``O_j -> O_j E_j``.

The calibration of several chains of one robot (:mod:`calib.calibration.engine`)
fits one error per URDF joint, shared by every chain through it; its URDF is the nominal
file with those joints' ``<origin>`` edited, nothing else (joints without error keep their
bytes).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..core.fileio import check_outputs, write_atomic
from ..exceptions import CalibError, InvalidArgumentError
from .robot import Chain
from .urdf_export import (
    NominalPoses,
    base_joint,
    base_to_root,
    chain_joint_below,
    child_link,
    edited_joints,
    keep_tool_children,
    origin_of,
    parent_link,
    read_urdf_source,
    set_origin,
    spliced,
    tool_on_moving_joint,
    xml_layout,
)
from .urdf_links import add_marker_links, add_world_link, calibrated_tool_name, set_fixed_link
from .urdf_xml import parse_xml

__all__ = [
    "camera_placement",
    "camera_urdf",
    "instrument_joint",
    "marker_urdf",
    "moved_origins_urdf",
    "place_calibrated_tool",
    "write_moved_origins_urdf",
]


def moved_origins_urdf(chain: Chain, errors: dict[str, np.ndarray]) -> bytes:
    """The URDF of ``chain`` with the origin of each joint named in ``errors`` right-multiplied.

    Args:
        chain: Any chain of the robot (its ``urdf_path`` is read).
        errors: ``E_j`` ``(4, 4)`` by URDF joint name, in the joint's frame.

    Raises:
        CalibError: A joint the file does not have, or a file that cannot be read.
    """
    raw, root = read_urdf_source(chain)
    if not errors:
        return raw
    start, stop = xml_layout(raw, str(chain.urdf_path))
    joints = {j.get("name", ""): j for j in root.findall("joint")}
    for name, E in errors.items():
        if name not in joints:
            raise CalibError(f"{chain.urdf_path}: no <joint name='{name}'>")
        E = np.asarray(E, dtype=float)
        if E.shape != (4, 4) or not np.all(np.isfinite(E)):
            raise InvalidArgumentError(f"the error of joint {name} must be a finite (4, 4) pose")
        if not np.array_equal(E, np.eye(4)):
            set_origin(joints[name], origin_of(joints[name]) @ E)
    return spliced(raw, root, start, stop)


def write_moved_origins_urdf(path: str | Path, chain: Chain, errors: dict[str, np.ndarray]) -> None:
    """Write :func:`moved_origins_urdf` atomically (never over the nominal URDF)."""
    if not isinstance(path, str | os.PathLike):
        raise InvalidArgumentError(f"path must be a file path, got {path!r:.60}")
    check_outputs({"path": path}, {"the nominal URDF": chain.urdf_resolved})
    write_atomic(path, moved_origins_urdf(chain, errors))


def camera_placement(chain: Chain, name: str, link: str) -> np.ndarray | None:
    """The placement ``(4, 4)`` [m] of link ``name`` fixed to ``link`` in the URDF, or None.

    A robot description's optical frame (TIAGo's ``xtion_optical_frame`` on ``xtion_link``)
    is a camera's starting placement.

    Raises:
        InvalidArgumentError: A link ``name`` that is not fixed to ``link`` directly.
    """
    _, root = read_urdf_source(chain)
    for joint in root.findall("joint"):
        if child_link(joint) == name:
            if parent_link(joint) != link or joint.get("type") != "fixed":
                raise InvalidArgumentError(
                    f"camera {name}: the URDF's link {name} is on {parent_link(joint)} by a "
                    f"{joint.get('type')} joint, not fixed to {link}: name the camera's link "
                    f"{parent_link(joint)}, or give the camera another name"
                )
            return origin_of(joint)
    if any(x.get("name") == name for x in root.findall("link")):
        raise InvalidArgumentError(f"camera {name}: the URDF's root link has that name")
    return None


def camera_urdf(
    chain: Chain, errors: dict[str, np.ndarray], cameras: tuple[tuple[str, str, np.ndarray], ...]
) -> bytes:
    """:func:`moved_origins_urdf` with each camera a link fixed to its link.

    Args:
        chain: Any chain of the robot (its ``urdf_path`` is read).
        errors: ``E_j`` ``(4, 4)`` by URDF joint name.
        cameras: ``(name, link, placement (4, 4) [m])`` of each camera's optical frame: a link
            ``name`` already fixed to ``link`` is moved, a new one added.
    """
    raw = moved_origins_urdf(chain, errors)
    src = str(chain.urdf_path)
    start, stop = xml_layout(raw, src)
    root = parse_xml(raw, src)
    for name, link, T in cameras:
        set_fixed_link(root, name, link, T)
    return spliced(raw, root, start, stop)


def marker_urdf(
    chain: Chain,
    errors: dict[str, np.ndarray],
    markers: tuple[tuple[Chain, np.ndarray], ...],
    tool: np.ndarray | None = None,
    world: tuple[str, np.ndarray] | None = None,
) -> bytes:
    """:func:`moved_origins_urdf` with each tool's markers as links ``<tool>_marker<k>``.

    Args:
        chain: Any chain of the robot (its ``urdf_path`` is read).
        errors: ``E_j`` ``(4, 4)`` by URDF joint name.
        markers: ``(chain to the tool, its markers (K, 3) [m])`` of each tool: each marker a
            link fixed to the tool's link (:func:`~.urdf_links.add_marker_links`), in the
            tool frame (with ``tool``: in the calibrated tool's).
        tool: One chain's calibrated tool ``(4, 4)`` (the measured frame in the tool frame;
            identity for position data), written as a chain's calibration writes it
            (:func:`place_calibrated_tool`: a tool link carried by the chain's
            last joint is allowed), the markers hung from it; None: a tree's tools, each
            marker on its tool's link (a fixed one, or the link of the tool chain's last
            joint: TALOS's ``left_sole_link``, a UR5's ``wrist_2_link``).
        world: ``(name, T)``: add the link ``name`` (the instrument) as the parent of the
            URDF's root link, ``T`` ``(4, 4)`` the pose of ``chain``'s base frame in it.

    Raises:
        CalibError: A tool carried by neither a fixed joint nor its chain's last joint, a
            marker or world link's name taken, or the base frame moved by a joint (``world``).
    """
    raw = moved_origins_urdf(chain, errors)
    src = str(chain.urdf_path)
    start, stop = xml_layout(raw, src)
    root = parse_xml(raw, src)
    for tool_chain, points in markers:
        tool_joint = edited_joints(root, tool_chain, moving=True)[1]  # a link moved by its joint
        tool_link = child_link(tool_joint)
        if tool is not None:
            tool_link = place_calibrated_tool(root, tool_chain, tool_joint, tool)
        add_marker_links(root, tool_chain.tool_frame, tool_link, points)
    if world is not None:
        add_world_link(root, world[0], world[1] @ base_to_root(chain, NominalPoses(chain)))
    return spliced(raw, root, start, stop)


def place_calibrated_tool(
    root: ET.Element, chain: Chain, tool_joint: ET.Element, X: np.ndarray
) -> str:
    """Write the calibrated tool on the tool's link; the link that holds it.

    ``X`` ``(4, 4)``: the measured frame in the tool frame of the written joints (identity
    for position data). A tool on a fixed joint: that joint's origin is right-multiplied by
    ``X`` and the joints fixed to the tool link keep their place; a tool link carried by the
    chain's last joint keeps its place and a link ``<tool>_calibrated`` is fixed to it at
    ``X`` (:func:`~.urdf_export.urdf_tool_frame`).

    Args:
        root: The URDF's ``<robot>`` element (edited).
        chain: The chain.
        tool_joint: The joint that carries the tool link (:func:`~.urdf_export.edited_joints`).
        X: The calibrated tool in the tool frame ``(4, 4)``.
    """
    tool_link = child_link(tool_joint)
    if tool_on_moving_joint(chain):
        held = calibrated_tool_name(chain.tool_frame)
        set_fixed_link(root, held, tool_link, X)
        return held
    set_origin(tool_joint, origin_of(tool_joint) @ X)
    keep_tool_children(root, tool_link, X)
    return tool_link


def instrument_joint(root: ET.Element, chain: Chain) -> ET.Element:
    """The fixed joint that takes an instrument on the robot's placement (``on_robot``).

    The base frame's fixed joint (:func:`~.urdf_export.base_joint`), off the chain: moving
    it moves the base frame alone (a head camera whose chain runs up the head and down the
    arm).

    Raises:
        CalibError: The base frame is the root link or a joint moves it, or the chain hangs
            from the base frame's link (moving its joint would move the whole chain).
    """
    joint = base_joint(root, chain)
    joints = {j.get("name", ""): j for j in root.findall("joint")}
    name = chain_joint_below(joints, chain, child_link(joint))
    if name is not None:
        raise CalibError(
            f"on_robot: the chain hangs from the base frame '{chain.base_frame}' (joint "
            f"'{name}' is below it): moving its fixed joint would move the whole chain; an "
            f"instrument on the robot is a frame the chain leaves upwards (a head camera "
            f"measuring the arm)"
        )
    return joint
