"""A measured chain's registration: its measuring frame and markers on the nominal model, checked.

Closed form refined by Levenberg-Marquardt (:func:`registrations`), then every kind's steps
(:mod:`.term_checks`) on its rows (:class:`Rows`). docs/developers/engine.md#chain_registration
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np

from ..core.words import counted
from ..exceptions import DataError
from ..identification.measures import POSE
from ..kinematics.mdh import Kinematics, MDHModel, from_chain
from ..kinematics.robot import Chain
from ..measurements.csvfile import Measurements
from ..measurements.unseen import FIT_ROWS, never_seen
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
"""Random configurations :func:`held_markers` reads the tool's rotations at."""

TURNS = 0.1
"""Range [rad] of two revolute joints, and sine of their axes' angle, that turn every tool."""


def held_markers(chain: Chain, nominal: MDHModel) -> tuple[int, ...]:
    """The first marker's coordinates no posture within the joint limits separates from the frame.

    0-based among the markers' ``3 K``; docs/developers/engine.md#chain_registration.
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
    """The note of marker coordinates held at their given ``guess`` [m] (None: not said)."""
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

    ``weight``: of the rotation rows [m/rad]; ``seen``: the registration's frames at its rows,
    None once the state moves; ``instrument``, ``held``: :class:`!model.MeasuredKind`'s.
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
        """``rows`` ``(m, rows, ...)`` (a fresh array) times :meth:`row_weights`, in place."""
        if self.inner.tool_rotation is not None:
            rows[:, 3 * self.inner.n_markers :] *= self.weight
        return rows

    def residuals(self, data, torque=None, kin=None) -> np.ndarray:
        """Weighted measured - predicted ``(m, rows)`` [m] (``kin``: the joint fit's frames)."""
        return self.weighed(self.inner.residuals(data, None, kin))

    def moved(self, x: np.ndarray) -> MeasuredState:
        """The state with its own unknowns moved by ``x`` (a fit's: without :attr:`seen`)."""
        return dataclasses.replace(self, inner=self.kind.apply(self.inner, x), seen=None)

    def frames_at(self, data: Measurements) -> Kinematics:
        """:attr:`inner`'s frames at ``data``'s joints, undeflected: :attr:`seen`'s if made."""
        s = self.seen
        if s is not None and s.mdh is self.inner.mdh:
            for q, kin in zip(s.q, s.kin, strict=True):
                if q is data.q:
                    return kin
        return self.inner.kinematics(data.q)

    def own_rows(
        self, x: np.ndarray, data: Measurements, kin, moved: MeasuredState | None = None
    ) -> np.ndarray:
        """Weighted d(prediction)/d(own unknowns) at ``x`` ``(m, rows, own)`` (``moved``: at x)."""
        inner = None if moved is None else moved.inner
        return self.weighed(self.kind.jacobian(self.inner, x, data, None, inner, kin))

    def motion_rows(self, kin, data, lin: np.ndarray, ang: np.ndarray) -> np.ndarray:
        """Weighted d(prediction) ``(m, rows, k)`` per unit of k motions of the tool side.

        ``lin``, ``ang`` ``(m, 3, k)``: the velocity of the base frame's origin moving with
        the tool side, and the angular velocity (base frame).
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
        return self.kind.size()

    def apply(self, start: MeasuredState, x: np.ndarray) -> MeasuredState:
        return start.moved(x)

    def jacobian(self, start: MeasuredState, x, data, torque, state, kin) -> np.ndarray:
        return start.own_rows(x, data, kin, state)


def registrations(nominal, data, guess, opts, held=()) -> Callable[[float], Fit]:
    """The registration of ``data`` at an orientation weight, each weight run once.

    The nominal kinematics and the closed-form start (on the first call) are made once;
    ``held``: marker coordinates held at the ``guess``.
    """
    if data.partial and (k := never_seen(data.position, FIT_ROWS)) is not None:
        seen = counted(int(np.sum(data.seen[:, k])), "rows")
        raise DataError(
            data.source,
            f"marker {k + 1} is seen in {seen} of those fitted (held-out rows and outliers "
            f"aside), fewer than {FIT_ROWS}: its place cannot be fitted; hold out fewer rows, "
            "or fit the other points only (Columns' points)",
        )
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
    mistakes="swapped joint columns, degrees, a joint too many or left out (logged) at an end of "
    "the chain, millimetres, centimetres, swapped coordinate columns, quaternion order"
)
_TURNS = diagnosis.Words(
    error="orientation error",
    mistakes="quaternion order, degrees, rpy order",
    check="the orientation columns",
)


@dataclass(frozen=True, eq=False)
class Rows:
    """A chain's steps on one set of measurements (:class:`~.term_checks.Steps`).

    ``at``: :func:`registrations` of ``rows``; ``frames``: the registration's model when the
    outliers may not leave fewer equations than its unknowns (validation data), else None.
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
        the data's).
        """
        nominal, data, guess, opts = self.nominal, self.rows, self.guess, self.opts
        weight = cast(float, opts.orientation_weight)

        def refit(keep: np.ndarray) -> Fit:
            if keep.all():
                return state
            sub = data.subset(keep)
            what = f"{determined.FRAMES} once the outliers are set aside"
            kind = measured_kind(sub, self.hold)
            seen = determined.seen_equations(sub, kind.rows)
            determined.check_frames(kind, sub.m, sub.source, what, equations=seen)
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

        At the default orientation weight: an estimated one could weigh wrong orientations
        (quaternions in the wrong order) to nothing. Points first, then orientations.
        """
        nominal, guess, opts, unit = self.nominal, self.guess, self.opts, weighting.DEFAULT_WEIGHT

        def errors(d, mdh=nominal, hold=self.hold):  # the registration's kin: mdh's at d's joints
            at = self.at if d is self.rows else registrations(mdh, d, guess, opts, hold)
            return validation.stats(at(unit).state.inner, d, None, at(unit).kin)

        def on(longer: Chain):  # another chain's registration (no marker held)
            return lambda d: errors(d, from_chain(longer), ()).position_rms

        first = errors(rows)
        chain, rot = self.chain, first.orientation_rms
        position = lambda d: errors(d).position_rms  # noqa: E731
        notes = diagnosis.explain(
            rows, chain, position, first.position_rms, opts.noise, _WORDS, False, other=on
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
    unseen = held.partial and never_seen(held.position, FIT_ROWS) is not None
    if unseen or not frames.determined_by(held.m):  # too few rows to register on their own
        return []
    at = registrations(steps.nominal, held, steps.guess, steps.opts, steps.hold)
    return [(dataclasses.replace(steps, rows=held, at=at, frames=frames), held.source)]
