"""Collision-free candidates: Pinocchio's collision model of the URDF (hpp-fcl / coal).

The collision geometry (``<collision>`` elements; meshes found through example-robot-data's
package path and the URDF's folders) is attached to the chain's (or tree's) Pinocchio model.
Pairs checked: every pair of geometries that its joints move relative to each other, except

* pairs the robot's SRDF disables (``<disable_collisions>``; given, or found beside the URDF
  as example-robot-data ships them: ``../srdf/NAME.srdf``, ``NAME`` without ``_robot``);
* pairs on one link or on two adjacent links (parent and child joint), and pairs whose
  relative pose no chain joint changes (fingers of a hand, wheels of a base);
* pairs already in contact at the reference configuration (joints at zero, or at the middle
  of their limits if zero is outside them): touching covers and wheels, not a motion.

The joints off the chain (another arm, the other leg) are at their neutral positions (zero)
in the checks, or where a recorded posture has them (``readings``). Obstacles are
boxes in the chain's base frame, checked against every moving geometry. The line of sight
from an instrument to a measured point is a thin capsule, drawn where each configuration puts
the base frame (a head camera turns with the head), checked against every geometry except
those of the point's tool link and the links it carries (the marker sits on them) and, when a
joint moves the base frame, those of the body that carries it (the head around the camera).
"""

from __future__ import annotations

import contextlib
import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin

from ..core.fileio import read_bytes_limited, read_failure, read_text_limited
from ..core.words import counted
from ..exceptions import CalibError, InvalidArgumentError, URDFError
from ..kinematics.catalog import erd_robots_dir
from ..kinematics.robot import Chain
from ..kinematics.standing import JointReadings
from ..kinematics.tree import Tree
from ..kinematics.urdf_model import console_captured
from ..kinematics.urdf_xml import MAX_URDF_BYTES, parse_xml

_LOG = logging.getLogger("calib")

SIGHT_RADIUS = 1e-3
"""Radius [m] of the line of sight (a capsule from the instrument to the point)."""


@dataclass(frozen=True, eq=False)
class CollisionChecker:
    """The collision model of a chain or a tree, with the pairs to check.

    Attributes:
        robot: The chain or tree (its Pinocchio model carries the geometry).
        geometry: Collision geometry, with the active pairs.
        moving: Geometry indices that move with the robot's joints.
        tool_geometries: For each tool, the geometry indices on the tool frame's link and the
            links beyond it (a gripper's fingers): the measured point sits among them.
        notes: What was disabled, or why nothing is checked.
    """

    robot: Chain | Tree
    geometry: pin.GeometryModel
    moving: tuple[int, ...]
    tool_geometries: tuple[tuple[int, ...], ...]
    notes: tuple[str, ...]

    @property
    def pairs(self) -> int:
        """Number of pairs checked."""
        return len(self.geometry.collisionPairs)

    def _configurations(self, q: np.ndarray, readings: JointReadings | None) -> np.ndarray:
        """Pinocchio configurations ``(m, nq)``: the joints off the robot as read, or at zero.

        Raises:
            InvalidArgumentError: Readings of a tree, or readings that do not fit ``q``
                (:meth:`~calib.kinematics.standing.JointReadings.configurations`).
        """
        if readings is None:
            return self.robot.pin_configurations(q)
        if not isinstance(self.robot, Chain):
            raise InvalidArgumentError("joint readings off the chain are for a chain, not a tree")
        return readings.configurations(self.robot, q)

    def _placements(self, q: np.ndarray, readings: JointReadings | None):
        """Pinocchio data for each configuration: yields (index, base frame, geometry data).

        The base frame ``(4, 4)`` is where the configuration puts it (a head camera's).
        """
        model = self.robot.model
        data = model.createData()
        gdata = pin.GeometryData(self.geometry)
        for i, qp in enumerate(self._configurations(q, readings)):
            pin.updateGeometryPlacements(model, data, self.geometry, gdata, qp)
            yield i, pin.updateFramePlacement(model, data, self.robot.base_id).homogeneous, gdata

    def instrument_geometries(self) -> tuple[int, ...]:
        """The geometries of the body that carries the base frame, if a joint moves it.

        A head camera's head, around the camera: they do not hide its view (none for an
        instrument in the cell).
        """
        model = self.robot.model
        joint = model.frames[self.robot.base_id].parentJoint
        objects = enumerate(self.geometry.geometryObjects)
        return tuple(g for g, o in objects if joint != 0 and o.parentJoint == joint)

    def colliding(self, q: np.ndarray, readings: JointReadings | None = None) -> np.ndarray:
        """Whether each configuration ``(m, n)`` has a pair in contact ``(m,)``.

        Args:
            q: Joint positions ``(m, n)``.
            readings: Positions of joints off the chain, a row per configuration (a
                recorded posture's other arm and leg), or None: they are at zero (the
                reference configuration's).
        """
        out = np.zeros(len(np.atleast_2d(q)), dtype=bool)
        if not self.pairs:
            return out
        model = self.robot.model
        data = model.createData()
        gdata = pin.GeometryData(self.geometry)
        for i, qp in enumerate(self._configurations(q, readings)):
            out[i] = pin.computeCollisions(model, data, self.geometry, gdata, qp, True)
        return out

    def blocked(
        self,
        q: np.ndarray,
        points: np.ndarray,
        instrument: np.ndarray,
        readings: JointReadings | None = None,
    ) -> np.ndarray:
        """Whether a geometry hides a point from the instrument, per configuration ``(m,)``.

        Args:
            q: Joint positions ``(m, n)``.
            points: Measured points in the base frame ``(m, K, 3)`` [m]: on the one tool of
                a chain, or point k on tool k of a tree.
            instrument: Instrument position in the base frame ``(3,)`` [m].
            readings: Positions of joints off the chain, as :meth:`colliding` takes them.
        """
        out = np.zeros(len(points), dtype=bool)
        every = range(len(self.geometry.geometryObjects))
        own = self.instrument_geometries()
        others = [
            [g for g in every if g not in tool and g not in own] for tool in self.tool_geometries
        ]  # what may hide a point on each tool
        request, shapes = coal.CollisionRequest(), self.geometry.geometryObjects
        for i, world, gdata in self._placements(q, readings):
            src = world[:3, :3] @ instrument + world[:3, 3]
            for k, p in enumerate(points[i] @ world[:3, :3].T + world[:3, 3]):
                capsule, tf = _segment(src, p)
                if capsule is None:
                    continue
                for g in others[k if len(others) > 1 else 0]:
                    result = coal.CollisionResult()
                    placement = gdata.oMg[g]
                    other_tf = coal.Transform3s(placement.rotation, placement.translation)
                    if coal.collide(capsule, tf, shapes[g].geometry, other_tf, request, result):
                        out[i] = True
                        break
                if out[i]:
                    break
        return out


def _segment(a: np.ndarray, b: np.ndarray):
    """A thin capsule from a to b and its placement (None if the points coincide)."""
    v = b - a
    length = float(np.linalg.norm(v))
    if length < 1e-9:
        return None, None
    z = v / length
    x = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    R = np.column_stack([x, np.cross(z, x), z])
    return coal.Capsule(SIGHT_RADIUS, length), coal.Transform3s(R, (a + b) / 2)


def find_srdf(urdf: Path, robot_name: str = "") -> Path | None:
    """The SRDF example-robot-data ships for a URDF, if any (``../srdf/NAME.srdf``).

    Args:
        urdf: The URDF file.
        robot_name: Its ``<robot name>``, the SRDF's name when the file's is another
            (``talos_full_v2.urdf`` and ``talos_reduced.urdf``: ``talos.srdf``).
    """
    folder = urdf.parent.parent / "srdf"
    for stem in (urdf.stem, urdf.stem.removesuffix("_robot"), robot_name or urdf.stem):
        path = folder / f"{stem}.srdf"
        if path.is_file():
            return path
    return None


def _srdf_error(path: Path, reason: str) -> InvalidArgumentError:
    return InvalidArgumentError(f"SRDF {path}: {reason}")


def _read_srdf(path: str | Path, robot: Chain | Tree) -> tuple[str, tuple[str, ...]]:
    """An SRDF's text, read with the URDF's size limit and checked, and notes on it.

    Checked: well-formed XML whose root is ``<robot>`` (without a URDF's links), every
    ``<disable_collisions>`` with ``link1`` and ``link2``, and at least one pair naming two
    links of the robot when the file disables any (an SRDF of another robot). Pairs naming
    other links are skipped, with a note (example-robot-data's SRDFs hold some).

    Raises:
        InvalidArgumentError: One line naming the file: missing, unreadable, too large,
            empty, not XML, not an SRDF, or for another robot.
    """
    path = Path(path)
    try:
        raw = read_bytes_limited(path, MAX_URDF_BYTES)
    except OSError as exc:
        raise _srdf_error(path, read_failure(exc)) from None
    if not raw.strip():
        raise _srdf_error(path, "empty file")
    try:
        root = parse_xml(raw, str(path))
        text = raw.decode("utf-8-sig")
    except (URDFError, UnicodeDecodeError) as exc:
        reason = exc.reason if isinstance(exc, URDFError) else "not UTF-8 text"
        raise _srdf_error(path, reason) from None
    if root.tag != "robot":
        raise _srdf_error(path, f"the root element is <{root.tag}>, not an SRDF's <robot>")
    if root.find("link") is not None or root.find("joint") is not None:
        raise _srdf_error(path, "it has <link> or <joint> elements: a URDF, not an SRDF")
    pairs = [(p.get("link1"), p.get("link2")) for p in root.iter("disable_collisions")]
    if any(a is None or b is None for a, b in pairs):
        raise _srdf_error(path, "a <disable_collisions> element lacks link1 or link2")
    links = {f.name for f in robot.model.frames if f.type == pin.FrameType.BODY}
    known = sum(a in links and b in links for a, b in pairs)
    if pairs and not known:
        raise _srdf_error(
            path,
            f"none of its {len(pairs)} disabled pairs names two links of {robot.name} "
            f"(first: {pairs[0][0]}, {pairs[0][1]}): the SRDF of another robot?",
        )
    notes = (
        ()
        if known == len(pairs)
        else (
            f"{counted(len(pairs) - known, 'pairs')} of {path.name} name links not in the URDF: "
            "skipped",
        )
    )
    return text, notes


def _first_line(exc: Exception) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _package_dirs(urdf: Path) -> list[str]:
    """Folders where ``package://NAME/...`` meshes are looked for.

    Example-robot-data's, then the URDF's folders, nearest first (a ROS package's
    ``NAME/urdf/robot.urdf``: three up); Pinocchio adds ``ROS_PACKAGE_PATH``.
    """
    dirs = [str(folder) for folder in urdf.absolute().parents]
    with contextlib.suppress(CalibError):
        dirs.insert(0, str(erd_robots_dir().parent.parent))
    return dirs


NO_COLLISION = "constraints=calib.design.constraints.Constraints(collision=False)"
"""How a missing mesh's message says to skip the check (``calib design``: ``--no-collision``)."""


def _geometry(robot: Chain | Tree, self_collision: bool = True) -> pin.GeometryModel:
    """The URDF's collision geometry on the robot's model (meshes loaded).

    A missing mesh's message says how to skip the self-collision check, or, with that check
    off (the geometry loaded for the line of sight or obstacles), what needs the meshes.
    """
    path, read = robot.urdf_path, robot.urdf_resolved  # named as given, read as loaded
    try:
        text = read_text_limited(read, MAX_URDF_BYTES)
    except OSError as exc:
        raise URDFError(str(path), exc.strerror or str(exc)) from None
    with console_captured() as captured:
        try:
            geom = pin.buildGeomFromUrdfString(
                robot.model,
                _limits_completed(text, str(path)),
                pin.GeometryType.COLLISION,
                package_dirs=_package_dirs(read),
            )
        except (RuntimeError, ValueError) as exc:
            geom = exc
    if captured and captured[0].strip():
        _LOG.info("Pinocchio on %s:\n%s", path, captured[0].rstrip())
    if isinstance(geom, Exception):
        reason = _reason(geom)
        raise URDFError(
            str(path),
            reason,
            f"cannot load the collision geometry of URDF '{path}' ({reason}); its kinematics "
            "loads (show, analyze, simulate and calibrate need no mesh): check the mesh paths "
            "(package:// is looked up in the URDF's folders and ROS_PACKAGE_PATH)"
            + (
                f", or skip the collision check ({NO_COLLISION})"
                if self_collision
                else " (the line of sight and the obstacles are checked against the meshes)"
            ),
        )
    return geom


def _limits_completed(text: str, src: str) -> str:
    """The URDF with a ``<limit>`` on each revolute or prismatic joint that has none.

    Pinocchio's URDF parser refuses such a joint ("Unable to parse URDF"); calib reads it as
    a joint without usable limits, and the collision geometry does not depend on limits.
    """
    root = parse_xml(text.encode(), src)
    bare = [
        joint
        for joint in root.findall("joint")
        if joint.get("type") in ("revolute", "prismatic") and joint.find("limit") is None
    ]
    for joint in bare:
        ET.SubElement(joint, "limit", effort="0", velocity="0")
    return ET.tostring(root, encoding="unicode") if bare else text


def _reason(exc: Exception) -> str:
    """Pinocchio's message in one line: its ``message:`` line (the mesh), not the C++ file."""
    lines = [line.strip() for line in str(exc).strip().splitlines() if line.strip()]
    said = [line.removeprefix("message:").strip() for line in lines if line.startswith("message:")]
    return (said or lines or [type(exc).__name__])[0]


def _moving(robot: Chain | Tree, geom: pin.GeometryModel) -> list[int]:
    """Geometries whose joint lies on or after a joint of the chain or tree."""
    joints = set(robot.joint_ids)
    return [
        g
        for g, obj in enumerate(geom.geometryObjects)
        if joints.intersection(robot.model.supports[obj.parentJoint])
    ]


def reference_configuration(robot: Chain | Tree) -> np.ndarray:
    """Zero, or the middle of the limits for the joints whose limits exclude zero ``(n,)``."""
    inside = (robot.lower <= 0.0) & (robot.upper >= 0.0)
    return np.where(inside, 0.0, 0.5 * (robot.lower + robot.upper))


def _relative_motion(robot: Chain | Tree, a: int, b: int) -> bool:
    """Whether the robot's joints move joint a's body relative to joint b's (not adjacent).

    The path between two bodies in the tree is the symmetric difference of their supports;
    a pair whose path holds no robot joint keeps its relative pose (its state is that of the
    reference configuration), and adjacent bodies touch at their joint by construction.
    """
    model = robot.model
    if a == b or model.parents[a] == b or model.parents[b] == a:
        return False
    path = set(model.supports[a]) ^ set(model.supports[b])
    return bool(path & set(robot.joint_ids))


def _keep_pairs(robot: Chain | Tree, geom: pin.GeometryModel, srdf: Path | None) -> list[str]:
    """Active pairs: those the robot moves, minus SRDF-disabled and touching at reference."""
    model = robot.model
    srdf_text, srdf_notes = _read_srdf(srdf, robot) if srdf is not None else (None, ())
    notes = list(srdf_notes)
    joints = [o.parentJoint for o in geom.geometryObjects]
    for a in range(len(joints)):
        for b in range(a + 1, len(joints)):
            if _relative_motion(robot, joints[a], joints[b]):
                geom.addCollisionPair(pin.CollisionPair(a, b))
    before = len(geom.collisionPairs)
    if srdf is not None:
        with console_captured():
            try:
                pin.removeCollisionPairsFromXML(model, geom, srdf_text)
            except (RuntimeError, ValueError) as exc:
                raise _srdf_error(srdf, f"Pinocchio cannot read it ({_first_line(exc)})") from None
        notes.append(
            f"{counted(before - len(geom.collisionPairs), 'pairs')} disabled by {srdf.name}"
        )
    data, gdata = model.createData(), pin.GeometryData(geom)
    q0 = robot.pin_configurations(reference_configuration(robot))[0]
    pin.computeCollisions(model, data, geom, gdata, q0, False)
    touching = [  # copies: removing a pair moves the others in the vector
        pin.CollisionPair(geom.collisionPairs[k].first, geom.collisionPairs[k].second)
        for k, res in enumerate(gdata.collisionResults)
        if res.isCollision()
    ]
    for pair in touching:
        geom.removeCollisionPair(pair)
    if touching:
        notes.append(
            f"{counted(len(touching), 'pairs')} in contact at the reference configuration skipped"
        )
    return notes


def _add_obstacles(robot: Chain | Tree, geom, moving, obstacles, base: np.ndarray) -> None:
    for k, box in enumerate(obstacles):
        lo, hi = np.asarray(box[:3], dtype=float), np.asarray(box[3:], dtype=float)
        center = base[:3, :3] @ ((lo + hi) / 2) + base[:3, 3]
        placement = pin.SE3(base[:3, :3], center)
        obj = pin.GeometryObject(f"obstacle{k + 1}", 0, 0, placement, coal.Box(*(hi - lo)))
        g = geom.addGeometryObject(obj)
        for other in moving:
            geom.addCollisionPair(pin.CollisionPair(other, g))


def collision_checker(
    robot: Chain | Tree, srdf: str | Path | None = None, obstacles=(), self_collision: bool = True
) -> CollisionChecker:
    """The collision model of a chain or tree, from its URDF's ``<collision>`` geometry.

    Args:
        robot: The chain or tree.
        srdf: SRDF whose ``<disable_collisions>`` pairs are skipped (default: the one
            example-robot-data ships beside the URDF, if any).
        obstacles: Boxes ``(xmin, ymin, zmin, xmax, ymax, zmax)`` in the base frame [m].
        self_collision: Check the robot against itself; False: only against the obstacles
            (no SRDF is read).

    Returns:
        The checker; without collision geometry it checks nothing and its notes say so.

    Raises:
        URDFError: The geometry cannot be loaded (a missing mesh).
        InvalidArgumentError: A missing, unreadable or invalid SRDF (:func:`_read_srdf`) or a
            box with min > max.
    """
    for box in obstacles:
        if len(box) != 6 or not np.all(np.asarray(box[:3]) < np.asarray(box[3:])):
            raise InvalidArgumentError(
                f"an obstacle box is xmin ymin zmin xmax ymax zmax with min < max, got {box}"
            )
    if srdf is not None and self_collision:
        _read_srdf(srdf, robot)  # a bad SRDF is refused even on a URDF without geometry
    srdf_path = Path(srdf) if srdf is not None else find_srdf(robot.urdf_resolved, robot.model.name)
    geom = _geometry(robot, self_collision)
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(
        model, data, robot.pin_configurations(reference_configuration(robot))[0]
    )
    base = data.oMf[robot.base_id].homogeneous.copy()
    moving = _moving(robot, geom)
    tool = tuple(
        tuple(
            g
            for g, o in enumerate(geom.geometryObjects)
            if model.frames[t].parentJoint in model.supports[o.parentJoint]
        )
        for t in robot.tool_ids
    )
    if not geom.geometryObjects:
        notes = [f"{Path(robot.urdf_path).name} has no collision geometry: collisions not checked"]
    elif not self_collision:
        notes = ["self-collisions not checked" + (": obstacles only" if obstacles else "")]
    else:
        notes = _keep_pairs(robot, geom, srdf_path)
    _add_obstacles(robot, geom, moving, obstacles, base)
    return CollisionChecker(robot, geom, tuple(moving), tool, tuple(notes))


__all__ = [
    "NO_COLLISION",
    "CollisionChecker",
    "collision_checker",
    "find_srdf",
    "reference_configuration",
]
