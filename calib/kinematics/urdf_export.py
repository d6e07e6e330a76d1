"""Write a calibrated model back as a URDF that changes only what calibration changed.

Only the ``<origin xyz rpy>`` of chain joints 2..n and of the fixed joint that carries the
tool frame are rewritten; everything else of the original file is kept (comments, limits,
mimic tags, transmissions, mesh paths, other branches). Joint 1 keeps its nominal placement
in the base link: the base part of the calibration is the measurement-frame -> base
transform (:func:`measurement_to_base`). On request the file gains links
(:mod:`.urdf_links`): the markers under the tool link, and the measurement frame as a
new root link; pose data's measured frame is folded into the tool's fixed joint.

For chain joint k the constant ``C_k = T_mdh_k_nom(0)^-1 T_urdf_joint_k_nom(0)`` maps the MDH
frame onto the URDF joint frame (it keeps the joint axis); the calibrated joint frame is
``T_mdh_k_cal(0) C_k``. A link rigidly carried by joint k-1 (the parent link of joint k,
possibly behind fixed joints) moves with joint k-1's frame, so the fixed joints in between
keep their placements, and the new origin is ``T_parent_new^-1 T_joint_new``. The same holds
for the tool: frame n+1 of the MDH model is the tool frame.

A chain that runs up the tree first (from a foot to a hand: joints traversed backwards,
``Chain.sign`` -1) keeps the URDF's tree and root. Its body k still carries MDH frame k,
but a backwards joint k+1 hangs body k from its *child* link, whose frame is joint k+1's
frame: that link's frame moves with joint k+1's calibrated axis, and the origins of what
hangs from it (the next joint down the chain, its fixed links and other branches) are written
from there, so the fitted placement of body k in body k+1 lands in the URDF inverted. Its
visuals, collisions and inertia are placed back where the body carries them. Nothing else
changes: a forward chain's file is edited as before.
"""

from __future__ import annotations

import io
import os
import xml.etree.ElementTree as ET
import xml.parsers.expat
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..core.fileio import check_outputs, read_bytes_limited, write_atomic
from ..exceptions import CalibError, InvalidArgumentError, URDFError
from .frames import frame_placement, joint_placements
from .mdh import MDHModel, frames_at_zero
from .robot import Chain
from .urdf_links import add_marker_links, add_world_link, calibrated_tool_name, set_fixed_link
from .urdf_xml import MAX_URDF_BYTES, parse_xml

__all__ = [
    "NominalPoses",
    "base_joint",
    "base_to_root",
    "calibrated_urdf",
    "chain_joint_below",
    "check_base_fixed",
    "check_exportable",
    "child_link",
    "edited_joints",
    "keep_tool_children",
    "measurement_to_base",
    "origin_of",
    "parent_link",
    "read_urdf_source",
    "set_origin",
    "spliced",
    "tool_on_moving_joint",
    "urdf_tool_frame",
    "write_calibrated_urdf",
    "xml_layout",
]


def xml_layout(raw: bytes, src: str) -> tuple[int, int]:
    """Byte offsets of the root element: where it starts and where it ends."""
    parser = xml.parsers.expat.ParserCreate()  # no namespace processing, as parse_xml
    state = {"depth": 0, "start": -1, "end": -1}

    def start(name, attrs):
        if state["depth"] == 0 and state["start"] < 0:
            state["start"] = parser.CurrentByteIndex
        state["depth"] += 1

    def end(name):
        state["depth"] -= 1
        if state["depth"] == 0:
            state["end"] = parser.CurrentByteIndex

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(raw, True)
    except xml.parsers.expat.ExpatError as exc:
        raise URDFError(src, f"malformed XML: {exc}") from None
    stop = raw.index(b">", state["end"]) + 1
    if raw[state["end"] : state["end"] + 2] != b"</":  # a self-closing root element
        stop = raw.index(b"/>", state["start"]) + 2
    return state["start"], stop


def spliced(raw: bytes, root: ET.Element, start: int, stop: int) -> bytes:
    """The file with its root element (bytes ``start:stop``) replaced by the edited ``root``."""
    body = io.BytesIO()
    ET.ElementTree(root).write(body, encoding="utf-8", xml_declaration=False)
    return raw[:start] + body.getvalue() + raw[stop:]


def _homogeneous(se3: pin.SE3) -> np.ndarray:
    return np.array(se3.homogeneous)


class NominalPoses:
    """Poses of URDF joint frames and links in the base frame, chain at zero."""

    def __init__(self, chain: Chain):
        model = chain.model
        self.model = model
        q0 = chain.pin_configurations(np.zeros((1, chain.n)))[0]
        self.oMi = joint_placements(model, q0)
        self.bMo = frame_placement(model, self.oMi, chain.base_id).inverse()

    def joint(self, jid: int) -> np.ndarray:
        """URDF joint frame of Pinocchio joint ``jid``."""
        return _homogeneous(self.bMo * self.oMi[jid])

    def link(self, name: str) -> np.ndarray:
        """Frame of a link."""
        if not self.model.existBodyName(name):
            raise CalibError(f"link '{name}' of the URDF is not in the Pinocchio model")
        fid = self.model.getFrameId(name, pin.FrameType.BODY)
        return _homogeneous(self.bMo * frame_placement(self.model, self.oMi, fid))


def child_link(joint: ET.Element) -> str:
    """The ``<child link>`` of a URDF joint element ('' without one)."""
    child = joint.find("child")
    return "" if child is None else child.get("link", "")


def parent_link(joint: ET.Element) -> str:
    """The ``<parent link>`` of a URDF joint element ('' without one)."""
    parent = joint.find("parent")
    return "" if parent is None else parent.get("link", "")


def _joints_carrying(root: ET.Element, chain: Chain, frame_id: int) -> list[ET.Element]:
    """The URDF joints that carry a frame: its joint (a joint frame), or its link's parents."""
    frame = chain.model.frames[frame_id]
    joints = root.findall("joint")
    if frame.type in (pin.FrameType.FIXED_JOINT, pin.FrameType.JOINT):
        return [j for j in joints if j.get("name") == frame.name]
    return [j for j in joints if child_link(j) == frame.name]


def _tool_joint(root: ET.Element, chain: Chain, moving: bool = False) -> ET.Element:
    """The fixed joint whose child link is the tool frame (or which is the tool frame).

    ``moving``: a tool link carried by the chain's last joint is allowed (that joint is
    returned; :func:`calibrated_urdf` adds the calibrated tool as a link fixed to it).
    """
    found = _joints_carrying(root, chain, chain.tool_id)
    if not found:
        raise CalibError(f"no URDF joint carries the tool frame '{chain.tool_frame}'")
    joint = found[0]
    kind = joint.get("type", "")
    if kind != "fixed" and not (moving and joint.get("name") == chain.joint_names[-1]):
        raise CalibError(
            f"the tool frame '{chain.tool_frame}' is carried by the {kind} joint "
            f"'{joint.get('name')}', not by a fixed joint: the calibrated tool placement has "
            f"nowhere to go in the URDF (attach a tool link with a fixed joint and use it "
            f"as the tool)"
        )
    return joint


def base_joint(root: ET.Element, chain: Chain) -> ET.Element:
    """The fixed joint that places the base frame on its link (an instrument on the robot).

    Raises:
        CalibError: The base frame is the root link or a link a joint moves: its calibrated
            placement has nowhere to go in the URDF.
    """
    found = _joints_carrying(root, chain, chain.base_id)
    if not found or found[0].get("type") != "fixed":
        raise CalibError(
            f"on_robot: the base frame '{chain.base_frame}' is not fixed to a link of the robot "
            f"by a fixed joint (it is the root link, or a joint moves it): the instrument's "
            f"calibrated placement has nowhere to go in the URDF"
        )
    return found[0]


def tool_on_moving_joint(chain: Chain) -> bool:
    """Whether the tool frame is the link of the chain's last joint (no fixed tool joint).

    Then the calibrated URDF adds the calibrated tool (the measured frame, the markers'
    frame) as a link ``<tool>_calibrated`` fixed to it (:func:`calibrated_urdf`).
    """
    model = chain.model
    frame = model.frames[chain.tool_id]
    if frame.type == pin.FrameType.JOINT:
        return True
    return (
        frame.type == pin.FrameType.BODY
        and model.frames[frame.parentFrame].type == pin.FrameType.JOINT
    )


def urdf_tool_frame(chain: Chain) -> str:
    """The frame of the calibrated URDF that holds the calibrated tool and its markers."""
    return (
        calibrated_tool_name(chain.tool_frame) if tool_on_moving_joint(chain) else chain.tool_frame
    )


def set_origin(joint: ET.Element, T: np.ndarray) -> None:
    """Set a joint element's ``<origin xyz rpy>`` to the pose ``T`` ``(4, 4)`` (added if none)."""
    origin = joint.find("origin")
    if origin is None:
        origin = ET.Element("origin")
        origin.tail = joint.text
        joint.insert(0, origin)
    origin.set("xyz", " ".join(repr(float(v)) for v in T[:3, 3]))
    origin.set("rpy", " ".join(repr(float(v)) for v in pin.rpy.matrixToRpy(T[:3, :3])))


def read_urdf_source(chain: Chain) -> tuple[bytes, ET.Element]:
    """The URDF file's bytes and its element tree (comments and processing instructions kept)."""
    src = str(chain.urdf_path)
    try:
        raw = read_bytes_limited(chain.urdf_resolved, MAX_URDF_BYTES)
    except OSError as exc:
        raise URDFError(src, f"cannot read: {exc.strerror or exc}") from None
    return raw, parse_xml(raw, src)


def edited_joints(
    root: ET.Element, chain: Chain, moving: bool = False
) -> tuple[dict[str, ET.Element], ET.Element]:
    """The chain's joint elements by name and the tool's fixed joint.

    ``moving``: a tool link carried by the chain's last joint is allowed (a chain's URDF; a
    tree's tools need their fixed joints).
    """
    joints = {j.get("name", ""): j for j in root.findall("joint")}
    missing = [name for name in chain.joint_names if name not in joints]
    if missing:
        raise CalibError(f"{chain.urdf_path}: no <joint name='{missing[0]}'> (a chain joint)")
    tool_joint = _tool_joint(root, chain, moving)
    name = chain_joint_below(joints, chain, child_link(tool_joint))
    if name is not None:  # a tool above the chain: its origin would move the chain
        raise CalibError(
            f"the tool frame '{chain.tool_frame}' is carried by a link above joint "
            f"'{name}' in the URDF: its calibrated placement would move the chain "
            f"(use a tool link that no chain joint hangs from)"
        )
    return joints, tool_joint


def chain_joint_below(joints: dict[str, ET.Element], chain: Chain, link: str) -> str | None:
    """The first chain joint that hangs from ``link`` (``link`` above it in the URDF), or None."""
    parents = {child_link(j): parent_link(j) for j in joints.values()}
    for name in chain.joint_names:
        up, seen = parent_link(joints[name]), set()
        while up and up not in seen:
            if up == link:
                return name
            seen.add(up)
            up = parents.get(up, "")
    return None


def check_exportable(chain: Chain, moving: bool = False) -> None:
    """Raise now what :func:`calibrated_urdf` would raise about the chain's URDF.

    ``moving``: a tool link carried by the last joint is allowed (a chain's calibration).

    Raises:
        URDFError: The file cannot be read.
        CalibError: The tool frame is not carried by a fixed joint, or a joint is missing.
    """
    edited_joints(read_urdf_source(chain)[1], chain, moving)


def measurement_to_base(nominal: MDHModel, calibrated: MDHModel) -> np.ndarray:
    """Pose of the calibrated URDF's base frame in frame -1 of ``calibrated`` ``(4, 4)``.

    The calibrated URDF keeps the nominal placement of joint 1 in its base link, so the base
    part of a calibrated model (rows 0 and 1) becomes this transform:
    ``T @ FK_urdf_calibrated(q) == calibrated.forward(q)``.

    Raises:
        InvalidArgumentError: Not two MDH models of the same joints.
    """
    if not (isinstance(nominal, MDHModel) and isinstance(calibrated, MDHModel)) or not (
        np.array_equal(nominal.sigma, calibrated.sigma)
    ):
        raise InvalidArgumentError("measurement_to_base takes two MDH models of one chain")
    return frames_at_zero(calibrated)[1] @ np.linalg.inv(frames_at_zero(nominal)[1])


def _check_models(chain: Chain, nominal: MDHModel, calibrated: MDHModel) -> None:
    if not isinstance(chain, Chain):
        raise InvalidArgumentError(f"chain must be a Chain (see load_chain), got {chain!r:.60}")
    for what, model in (("nominal", nominal), ("calibrated", calibrated)):
        if not isinstance(model, MDHModel):
            raise InvalidArgumentError(f"the {what} model must be an MDHModel, got {model!r:.60}")
        if not np.array_equal(model.sigma[1:-1], chain.sigma):
            raise InvalidArgumentError(
                f"the {what} model has joints {model.sigma[1:-1].tolist()} (0 revolute, "
                f"1 prismatic), the chain {chain.sigma.tolist()}: not a model of this chain"
            )


def calibrated_urdf(
    chain: Chain,
    nominal: MDHModel,
    calibrated: MDHModel,
    *,
    tool: np.ndarray | None = None,
    markers: np.ndarray | None = None,
    world: tuple[str, np.ndarray] | None = None,
    on_robot: np.ndarray | None = None,
) -> bytes:
    """The chain's URDF file with the calibrated joint and tool placements.

    Args:
        chain: The nominal chain (its ``urdf_path`` is edited).
        nominal: The nominal MDH model of the chain (``from_chain(chain)``).
        calibrated: The calibrated model (same rows; frame -1 = the measurement frame).
        tool: Pose of the measured frame in the calibrated tool frame ``(4, 4)`` (pose data:
            the fitted marker 1 and measured-frame rotation), written into the tool's fixed
            joint so that the URDF's tool frame is the measured frame; the links fixed to
            the tool link keep their calibrated place. Default: identity.
        markers: Measured points in the written tool frame ``(K, 3)`` [m], each written as a
            fixed link ``<tool>_marker<k>`` under the tool link (default: none).
        world: ``(name, T)``: add the link ``name`` as the parent of the URDF's root link,
            ``T`` ``(4, 4)`` the pose of the base frame in it (``measurement_to_base``), so
            that forward kinematics from ``name`` gives measured coordinates.
        on_robot: The instrument is the base frame itself, on the robot (a head camera): its
            fixed joint's origin is moved by ``measurement_to_base`` ``(4, 4)`` (this
            argument), so that forward kinematics from the base frame gives measured
            coordinates (not with ``world``).

    Returns:
        The new file content (UTF-8). Loaded with the same base and tool frames, its forward
        kinematics T satisfies ``measurement_to_base(nominal, calibrated) @ T(q) ==
        calibrated.forward(q) @ tool``.

    Raises:
        InvalidArgumentError: The models are not models of the chain, or a new link's name
            is taken.
        URDFError: The original file cannot be read.
        CalibError: The tool frame is not carried by a fixed joint, or the file does not
            match the chain.
    """
    _check_models(chain, nominal, calibrated)
    X = np.eye(4) if tool is None else _array(tool, (4, 4), "tool")
    if not np.allclose(X[:3, :3] @ X[:3, :3].T, np.eye(3), atol=1e-9):
        raise InvalidArgumentError("tool must be a rigid transform (4, 4)")
    if markers is not None:
        markers = _array(markers, (-1, 3), "markers")
    if world is not None and not (
        isinstance(world, tuple) and len(world) == 2 and isinstance(world[0], str)
    ):
        raise InvalidArgumentError("world must be (link name, pose (4, 4))")
    if world is not None:
        world = (world[0], _array(world[1], (4, 4), "the world pose"))
    if on_robot is not None:
        if world is not None:
            raise InvalidArgumentError("on_robot and world: the instrument is one or the other")
        on_robot = _array(on_robot, (4, 4), "on_robot")
    raw, root = read_urdf_source(chain)
    joints, tool_joint = edited_joints(root, chain, moving=True)
    start, stop = xml_layout(raw, str(chain.urdf_path))

    poses = NominalPoses(chain)
    # T_mdh_cal(0) T_mdh_nom(0)^-1 per MDH frame: applied to a nominal pose (base frame) that
    # frame carries, it gives the calibrated pose (measurement frame).
    moved = frames_at_zero(calibrated) @ np.linalg.inv(frames_at_zero(nominal))
    links = _link_motions(chain, moved, joints)
    moving = tool_on_moving_joint(chain)
    fixed_tool = None if moving else tool_joint
    _write_path(root, chain, poses, moved, links, child_link(tool_joint), fixed_tool)
    tool_child = _write_tool(root, chain, poses, moved, links, tool_joint, X, moving)
    if markers is not None:
        add_marker_links(root, chain.tool_frame, tool_child, markers)
    if world is not None:
        add_world_link(root, world[0], world[1] @ base_to_root(chain, poses))
    if on_robot is not None:
        joint = base_joint(root, chain)
        set_origin(joint, origin_of(joint) @ np.linalg.inv(on_robot))
    return spliced(raw, root, start, stop)


def _write_tool(root, chain, poses, moved, links, tool_joint, X, moving: bool) -> str:
    """Write the calibrated tool (the measured frame ``X`` in it); the link holding it.

    The tool's fixed joint takes it; a tool link carried by the chain's last joint (``moving``)
    keeps its place and a link ``<tool>_calibrated`` fixed to it takes it.
    """
    tool_child = child_link(tool_joint)
    tool_new = moved[chain.n + 1] @ poses.link(tool_child) @ X
    if moving:
        where = links.frame[tool_child] @ poses.link(tool_child)
        held = calibrated_tool_name(chain.tool_frame)
        set_fixed_link(root, held, tool_child, np.linalg.inv(where) @ tool_new)
        return held
    parent = parent_link(tool_joint)
    where = links.frame[parent] @ poses.link(parent)
    set_origin(tool_joint, np.linalg.inv(where) @ tool_new)
    keep_tool_children(root, tool_child, X)
    return tool_child


@dataclass(frozen=True)
class _LinkMotions:
    """How calibration moves the links of a chain's bodies, at the zero configuration.

    A link's new pose (base frame of the written URDF) is ``frame[link] @ nominal pose``;
    whatever is fixed to the link's body (its fixed children, the joints of other branches,
    its visuals and inertia) moves by ``body[link]``. The two differ only for the child link
    of a joint traversed backwards: its frame is that joint's frame, which moves with the
    joint's axis, while the body carries the previous MDH frame.
    """

    frame: dict[str, np.ndarray]
    body: dict[str, np.ndarray]


def _link_motions(chain: Chain, moved: np.ndarray, joints: dict[str, ET.Element]) -> _LinkMotions:
    """The motions of the links on the chain's bodies (see :class:`_LinkMotions`).

    Body k (between chain joints k and k+1; body 0 holds the base frame, body n the tool)
    carries MDH frame k and moves by ``moved[k]``, body 0 by ``moved[1]`` (the URDF keeps
    joint 1's placement: the base part is :func:`measurement_to_base`). The child link of
    the joint of row j has that joint's frame and moves by ``moved[j]``.
    """
    model = chain.model
    bodies = [model.frames[chain.base_id].parentJoint]
    for jid, s in zip(chain.joint_ids, chain.sign, strict=True):
        bodies.append(jid if s > 0 else model.parents[jid])
    motion = {jid: moved[max(k, 1)] for k, jid in enumerate(bodies)}
    body = {
        f.name: motion[f.parentJoint]
        for f in model.frames
        if f.type == pin.FrameType.BODY and f.parentJoint in motion
    }
    frame = dict(body)
    for k, name in enumerate(chain.joint_names, start=1):
        frame[child_link(joints[name])] = moved[k]
    return _LinkMotions(frame, body)


def _write_path(
    root: ET.Element,
    chain: Chain,
    poses: NominalPoses,
    moved: np.ndarray,
    links: _LinkMotions,
    tool_link: str,
    tool_joint: ET.Element | None,
) -> None:
    """Rewrite the origins that calibration changes, except the tool joint's.

    A joint whose parent link is on the chain gets the origin that places its new frame in
    its parent's new frame: a chain joint's new frame is ``moved[row]`` applied to its
    nominal one; another joint's follows its child link (a link of the chain) or else the
    parent link's body. Origins whose parent and frame move alike are left as written, and
    so is everything under the tool link (:func:`keep_tool_children`); ``tool_joint`` is
    the tool's fixed joint (its origin is written apart), or None where the tool link is the
    last chain joint's (that joint is written like the others). The visuals,
    collisions and inertia of a link whose frame moves within its body are placed back on
    the body.
    """
    rows = {name: k for k, name in enumerate(chain.joint_names, start=1)}
    for joint in root.findall("joint"):
        parent, child, name = parent_link(joint), child_link(joint), joint.get("name", "")
        if parent not in links.frame or parent == tool_link or joint is tool_joint:
            continue
        if name in rows:
            motion = moved[rows[name]]
            nominal = poses.joint(chain.joint_ids[rows[name] - 1])
        else:
            motion = links.frame.get(child, links.body[parent])
            nominal = poses.link(parent) @ origin_of(joint)
        if np.array_equal(motion, links.frame[parent]):
            continue
        new_parent = links.frame[parent] @ poses.link(parent)
        set_origin(joint, np.linalg.inv(new_parent) @ motion @ nominal)
    for link in root.findall("link"):
        name = link.get("name", "")
        if name in links.frame and not np.array_equal(links.frame[name], links.body[name]):
            nominal = poses.link(name)
            shift = np.linalg.inv(links.frame[name] @ nominal) @ links.body[name] @ nominal
            for part in link:
                if part.tag in ("inertial", "visual", "collision"):
                    set_origin(part, shift @ origin_of(part))


def _array(value, shape: tuple[int, int], what: str) -> np.ndarray:
    """``value`` as finite numbers of ``shape`` (-1: any count), else InvalidArgumentError."""
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        a = np.zeros(0)
    ok = a.ndim == 2 and all(s in (-1, d) for s, d in zip(shape, a.shape, strict=True))
    if not ok or not np.all(np.isfinite(a)):
        raise InvalidArgumentError(f"{what} must be finite numbers of shape {shape}")
    return a


def origin_of(joint: ET.Element) -> np.ndarray:
    """A joint element's ``<origin xyz rpy>`` as a pose ``(4, 4)`` (identity if none)."""
    origin = joint.find("origin")
    T = np.eye(4)
    if origin is None:
        return T
    xyz = [float(v) for v in origin.get("xyz", "0 0 0").split()]
    rpy = [float(v) for v in origin.get("rpy", "0 0 0").split()]
    T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
    T[:3, 3] = xyz
    return T


def keep_tool_children(root: ET.Element, tool_link: str, X: np.ndarray) -> None:
    """Joints fixed to the tool link keep their place when its frame moves by ``X``."""
    if np.array_equal(X, np.eye(4)):
        return
    for joint in root.findall("joint"):
        if parent_link(joint) == tool_link:
            set_origin(joint, np.linalg.inv(X) @ origin_of(joint))


def check_base_fixed(chain: Chain) -> None:
    """Raise if the base frame moves relative to the URDF's root link (``--world-link``).

    Raises:
        CalibError: A joint lies between the root link and the base frame.
    """
    if chain.model.frames[chain.base_id].parentJoint != 0:
        raise CalibError(
            f"world_link: the base frame '{chain.base_frame}' is moved by a joint relative "
            f"to the URDF's root link: the measurement frame cannot be fixed to the root"
        )


def base_to_root(chain: Chain, poses: NominalPoses) -> np.ndarray:
    """Pose of the URDF's root link in the base frame ``(4, 4)``.

    Raises:
        CalibError: The base frame moves relative to the root link (a joint between them).
    """
    check_base_fixed(chain)
    return _homogeneous(poses.bMo)


def write_calibrated_urdf(
    path: str | Path, chain: Chain, nominal: MDHModel, calibrated: MDHModel, **links
) -> None:
    """Write :func:`calibrated_urdf` to ``path`` atomically (complete or not at all).

    ``links``: ``tool``, ``markers``, ``world`` of :func:`calibrated_urdf`.

    Raises:
        InvalidArgumentError: ``path`` is not a path, or is the nominal URDF
            (``chain.urdf_path``).
        CalibError: As :func:`calibrated_urdf`.
        OutputError: The file cannot be written (a missing directory, no permission, a full
            disk; the message names the file).
    """
    if not isinstance(path, str | os.PathLike):
        raise InvalidArgumentError(f"path must be a file path, got {path!r:.60}")
    check_outputs({"path": path}, {"the nominal URDF": chain.urdf_resolved})
    write_atomic(path, calibrated_urdf(chain, nominal, calibrated, **links))
