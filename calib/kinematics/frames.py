"""Joints and frames of a Pinocchio model: joint kinds, placements, frame lookup, joint paths.

What loading a chain (:mod:`.robot`) and its users need from the model itself, with
Pinocchio's joint models and without ``pin.Data``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping

import numpy as np
import pinocchio as pin

from ..exceptions import (
    AmbiguousFrameError,
    FrameNotFoundError,
    InvalidArgumentError,
)

__all__ = [
    "DEFAULT_PRISMATIC_RANGE",
    "PLACEMENT_TOL",
    "beyond_ends",
    "default_tool",
    "describe_joint",
    "end_joint_links",
    "finger_joints",
    "frame_placement",
    "joint_kind",
    "joint_placements",
    "motion_axis",
    "path_joints",
    "resolve_frame",
    "sampling_bounds",
    "urdf_limits",
]


PLACEMENT_TOL = 1e-12
"""Two same-named frames closer than this [m, rotation entries] are the same place."""


DEFAULT_PRISMATIC_RANGE = 0.1
"""Half-range [m] sampled for a prismatic joint whose URDF gives no usable limits."""


_KIND_PREFIX = {
    "link": (pin.FrameType.BODY,),
    "joint": (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT),
}


def joint_kind(shortname: str) -> str | None:
    """'revolute', 'prismatic' or None for a Pinocchio joint model short name."""
    if shortname.startswith("JointModelRevoluteUnaligned") or shortname.startswith(
        "JointModelRevoluteUnboundedUnaligned"
    ):
        return "revolute"
    if shortname.startswith("JointModelPrismaticUnaligned"):
        return "prismatic"
    if shortname in ("JointModelRX", "JointModelRY", "JointModelRZ") or shortname.startswith(
        "JointModelRUB"
    ):
        return "revolute"
    if shortname in ("JointModelPX", "JointModelPY", "JointModelPZ"):
        return "prismatic"
    return None


def describe_joint(shortname: str) -> str:
    """How an error names a joint of this Pinocchio type (``a planar joint``)."""
    names = {
        "JointModelPlanar": "a planar joint",
        "JointModelFreeFlyer": "a floating joint",
        "JointModelSpherical": "a spherical joint",
        "JointModelSphericalZYX": "a spherical joint",
        "JointModelTranslation": "a 3-DOF translation joint",
        "JointModelComposite": "a composite joint",
    }
    if shortname.startswith("JointModelHelical"):
        return "a helical joint"
    return names.get(shortname, f"of unsupported type {shortname}")


def joint_placements(
    model: pin.Model, q: np.ndarray, last: int | tuple[int, ...] | None = None
) -> dict:
    """Placements ``oMi`` of the joints at a Pinocchio configuration, without ``pin.Data``.

    ``pin.Data`` holds tensors whose size grows as the cube of the number of joints (1.8 GB
    for 300 joints): calib walks the tree itself, with Pinocchio's joint models.

    Args:
        model: Pinocchio model.
        q: Configuration ``(nq,)``.
        last: Only this joint (or these joints) and its ancestors (default: every joint).

    Returns:
        ``pin.SE3`` placement in the world by joint index.
    """
    if last is None:
        joints: list[int] | range = range(1, model.njoints)
    elif isinstance(last, tuple):  # Pinocchio numbers a parent before its children
        joints = sorted({j for one in last for j in _ancestors(model, one)} - {0})
    else:
        joints = _ancestors(model, last)[1:]
    at, neutral = np.asarray(q, dtype=float).tolist(), pin.neutral(model).tolist()
    out = {0: pin.SE3.Identity()}
    kinds, parents, placements = model.joints, model.parents, model.jointPlacements
    for jid in joints:
        joint = kinds[jid]
        span = slice(joint.idx_q, joint.idx_q + joint.nq)
        motion = pin.SE3.Identity()
        if at[span] != neutral[span]:  # as floats: np.array_equal's test
            motion = _joint_motion(model.names[jid], joint, q[span])
        out[jid] = out[parents[jid]] * placements[jid] * motion
    return out


def _ancestors(model: pin.Model, jid: int) -> list[int]:
    """``model.supports[jid]``: the joint's ancestors from the universe (0), then itself."""
    chain = [jid]
    parents = model.parents
    while chain[-1]:
        chain.append(parents[chain[-1]])
    return chain[::-1]


_ALONG_AXIS = {
    **{f"JointModelP{a}": k for k, a in enumerate("XYZ")},
    **{f"JointModelR{a}": 3 + k for k, a in enumerate("XYZ")},
    **{f"JointModelRUB{a}": 3 + k for k, a in enumerate("XYZ")},
}
"""The joints along an axis of their frame: the entry of their motion subspace that is 1."""


def motion_axis(joint) -> np.ndarray:
    """Motion subspace ``(6,)`` (linear, angular) of a 1-DOF joint model, in its own frame.

    A joint along an axis of its frame (a unit vector: the one Pinocchio's ``calc`` gives) is
    read from its name, any other computed by Pinocchio.
    """
    k = _ALONG_AXIS.get(joint.shortname())
    if k is not None:
        S = np.zeros(6)
        S[k] = 1.0
        return S
    jdata = joint.createData()
    q = np.zeros(joint.nq)
    q[0] = 1.0 if joint.nq == 2 else 0.0  # continuous joints: (cos, sin) = (1, 0)
    joint.calc(jdata, q)
    return np.reshape(np.array(jdata.S), (6, -1))[:, 0]


def _joint_motion(name: str, joint, qj: np.ndarray) -> pin.SE3:
    """Transform of a revolute, continuous or prismatic joint at its position ``qj``."""
    if joint_kind(joint.shortname()) is None or joint.nv != 1:
        raise InvalidArgumentError(f"joint '{name}' ({joint.shortname()}) can only stay neutral")
    value = math.atan2(qj[1], qj[0]) if joint.nq == 2 else float(qj[0])
    return pin.exp6(pin.Motion(motion_axis(joint) * value))


def frame_placement(model: pin.Model, oMi: dict, fid: int) -> pin.SE3:
    """Placement of frame ``fid`` in the world, from :func:`joint_placements`."""
    frame = model.frames[fid]
    return oMi[frame.parentJoint] * frame.placement


def resolve_frame(model: pin.Model, name: str) -> int:
    """Find a frame by name; ``link:NAME`` or ``joint:NAME`` pick a kind.

    Frames that share a name but sit at the same place on the same body (a link and the
    fixed joint that carries it) are one frame; otherwise the name is ambiguous.

    Args:
        model: Pinocchio model.
        name: Frame name, optionally prefixed by ``link:`` or ``joint:``.

    Returns:
        Index of the frame in ``model.frames``.

    Raises:
        FrameNotFoundError: No frame has that name.
        AmbiguousFrameError: Several frames of that name are at different places.
    """
    kinds = None
    bare = name
    prefix, sep, rest = name.partition(":")
    if sep and prefix in _KIND_PREFIX:
        kinds, bare = _KIND_PREFIX[prefix], rest
    ids = [
        i
        for i, f in enumerate(model.frames)
        if f.name == bare and (kinds is None or f.type in kinds)
    ]
    if not ids:
        raise FrameNotFoundError(
            name, [f.name for f in model.frames if f.name != "universe"], ranked_as=bare
        )
    if len(ids) == 1:
        return ids[0]
    oMi = joint_placements(model, pin.neutral(model))
    first = frame_placement(model, oMi, ids[0])
    same = all(
        model.frames[i].parentJoint == model.frames[ids[0]].parentJoint
        and np.allclose(
            frame_placement(model, oMi, i).homogeneous,
            first.homogeneous,
            atol=PLACEMENT_TOL,
            rtol=0,
        )
        for i in ids
    )
    if same:
        bodies = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
        return bodies[0] if bodies else ids[0]
    found = []
    for i in ids:
        kind = "link" if model.frames[i].type == pin.FrameType.BODY else "joint"
        if kind not in found:
            found.append(kind)
    raise AmbiguousFrameError(bare, found)


_MARKER_LINK = re.compile(r"(?P<tool>.+)_marker\d+(_joint)?")
"""Names of the marker links (and their joints) a calibrated URDF adds under its tool."""


def _calib_marker(model: pin.Model, frame) -> bool:
    """True for a marker link calib wrote (``<tool>_markerK``) or its joint, on its tool."""
    match = _MARKER_LINK.fullmatch(frame.name)
    if match is None or not model.existFrame(match["tool"]):
        return False
    return model.frames[model.getFrameId(match["tool"])].parentJoint == frame.parentJoint


def finger_joints(model: pin.Model, mimics: Mapping[str, str]) -> frozenset[int]:
    """The joints of the fingers of a gripper whose fingers are coupled by ``<mimic>`` tags.

    ``mimics``: each joint with a ``<mimic>`` tag and the joint the tag names. Fingers: two
    or more revolute or prismatic joints hanging on one body (links fixed together) that
    follow one joint, the end of their ``<mimic>`` tags (one of them may be that joint),
    with no revolute or prismatic joint beyond them that does not follow it too (a finger's
    tip joint may). A linkage coupled by ``<mimic>`` tags that carries further joints (an
    arm's parallelogram) is no gripper; fingers without ``<mimic>`` tags are not told apart.
    """
    moving = [j for j in range(1, model.njoints) if joint_kind(model.joints[j].shortname())]
    follows = {j: _tags_end(mimics, model.names[j]) for j in moving}
    hanging: dict[tuple[int, str], list[int]] = {}
    for j in moving:
        hanging.setdefault((model.parents[j], follows[j]), []).append(j)
    fingers: set[int] = set()
    for (_, end), joints in hanging.items():
        beyond = (k for k in moving if not set(joints).isdisjoint(model.supports[k]))
        if len(joints) > 1 and all(follows[k] == end for k in beyond):
            fingers.update(joints)
    return frozenset(fingers)


def _tags_end(mimics: Mapping[str, str], name: str) -> str:
    """The joint at the end of a joint's ``<mimic>`` tags (itself without one; cycles stop)."""
    seen = {name}
    while (name := mimics.get(name, name)) not in seen:
        seen.add(name)
    return name


def default_tool(model: pin.Model, mimics: Mapping[str, str] | None = None) -> int:
    """The frame at the tip of the deepest joint path (last such frame in model order).

    Passed over:

    - the marker links of a calibrated URDF (``<tool>_markerK``, fixed under its tool): the
      calibrated URDF keeps the tool its nominal URDF has by default;
    - the frames beyond the fingers of a gripper (:func:`finger_joints` of ``mimics``, each
      joint with a ``<mimic>`` tag and the joint it names), unless nothing but the fingers
      moves: where no other branch is deeper, the default is then the link that carries the
      fingers or a frame fixed on it, the one last in model order (a hand's TCP frame).
    """
    depth = [len(model.supports[f.parentJoint]) for f in model.frames]
    fingers = finger_joints(model, mimics or {})
    kept = [
        i
        for i, f in enumerate(model.frames)
        if fingers.isdisjoint(model.supports[f.parentJoint]) and not _calib_marker(model, f)
    ]
    if max(depth[i] for i in kept) == 1:  # nothing moves but the fingers: keep them
        kept = [i for i, f in enumerate(model.frames) if not _calib_marker(model, f)]
    best = max(depth[i] for i in kept)
    return max(i for i in kept if depth[i] == best)


def path_joints(model: pin.Model, jb: int, jt: int) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The joints between two joints' bodies, in order, and their signs.

    Args:
        model: Pinocchio model.
        jb: The joint whose body holds the base frame.
        jt: The joint whose body holds the tool frame.

    Returns:
        The joints from ``jb`` up to (not including) the common ancestor, each traversed
        backwards (sign -1), then those from the common ancestor down to ``jt`` (sign +1).
    """
    up, down = list(model.supports[jb]), list(model.supports[jt])
    common = 0
    while common < min(len(up), len(down)) and up[common] == down[common]:
        common += 1
    backwards = tuple(reversed(up[common:]))
    forwards = tuple(down[common:])
    return backwards + forwards, (-1,) * len(backwards) + (1,) * len(forwards)


def end_joint_links(
    model: pin.Model, names: tuple[str, ...], sign, ends: tuple[str, str]
) -> dict[str, tuple[str, str]]:
    """The frames a chain's end joints move, and the links beyond those joints.

    ``{joint: (end frame, link)}`` for the first joint (``ends[0]``, the base frame) and the
    last (``ends[1]``, the tool frame) of a chain of joints ``names`` and ``sign``
    (:func:`path_joints`): a frame given at that end but fixed to ``link`` does not move with
    the joint (a joint too many in its chain). A one-joint chain: its base end only.
    """
    out: dict[str, tuple[str, str]] = {}
    if not names:
        return out
    for k, end, toward in ((0, ends[0], -1), (-1, ends[1], 1)):
        frame = model.getFrameId(names[k], pin.FrameType.JOINT)
        below = [f.name for f in model.frames if f.parentFrame == frame]  # the child link's
        parent = model.frames[model.frames[frame].parentFrame].name
        out.setdefault(names[k], (end, parent if sign[k] == toward else below[0]))
    return out


def beyond_ends(model: pin.Model, joints, ends: tuple[int, int]) -> dict[str, tuple[int, str]]:
    """The joints one step beyond a chain's ends, and the links they move.

    ``{joint: (end, link)}``: each 1-DOF joint off the chain (``joints``: its Pinocchio
    indices) whose parent or child is the body of an end frame (``ends``: the base and tool
    frames' indices in ``model.frames``; ``end`` 0 or 1), and the link on its far side from
    that end. A frame given at that end but fixed to ``link`` misses that joint (a joint left
    out of its chain).
    """
    out: dict[str, tuple[int, str]] = {}
    for k, fid in enumerate(ends):
        body = model.frames[fid].parentJoint
        for jid in range(1, model.njoints):
            kind = joint_kind(model.joints[jid].shortname())
            if jid in joints or kind is None or body not in (jid, model.parents[jid]):
                continue
            frame = model.getFrameId(model.names[jid], pin.FrameType.JOINT)
            if jid == body:  # the end's body hangs on it: its parent's link
                link = model.frames[model.frames[frame].parentFrame].name
            else:
                below = (f for f in model.frames if f.parentFrame == frame)
                link = next(f.name for f in below if f.type == pin.FrameType.BODY)
            out.setdefault(model.names[jid], (k, link))
    return out


def urdf_limits(model: pin.Model, jid: int) -> tuple[float, float] | None:
    """A 1-DOF joint's URDF limits [rad or m], None for a continuous one or unusable limits."""
    joint = model.joints[jid]
    if joint.nq == 2:  # continuous
        return None
    lo = float(model.lowerPositionLimit[joint.idx_q])
    hi = float(model.upperPositionLimit[joint.idx_q])
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        return None
    return lo, hi


def sampling_bounds(model: pin.Model, jid: int) -> tuple[float, float]:
    """Sampling bounds of a 1-DOF joint [rad or m]: its limits, else a default range."""
    limits = urdf_limits(model, jid)
    if limits is not None:
        return limits
    prismatic = joint_kind(model.joints[jid].shortname()) == "prismatic"
    half = DEFAULT_PRISMATIC_RANGE if prismatic else math.pi
    return -half, half
