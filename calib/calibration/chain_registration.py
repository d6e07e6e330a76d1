"""A measured chain's registration: its measuring frame and markers on the nominal model, checked.

Closed form refined by Levenberg-Marquardt (:func:`registrations`), then the steps of every
kind of term (:mod:`.term_checks`) on its rows (:class:`Rows`, :func:`validation_steps`).
Marker coordinates no posture within the joint limits separates from the frame's translation
(a gantry's tool never turns: :func:`held_markers`) are held at their given value, the frame
absorbing them (:func:`held_note`).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..identification.measures import POSE
from ..kinematics.mdh import Kinematics, MDHModel
from ..kinematics.robot import Chain
from ..measurements.csvfile import Measurements
from . import determined, diagnosis, outliers, term_checks, validation, weighting
from .model import MeasuredKind, State, measured_kind, point_rows
from .options import Options
from .registration import register
from .solve import Fit, fit
from .term_checks import Aside

__all__ = [
    "STRUCTURE_CONFIGS",
    "TURNS",
    "MeasuredState",
    "Rows",
    "Seen",
    "held_markers",
    "held_note",
    "registrations",
    "validation_steps",
]


STRUCTURE_CONFIGS = 20
"""Random configurations :func:`held_markers` reads the tool's rotations at: a tool that turns
about two axes turns its every direction at almost any two of them."""


TURNS = 0.1
"""Range [rad] of two revolute joints, and sine of the angle between their axes, over which a
tool turns about two axes at every posture (:func:`held_markers` holds nothing)."""


def held_markers(chain: Chain, nominal: MDHModel) -> tuple[int, ...]:
    """The first marker's coordinates no posture within the joint limits separates from the frame.

    :func:`~.determined.still_axes` of the ``nominal`` tool's rotations at
    ``STRUCTURE_CONFIGS`` random configurations of ``chain`` (seed 0: the robot's structure,
    not the data's); 0-based among the markers' ``3 K``. None without them when two revolute
    joints of independent ranges over :data:`TURNS` turn about axes :data:`TURNS` apart at
    the middle of the limits: every direction of the tool turns there.
    """
    if chain.coupling is None:
        turning = (chain.sigma == 0) & (chain.upper - chain.lower > TURNS)
        middle = nominal.kinematics(0.5 * (chain.lower + chain.upper)).R[0, 1:-1, :, 2]
        axes = middle[turning]  # each turning joint's axis (z of its frame)
        if len(axes) > 1 and np.max(np.linalg.norm(np.cross(axes[0], axes[1:]), axis=1)) > TURNS:
            return ()
    q = chain.random_configurations(STRUCTURE_CONFIGS, 0)
    return determined.still_axes(nominal.kinematics(q).R[:, -1])


def held_note(held: tuple[int, ...], guess: np.ndarray | None) -> str:
    """The note of marker coordinates held at their given value (:func:`held_markers`).

    ``guess``: the markers' given values [m] (None: not said, as ``calib analyze`` does).
    """
    whole = [k for k in range(max(held) // 3 + 1) if all(3 * k + a in held for a in range(3))]
    named = [f"marker{k + 1}" for k in whole] + [
        f"marker{c // 3 + 1}.{'xyz'[c % 3]}" for c in held if c // 3 not in whole
    ]
    given = "" if guess is None else ", ".join(f"{v:.4g}" for v in guess.ravel()[list(held)])
    values = f" ({given} m in the tool frame)" if given else ""
    one = len(named) == 1
    it, turns = ("it" if one else "them"), "never turns" if whole else "turns about one axis only"
    return (
        f"{' and '.join(named)} held at {'its' if one else 'their'} given value{values}: no "
        f"posture within the joint limits separates {it} from the "
        f"measurement frame's translation (the tool {turns}), which absorbs {it}: the "
        f"predictions do not depend on {it}"
    )


@dataclass(frozen=True, eq=False)
class Seen:
    """The registration's frames ``kin`` of the nominal chain at each rows' ``q`` (those arrays)."""

    mdh: MDHModel
    q: tuple[np.ndarray, ...]
    kin: tuple[Kinematics, ...]


@dataclass(frozen=True, eq=False)
class MeasuredState:
    """A measured term's state: its chain's model on the robot, frame, markers and weight.

    Attributes:
        inner: The single chain's state (its ``mdh`` the chain on the perturbed robot,
            ``frame`` the pose of the nominal base frame in the measuring frame).
        weight: Weight of the rotation rows [m/rad].
        instrument: Measured by an instrument outside the robot, shared by every such term
            (:attr:`~.model.MeasuredKind.instrument`).
        seen: The registration's frames of the nominal robot at its rows (kept and held
            out), read by :meth:`frames_at`; None once the state moves (:meth:`moved`).
        held: Marker coordinates held at their given value (:attr:`~.model.MeasuredKind.held`).
    """

    inner: State
    weight: float
    instrument: bool = False
    seen: Seen | None = None
    held: tuple[int, ...] = ()

    @property
    def kind(self) -> MeasuredKind:
        """The term's layout."""
        pose = self.inner.tool_rotation is not None
        return MeasuredKind(self.inner.n_markers, pose, self.instrument, self.held)

    @property
    def mdh(self):
        """The chain's MDH model on the perturbed robot."""
        return self.inner.mdh

    def row_weights(self) -> np.ndarray:
        """1 on the point rows, :attr:`weight` on the rotation rows."""
        return self.kind.row_weights(self.weight)

    def step_kinematics(self, data: Measurements, torque=None) -> Kinematics:
        """:attr:`inner`'s frames at the data's joints (a fit's, once per x)."""
        return self.inner.step_kinematics(data, torque)

    def same_geometry(self, other: MeasuredState) -> bool:
        """Whether ``other``'s kinematics at the same data are this state's."""
        return self.inner.same_geometry(other.inner)

    def weighed(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` ``(m, rows, ...)`` (a fresh array) times :meth:`row_weights`, in place.

        The rotation rows only: a point row's weight is 1 (the same numbers untouched).
        """
        if self.inner.tool_rotation is not None:
            rows[:, 3 * self.inner.n_markers :] *= self.weight
        return rows

    def residuals(self, data, torque=None, kin=None) -> np.ndarray:
        """Weighted measured - predicted ``(m, rows)`` [m].

        ``kin``: the chain's frames at the data's joints (the joint fit's), or None: its
        MDH model's.
        """
        return self.weighed(self.inner.residuals(data, None, kin))

    def moved(self, x: np.ndarray) -> MeasuredState:
        """The state with its own unknowns moved by ``x`` (a fit's: without :attr:`seen`)."""
        return dataclasses.replace(self, inner=self.kind.apply(self.inner, x), seen=None)

    def frames_at(self, data: Measurements) -> Kinematics:
        """:attr:`inner`'s frames at ``data``'s joints, undeflected: :attr:`seen`'s if made.

        The registration's when the model is its and ``data`` are its rows (the same
        arrays), else made.
        """
        s = self.seen
        if s is not None and s.mdh is self.inner.mdh:
            for q, kin in zip(s.q, s.kin, strict=True):
                if q is data.q:
                    return kin
        return self.inner.kinematics(data.q)

    def own_rows(
        self, x: np.ndarray, data: Measurements, kin, moved: MeasuredState | None = None
    ) -> np.ndarray:
        """Weighted d(prediction)/d(own unknowns) at ``x`` from this state ``(m, rows, own)``.

        ``kin``: the chain's frames at the data's joints at x (the joint fit's); ``moved``:
        :meth:`moved` at x, if already made.
        """
        inner = None if moved is None else moved.inner
        return self.weighed(self.kind.jacobian(self.inner, x, data, None, inner, kin))

    def motion_rows(self, kin, data, lin: np.ndarray, ang: np.ndarray) -> np.ndarray:
        """Weighted d(prediction) ``(m, rows, k)`` per unit of k motions of the chain's tool side.

        ``lin`` ``(m, 3, k)``: each motion's velocity of the base frame's origin moving with
        the tool side (base frame); ``ang`` ``(m, 3, k)``: its angular velocity.
        """
        s = self.inner
        R, p = kin.R[:, -1], kin.p[:, -1]
        points = np.stack([p + R @ marker for marker in s.markers], axis=1)
        W = point_rows(s.frame[:3, :3], lin, ang, points, s.tool_rotation is not None)
        rot = None  # the measured frame's orientation (pose data only: no points predicted)
        if s.tool_rotation is not None:
            rot = POSE.predict(R, p, s.markers, s.frame, s.tool_rotation)[1]
        return self.weighed(self.kind.measured_rows(W, rot, data, held=False))


@dataclass(frozen=True)
class _Own:
    """The registration's fit model: a :class:`MeasuredState`'s own unknowns (``kind``)."""

    kind: MeasuredKind

    def size(self) -> int:
        """Number of unknowns."""
        return self.kind.size()

    def apply(self, start: MeasuredState, x: np.ndarray) -> MeasuredState:
        """The state at unknowns x (:meth:`MeasuredState.moved`)."""
        return start.moved(x)

    def jacobian(self, start: MeasuredState, x, data, torque, state, kin) -> np.ndarray:
        """Weighted d(model)/dx ``(m, rows, size)`` (:meth:`MeasuredState.own_rows`)."""
        return start.own_rows(x, data, kin, state)


def registrations(nominal, data, guess, opts, held=()) -> Callable[[float], Fit]:
    """The registration of ``data`` at an orientation weight, each weight run once.

    Closed form (Horn/Umeyama), refined by Levenberg-Marquardt (frame and markers only, the
    rows weighted by the :class:`MeasuredState`). The nominal kinematics at the data's
    joints (the fit moves no geometry) and the closed-form start (no weight changes it) are
    made once, the start on the first call. ``held``: marker coordinates held at the
    ``guess`` (:func:`held_markers`).
    """
    kin = nominal.kinematics(data.q)
    model = _Own(measured_kind(data, held))

    @functools.cache
    def start() -> State:
        return register(nominal, data.q, data.points, data.rotations, guess, kin, held)

    @functools.cache
    def at(weight: float) -> Fit:
        n = opts.max_iterations
        first = MeasuredState(start(), weight, held=held)
        return fit(model, first, data, None, max_iterations=n, kin=kin)

    return at


_WORDS = diagnosis.Words(
    mistakes="swapped joint columns, degrees, a joint too many at an end of the chain, "
    "millimetres, centimetres, swapped coordinate columns, quaternion order"
)
_TURNS = diagnosis.Words(
    error="orientation error",
    mistakes="quaternion order, degrees, rpy order",
    check="the orientation columns",
)


@dataclass(frozen=True, eq=False)
class Rows:
    """A chain's steps on one set of measurements (:class:`~.term_checks.Steps`).

    ``guess``: the markers' in the tool frame [m]; ``opts``: with the orientation weight;
    ``at``: :func:`registrations` of ``rows``; ``frames``: the registration's model when the
    outliers may not leave fewer equations than its unknowns (validation data: the outliers
    stay), else None (that is an error); ``hold``: marker coordinates held at the ``guess``.
    """

    chain: Chain
    nominal: MDHModel
    rows: Measurements
    guess: np.ndarray
    opts: Options
    at: Callable[[float], Fit]
    frames: MeasuredKind | None = None
    hold: tuple[int, ...] = ()

    diagnose_first = False

    def register(self) -> Fit:
        """The registration of every row at the options' weight."""
        return self.at(cast(float, self.opts.orientation_weight))  # weighted: a number

    def set_aside(self, state: Fit) -> Aside[Measurements, Fit]:
        """The registration without the outlier rows, until stable (:mod:`.outliers`).

        A registration stopped by the evaluation cap sets no row aside (its errors are not
        the data's): the last converged one's set stays, or none.
        """
        nominal, data, guess, opts = self.nominal, self.rows, self.guess, self.opts
        weight = cast(float, opts.orientation_weight)

        def refit(keep: np.ndarray) -> Fit:
            if keep.all():
                return state
            sub = data.subset(keep)
            what = f"{determined.FRAMES} once the outliers are set aside"
            determined.check_frames(measured_kind(sub, self.hold), sub.m, sub.source, what)
            return registrations(nominal, sub, guess, opts, self.hold)(weight)

        def errors(reg: Fit) -> outliers.Errors:  # every registration's kin: the nominal's
            residuals = reg.state.inner.residuals(data, None, state.kin)
            return outliers.point_errors(residuals, data.n_markers)

        def allowed(bad: np.ndarray) -> bool:
            return self.frames is None or self.frames.determined_by(int(np.sum(~bad)))

        rows = term_checks.file_lines(data)
        reg, bad, found = outliers.until_stable(
            refit, errors, opts.noise, rows, allowed, lambda reg: reg.converged
        )
        return Aside(reg, bad, data.subset(~bad) if bad.any() else data, tuple(found))

    def diagnose(self, rows: Measurements, state: Fit) -> list[str]:
        """Raise the rows' likely mistake if they cannot be registered; a note if none explains it.

        It runs at the default orientation weight: an estimated weight would let wrong
        orientations (e.g. quaternions in the wrong order) weigh nothing and go unnoticed. The
        points are diagnosed first, then the orientations (on the orientation error).
        """
        nominal, guess, opts, unit = self.nominal, self.guess, self.opts, weighting.DEFAULT_WEIGHT

        def errors(d):  # the registration's kin: the nominal's at d's joints
            at = self.at if d is self.rows else registrations(nominal, d, guess, opts, self.hold)
            return validation.stats(at(unit).state.inner, d, None, at(unit).kin)

        first = errors(rows)
        chain, rot = self.chain, first.orientation_rms
        position = lambda d: errors(d).position_rms  # noqa: E731
        notes = diagnosis.explain(
            rows, chain, position, first.position_rms, opts.noise, _WORDS, joints_only=False
        )
        if notes or rot is None:  # the positions are suspect: the orientations are not read
            return notes
        turns = lambda d: errors(d).orientation_rms  # noqa: E731
        return diagnosis.explain(rows, chain, turns, rot, None, _TURNS, orientation=True)


def validation_steps(steps: Rows, held: Measurements | None) -> list[tuple[Rows, str]]:
    """The ``steps`` on validation data ``held`` (or None), labelled by their source."""
    if held is None:
        return []
    frames = measured_kind(held, steps.hold)
    if not frames.determined_by(held.m):  # too few rows to register on their own
        return []
    at = registrations(steps.nominal, held, steps.guess, steps.opts, steps.hold)
    return [(dataclasses.replace(steps, rows=held, at=at, frames=frames), held.source)]
