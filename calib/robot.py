"""Load a robot from a URDF (a file or a catalog name) and extract a serial chain with Pinocchio."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from .catalog import catalog_entry
from .exceptions import (
    AmbiguousFrameError,
    ChainError,
    FrameNotFoundError,
    InvalidArgumentError,
    UnsupportedJointError,
    URDFError,
)

PLACEMENT_TOL = 1e-12
"""Two same-named frames closer than this [m, rotation entries] are the same place."""

DEFAULT_PRISMATIC_RANGE = 0.1
"""Half-range [m] sampled for a prismatic joint whose URDF gives no usable limits."""

_KIND_PREFIX = {
    "link": (pin.FrameType.BODY,),
    "joint": (pin.FrameType.JOINT, pin.FrameType.FIXED_JOINT),
}


def _joint_kind(shortname: str) -> str | None:
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


def _describe_joint(shortname: str) -> str:
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


@dataclass(frozen=True)
class URDFInfo:
    """What calib reads from the URDF XML itself (Pinocchio does not keep it).

    Attributes:
        root_link: Name of the root link.
        mimic_joints: Names of joints carrying a ``<mimic>`` tag.
    """

    root_link: str
    mimic_joints: frozenset[str]


def read_urdf_info(path: Path) -> URDFInfo:
    """Parse the URDF XML for what Pinocchio's model does not keep.

    Raises:
        URDFError: The file is missing or is not a well-formed URDF.
    """
    if not path.is_file():
        raise URDFError(str(path), "no such file")
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise URDFError(str(path), f"malformed XML: {exc}") from None
    if root.tag != "robot":
        raise URDFError(str(path), f"root element is <{root.tag}>, not <robot>")
    links = [e.get("name") for e in root.findall("link")]
    if not links:
        raise URDFError(str(path), "no <link> element")
    children = {c.get("link") for j in root.findall("joint") for c in j.findall("child")}
    roots = [name for name in links if name not in children]
    names = set(links)
    for j in root.findall("joint"):
        for tag in ("parent", "child"):
            e = j.find(tag)
            link = e.get("link") if e is not None else None
            if link not in names:
                raise URDFError(
                    str(path), f"joint '{j.get('name')}' names a missing {tag} link '{link}'"
                )
        axis = j.find("axis")
        if j.get("type") not in ("fixed", "floating", "planar") and axis is not None:
            try:
                xyz = [float(v) for v in axis.get("xyz", "1 0 0").split()]
            except ValueError:
                xyz = []
            if len(xyz) != 3 or not all(map(math.isfinite, xyz)) or max(map(abs, xyz)) == 0.0:
                raise URDFError(
                    str(path), f"joint '{j.get('name')}' has an invalid axis '{axis.get('xyz')}'"
                )
    mimic = frozenset(
        j.get("name", "") for j in root.findall("joint") if j.find("mimic") is not None
    )
    return URDFInfo(roots[0] if roots else links[0], mimic)


def load_model(path: str | Path) -> tuple[pin.Model, URDFInfo]:
    """Build a fixed-base Pinocchio model from a URDF file (meshes are not needed).

    Args:
        path: URDF file.

    Returns:
        The model and the URDF facts Pinocchio does not keep.

    Raises:
        URDFError: The file is missing, malformed, or Pinocchio rejects it.
    """
    path = Path(path)
    info = read_urdf_info(path)
    try:
        model = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError) as exc:
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise URDFError(str(path), reason) from None
    return model, info


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
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    first = data.oMf[ids[0]]
    same = all(
        model.frames[i].parentJoint == model.frames[ids[0]].parentJoint
        and np.allclose(data.oMf[i].homogeneous, first.homogeneous, atol=PLACEMENT_TOL, rtol=0)
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


def check_count(value, what: str, minimum: int = 1) -> int:
    """Validate an integer argument (a count or a seed).

    Raises:
        InvalidArgumentError: Not an integer, a bool, or below ``minimum``.
    """
    ok = isinstance(value, int | np.integer) and not isinstance(value, bool) and value >= minimum
    if not ok:
        raise InvalidArgumentError(f"{what} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _default_tool(model: pin.Model) -> int:
    """The frame at the tip of the deepest joint path (last such frame in model order)."""
    depth = [len(model.supports[f.parentJoint]) for f in model.frames]
    best = max(depth)
    return max(i for i, d in enumerate(depth) if d == best)


@dataclass(frozen=True, eq=False)
class Chain:
    """A serial chain between a base frame and a tool frame of a Pinocchio model.

    Joint positions are *URDF* positions, one number per chain joint (radians for revolute
    and continuous joints, metres for prismatic ones). Joints outside the chain stay at the
    reference configuration ``q_ref``; they cannot move the tool relative to the base.

    Attributes:
        name: Robot name (catalog name or URDF file stem).
        urdf_path: The URDF file.
        model: Pinocchio model (never mutated by calib).
        base_frame: Name of the base frame (frame -1).
        tool_frame: Name of the tool frame (frame n+1).
        base_id: Index of the base frame in ``model.frames``.
        tool_id: Index of the tool frame in ``model.frames``.
        joint_ids: Pinocchio joint indices of the chain, from base to tool.
        joint_names: URDF names of those joints.
        sigma: 0 for revolute, 1 for prismatic, per chain joint.
        continuous: True for joints without limits (continuous joints).
        lower: Lower sampling bound per joint [rad or m].
        upper: Upper sampling bound per joint [rad or m].
        q_ref: Pinocchio configuration of the joints outside the chain.
    """

    name: str
    urdf_path: Path
    model: pin.Model
    base_frame: str
    tool_frame: str
    base_id: int
    tool_id: int
    joint_ids: tuple[int, ...]
    joint_names: tuple[str, ...]
    sigma: np.ndarray
    continuous: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    q_ref: np.ndarray

    @property
    def n(self) -> int:
        """Number of joints in the chain."""
        return len(self.joint_ids)

    @property
    def n_revolute(self) -> int:
        """Number of revolute (and continuous) joints."""
        return int(np.sum(self.sigma == 0))

    @property
    def n_prismatic(self) -> int:
        """Number of prismatic joints."""
        return int(np.sum(self.sigma == 1))

    def check_configurations(self, q: np.ndarray) -> np.ndarray:
        """Validate and reshape joint positions to ``(m, n)``.

        Raises:
            InvalidArgumentError: Wrong shape or non-finite values.
        """
        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            q = q[None, :]
        if q.ndim != 2 or q.shape[1] != self.n:
            raise InvalidArgumentError(
                f"expected joint positions of shape (m, {self.n}), got {np.shape(q)}"
            )
        if not np.all(np.isfinite(q)):
            raise InvalidArgumentError("joint positions contain NaN or infinity")
        return q

    def pin_configurations(self, q: np.ndarray) -> np.ndarray:
        """Map URDF joint positions ``(m, n)`` to Pinocchio configurations ``(m, nq)``."""
        q = self.check_configurations(q)
        out = np.repeat(self.q_ref[None, :], len(q), axis=0)
        for k, jid in enumerate(self.joint_ids):
            joint = self.model.joints[jid]
            if joint.nq == 2:  # continuous joint: (cos, sin)
                out[:, joint.idx_q] = np.cos(q[:, k])
                out[:, joint.idx_q + 1] = np.sin(q[:, k])
            else:
                out[:, joint.idx_q] = q[:, k]
        return out

    def random_configurations(self, m: int, seed: int) -> np.ndarray:
        """Draw ``m`` configurations uniformly inside the joint limits (continuous: full turn).

        Args:
            m: Number of configurations.
            seed: Seed of the random generator.

        Returns:
            Joint positions, shape ``(m, n)`` [rad or m].
        """
        check_count(m, "the number of configurations")
        check_count(seed, "the seed", minimum=0)
        rng = np.random.default_rng(int(seed))
        return self.lower + (self.upper - self.lower) * rng.random((int(m), self.n))

    def gravity_torques(self, q: np.ndarray) -> np.ndarray:
        """Gravity torque each chain joint carries ``(m, n)`` [N m or N] (URDF masses).

        The generalized gravity of Pinocchio's model (joints outside the chain at
        ``q_ref``, gravity along -z of the URDF root); zero for a URDF without masses.
        """
        data = self.model.createData()
        idx = [self.model.joints[j].idx_v for j in self.joint_ids]
        return np.array(
            [
                pin.computeGeneralizedGravity(self.model, data, qp)[idx]
                for qp in self.pin_configurations(q)
            ]
        ).reshape(-1, self.n)

    def tool_placements(self, q: np.ndarray) -> np.ndarray:
        """Tool frame in the base frame computed by Pinocchio, shape ``(m, 4, 4)``.

        A reference implementation for tests and checks (one Pinocchio call per row).
        """
        data = self.model.createData()
        out = []
        for qp in self.pin_configurations(q):
            pin.framesForwardKinematics(self.model, data, qp)
            out.append((data.oMf[self.base_id].actInv(data.oMf[self.tool_id])).homogeneous)
        return np.array(out)

    def joint_lines(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Joint axes at the zero configuration, in the base frame.

        Returns:
            points ``(n, 3)`` [m] on each axis (the joint frame origin), unit directions
            ``(n, 3)`` such that a positive joint motion turns (or slides) along ``+u``, and the
            tool placement ``(4, 4)`` in the base frame.
        """
        model = self.model
        data = model.createData()
        q0 = self.pin_configurations(np.zeros(self.n))[0]
        pin.forwardKinematics(model, data, q0)
        pin.updateFramePlacements(model, data)
        pin.computeJointJacobians(model, data, q0)
        oMb = data.oMf[self.base_id]
        points, dirs = [], []
        for jid, s in zip(self.joint_ids, self.sigma, strict=True):
            J = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.LOCAL)
            col = np.reshape(J, (6, -1))[:, model.joints[jid].idx_v]
            local = col[:3] if s == 1 else col[3:]
            bMj = oMb.actInv(data.oMi[jid])
            u = bMj.rotation @ local
            points.append(bMj.translation.copy())
            dirs.append(u / np.linalg.norm(u))
        tool = oMb.actInv(data.oMf[self.tool_id]).homogeneous
        return np.array(points).reshape(-1, 3), np.array(dirs).reshape(-1, 3), tool


def _frozen(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def _chain_from_model(
    name: str, path: Path, model: pin.Model, info: URDFInfo, base: str | None, tool: str | None
) -> Chain:
    for option, frame in (("base", base), ("tool", tool)):
        if frame is not None and not frame.strip():
            raise InvalidArgumentError(f"the {option} frame name is empty")
    base_id = resolve_frame(model, base) if base else resolve_frame(model, info.root_link)
    tool_id = resolve_frame(model, tool) if tool else _default_tool(model)
    base_name, tool_name = model.frames[base_id].name, model.frames[tool_id].name
    jb, jt = model.frames[base_id].parentJoint, model.frames[tool_id].parentJoint
    support = list(model.supports[jt])
    if jb not in support:
        if jt in model.supports[jb]:
            raise ChainError(
                f"tool frame '{tool_name}' is between the root and base frame '{base_name}': "
                f"swap --base and --tool"
            )
        raise ChainError(
            f"frames '{base_name}' and '{tool_name}' are not on one serial chain "
            f"(neither is an ancestor of the other)"
        )
    joint_ids = tuple(support[support.index(jb) + 1 :])
    if not joint_ids:
        raise ChainError(f"no joint between base frame '{base_name}' and tool frame '{tool_name}'")
    sigma, cont, lower, upper = [], [], [], []
    for jid in joint_ids:
        joint, jname = model.joints[jid], model.names[jid]
        short = joint.shortname()
        kind = _joint_kind(short)
        if kind is None or joint.nv != 1:
            raise UnsupportedJointError(jname, _describe_joint(short))
        if jname in info.mimic_joints:
            raise UnsupportedJointError(jname, "a mimic joint")
        sigma.append(1 if kind == "prismatic" else 0)
        unbounded = joint.nq == 2
        lo = -math.pi if unbounded else float(model.lowerPositionLimit[joint.idx_q])
        hi = math.pi if unbounded else float(model.upperPositionLimit[joint.idx_q])
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            half = DEFAULT_PRISMATIC_RANGE if kind == "prismatic" else math.pi
            lo, hi = -half, half
        cont.append(unbounded)
        lower.append(lo)
        upper.append(hi)
    return Chain(
        name=name,
        urdf_path=path,
        model=model,
        base_frame=base_name,
        tool_frame=tool_name,
        base_id=base_id,
        tool_id=tool_id,
        joint_ids=joint_ids,
        joint_names=tuple(model.names[j] for j in joint_ids),
        sigma=_frozen(np.array(sigma, dtype=int)),
        continuous=_frozen(np.array(cont, dtype=bool)),
        lower=_frozen(np.array(lower)),
        upper=_frozen(np.array(upper)),
        q_ref=_frozen(pin.neutral(model)),
    )


def load_chain(robot: str | Path, base: str | None = None, tool: str | None = None) -> Chain:
    """Load a serial chain from a catalog name or a URDF path.

    Args:
        robot: Catalog name (``ur5``) or path to a URDF file.
        base: Base frame; default: the catalog's, or the URDF root link.
        tool: Tool frame; default: the catalog's, or the tip of the deepest branch.

    Returns:
        The chain.

    Raises:
        CalibError: Unknown robot, bad URDF, unknown or ambiguous frame, no serial chain,
            unsupported joint in the chain.
    """
    text = str(robot)
    path = Path(text)
    if isinstance(robot, Path) or path.is_file() or text.endswith((".urdf", ".xml")) or "/" in text:
        model, info = load_model(path)
        return _chain_from_model(path.stem, path, model, info, base, tool)
    entry = catalog_entry(text)
    model, info = load_model(entry.path)
    return _chain_from_model(
        entry.name,
        entry.path,
        model,
        info,
        entry.base if base is None else base,
        entry.tool if tool is None else tool,
    )
