"""Independent references for the tests: Pinocchio look-ups and draws made without calib."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin


def pin_frame(model: pin.Model, name: str) -> int:
    """Frame id by name: the BODY (link) frame when there is one, as the catalog says."""
    bare = name.split(":", 1)[1] if name.startswith(("link:", "joint:")) else name
    ids = [i for i, f in enumerate(model.frames) if f.name == bare]
    assert ids, f"no frame {bare} in the Pinocchio model"
    bodies = [i for i in ids if model.frames[i].type == pin.FrameType.BODY]
    return bodies[0] if bodies else ids[0]


def pin_config(model: pin.Model, joint_ids, q: np.ndarray, q_full: np.ndarray | None = None):
    """Pinocchio configuration with URDF positions q on the given joints."""
    out = pin.neutral(model) if q_full is None else q_full.copy()
    for jid, qk in zip(joint_ids, q, strict=True):
        joint = model.joints[jid]
        if joint.nq == 2:
            out[joint.idx_q : joint.idx_q + 2] = (math.cos(qk), math.sin(qk))
        else:
            out[joint.idx_q] = qk
    return out


def rot(axis: str, a: float) -> np.ndarray:
    """Homogeneous rotation about x, y or z by a [rad]."""
    c, s = math.cos(a), math.sin(a)
    T = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def trans(axis: str, v: float) -> np.ndarray:
    """Homogeneous translation along x, y or z by v [m]."""
    T = np.eye(4)
    T["xyz".index(axis), 3] = v
    return T


def own_random_q(sigma, m: int, seed: int) -> np.ndarray:
    """Configurations drawn by the test, not by calib (wider than most joint limits)."""
    rng = np.random.default_rng(seed)
    sigma = np.asarray(sigma)
    q = rng.uniform(-math.pi, math.pi, (m, len(sigma)))
    q[:, sigma == 1] = rng.uniform(-0.3, 0.3, (m, int(np.sum(sigma == 1))))
    return q


def rigid_error_columns(frames, E: np.ndarray) -> np.ndarray:
    """Pose-error columns ``(6, 6 len(frames))`` of a 6-DOF error at each frame, seen at point E.

    For every frame (a pin.SE3 in the base frame) and each of its axes a: a translation along a
    ([a; 0]) and a rotation about a through the frame's origin ([a x (E - o); a]).
    """
    cols = []
    for F in frames:
        for i in range(3):
            a = F.rotation[:, i]
            cols.append(np.hstack([a, np.zeros(3)]))
            cols.append(np.hstack([np.cross(a, E - F.translation), a]))
    return np.array(cols).T


def file_chain_poses(path, base: str, tool: str, q: np.ndarray):
    """Pinocchio reads a URDF file itself and poses the chain between two frames.

    Yields, per row of ``q`` (URDF positions of the chain joints), the base placement
    ``bMo`` (world to base), the tool placement in the base, and the chain joints' placements
    in the base (pin.SE3).
    """
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    b, t = pin_frame(model, base), pin_frame(model, tool)
    jb, jt = model.frames[b].parentJoint, model.frames[t].parentJoint
    support = list(model.supports[jt])
    joints = support[support.index(jb) + 1 :]
    for qi in q:
        pin.framesForwardKinematics(model, data, pin_config(model, joints, qi))
        bMo = data.oMf[b].inverse()
        yield bMo, bMo * data.oMf[t], [bMo * data.oMi[j] for j in joints]


# --------------------------------------------------------------------------------------
# Trees: Pinocchio alone, from the URDF file or from a model built joint by joint
# --------------------------------------------------------------------------------------


class PinTree:
    """A tree of a Pinocchio model: a base frame, tool frames and the joints between.

    The joints are those Pinocchio's own ``supports`` put between the base frame's joint and
    each tool's joint; positions are URDF positions given by joint name.
    """

    def __init__(self, model: pin.Model, base: int, tools: list[int]):
        self.model, self.base, self.tools = model, base, list(tools)
        self.data = model.createData()
        jb = model.frames[base].parentJoint
        joints = set()
        for t in self.tools:
            support = list(model.supports[model.frames[t].parentJoint])
            assert jb in support, "a tool below the base"
            joints.update(support[support.index(jb) + 1 :])
        self.joint_ids = sorted(joints)
        self.joint_names = [model.names[j] for j in self.joint_ids]

    @staticmethod
    def of_file(path, base: str, tools) -> PinTree:
        """Pinocchio reads the URDF file itself."""
        model = pin.buildModelFromUrdf(str(path))
        return PinTree(model, pin_frame(model, base), [pin_frame(model, t) for t in tools])

    def _poses(self, qp: np.ndarray) -> list[pin.SE3]:
        pin.framesForwardKinematics(self.model, self.data, qp)
        bMo = self.data.oMf[self.base].inverse()
        return [bMo * self.data.oMf[t] for t in self.tools]

    def configs(self, names, q: np.ndarray) -> list[np.ndarray]:
        """Pinocchio configurations with URDF positions q (columns named by ``names``)."""
        ids = [self.model.getJointId(n) for n in names]
        return [pin_config(self.model, ids, qi) for qi in np.atleast_2d(q)]

    def poses(self, names, q: np.ndarray) -> np.ndarray:
        """Every tool in the base frame, ``(m, T, 4, 4)``."""
        return np.array([[T.homogeneous for T in self._poses(qp)] for qp in self.configs(names, q)])

    def _perturbable(self):
        """(getter, setter) of every placement a generic 6-DOF error can act on."""
        model = self.model
        out = []
        for j in self.joint_ids:

            def set_joint(M, j=j):
                model.jointPlacements[j] = M

            out.append((lambda j=j: model.jointPlacements[j].copy(), set_joint))
        for f in [self.base, *self.tools]:

            def set_frame(M, f=f):
                frame = model.frames[f]
                frame.placement = M
                model.frames[f] = frame

            out.append((lambda f=f: model.frames[f].placement.copy(), set_frame))
        return out

    def placement_jacobian(self, names, q, marker=(0.0, 0.0, 0.0), eps: float = 1e-6):
        """Finite differences of the tools' poses under a generic 6-DOF error on every joint
        placement, every tool frame placement and the base frame placement.

        Rows per (configuration, tool): the velocity of the marker point (x, y, z) and the
        rotation (rx, ry, rz), in the base frame; columns: 6 per placement.
        """
        point = np.append(np.asarray(marker, dtype=float), 1.0)
        qps = self.configs(names, q)

        def poses() -> np.ndarray:
            return np.array([[T.homogeneous for T in self._poses(qp)] for qp in qps])

        cols = []
        for get, put in self._perturbable():
            nominal = get()
            for i in range(6):
                xi = np.zeros(6)
                xi[i] = eps
                put(nominal * pin.exp6(pin.Motion(xi)))
                a = poses()
                put(nominal * pin.exp6(pin.Motion(-xi)))
                b = poses()
                put(nominal)
                dp = (a - b) @ point
                # a small rotation R_a R_b^T = I + [w]x: w from its skew part
                S = a[..., :3, :3] @ np.swapaxes(b[..., :3, :3], -1, -2)
                w = 0.5 * np.stack(
                    [
                        S[..., 2, 1] - S[..., 1, 2],
                        S[..., 0, 2] - S[..., 2, 0],
                        S[..., 1, 0] - S[..., 0, 1],
                    ],
                    axis=-1,
                )
                cols.append(np.concatenate([dp[..., :3], w], axis=-1).ravel() / (2 * eps))
        return np.array(cols).T

    def complete_rank(self, names, q, rows=(0, 1, 2, 3, 4, 5), marker=(0.0, 0.0, 0.0)) -> int:
        """Rank of :meth:`placement_jacobian` restricted to some rows (SVD, 1e-7 relative)."""
        W = self.placement_jacobian(names, q, marker)
        keep = np.concatenate([6 * k + np.array(rows) for k in range(W.shape[0] // 6)])
        s = np.linalg.svd(W[keep], compute_uv=False)
        return int(np.sum(s > 1e-7 * s[0]))


def urdf_links(path, joint: str) -> set[str]:
    """The parent and child links of a joint, read from a URDF's XML."""
    root = ET.parse(str(path)).getroot()
    (j,) = [e for e in root.findall("joint") if e.get("name") == joint]
    return {j.find("parent").get("link"), j.find("child").get("link")}


def mimic_tags(root: ET.Element) -> dict[str, tuple[str, float, float]]:
    """The URDF's mimic tags, read here: joint -> (leader, multiplier, offset)."""
    tags = {}
    for joint in root.iter("joint"):
        tag = joint.find("mimic")
        if tag is not None:
            tags[joint.get("name")] = (
                tag.get("joint").strip(),
                float(tag.get("multiplier", "1")),
                float(tag.get("offset", "0")),
            )
    return tags


class MimicChain:
    """A chain of a URDF with ``<mimic>`` tags, posed by the test from its independent joints.

    ``pin_mimic=True``: Pinocchio's own mimic joints (``buildModelFromUrdf(mimic=True)``),
    which need each master before its mimic joints in the file. Otherwise Pinocchio's model
    without the tags, and the test applies the relation itself: it reads the tags with
    ElementTree and sets each mimic joint to ``multiplier * q_master + offset``.
    """

    def __init__(self, path, base: str, tool: str, pin_mimic: bool = False):
        self.model = pin.buildModelFromUrdf(str(path), mimic=pin_mimic)
        self.data = self.model.createData()
        self.base, self.tool = pin_frame(self.model, base), pin_frame(self.model, tool)
        jb = self.model.frames[self.base].parentJoint
        support = list(self.model.supports[self.model.frames[self.tool].parentJoint])
        self.joints = support[support.index(jb) + 1 :]
        self.tags = {} if pin_mimic else mimic_tags(ET.parse(str(path)).getroot())

    def _master(self, name: str) -> str:
        while name in self.tags:
            name = self.tags[name][0]
        return name

    @property
    def variables(self) -> set[str]:
        """Names of the independent joints that move the chain (masters included)."""
        if not self.tags:
            pairs = zip(self.model.mimicking_joints, self.model.mimicked_joints, strict=True)
            mimic = dict(pairs)
            return {self.model.names[mimic.get(j, j)] for j in self.joints}
        return {self._master(self.model.names[j]) for j in self.joints}

    def config(self, names, values) -> np.ndarray:
        """Pinocchio configuration with the named independent joints at ``values``."""
        given = dict(zip(names, values, strict=True))

        def value(name: str) -> float:
            if name in given:
                return given[name]
            master, factor, offset = self.tags[name]
            return factor * value(master) + offset

        q = pin.neutral(self.model)
        for jid in range(1, self.model.njoints):
            name = self.model.names[jid]
            joint = self.model.joints[jid]
            if joint.nq == 0 or (name not in given and self._master(name) not in given):
                continue
            v = value(name)
            if joint.nq == 2:
                q[joint.idx_q : joint.idx_q + 2] = (math.cos(v), math.sin(v))
            else:
                q[joint.idx_q] = v
        return q

    def pose(self, q: np.ndarray) -> pin.SE3:
        """Tool frame in the base frame."""
        pin.forwardKinematics(self.model, self.data, q)
        b = pin.updateFramePlacement(self.model, self.data, self.base)
        return b.actInv(pin.updateFramePlacement(self.model, self.data, self.tool))

    def _placement(self, kind: str, i: int) -> pin.SE3:
        if kind == "joint":
            return self.model.jointPlacements[i].copy()
        return self.model.frames[i].placement.copy()

    def _place(self, kind: str, i: int, placement: pin.SE3) -> None:
        if kind == "joint":
            self.model.jointPlacements[i] = placement
        else:
            frame = self.model.frames[i]
            frame.placement = placement
            self.model.frames[i] = frame

    def error_rank(self, configs, rows, h: float = 1e-6, rtol: float = 1e-8):
        """Rank of a generic 6-DOF error on every chain joint placement, the base and the tool.

        Central finite differences of the tool pose (position, rotation vector, in the base
        frame) over ``configs`` (Pinocchio configurations); ``rows`` picks among
        (x, y, z, rx, ry, rz). Returns the rank and the singular values.
        """
        places = [("joint", j) for j in self.joints]
        places += [("frame", self.base), ("frame", self.tool)]
        cols = []
        for kind, i in places:
            nominal = self._placement(kind, i)
            for a in range(6):
                diffs = []
                for sign in (1.0, -1.0):
                    step = np.zeros(6)
                    step[a] = sign * h
                    self._place(kind, i, nominal * pin.exp6(pin.Motion(step)))
                    diffs.append([self.pose(q) for q in configs])
                self._place(kind, i, nominal)
                col = [
                    np.hstack([p.translation - n.translation, pin.log3(p.rotation @ n.rotation.T)])
                    / (2 * h)
                    for p, n in zip(*diffs, strict=True)
                ]
                cols.append(np.array(col)[:, list(rows)].ravel())
        s = np.linalg.svd(np.array(cols).T, compute_uv=False)
        return int(np.sum(s > rtol * s[0])), s


def pair_collides(urdf, package_dir: str, joint_names, q, links) -> bool:
    """Pinocchio alone, on the original URDF: do two links' collision meshes touch?

    Args:
        urdf: The URDF file.
        package_dir: Where its ``package://`` meshes are found.
        joint_names: URDF joints set to ``q`` (the others at Pinocchio's neutral).
        q: Their positions [rad or m].
        links: The two links (their first collision geometry, ``<link>_0``).
    """
    model = pin.buildModelFromUrdf(str(urdf))
    geom = pin.buildGeomFromUrdf(
        model, str(urdf), pin.GeometryType.COLLISION, package_dirs=[package_dir]
    )
    names = [g.name for g in geom.geometryObjects]
    geom.addCollisionPair(pin.CollisionPair(*(names.index(f"{n}_0") for n in links)))
    full = pin.neutral(model)
    for name, v in zip(joint_names, q, strict=True):
        full[model.joints[model.getJointId(name)].idx_q] = v
    data, gdata = model.createData(), pin.GeometryData(geom)
    pin.updateGeometryPlacements(model, data, geom, gdata, full)
    return pin.computeCollision(geom, gdata, 0)


class MimicTree(PinTree):
    """A tree of a URDF with ``<mimic>`` tags, posed by the test from its independent joints.

    Pinocchio's model without the tags (``buildModelFromUrdf``); the test reads the tags with
    ElementTree and sets every mimic joint to ``multiplier * q_leader + offset``, the leader's
    own position computed first when it mimics another joint in turn.
    """

    def __init__(self, path, base: str, tools):
        model = pin.buildModelFromUrdf(str(path))
        super().__init__(model, pin_frame(model, base), [pin_frame(model, t) for t in tools])
        root = ET.parse(str(path)).getroot()
        self.tags, self.axes = mimic_tags(root), {}
        for joint in root.iter("joint"):
            axis = joint.find("axis")
            xyz = "1 0 0" if axis is None else axis.get("xyz", "1 0 0")
            self.axes[joint.get("name")] = np.array([float(v) for v in xyz.split()])

    def leader(self, name: str) -> str:
        """The independent joint at the end of a joint's mimic tags."""
        while name in self.tags:
            name = self.tags[name][0]
        return name

    @property
    def variables(self) -> set[str]:
        """The independent joints that move the tree (leaders outside it included)."""
        return {self.leader(n) for n in self.joint_names}

    def values(self, names, q: np.ndarray) -> np.ndarray:
        """Positions ``(m, n)`` of the tree joints (``joint_names``) from the independent ones."""

        def value(given: dict, name: str) -> float:
            if name in given:
                return given[name]
            leader, factor, offset = self.tags[name]
            return factor * value(given, leader) + offset

        rows = [dict(zip(names, qi, strict=True)) for qi in np.atleast_2d(q)]
        return np.array([[value(g, n) for n in self.joint_names] for g in rows])

    def configs(self, names, q: np.ndarray) -> list[np.ndarray]:
        """Pinocchio configurations from independent joint positions (columns ``names``)."""
        return super().configs(self.joint_names, self.values(names, q))


class PathRef:
    """Pinocchio alone, on a URDF file: two frames anywhere in the tree and the joints between.

    The joints are those of the two frames' supports that are not shared (the path through
    their common ancestor), found here from Pinocchio's ``supports``; positions are URDF
    positions given by joint name, so that the order of the path does not matter.
    """

    def __init__(self, path, base: str, tool: str):
        self.model = pin.buildModelFromUrdf(str(path))
        self.data = self.model.createData()
        self.base, self.tool = pin_frame(self.model, base), pin_frame(self.model, tool)
        jb = self.model.frames[self.base].parentJoint
        jt = self.model.frames[self.tool].parentJoint
        up, down = set(self.model.supports[jb]), set(self.model.supports[jt])
        self.up = sorted(up - down)  # the base side (traversed backwards)
        self.down = sorted(down - up)  # the tool side
        self.joint_ids = self.up + self.down

    @property
    def names(self) -> set[str]:
        """Names of the joints on the path."""
        return {self.model.names[j] for j in self.joint_ids}

    def config(self, names, q: np.ndarray) -> np.ndarray:
        """Pinocchio configuration with the named joints at URDF positions q."""
        ids = [self.model.getJointId(n) for n in names]
        return pin_config(self.model, ids, q)

    def relative(self, qp: np.ndarray) -> pin.SE3:
        """``oMf[base]^-1 oMf[tool]`` at a Pinocchio configuration."""
        pin.framesForwardKinematics(self.model, self.data, qp)
        return self.data.oMf[self.base].actInv(self.data.oMf[self.tool])

    def placements(self, names, q: np.ndarray) -> np.ndarray:
        """The tool in the base frame ``(m, 4, 4)`` at URDF positions ``q`` (columns ``names``)."""
        return np.array([self.relative(self.config(names, qi)).homogeneous for qi in q])

    def relative_jacobian(self, names, q: np.ndarray, marker=(0.0, 0.0, 0.0)) -> np.ndarray:
        """d(tool pose in base)/dq by Pinocchio's frame Jacobians: ``(m * 6, len(names))``.

        Rows: velocity of the marker (on the tool) relative to the base frame, then the
        relative angular velocity, both in the base frame; the base frame's own motion (the
        joints on its side move it) is subtracted.
        """
        model, data = self.model, self.data
        cols = [model.joints[model.getJointId(n)].idx_v for n in names]
        out = []
        for qi in q:
            qp = self.config(names, qi)
            pin.computeJointJacobians(model, data, qp)
            pin.updateFramePlacements(model, data)
            Jt, Jb = (
                np.reshape(pin.getFrameJacobian(model, data, f, pin.LOCAL_WORLD_ALIGNED), (6, -1))
                for f in (self.tool, self.base)
            )
            Jt, Jb = Jt[:, cols], Jb[:, cols]
            ob, ot = data.oMf[self.base], data.oMf[self.tool]
            point = ot.translation + ot.rotation @ np.asarray(marker, dtype=float)
            w_rel = Jt[3:] - Jb[3:]
            lever_t, lever_b = point - ot.translation, point - ob.translation
            v_point = Jt[:3] + np.cross(Jt[3:].T, lever_t).T  # the marker, moved with the tool
            v_base = Jb[:3] + np.cross(Jb[3:].T, lever_b).T  # the same point, moved with the base
            # p_b = R_b^T (P - o_b): d p_b = R_b^T (dP - d o_b - w_b x (P - o_b))
            R = ob.rotation.T
            out.append(np.vstack([R @ (v_point - v_base), R @ w_rel]))
        return np.vstack(out)

    def nominal_places(self) -> list[tuple[str, int, pin.SE3]]:
        """Every placement a path's error moves: its joints', then the base and tool frames'."""
        model = self.model
        places = [("joint", j, model.jointPlacements[j].copy()) for j in self.joint_ids]
        places += [("frame", f, model.frames[f].placement.copy()) for f in (self.base, self.tool)]
        return places

    def place(self, kind: str, i: int, M: pin.SE3) -> None:
        """Set joint ``i``'s placement or frame ``i``'s (``kind``: ``joint`` or ``frame``)."""
        if kind == "joint":
            self.model.jointPlacements[i] = M
        else:
            frame = self.model.frames[i]
            frame.placement = M
            self.model.frames[i] = frame

    def error_rank(
        self, names, q: np.ndarray, rows=(0, 1, 2, 3, 4, 5), marker=(0.0, 0.0, 0.0), h=1e-6
    ) -> int:
        """Rank of a generic 6-DOF error on every path joint placement, the base and the tool.

        Central finite differences of the marker position and the tool rotation in the base
        frame (rows among x, y, z, rx, ry, rz) at URDF positions ``q`` (columns ``names``).
        """
        qps = [self.config(names, qi) for qi in q]
        mk = np.append(np.asarray(marker, dtype=float), 1.0)

        def poses() -> list[pin.SE3]:
            return [self.relative(qp) for qp in qps]

        cols = []
        for kind, i, nominal in self.nominal_places():
            for a in range(6):
                step = np.zeros(6)
                step[a] = h
                self.place(kind, i, nominal * pin.exp6(pin.Motion(step)))
                plus = poses()
                self.place(kind, i, nominal * pin.exp6(pin.Motion(-step)))
                minus = poses()
                self.place(kind, i, nominal)
                col = [
                    np.hstack(
                        [
                            (p.homogeneous @ mk - n.homogeneous @ mk)[:3],
                            pin.log3(p.rotation @ n.rotation.T),
                        ]
                    )[list(rows)]
                    / (2 * h)
                    for p, n in zip(plus, minus, strict=True)
                ]
                cols.append(np.concatenate(col))
        s = np.linalg.svd(np.array(cols).T, compute_uv=False)
        return int(np.sum(s > 1e-8 * s[0]))


def instrument_points(urdf, report: dict, base: str, tool: str, joint_names, q) -> np.ndarray:
    """Pinocchio alone: a written URDF's marker 1 in the instrument's frame ``(m, 3)`` [m].

    The marker link ``<tool>_marker1`` is placed in the base frame by Pinocchio, then in the
    instrument's frame by the report's ``frames.measurement`` (xyz and rpy: the pose of the
    base frame in the instrument's; a joint fit's is keyed by its base frame).
    """
    frame = report["frames"]["measurement"]
    if "xyz" not in frame:
        (frame,) = frame.values()
    ref = PinTree.of_file(urdf, base, [f"{tool}_marker1"])
    points = ref.poses(joint_names, q)[:, 0, :3, 3]
    R = pin.rpy.rpyToMatrix(np.array(frame["rpy"]))
    return points @ R.T + np.array(frame["xyz"])
