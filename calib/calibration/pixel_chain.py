"""The pixel kind: a camera fixed to a link sees target points fixed to a tool, in pixels.

``pixel = pinhole(C^-1 T(q) X)``. Here: its unknowns (the columns of :func:`pixel_jacobian`:
the camera's 6, the joint placements, the optional blocks of :class:`Unknowns`), its data
(:class:`PixelData`), layout and state in the joint engine, and what pixels determine
(:func:`pixel_count`); the registration is :mod:`.pixel_fit`'s.
Model, units and weight: docs/developers/engine.md#pixel_chain
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..core.choices import DEFAULT_CONFIGS
from ..exceptions import InvalidArgumentError
from ..identification.pinhole import Pinhole
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..kinematics.so3 import left_jacobian, rotation_matrix, skew
from ..measurements.cameras import PixelCamera, PixelRows, pixel_rows
from ..measurements.limits import warn_default_ranges
from ..measurements.pixel_simulation import simulate_cameras
from ..measurements.pixels import PixelObservations, Target
from . import term_checks, validation
from .determined import determined_columns
from .placements import Placements, joint_twists, offset_component

__all__ = [
    "GAUGE_POINTS",
    "PixelCamera",
    "PixelData",
    "PixelKind",
    "PixelPart",
    "PixelRows",
    "PixelTermState",
    "Unknowns",
    "camera_points",
    "camera_step",
    "check_pixels",
    "free_columns",
    "joint_postures",
    "pixel_block",
    "pixel_count",
    "pixel_jacobian",
    "pixel_part",
    "pixel_parts",
    "pixel_rows",
    "with_tool",
]

CAMERA_NAMES = ("camera.x", "camera.y", "camera.z", "camera.rx", "camera.ry", "camera.rz")
"""The camera placement's unknowns (in the camera frame)."""

MOUNT_NAMES = ("mount.x", "mount.y", "mount.z", "mount.rx", "mount.ry", "mount.rz")
"""The target mounting's unknowns (in the tool frame)."""

GAUGE_POINTS = 3
"""Target points kept as given when the target is refined (the gauge and the scale)."""


@dataclass(frozen=True)
class Unknowns:
    """The optional unknowns of a pixel term.

    Attributes:
        mount: The target's mounting on its link (6).
        targets: The target points after the first :data:`!GAUGE_POINTS` (3 each).
        intrinsics: The camera's intrinsics (4 + the distortion coefficients).
    """

    mount: bool = False
    targets: bool = False
    intrinsics: bool = False


KNOWN = Unknowns()
"""No optional unknown: the target and the intrinsics as given."""


def camera_points(kin, camera: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points ``X`` ``(m, 3)`` of the tool, in the camera ``(m, 3)`` and the base link [m]."""
    p_link = kin.p[:, -1] + np.einsum("mij,mj->mi", kin.R[:, -1], X)
    return (p_link - camera[:3, 3]) @ camera[:3, :3], p_link


def camera_step(p_cam: np.ndarray) -> np.ndarray:
    """How points ``(m, 3)`` of the camera frame move by the camera's step ``(m, 3, 6)``."""
    m = len(p_cam)
    return np.concatenate([-np.broadcast_to(np.eye(3), (m, 3, 3)), skew(p_cam)], axis=2)


def pixel_jacobian(
    placements: Placements,
    state: PixelTermState,
    chain: Chain,
    rows: PixelRows,
    robot: bool = True,
    kin=None,
) -> tuple[np.ndarray, np.ndarray]:
    """The residuals ``pixel - observed`` ``(m, 2)`` [px] and their derivatives ``(m, 2, c)``.

    Columns: the camera's 6, every joint placement's 6, the mounting's 6 (always), then the
    target points' and the intrinsics' per ``state.what`` [px per m, rad or px]; ``robot``
    False: the joint placement columns are zero.
    """
    if kin is None:
        kin = placements.frames(chain, rows.q)
    X = state.target[rows.point]
    p_cam, p_link = camera_points(kin, state.camera, X)
    seen = state.lens.projection(p_cam, derivatives=True)
    D = np.asarray(seen.d_point)  # (m, 2, 3) [px/m]
    RcT = state.camera[:3, :3].T
    m = rows.m
    moving = np.zeros((m, 3, len(placements.joints), 6))  # the point's motion in the base link
    if robot:
        columns = placements.path(chain).columns
        ang, lin = joint_twists(placements, chain, kin)
        moving[:, :, columns] = np.moveaxis(lin - skew(p_link)[:, None] @ ang, 1, 2)
    by_camera = camera_step(p_cam)
    mount = RcT @ kin.R[:, -1]  # d(point in the camera) / d(point in the tool)
    by_mount = mount @ np.concatenate([np.broadcast_to(np.eye(3), (m, 3, 3)), -skew(X)], axis=2)
    parts = [D @ by_camera, D @ (RcT @ moving.reshape(m, 3, -1)), D @ by_mount]
    k = len(state.target)
    if state.what.targets and k > GAUGE_POINTS:
        by_point = np.zeros((m, 3, k, 3))
        by_point[np.arange(m), :, rows.point] = mount
        parts.append(D @ by_point[:, :, GAUGE_POINTS:].reshape(m, 3, -1))
    if state.what.intrinsics:
        parts.append(np.asarray(seen.d_parameters))
    return seen.pixels - rows.pixels, np.concatenate(parts, axis=2)


def free_columns(
    W: np.ndarray, placements: Placements, what: Unknowns, cameras: int = 1
) -> tuple[int, ...]:
    """The columns of ``W`` ``(r, c)`` the rows determine, in order of preference.

    ``W``'s columns: each camera's 6, the joint placements, the mounting (never free without
    ``what.mount``), the target points, the intrinsics.
    Order of preference: docs/developers/engine.md#pixel_chain
    """
    norms = np.linalg.norm(W, axis=0)
    used = norms > 0
    n = 6 * cameras + placements.y.size
    if not what.mount:
        used[n : n + 6] = False
    scaled = np.where(used, W / np.where(used, norms, 1.0), 0.0)
    offsets: list[int] = []
    others: list[int] = []
    for j, jid in enumerate(placements.ids):
        off = ("x", "y", "z", "rx", "ry", "rz").index(offset_component(placements.nominal, jid))
        for c in range(6):
            (offsets if c == off else others).append(6 * cameras + 6 * j + c)
    preferred = [*range(6 * cameras), *range(n, n + 6), *offsets, *others, *range(n + 6, len(W.T))]
    order = [c for c in preferred if used[c]]
    return tuple(sorted(order[i] for i in determined_columns(scaled[:, order])))


@dataclass(frozen=True, eq=False)
class PixelData:
    """A pixel term's data: one camera's observations of a target.

    Attributes:
        camera: The camera (its name: the ``camera`` column; its link: the chain's base).
        target: The target points in the chain's tool frame [m].
        obs: The observations (the camera's rows are used).
        what: The optional unknowns (target mounting, target points, intrinsics).
    """

    camera: PixelCamera
    target: Target
    obs: PixelObservations
    what: Unknowns = KNOWN

    def __repr__(self) -> str:
        """One line (what it holds is in the attributes)."""
        return f"<PixelData {self.source}: {self.m} pixels of camera {self.camera.name}>"

    @property
    def source(self) -> str:
        """The observations' file."""
        return self.obs.source

    @property
    def m(self) -> int:
        """Rows of the camera."""
        return sum(c == self.camera.name for c in self.obs.camera)


@dataclass(frozen=True, eq=False)
class PixelPart:
    """A pixel term's ``data`` and its ``rows`` on its chain (joints in the chain's order)."""

    data: PixelData
    rows: PixelRows

    @property
    def source(self) -> str:
        """The observations' file."""
        return self.data.source

    @property
    def m(self) -> int:
        """Rows."""
        return self.rows.m

    tool = None  # one tool: postures are the joints' (validation.split)

    @property
    def q(self) -> np.ndarray:
        """The rows' joint positions ``(m, n)`` [rad or m]."""
        return self.rows.q

    @property
    def kind(self) -> PixelKind:
        """The term's layout."""
        lens = len(self.data.camera.intrinsics.camera.parameters)
        return PixelKind(len(self.data.target.position), lens, self.data.what)

    def subset(self, keep: np.ndarray) -> PixelPart:
        """The rows where ``keep``."""
        return PixelPart(self.data, self.rows.subset(keep))

    def as_data(self) -> PixelData:
        """The term's data of these rows only, each keeping its line: a run's data again."""
        obs = self.data.obs
        lines = term_checks.file_lines(obs)
        keep = np.isin(lines, self.rows.lines)
        pick = np.flatnonzero(keep)
        rows = PixelObservations(
            obs.joint_names,
            obs.q[keep],
            tuple(obs.camera[i] for i in pick),
            tuple(obs.point[i] for i in pick),
            obs.pixels[keep],
            obs.source,
            tuple(lines[i] for i in pick),
        )
        return dataclasses.replace(self.data, obs=rows)


@dataclass(frozen=True)
class PixelKind:
    """The layout of a pixel term: its unknowns and rows (``points``: the target's)."""

    points: int
    lens: int
    what: Unknowns = KNOWN

    label = "pixels"
    object_name = "camera"
    contact_dofs: tuple[int, ...] = ()
    row_names = ("u", "v")
    angular = (False, False)

    def names(self) -> tuple[str, ...]:
        """The camera's 6, the mounting's 6, the free target points, the intrinsics."""
        points = range(GAUGE_POINTS, self.points) if self.what.targets else ()
        return (
            *CAMERA_NAMES,
            *(MOUNT_NAMES if self.what.mount else ()),
            *(f"target{k + 1}.{a}" for k in points for a in "xyz"),
            *(f"camera.p{k + 1}" for k in range(self.lens if self.what.intrinsics else 0)),
        )

    @property
    def object_dofs(self) -> tuple[int, ...]:
        """One index per unknown."""
        return tuple(range(len(self.names())))


@dataclass(frozen=True, eq=False)
class PixelTermState:
    """A pixel term's state: its chain's MDH model, the camera, the target, the lens.

    ``camera``: the optical frame in the chain's base link ``(4, 4)`` [m]; ``target``: the
    points in the tool frame ``(k, 3)`` [m]; ``weight``: the rows' weight [m/px at the target].
    """

    mdh: MDHModel
    camera: np.ndarray
    target: np.ndarray
    lens: Pinhole
    weight: float
    what: Unknowns = KNOWN

    @property
    def kind(self) -> PixelKind:
        """The term's layout."""
        return PixelKind(len(self.target), len(self.lens.parameters), self.what)

    def seen(self, part: PixelPart, kin=None) -> np.ndarray:
        """The rows' points in the camera frame ``(m, 3)`` [m] (``kin``: None: the MDH model's)."""
        if kin is None:
            kin = self.mdh.kinematics(part.rows.q)
        return camera_points(kin, self.camera, self.target[part.rows.point])[0]

    def pixel_errors(self, part: PixelPart, kin=None) -> np.ndarray:
        """Reprojection errors ``pixel - observed`` ``(m, 2)`` [px] (``kin``: :meth:`seen`)."""
        return self.lens.projection(self.seen(part, kin)).pixels - part.rows.pixels

    def residuals(self, part, torque=None, kin=None) -> np.ndarray:
        """Weighted ``observed - pixel`` ``(m, 2)`` [m-equivalent] (``kin``: :meth:`seen`)."""
        return -self.pixel_errors(part, kin) * self.weight

    def moved(self, x: np.ndarray) -> PixelTermState:
        """The state with its own unknowns (:attr:`kind`'s) at ``x``."""
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = rotation_matrix(x[3:6]), x[:3]
        target, lens, what, start = np.array(self.target, dtype=float), self.lens, self.what, 6
        if what.mount:
            target = target @ rotation_matrix(x[9:12]).T + x[6:9]
            start = 12
        if what.targets and len(target) > GAUGE_POINTS:
            stop = start + 3 * (len(target) - GAUGE_POINTS)
            target[GAUGE_POINTS:] += x[start:stop].reshape(-1, 3)
            start = stop
        if what.intrinsics:
            lens = lens.with_parameters(lens.parameters + x[start:])
        return dataclasses.replace(self, camera=self.camera @ step, target=target, lens=lens)

    def own_columns(self, n: int) -> np.ndarray:
        """Its own unknowns' columns among :func:`pixel_jacobian`'s (``n`` joints')."""
        extra = len(self.kind.names()) - 6 - 6 * self.what.mount  # target points, intrinsics
        mount = range(6 + n, 12 + n) if self.what.mount else ()
        return np.r_[0:6, list(mount), 12 + n : 12 + n + extra].astype(int)


def pixel_block(
    placements, chain, state: PixelTermState, start: PixelTermState, x, part, lift, kin
):
    """Weighted rows of a pixel term: ``(m, 2, own)`` by ``x`` and ``(m, 2, free)`` by ``lift``.

    ``state`` at ``x``, ``start`` at x = 0. Derivation: docs/developers/engine.md#pixel_chain
    """
    J = pixel_jacobian(placements, state, chain, part.rows, len(lift) > 0, kin)[1]
    n = placements.y.size
    own = J[:, :, state.own_columns(n)]  # in x's order
    own[..., 0:3] = own[..., 0:3] @ rotation_matrix(x[3:6]).T
    own[..., 3:6] = own[..., 3:6] @ left_jacobian(-x[3:6])
    if start.what.mount:
        k, d = len(start.target), np.zeros_like(start.target)
        if start.what.targets and k > GAUGE_POINTS:
            d[GAUGE_POINTS:] = x[12 : 12 + 3 * (k - GAUGE_POINTS)].reshape(-1, 3)
        rot = own[..., 9:12] + own[..., 6:9] @ skew(x[6:9] + d[part.rows.point])
        own[..., 9:12] = rot @ left_jacobian(x[9:12])
    robot = J[:, :, 6 : 6 + n] @ lift.T
    return own * state.weight, robot * state.weight


def with_tool(placements, chain: Chain, state, D: np.ndarray, labels):
    """A pixel term's offered directions with its last joint's six (a target known on its tool)."""
    if not isinstance(state, PixelTermState) or state.what.mount:
        return D, labels
    j = placements.joints.index(chain.joint_names[-1])
    extra = np.eye(D.shape[1])[6 * j : 6 * j + 6]
    names = placements.names()[6 * j : 6 * j + 6]
    return np.vstack([D, extra]), (*labels, *names)


def check_pixels(chain: Chain, data: PixelData, validate) -> None:
    """A pixel term's data: its camera's link is the chain's base, validation rows alike.

    Raises:
        InvalidArgumentError: Another base, or validation rows that are not PixelData.
        DataError: Validation rows that are rows of the data (or its file).
    """
    if chain.base_frame != data.camera.link:
        raise InvalidArgumentError(
            f"camera {data.camera.name}: its chain must start at its link {data.camera.link}, "
            f"not {chain.base_frame}"
        )
    if validate is not None and not isinstance(validate, PixelData):
        raise InvalidArgumentError(
            f"{chain.base_frame} -> {chain.tool_frame}: validation rows must be PixelData like "
            f"its data, got {type(validate).__name__}"
        )
    if validate is not None:
        validation.check_held_out(data.obs, validate.obs)
    links = set(data.target.link or (chain.tool_frame,))
    if chain.tool_frame not in links:
        raise InvalidArgumentError(
            f"camera {data.camera.name}: no target point on {chain.tool_frame} (its chain's tool)"
        )
    if len(links) > 1 and (data.what.mount or data.what.targets):
        raise InvalidArgumentError(
            f"camera {data.camera.name}: a target on several links takes no mounting or target "
            "point unknowns (not yet: its points are taken as given)"
        )


def pixel_part(chain: Chain, data: PixelData) -> PixelPart:
    """The camera's rows of the data on its chain."""
    return PixelPart(data, pixel_rows(chain, data.obs, data.target, data.camera.name))


def pixel_parts(chains, data) -> list:
    """The terms' data, each :class:`PixelData` as its rows on its chain."""
    return [
        pixel_part(c, d) if isinstance(d, PixelData) else d
        for c, d in zip(chains, data, strict=True)
    ]


def _stacked(names, cameras, rows, chains, placements: Placements, target, what) -> np.ndarray:
    """The rows' Jacobian ``(r, c)``: each camera's 6 (one per name), the joints', the mounting."""
    blocks = []
    models = placements.chain_models(tuple(chains))
    for chain, camera, part, mdh in zip(chains, cameras, rows, models, strict=True):
        lens = camera.intrinsics.camera
        state = PixelTermState(mdh, np.asarray(camera.placement), target.position, lens, 1.0, what)
        J = pixel_jacobian(placements, state, chain, part)[1]
        W = np.zeros((part.m, 2, 6 * len(names) + J.shape[2] - 6))
        i = names.index(camera.name)
        W[:, :, 6 * i : 6 * i + 6] = J[:, :, :6]
        W[:, :, 6 * len(names) :] = J[:, :, 6:]
        blocks.append(W.reshape(-1, W.shape[2]))
    return np.concatenate(blocks)


POSTURE_UNKNOWNS = 6
"""The most one posture's pixels of a camera determine: the target's placement in the camera
(2 per pixel below 3 pixels)."""

COUNT_MARGIN = 2
"""The generic count is made at postures whose pixels could determine this many times the
unknowns."""

MAX_DOUBLINGS = 5
"""Times :func:`pixel_count` doubles its random postures (at most 32 times ``configs``)."""


def joint_postures(chains, drawn) -> tuple[tuple[str, ...], np.ndarray]:
    """Every joint of the chains and their postures ``(m, n)`` [rad or m].

    ``drawn``: each chain's postures ``(m, n_chain)``; a joint of several chains takes the
    first chain's values.
    """
    joints = tuple(dict.fromkeys(j for c in chains for j in c.joint_names))
    q = np.zeros((len(drawn[-1]), len(joints)))
    for chain, own in reversed(list(zip(chains, drawn, strict=True))):
        q[:, [joints.index(j) for j in chain.joint_names]] = own
    return joints, q


def pixel_count(
    chains,
    cameras: tuple[PixelCamera, ...],
    target: Target,
    joints=None,
    q=None,
    params: str | None = None,
    configs: int = DEFAULT_CONFIGS,
    seed: int = 0,
) -> dict:
    """The unknowns cameras' pixels determine (``n_base``): what ``calib analyze`` counts.

    Without ``q``: the generic count, at ``configs`` random postures, then twice as many (the
    same seed: the first ones kept) until the seeing postures could determine
    :data:`!COUNT_MARGIN` (2) times the unknowns (:data:`!POSTURE_UNKNOWNS`, 6, each; 2 per
    pixel) and the count no longer grows, at most :data:`!MAX_DOUBLINGS` (5) times: a count
    on too few seeing postures is low. With ``q``: the count at those postures.

    Args:
        chains: Each camera's chain to the target's tool (a target on several links: a chain
            per link, the camera given once per chain).
        cameras: Each chain's camera, placed.
        target: Its points in the tool frame [m].
        joints: ``q``'s columns (the joints of the chains), with ``q``.
        q: Postures ``(m, n)`` [rad or m], or None: drawn.
        params: ``complete``: the target's mounting is an unknown too.
        configs: Random postures drawn first (without ``q``).
        seed: Seed of the draws.

    Returns:
        ``n_base`` (the rank on the nominal robot), ``n_unknowns``, the ``rows``,
        ``postures`` and ``cameras`` counted, ``configs`` (the postures drawn or given) and
        ``notes`` (a count that may be low, postures drawn again): ``--json``'s document.

    Raises:
        InvalidArgumentError: No point seen at any posture (drawn: at the last draw);
            ``joints`` without ``q`` or ``q`` without ``joints``; a bad count or seed.
    """
    if (joints is None) != (q is None):
        raise InvalidArgumentError("pixel_count: give joints and q together (q's columns)")
    if q is not None:
        found = _count_at(chains, cameras, target, joints, q, params)
        low = [] if _enough(found) else [_low(found, f"{len(q)} postures", "more postures")]
        return found | {"configs": len(q), "notes": low}
    return _drawn_count(chains, cameras, target, params, configs, seed)


def _drawn_count(chains, cameras, target: Target, params, configs: int, seed: int) -> dict:
    """:func:`pixel_count` at random postures, drawn again until the count settles."""
    counts: list[dict] = []
    m, first, settled = configs, 0, False
    for doubling in range(MAX_DOUBLINGS + 1):
        if doubling == 0:
            for chain in chains:
                warn_default_ranges(chain, "give your own configurations")
        joints, q = joint_postures(chains, [c.random_configurations(m, seed) for c in chains])
        try:
            found = _count_at(chains, cameras, target, joints, q, params)
        except InvalidArgumentError:  # no point seen: more postures, else the error
            if doubling == MAX_DOUBLINGS:
                raise
            m *= 2
            continue
        settled = _enough(found) and (not counts or found["n_base"] == counts[-1]["n_base"])
        counts.append(found)
        first = found["postures"] if doubling == 0 else first
        if settled:
            break
        m *= 2
    notes = [] if settled else [_low(found, f"{len(q)} random postures", "more --configs")]
    if settled and len(counts) > 1:
        notes.append(
            f"{first} of the first {configs} random postures "
            f"{'sees' if first == 1 else 'see'} the target: counted at {len(q)} "
            f"({found['postures']} seeing), where the count stops growing"
        )
    return found | {"configs": len(q), "notes": notes}


def _enough(found: dict) -> bool:
    """Whether the seeing postures could determine :data:`COUNT_MARGIN` times the unknowns."""
    seeing = min(POSTURE_UNKNOWNS * found["postures"], 2 * found["rows"])
    return seeing >= COUNT_MARGIN * found["n_unknowns"]


def _low(found: dict, postures: str, more: str) -> str:
    """The note of a count at too few seeing ``postures`` (what to give: ``more``)."""
    wanted = -(-COUNT_MARGIN * found["n_unknowns"] // POSTURE_UNKNOWNS)
    return (
        f"only {found['postures']} of {postures} see the target: the count may be low (it "
        f"wants about {wanted} seeing postures and a count that stops growing); give {more}, "
        "or a camera placement that sees the target more often"
    )


def _count_at(chains, cameras, target: Target, joints, q, params: str | None) -> dict:
    """:func:`pixel_count` at postures ``q``."""
    views = tuple((camera.name, camera.placement, camera.intrinsics) for camera in cameras)
    obs = simulate_cameras(chains, views, target, joints, q)
    placements = Placements.of(tuple(chains))
    what = Unknowns(mount=params == "complete")
    rows = [pixel_rows(c, obs, target, cam.name) for c, cam in zip(chains, cameras, strict=True)]
    names = tuple(dict.fromkeys(c.name for c in cameras))
    W = _stacked(names, cameras, rows, chains, placements, target, what)
    free = free_columns(W, placements, what, len(names))
    first = cameras[0]
    return {
        "kind": "pixels",
        "camera": first.name,
        "link": first.link,
        "cameras": [
            {"name": c.name, "link": c.link, "rows": r.m}
            for c, r in zip(cameras, rows, strict=True)
        ],
        "tool": chains[0].tool_frame,
        "rows": int(obs.m),
        "postures": len(np.unique(obs.q, axis=0)),
        "mount": what.mount,
        "n_unknowns": 6 * len(names) + placements.y.size + 6 * what.mount,
        "n_base": len(free),
    }
