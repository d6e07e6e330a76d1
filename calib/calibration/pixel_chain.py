"""A pixel term among several chains: a camera on a link sees a target on a tool, in pixels.

A kind of term of the joint engine (:func:`~.contact_chains.calibrate_contact_chains`): its
data are :class:`PixelData`, its chain, rows ``u, v`` [px] and own unknowns (the camera's 6
and the optional ones of :class:`~.pixel_term.Unknowns`) are :mod:`.pixel_term`'s; the joint
placement columns are shared with every other term through the joints.

Weight: each pixel enters the joint fit times :attr:`PixelTermState.weight` [m/px] (the
target's median depth in the camera at the registration over the mean focal length), so the
refusal rule (``validation.worse``) and the outlier rule (:func:`~.outliers.find_outliers`)
read millimetres at the target; the report gives both (px and mm).

Registration: the camera placed on the nominal robot (given, the URDF's link NAME on LINK, or
in closed form, :func:`~.pixel_fit.camera_from_rays`), refined by least squares on its 6.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..identification.pinhole import Pinhole
from ..kinematics.mdh import MDHModel
from ..kinematics.placement_export import camera_placement
from ..kinematics.robot import Chain
from ..measurements.pixels import PixelObservations, Target
from . import determined, diagnosis, outliers, term_checks, validation
from .pixel_fit import PixelView, camera_from_rays, fit_alone, rays, refine_camera
from .pixel_term import (
    CAMERA_NAMES,
    GAUGE_POINTS,
    KNOWN,
    MOUNT_NAMES,
    PixelCamera,
    PixelRows,
    PixelState,
    Unknowns,
    camera_points,
    check_in_front,
    exact_columns,
    move_own,
    pixel_jacobian,
    pixel_rows,
    target_points,
)
from .placements import Placements
from .term_checks import Aside

__all__ = [
    "ROUND_OFF_PX",
    "PixelData",
    "PixelKind",
    "PixelPart",
    "PixelTermState",
    "check_pixels",
    "checked_pixels",
    "pixel_block",
    "pixel_part",
    "pixel_parts",
    "with_tool",
]


ROUND_OFF_PX = 1e-6
"""Pixel errors below 6 times this [px] are round-off, never outliers (a noise-free fit leaves
1e-12 px, of which one may be 5 times the median), far below any detector's noise."""


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
    """A pixel term's rows on its chain (training or held out).

    Attributes:
        data: The term's data.
        rows: The rows, joints in the chain's order.
    """

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


@dataclass(frozen=True)
class PixelKind:
    """The layout of a pixel term: its unknowns and rows.

    Attributes:
        points: Target points.
        lens: Intrinsic parameters of the camera.
        what: The optional unknowns.
    """

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
    """A pixel term's state: its chain on the robot, the camera, the target, the lens.

    Attributes:
        mdh: The chain's MDH model on the perturbed robot.
        camera: The camera's optical frame in the chain's base link ``(4, 4)`` [m].
        target: The target points in the tool frame ``(k, 3)`` [m].
        lens: The intrinsics.
        weight: Metres per pixel at the target (the rows' weight in the joint fit) [m/px].
        what: The optional unknowns.
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
        """The rows' points in the camera frame ``(m, 3)`` [m].

        ``kin``: the chain's frames at the rows' joints (the last the tool's; a joint fit's),
        or None: its MDH model's.
        """
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
        """The state with its own unknowns at ``x``."""
        camera, target, lens = move_own(self.camera, self.target, self.lens, x, self.what)
        return dataclasses.replace(self, camera=camera, target=target, lens=lens)


def _own_index(n: int, what: Unknowns, total: int) -> np.ndarray:
    """The own unknowns' columns among :func:`~.pixel_term.pixel_jacobian`'s."""
    mount = range(6 + n, 12 + n) if what.mount else ()
    return np.r_[0:6, list(mount), 12 + n : total].astype(int)


def pixel_block(
    placements, chain, state: PixelTermState, start: PixelTermState, x, part, lift, kin
):
    """Weighted rows of a pixel term: its own columns and the free placement directions.

    Args:
        placements: The current joint placement errors.
        chain: The term's nominal chain.
        state: Its state at ``x``.
        start: Its state at x = 0.
        x: Its own unknowns.
        part: Its rows.
        lift: The free directions ``(free, 6 J)``.
        kin: The chain's frames at the rows' joints (:meth:`~.placements.Placements.frames`).

    Returns:
        ``(m, 2, own)`` and ``(m, 2, free)`` [m-equivalent per unit].
    """
    pix = PixelState(placements, state.camera, state.target, state.lens)
    J = pixel_jacobian(pix, chain, part.rows, state.what, kin=kin)[1]
    n = placements.y.size
    J = exact_columns(J, start.what, start.target, x, n, part.rows.point)
    own = J[:, :, _own_index(n, state.what, J.shape[2])]
    robot = J[:, :, 6 : 6 + n] @ lift.T
    return own * state.weight, robot * state.weight


def with_tool(placements, chain: Chain, state, D: np.ndarray, labels):
    """A pixel term's offered directions with its tool's placement (a target known on it).

    A chain's MDH directions cover its joint rows, not the tool's own placement, which a
    measured or contact term's own unknowns hold. A target known on its link (no mounting
    unknown) sees it: the six components of the chain's last joint (its origin carries the
    tool: ``panda_joint1``'s in ``panda_link0`` for a board on the Panda's root) are offered
    too (the rank test keeps those determined). Other terms: ``D`` and ``labels`` as given.
    """
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
    """The terms' data with each :class:`PixelData` as its rows on its chain (the rest kept)."""
    return [
        pixel_part(c, d) if isinstance(d, PixelData) else d
        for c, d in zip(chains, data, strict=True)
    ]


def _registered(chain: Chain, part: PixelPart) -> PixelTermState:
    """The camera placed on the nominal robot (given, the URDF's, or closed form), refined."""
    cam, rows = part.data.camera, part.rows
    placements = Placements.of((chain,))
    guess = cam.placement
    if guess is None:
        guess = camera_placement(chain, cam.name, cam.link)
    lens, target = cam.intrinsics.camera, part.data.target.position
    if guess is None:
        p_link = target_points(PixelState(placements, np.eye(4), target, lens), chain, rows)[1]
        guess = camera_from_rays(p_link, rays(lens, rows.pixels), part.source)
    state = PixelState(placements, guess, target, lens)
    check_in_front(target_points(state, chain, rows)[0], rows, part.source)
    state = refine_camera(state, chain, rows)
    p_cam = target_points(state, chain, rows)[0]
    mdh = placements.chain_models((chain,))[0]
    weight = float(np.median(p_cam[:, 2])) / (0.5 * (lens.fx + lens.fy))
    return PixelTermState(mdh, state.camera, target, lens, weight, part.data.what)


@dataclass(frozen=True, eq=False)
class _Joints:
    """A pixel term's joint columns, as the usual mistakes (:mod:`.diagnosis`) read them."""

    joint_names: tuple[str, ...]
    q: np.ndarray
    source: str

    @property
    def m(self) -> int:
        """Rows."""
        return len(self.q)


def _rms_m(state: PixelTermState, part: PixelPart) -> float:
    """RMS reprojection error of the rows [m at the target]."""
    return float(np.sqrt(2 * np.mean(state.pixel_errors(part) ** 2)) * state.weight)


def _error_m(chain: Chain, part: PixelPart, q: np.ndarray) -> float:
    """RMS error [m at the target] of the registration of the rows at joint positions ``q``."""
    moved = PixelPart(part.data, dataclasses.replace(part.rows, q=q))
    return _rms_m(_registered(chain, moved), moved)


_WORDS = diagnosis.Words("pixels", "row of the pixels", "error at the target",
                         check="the pixels, the camera's link and the target")  # fmt: skip


def _explain(chain: Chain, part: PixelPart, first: float) -> list[str]:
    """:func:`~.diagnosis.explain` of the rows' joint columns (``first``: error [m])."""

    def error(fixed: object) -> float:
        return _error_m(chain, part, cast(_Joints, fixed).q)

    joints = _Joints(chain.joint_names, part.rows.q, part.source)
    notes = diagnosis.explain(joints, chain.sigma == 0, error, first, None, _WORDS)
    return [f"camera {part.data.camera.name}: {n}" for n in notes]


def _from_behind(state: PixelTermState, part: PixelPart) -> np.ndarray:
    """Rows whose point's outward normal (the target's) faces away from the camera."""
    normals = part.data.target.normal
    if normals is None:
        return np.zeros(part.m, dtype=bool)
    R = state.mdh.kinematics(part.rows.q).R[:, -1]
    n_cam = np.einsum("ji,mjk,mk->mi", state.camera[:3, :3], R, normals[part.rows.point])
    return np.einsum("mi,mi->m", n_cam, state.seen(part)) >= 0


def _judged(chain: Chain, state: PixelTermState, part: PixelPart, held):
    """Each row's error [m at the target] on the term's own fit, and the held-out rows'.

    The term alone fitted (its camera and its chain's joint placements,
    :func:`~.pixel_fit.fit_alone`): a camera registered on the nominal robot errs by tens
    of pixels at far postures, which no outlier rule should read as gross.
    """
    start = PixelState(Placements.of((chain,)), state.camera, state.target, state.lens)
    own = fit_alone(start, PixelView(chain, part.rows), part.data.what)
    errors = [np.linalg.norm(own.residuals(PixelView(chain, p.rows)), axis=1) * state.weight
              for p in (part, held) if p is not None]  # fmt: skip
    return errors[0], (errors[1] if held is not None else None)


def _size(part: PixelPart) -> int:
    """The camera's unknowns (placement, mounting, target points) of a pixel term."""
    return len(PixelKind(len(part.data.target.position), 0, part.data.what).names())


@dataclass(frozen=True, eq=False)
class _Camera:
    """A pixel term's steps on its rows (:class:`~.term_checks.Steps`).

    Every row is diagnosed before the outliers are set aside: the outlier rule reads the
    term's own fit (:func:`_judged`), made from the registration.

    Attributes:
        chain: The term's chain.
        rows: Its rows.
        held: Its held-out rows (their outliers set aside by the same own fit), or None.
    """

    chain: Chain
    rows: PixelPart
    held: PixelPart | None

    diagnose_first = True

    def register(self) -> PixelTermState:
        """The camera registered; no registration (points behind it) is diagnosed too.

        Raises:
            DataError: The mistake named, or the registration's own error.
        """
        try:
            return _registered(self.chain, self.rows)
        except DataError:
            _explain(self.chain, self.rows, np.inf)
            raise

    def diagnose(self, rows: PixelPart, state: PixelTermState) -> list[str]:
        """:func:`_explain` of the rows (``state``: their registration)."""
        return _explain(self.chain, rows, _rms_m(state, rows))

    def set_aside(self, state: PixelTermState) -> Aside[PixelPart, PixelTermState]:
        """Rows seen from behind or far off the own fit set aside (:func:`checked_pixels`)."""
        chain, part, held = self.chain, self.rows, self.held
        behind = _from_behind(state, part)
        errors, e_held = _judged(chain, state, part, held)
        floor = ROUND_OFF_PX * state.weight  # as the instrument noise: 6 x it, never an outlier
        pixel = outliers.Errors(errors, None, (2, 3))
        bad, found = outliers.find_outliers(pixel, floor, part.rows.lines)
        found = [dataclasses.replace(o, kind="pixels") for o in found]  # set aside on pixels
        found += [outliers.Outlier(part.rows.lines[i], float(errors[i]), float(np.median(errors)),
                  "from behind") for i in np.flatnonzero(behind & ~bad)]  # fmt: skip
        bad = bad | behind
        kept = part
        if bad.any():
            if part.m - int(bad.sum()) < _size(part):
                raise DataError(part.source, f"camera {part.data.camera.name}: too few rows kept")
            kept = part.subset(~bad)
            state = _registered(chain, kept)
        notes: list[str] = []
        if held is not None and e_held is not None:
            fitted, other = (outliers.Errors(e, None, (2, 3)) for e in (errors[~bad], e_held))
            held = term_checks.held_out(fitted, other, held, held.rows.lines, held.subset, notes)
        found.sort(key=lambda o: o.row)
        return Aside(state, bad, kept, tuple(found), held, tuple(notes))


def checked_pixels(chain: Chain, part: PixelPart, held):
    """A pixel term's registration and its outliers (the shared rule, in mm at the target).

    The steps of every kind of term (:func:`~.term_checks.checked`): rows seen from behind
    their normal, and rows that the shared rule (:func:`~.outliers.find_outliers`) sets
    aside on the term's own fit (:func:`_judged`), are outliers named by their line; the
    camera is registered again without them. Held-out rows' outliers: the same rule
    (:func:`~.term_checks.held_out`).

    Returns:
        Its registered state, the mask of its outlier rows, the outliers, the notes and its
        held-out rows without their outliers (or None).
    """
    out_m = 0 if held is None else held.m
    what = f"unknowns of camera {part.data.camera.name}'s placement"
    unit = "observations"
    determined.check_equations(part.m, 2, _size(part), what, part.source, held=out_m, unit=unit)
    aside, notes = term_checks.checked(_Camera(chain, part, held))
    return aside.state, aside.bad, list(aside.found), notes, aside.held
