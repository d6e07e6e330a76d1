"""What a calibration returns: residual statistics, the result, its report."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.fileio import json_text
from ..exceptions import CalibrationRefusedError, ConvergenceError
from ..kinematics.elastic import compliance_document
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..kinematics.urdf_export import calibrated_urdf, measurement_to_base, urdf_tool_frame
from ..kinematics.urdf_links import marker_link_names
from ..measurements.data import Measurements
from .delivery import Delivered, RowErrors, compliance_path, row_rms_mm
from .model import ErrorModel, State
from .outliers import Outlier
from .report import (
    FORMAT2_MOVED,
    REPORT_FORMAT,
    build_report,
    finite,
    finite_tree,
    fit_dict,
    gravity_dict,
    model_choice,
    outlier_dict,
    parameter_entries,
    pose_dict,
    term_dict,
    verdict,
)
from .residuals import ResidualStats, Validation
from .selection import Selection

__all__ = [
    "REPORT_FORMAT",
    "CalibrationResult",
    "ResidualStats",
    "Validation",
    "finite",
    "finite_tree",
    "gravity_dict",
]


@dataclass(frozen=True, eq=False, repr=False)
class CalibrationResult(Delivered):
    """Result of a calibration.

    Attributes:
        robot: Robot name.
        chain: The nominal chain (its URDF is what :mod:`calib.kinematics.urdf_export` edits).
        data: The measurements fitted (outliers and held-out rows removed).
        level: Parameter level: ``auto``, ``frames``, ``offsets``, ``paper`` or ``complete``.
        model: The free parameters of the fit.
        names: Their names, in the order of ``estimate``.
        nominal: The nominal MDH model (URDF base frame).
        registration: The registration: nominal geometry, fitted frame and markers.
        state: The calibrated model.
        estimate: Fitted parameters (changes from the registration's start) [rad, m, ...].
        std: Standard deviation of each [same units] (NaN where undefined).
        covariance: Their covariance.
        sigma: Estimated noise of a weighted residual row sigma_hat [m].
        condition: Condition number of the weighted Jacobian with unit-norm columns.
        before: Errors of the registration on the fitted data.
        after: Errors of the calibrated model on the fitted data.
        predicted_std: Predicted position standard deviation at the fitted
            configurations, RMS over them [m].
        validation: Errors on held-out configurations, or None.
        selection: The automatic choice (level ``auto``), or None.
        outliers: Configurations set aside.
        prior: Prior weight of each parameter in the fit (zeros: none).
        iterations: Jacobian evaluations of the final fit.
        evaluations: Residual evaluations of the final fit.
        converged: The final fit converged.
        message: Solver message.
        orientation_weight: Weight of the orientation rows [m/rad].
        refusal: Why the model must not be written (None: accepted).
        warnings: Reasons to be careful with the result.
        timings_ms: Time of each stage [ms].
        urdf_after: Errors of the calibrated URDF alone (no compliance) on the fitted data,
            or None when no compliance was fitted (then it is ``after``).
    """

    robot: str
    chain: Chain
    data: Measurements
    level: str
    model: ErrorModel
    names: tuple[str, ...]
    nominal: MDHModel
    registration: State
    state: State
    estimate: np.ndarray
    std: np.ndarray
    covariance: np.ndarray
    sigma: float
    condition: float
    before: ResidualStats
    after: ResidualStats
    predicted_std: float
    validation: Validation | None
    selection: Selection | None
    outliers: tuple[Outlier, ...]
    prior: np.ndarray
    iterations: int
    evaluations: int
    converged: bool
    message: str
    orientation_weight: float
    refusal: str | None = None
    warnings: tuple[str, ...] = ()
    timings_ms: dict[str, float] = field(default_factory=dict)
    urdf_after: ResidualStats | None = None

    def row_errors(self) -> RowErrors:
        """Position error of each fitted and held-out configuration, before and after [mm]."""
        torque = self.chain.gravity_torques(self.data.q) if self.elastic else None
        parts = [(self.data, torque, False)]
        if self.validation is not None and self.validation.rows is not None:
            held = self.validation.rows
            torque = self.chain.gravity_torques(held.q) if self.elastic else None
            parts.append((held, torque, True))
        before, after, mask = [], [], []
        for data, tau, is_held in parts:
            before.append(row_rms_mm(self.registration.residuals(data), data.n_markers))
            after.append(row_rms_mm(self.state.residuals(data, tau), data.n_markers))
            mask.append(np.full(len(data.q), is_held))
        return RowErrors(np.concatenate(before), np.concatenate(after), np.concatenate(mask))

    @property
    def calibrated(self) -> MDHModel:
        """The calibrated MDH model (URDF base frame; see :attr:`measurement_to_base`)."""
        return self.state.mdh

    @property
    def accepted(self) -> bool:
        """The model passed every check and may be written."""
        return self.refusal is None

    @property
    def measurement_to_base(self) -> np.ndarray:
        """Pose of the calibrated URDF's base frame in the measurement frame ``(4, 4)``.

        The calibrated URDF keeps the nominal placement of joint 1 in its base link: the
        change of MDH rows 0 and 1 joins the measurement frame.
        """
        return self.state.frame @ measurement_to_base(self.nominal, self.calibrated)

    @property
    def elastic(self) -> bool:
        """Joint compliance was fitted (nonzero): the URDF alone is not the whole model."""
        return bool(np.any(self.state.compliance))

    @property
    def tool_placement(self) -> np.ndarray:
        """Pose of the measured frame in the calibrated model's tool frame ``(4, 4)``.

        Pose data: the fitted marker 1 and measured-frame rotation, written into the URDF's
        tool joint (the URDF's tool frame is the measured frame). Position data: identity.
        """
        T = np.eye(4)
        if self.state.tool_rotation is not None:
            T[:3, :3], T[:3, 3] = self.state.tool_rotation, self.state.markers[0]
        return T

    @property
    def urdf_markers(self) -> np.ndarray:
        """The markers in the written URDF's tool frame ``(K, 3)`` [m] (the marker links)."""
        T = self.tool_placement
        return (self.state.markers - T[:3, 3]) @ T[:3, :3]

    @property
    def urdf_tool_frame(self) -> str:
        """The written URDF's frame of the calibrated tool (the measured frame, the markers').

        The tool frame, or ``<tool>_calibrated`` where the tool link is the last joint's.
        """
        return urdf_tool_frame(self.chain)

    @property
    def marker_links(self) -> tuple[str, ...]:
        """Names of the marker links of the written URDF."""
        return marker_link_names(self.chain.tool_frame, self.state.n_markers)

    def urdf(self, world_link: str | None = None, on_robot: bool = False) -> bytes:
        """The calibrated URDF: joints, tool (measured frame), marker links, world link.

        Args:
            world_link: Add the measurement frame as this root link (None: not added).
            on_robot: The instrument is the base frame, on the robot (a head camera): its
                fitted placement is written into the base frame's fixed joint.

        Raises:
            CalibError: As :func:`calib.kinematics.urdf_export.calibrated_urdf`.
        """
        world = None if world_link is None else (world_link, self.measurement_to_base)
        return calibrated_urdf(
            self.chain,
            self.nominal,
            self.calibrated,
            tool=self.tool_placement,
            markers=self.urdf_markers,
            world=world,
            on_robot=self.measurement_to_base if on_robot else None,
        )

    def summary(self) -> str:
        """The text ``calib calibrate`` prints (:func:`~.text.calibration_text`)."""
        from .text import calibration_text  # the text reads the result

        return calibration_text(self)

    def compliance_files(self, out: Path) -> dict[Path, str]:
        """With fitted compliance, its file beside the URDF ``out`` (see :meth:`write`)."""
        if not self.elastic:
            return {}
        return {compliance_path(out): json_text(compliance_document(self, str(out)))}

    def check(self) -> CalibrationResult:
        """Return self if the model may be written.

        Raises:
            ConvergenceError: The fit did not converge.
            CalibrationRefusedError: A check failed (``refusal`` says which).
        """
        if not self.converged:
            raise ConvergenceError(f"the fit did not converge: {self.message}")
        if self.refusal is not None:
            raise CalibrationRefusedError(self.refusal)
        return self

    def points(self, q: np.ndarray) -> np.ndarray:
        """Points predicted by the calibrated model, measurement frame ``(m, K, 3)`` [m].

        Joint compliance, if fitted, needs the gravity torques: use ``state.predict``.
        """
        return self.state.predict(np.atleast_2d(q))[0]

    def to_dict(self, world_link: str | None = None, on_robot: bool = False) -> dict:
        """The JSON report (format 3, :mod:`calib.calibration.report`).

        Args:
            world_link: The ``--world-link`` the URDF was written with (None: none).
            on_robot: The URDF was written with the instrument on the robot (its base frame's
                placement calibrated: ``frames.measurement`` is in the URDF).
        """
        chain, mdh = self.chain, self.nominal
        train = {
            "registration": self.before.in_mm(),
            "calibrated": self.after.in_mm(),
            "urdf": (self.after if self.urdf_after is None else self.urdf_after).in_mm(),
        }
        held = None if self.validation is None else self.validation.in_mm()
        fields = {
            "robot": self.robot,
            "urdf": str(chain.urdf_path),
            "shape": "chain",
            "terms": [
                term_dict(
                    chain.base_frame,
                    chain.tool_frame,
                    self.data.measure,
                    self.data.source,
                    self.data.m,
                )
            ],
            **verdict(self.level, self.refusal, (self.converged, self.message, self.iterations)),
            "parameters": parameter_entries(
                self.names, self.estimate, self.std, mdh.joint_names, mdh.sigma, self.prior
            ),
            "errors": {
                "train": train,
                "held_out": held,
                "terms": [{"train": train, "held_out": held}],
            },
            "frames": {
                "measurement": pose_dict(self.measurement_to_base),
                "measured": pose_dict(self.tool_placement),
                "markers": dict(zip(self.marker_links, self.urdf_markers.tolist(), strict=True)),
                "contacts": {},
                "world_link": world_link,
                "tool_link": self.urdf_tool_frame,
                "on_robot": on_robot,
            },
            "objects": {},
            "fit": fit_dict(
                self.sigma, self.condition, self.predicted_std, self.orientation_weight
            ),
            "model_choice": model_choice(self.selection),
            "outliers": [outlier_dict(o) for o in self.outliers],
            "compliance": dict(
                zip(mdh.joint_names[1:-1], self.state.compliance.tolist(), strict=True)
            ),
            "model": {
                "mdh_nominal": mdh.rows(),
                "mdh_calibrated": self.calibrated.rows(),
                "gravity": gravity_dict(chain),
            },
            "warnings": list(self.warnings),
            "timings_ms": dict(self.timings_ms),
        }
        return build_report(fields, self._format2(world_link), FORMAT2_MOVED)

    def _format2(self, world_link: str | None) -> dict:
        """Format 2's keys that format 3 replaced (written until format 4)."""
        return {
            "data": self.data.source,
            "base_frame": self.chain.base_frame,
            "tool_frame": self.chain.tool_frame,
            "measure": self.data.measure,
            "markers": self.urdf_markers.tolist(),
            "marker_links": list(self.marker_links),
            "measured_frame": pose_dict(self.tool_placement),
            "world_link": world_link,
            "configs": self.data.m,
            "orientation_weight": self.orientation_weight,
            "residuals": {
                "registration": self.before.to_dict(),
                "calibrated": self.after.to_dict(),
                "urdf": (self.after if self.urdf_after is None else self.urdf_after).to_dict(),
            },
            "validation": None if self.validation is None else self.validation.to_dict(),
            "selection": None if self.selection is None else self.selection.to_dict(),
            "sigma": self.sigma,
            "condition_number": self.condition,
            "predicted_std": self.predicted_std,
            "gravity": gravity_dict(self.chain),
            "measurement_to_base": pose_dict(self.measurement_to_base),
            "mdh_nominal": self.nominal.rows(),
            "mdh_calibrated": self.calibrated.rows(),
        }
