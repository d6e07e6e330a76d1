"""A measured term's part of the result (:class:`MeasuredChain`), and a chain's result.

:class:`ChainView`: what users of a chain's result read on a one-term joint fit.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import cached_property
from typing import Any, cast

import numpy as np

from ..exceptions import InvalidArgumentError
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..kinematics.so3 import rotation_vector
from ..kinematics.urdf_export import urdf_tool_frame
from ..measurements.csvfile import check_against_chain
from ..measurements.data import Measurements
from . import validation
from .chain_registration import MeasuredState
from .contact_elastic import urdf_alone
from .contact_result import GapStats, TermPart, part_stats, row_stats, units
from .engine_model import ChainsData
from .measured_report import chain_frames, written_markers
from .measured_term import measuring_joint
from .model import State
from .outliers import Outlier
from .report import parameter_entries
from .residuals import ResidualStats, Validation
from .solve import Fit, condition, covariance

__all__ = [
    "ChainView",
    "MeasuredChain",
    "NotOneChainError",
    "Solution",
    "measured_part",
    "residual_stats",
    "world_of",
]


@dataclass(frozen=True, eq=False)
class MeasuredChain(TermPart):
    """A measured term's part of the result (a frame measuring its chain's tool).

    ``joint``: the fixed joint placing the measuring frame (None: an instrument outside the
    robot); ``registered``, ``state``: its registration on the nominal robot and its fitted
    state (``inner.frame``: the nominal base frame in the measuring frame ``(4, 4)``; markers
    and the measured frame's rotation in the tool frame); ``data``/``held``: its rows fitted
    and held out (outliers left out); ``parameters``: its unknowns' report entries (the
    frame's ``joint`` is :attr:`!joint`); ``outliers``: the registration's; ``residuals``: the
    fitted state's at ``data`` ``(m, rows)`` [m, rad], rigid joints only (else None), read
    again by :mod:`!chain_outliers`.
    """

    chain: Chain
    source: str
    joint: str | None
    registered: MeasuredState
    state: MeasuredState
    stats: dict[str, GapStats]
    data: Measurements
    held: Measurements | None
    parameters: tuple[dict, ...] = ()
    held_source: str | None = None
    held_rows: tuple[int, ...] | None = None
    outliers: tuple[Outlier, ...] = ()
    compliance: np.ndarray | None = None
    residuals: np.ndarray | None = None

    @property
    def kind(self):
        """The term's layout (:class:`~.model.MeasuredKind`)."""
        return self.state.kind

    def heading(self) -> str:
        """Its kind, its rows' units and what measures it (the instrument, a frame's joint)."""
        joint = self.joint
        where = "the instrument" if joint is None else f"the measuring frame in joint '{joint}'"
        return f"measured {self.kind.label} (errors: {units(self.kind)}; {where}):"

    def _own(self) -> dict:
        """Its weight, measuring frame, joint, markers and errors (mm, degrees)."""
        s = self.state.inner
        return {
            "orientation_weight": self.state.weight,
            "measurement_to_base": s.frame.tolist(),
            "joint": self.joint,
            "markers": s.markers.tolist(),
            "errors": {k: v.to_dict() for k, v in self.stats.items()},
        }


def measured_part(
    chain, train, held, registered, state, std, term: int, torques=(None, None), notes=None
) -> MeasuredChain:
    """A measured term's part: its errors, and its unknowns' report entries.

    ``torques``: the gravity torques ``(m, n)`` of ``train`` and ``held`` (None: rigid); with
    compliance fitted, the URDF alone's errors too (``notes`` completed); ``term``: 1-based.
    """
    deflect = {id(train): torques[0], id(held): torques[1]}
    rigid = None if torques[0] is not None else state.inner.residuals(train, None)
    if rigid is not None:
        rigid.flags.writeable = False  # kept by the part (a value)

    def stat(st, rows):  # the fit's rigid residuals at train: made once
        made = rigid if st is state and rows is train else None
        return _measured_stats(st, rows, deflect[id(rows)] if st is state else None, made)

    stats = part_stats(stat, registered, state, train, held)
    compliance = state.inner.compliance if torques[0] is not None else None
    if compliance is not None and np.any(compliance):
        alone = dataclasses.replace(
            state, inner=dataclasses.replace(state.inner, compliance=0 * compliance)
        )
        urdf_alone(lambda d: _measured_stats(alone, d), (train, held), stats, notes, "rows")
    else:
        compliance = None
    joint = None if state.instrument else measuring_joint(chain)
    frame = "instrument" if state.instrument else f"term{term}"  # the instrument's: shared
    names = [f"{frame if n.startswith('frame') else f'term{term}'}.{n}" for n in state.kind.names()]
    entries = parameter_entries(names, _own_change(registered, state)[state.kind.kept], std, ())
    for e in entries:
        e["joint"] = joint if ".frame." in e["name"] else None
    bare = dataclasses.replace(registered, seen=None)  # a result keeps no frames of its rows
    return MeasuredChain(
        chain,
        train.source,
        joint,
        bare,
        state,
        stats,
        train,
        held,
        tuple(entries),
        compliance=compliance,
        residuals=rigid,
    )


def _measured_stats(
    state: MeasuredState, data: Measurements, torque=None, residuals=None
) -> GapStats:
    """Errors of a measured term's rows (mm, degrees); ``residuals``: if already made."""
    if residuals is None:
        kin = state.frames_at(data) if torque is None else None
        residuals = state.inner.residuals(data, torque, kin)
    return row_stats(residuals, state.kind, state.row_weights())


def _own_change(registered: MeasuredState, state: MeasuredState) -> np.ndarray:
    """The term's own unknowns x from the registration to ``state``, in their order.

    The frame's rotation vector of ``R R_0^T`` [rad] and translation change [m], the markers'
    changes [m], then (pose) the measured frame's rotation vector of ``R_t0^T R_t`` [rad].
    """
    a, b = registered.inner, state.inner
    parts = [
        rotation_vector((b.frame[:3, :3] @ a.frame[:3, :3].T)[None])[0],
        b.frame[:3, 3] - a.frame[:3, 3],
        (b.markers - a.markers).ravel(),
    ]
    if a.tool_rotation is not None and b.tool_rotation is not None:
        parts.append(rotation_vector((a.tool_rotation.T @ b.tool_rotation)[None])[0])
    return np.concatenate(parts)


def world_of(
    shape: str, frame: np.ndarray | None, world_link: str | None, on_robot: bool
) -> tuple[str, np.ndarray] | None:
    """The ``world`` argument of the URDF writer (``marker_urdf``), or None.

    ``frame``: the base frame's pose in the instrument's ``(4, 4)``, or None.

    Raises:
        InvalidArgumentError: ``world_link`` or ``on_robot`` not on shape ``chain``, or both.
    """
    for name, given in (("on_robot", on_robot), ("world_link", world_link is not None)):
        if given and (shape != "chain" or frame is None):
            raise InvalidArgumentError(
                f"{name} is for one chain measured by an instrument, not a fit of shape '{shape}'"
            )
    if on_robot and world_link is not None:
        raise InvalidArgumentError(
            "on_robot and world_link: the instrument is on the robot or in the world"
        )
    return None if world_link is None or frame is None else (world_link, frame)


class NotOneChainError(InvalidArgumentError, AttributeError):
    """A chain measured by an instrument's attribute asked of another fit (``hasattr``: False)."""


@dataclass(frozen=True, eq=False)
class Solution:
    """The joint fit's final fit and prior weights, kept for its uncertainty."""

    fit: Fit
    prior: np.ndarray | None = None

    @cached_property
    def covariance(self) -> tuple[np.ndarray, float]:
        """Covariance of x ``sigma^2 (J^T J + P^2)^-1`` and sigma_hat [m] (``solve.covariance``)."""
        f = self.fit.f
        return covariance(self.fit.J, float(f @ f), self.prior)

    def condition(self) -> float:
        """Condition number of the weighted Jacobian with unit-norm columns."""
        return condition(self.fit.J)

    def point_std(self, data: Measurements, torque: np.ndarray | None = None) -> float:
        """Predicted position std at one term's rows, RMS [m] (``torque``: fitted compliance)."""
        fit = self.fit
        rows = ChainsData((data,), None if torque is None else (torque,))
        J = fit.model.jacobian(fit.start, fit.x, rows)
        seen = int(data.seen.sum()) if data.partial else None
        return validation.predicted_std(J, self.covariance[0], data.n_markers, seen)


class ChainView:
    """What a chain's result offers, on a joint fit of one chain measured by an instrument.

    Other shapes raise :class:`NotOneChainError` (an InvalidArgumentError and an
    AttributeError: ``hasattr`` is False).
    """

    chains: tuple[Any, ...]
    solution: Solution | None
    selection: Any
    shape: str
    fitted: tuple[str, ...]
    solver: tuple[bool, str, int]
    notes: tuple[str, ...]
    folds: tuple[Any, ...]

    def one_chain(self) -> MeasuredChain:
        """The one term of a chain measured by an instrument (else :class:`NotOneChainError`)."""
        part = self.chains[0]
        if self.shape != "chain" or not isinstance(part, MeasuredChain) or part.joint:
            raise NotOneChainError(
                f"only a chain measured by an instrument has this attribute, not a fit of shape "
                f"'{self.shape}': each term's part is in result.chains (its errors: .stats)"
            )
        return part

    @property
    def measurement_to_base(self) -> np.ndarray:
        """The base frame's pose in the instrument's ``(4, 4)`` (the URDF keeps the base)."""
        return self.one_chain().state.inner.frame.copy()

    @property
    def robot(self) -> str:
        """The robot's name (its URDF's)."""
        return self.chain.name

    @property
    def chain(self) -> Chain:
        """The nominal chain."""
        return self.one_chain().chain

    @property
    def state(self) -> State:
        """The fitted chain's state (``predict``, ``residuals``; frame, markers)."""
        return self.one_chain().state.inner

    @property
    def registration(self) -> State:
        """The registration on the nominal robot (instrument frame and markers only)."""
        return self.one_chain().registered.inner

    @property
    def nominal(self) -> MDHModel:
        """The nominal MDH model of the chain."""
        return self.one_chain().registered.inner.mdh

    @property
    def orientation_weight(self) -> float:
        """Weight of the rotation rows [m/rad]."""
        return self.one_chain().state.weight

    def points(self, q: np.ndarray) -> np.ndarray:
        """Points predicted by the calibrated model, instrument frame ``(m, K, 3)`` [m]."""
        return self.state.predict(np.atleast_2d(q))[0]

    @property
    def names(self) -> tuple[str, ...]:
        """The fitted unknowns' names: the frame's, the markers', the tool's, then ``fitted``."""
        return (*self.one_chain().kind.names(), *self.fitted)

    @property
    def iterations(self) -> int:
        """Jacobian evaluations of the final fit."""
        return self.solver[2]

    @property
    def converged(self) -> bool:
        """The final fit converged."""
        return self.solver[0]

    @property
    def message(self) -> str:
        """The final fit's solver message."""
        return self.solver[1]

    @property
    def warnings(self) -> tuple[str, ...]:
        """The remarks for the user (``notes``)."""
        return self.notes

    @property
    def outliers(self) -> tuple[Outlier, ...]:
        """Every term's rows set aside, term after term."""
        return tuple(o for c in self.chains for o in c.outliers)

    @property
    def marker_links(self) -> tuple[str, ...]:
        """The written URDF's marker links."""
        return tuple(chain_frames(self.one_chain(), None)["markers"])

    @property
    def urdf_markers(self) -> np.ndarray:
        """The markers in the written URDF's tool frame ``(K, 3)`` [m] (the marker links)."""
        return written_markers(self.state)

    @property
    def urdf_tool_frame(self) -> str:
        """The written URDF's calibrated tool frame (``<tool>_calibrated`` on a last joint's)."""
        return urdf_tool_frame(self.chain)

    @property
    def data(self) -> Measurements:
        """The rows fitted (held-out rows and outliers left out)."""
        return self.one_chain().data

    @property
    def calibrated(self):
        """The chain's calibrated MDH model (the URDF's base frame: see ``measurement_to_base``)."""
        return self.state.mdh

    @cached_property
    def before(self) -> ResidualStats:
        """Errors of the registration (nominal robot, fitted frame and markers) on :attr:`data`."""
        return self._points("train_registration")

    @cached_property
    def after(self) -> ResidualStats:
        """Errors of the calibrated model on :attr:`data`."""
        return self._points("train")

    @cached_property
    def urdf_after(self) -> ResidualStats | None:
        """Errors of the URDF alone (compliance left out) on :attr:`data`; None when rigid."""
        return self._points("train_urdf") if self.one_chain().compliance is not None else None

    def _points(self, key: str) -> ResidualStats:
        part = self.one_chain()
        rows = cast(np.ndarray, part.stats[key].residuals)  # [m, rad]: measured_part keeps them
        return ResidualStats.of(rows, part.data.n_markers)

    @property
    def covariance(self) -> np.ndarray:
        """Covariance of the fit's unknowns (the term's own, then ``fitted``) ``(p, p)``."""
        return self._solution().covariance[0]

    @property
    def sigma(self) -> float:
        """Estimated noise of a weighted row sigma_hat = sqrt(RSS / (r - p)) [m]."""
        return self._solution().covariance[1]

    @property
    def condition(self) -> float:
        """Condition number of the fit's weighted Jacobian with unit-norm columns."""
        return self._solution().condition()

    @cached_property
    def predicted_std(self) -> float:
        """Predicted position std at :attr:`data`, RMS over them [m] (``Solution.point_std``)."""
        return self._point_std(self.data)

    @cached_property
    def validation(self) -> Validation | None:
        """Errors on the held-out rows [m, rad] (those :attr:`before` .. give), or None."""
        part = self.one_chain()
        held = part.held
        if held is None:
            return None
        urdf = self._points("held_out_urdf") if part.compliance is not None else None
        return Validation(
            part.held_source or held.source,
            self._points("held_out_registration"),
            self._points("held_out"),
            self._point_std(held),
            urdf,
            held,
        )

    def _point_std(self, rows: Measurements) -> float:
        return self._solution().point_std(rows, _gravity_torque(self.chain, self.state, rows))

    def _solution(self) -> Solution:
        self.one_chain()
        if self.solution is None:
            raise InvalidArgumentError("this result keeps no solution (its uncertainty is unknown)")
        return self.solution


def _gravity_torque(chain: Chain, state: State, data: Measurements) -> np.ndarray | None:
    """The chain's gravity torques at the rows where the state has compliance, else None."""
    return chain.gravity_torques(data.q) if np.any(state.compliance) else None


def residual_stats(result: ChainView, data: Measurements) -> ResidualStats:
    """Errors of a calibrated chain on other rows [m, rad] (gravity torques where fitted).

    Args:
        result: A calibration of one chain measured by an instrument (shape ``chain``).
        data: Rows of the same chain, measured as its data were.

    Raises:
        InvalidArgumentError: Not a calibration of one chain measured, or not measurements.
        DataError: Rows that are not of the chain.
    """
    if not isinstance(result, ChainView) or not isinstance(data, Measurements):
        raise InvalidArgumentError(
            "residual_stats takes the result of one chain measured and Measurements"
        )
    chain, state = result.chain, result.state
    check_against_chain(data, chain)
    return validation.stats(state, data, _gravity_torque(chain, state, data))
