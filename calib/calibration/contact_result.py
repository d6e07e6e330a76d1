"""The result of a calibration from flush contacts: gaps, plane, contact frame, report."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..exceptions import CalibrationRefusedError
from ..kinematics.elastic import COMPLIANCE_FORMAT, nominal_masses, nominal_origins
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..kinematics.standing import StandingLoad
from ..kinematics.urdf_export import write_calibrated_urdf
from ..kinematics.urdf_model import read_urdf_file
from .selection import Selection

__all__ = ["ContactCalibration", "GapStats", "gap_stats"]


@dataclass(frozen=True)
class GapStats:
    """Gaps of touches: the contact frame's height and tilts in the plane's frame.

    Attributes:
        m: Touches.
        height_rms_mm, height_max_mm: RMS and largest |height| [mm].
        roll_rms_deg, roll_max_deg, pitch_rms_deg, pitch_max_deg: The tilts [deg].
        weighted_mm: RMS of ``sqrt(z^2 + w^2 (roll^2 + pitch^2))`` [mm] (w: the tilt weight).
    """

    m: int
    height_rms_mm: float
    height_max_mm: float
    roll_rms_deg: float
    roll_max_deg: float
    pitch_rms_deg: float
    pitch_max_deg: float
    weighted_mm: float

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return dict(self.__dict__)


def gap_stats(state, q: np.ndarray, torque: np.ndarray | None = None) -> GapStats:
    """:class:`GapStats` of a :class:`~.contact_model.ContactState` at postures ``q``.

    ``torque``: the gravity torques ``(m, n)`` that deflect compliant joints (or None).
    """
    g = state.gaps(q, torque)
    w = np.array([1.0, state.weight, state.weight])
    rms = np.sqrt(np.mean(g**2, axis=0))
    top = np.max(np.abs(g), axis=0)
    return GapStats(
        len(g),
        1e3 * float(rms[0]),
        1e3 * float(top[0]),
        math.degrees(float(rms[1])),
        math.degrees(float(top[1])),
        math.degrees(float(rms[2])),
        math.degrees(float(top[2])),
        1e3 * float(np.sqrt(np.mean(np.sum((g * w) ** 2, axis=1)))),
    )


@dataclass(frozen=True, eq=False)
class ContactCalibration:
    """A calibration from contacts.

    Attributes:
        chain: The nominal chain.
        nominal: Its MDH model.
        calibrated: The calibrated MDH model (frame -1: the chain's base frame).
        contact: The contact frame in the tool frame ``(4, 4)``.
        plane: The plane in the base frame ``(4, 4)``, z = normal.
        plane_id: The plane's id.
        free: The robot parameters fitted.
        selection: The automatic choice (``auto``), or None.
        stats: ``train``, ``train_registration`` and, with held-out touches, ``held_out``
            and ``held_out_registration`` (the nominal robot with its own plane and contact);
            with compliance, ``train_urdf`` and ``held_out_urdf``: the URDF alone.
        refusal: Why the model must not be used, or None.
        notes: Remarks for the user.
        weight: Weight of the tilt rows [m/rad].
        timings_ms: Stage timings [ms].
        compliance: Fitted joint compliance ``(n,)`` [rad/(N m) or m/N], or None (rigid).
        load: The gravity load the compliance acts under, or None.
    """

    chain: Chain
    nominal: MDHModel
    calibrated: MDHModel
    contact: np.ndarray
    plane: np.ndarray
    plane_id: str
    free: tuple[str, ...]
    selection: Selection | None
    stats: dict[str, GapStats]
    refusal: str | None
    notes: tuple[str, ...]
    weight: float
    timings_ms: dict[str, float]
    compliance: np.ndarray | None = None
    load: StandingLoad | None = None

    @property
    def elastic(self) -> bool:
        """Joint compliance was fitted: the URDF alone is not the whole model."""
        return self.compliance is not None

    @property
    def accepted(self) -> bool:
        """The model may be used (not refused)."""
        return self.refusal is None

    def to_dict(self) -> dict:
        """The JSON report (metres, radians; gaps in mm and degrees)."""
        return {
            "robot": self.chain.name,
            "base": self.chain.base_frame,
            "tool": self.chain.tool_frame,
            "measure": "plane",
            "accepted": self.accepted,
            "refusal": self.refusal,
            "free": list(self.free),
            "selection": None if self.selection is None else self.selection.to_dict(),
            "tilt_weight": self.weight,
            "contact": {
                "planes": {
                    self.plane_id: {"frame": self.chain.base_frame, "matrix": self.plane.tolist()}
                },
                "frames": {self.chain.tool_frame: {"matrix": self.contact.tolist()}},
            },
            "gaps": {k: v.to_dict() for k, v in self.stats.items()},
            "compliance": {
                j: float(c)
                for j, c in zip(
                    self.chain.joint_names,
                    np.zeros(self.chain.n) if self.compliance is None else self.compliance,
                    strict=True,
                )
            },
            "load": None
            if self.load is None
            else {"kind": "standing", "support": self.load.support.to_dict()},
            "calibrated_mdh": self.calibrated.rows(),
            "notes": list(self.notes),
            "timings_ms": dict(self.timings_ms),
        }

    def compliance_document(self, urdf: str) -> dict:
        """The compliance file of the calibrated URDF ``urdf`` (JSON-ready).

        :func:`calib.kinematics.elastic.load_calibrated` reads it back with the URDF.

        Raises:
            CalibrationRefusedError: No compliance was fitted.
        """
        if self.compliance is None or self.load is None:
            raise CalibrationRefusedError("no joint compliance was fitted: no compliance file")
        chain = self.chain
        g = float(np.linalg.norm(chain.model.gravity.linear))
        return {
            "format_version": COMPLIANCE_FORMAT,
            "model": "q' = q + c * tau(q): the URDF's joints see q' at commanded q; tau = gravity "
            "torques of the URDF's masses, the robot standing on the base frame (gravity along "
            "its -z; load), other joints at their neutral position",
            "robot": chain.name,
            "urdf": urdf,
            "base_frame": chain.base_frame,
            "tool_frame": chain.tool_frame,
            "joints": list(chain.joint_names),
            "compliance": self.compliance.tolist(),
            "units": ["rad/(N m)" if s == 0 else "m/N" for s in chain.sigma],
            "gravity": {"frame": chain.base_frame, "vector": [0.0, 0.0, -g]},
            "load": {"kind": "standing", "support": self.load.support.to_dict()},
            "contact": {
                "plane_id": self.plane_id,
                "frame": self.contact.tolist(),
                "plane": self.plane.tolist(),
            },
            "measurement_to_base": np.eye(4).tolist(),
            "markers": [self.contact[:3, 3].tolist()],
            "marker_links": [],
            "nominal_origins": nominal_origins(read_urdf_file(chain.urdf_path)),
            "nominal_masses": nominal_masses(read_urdf_file(chain.urdf_path)),
        }

    def write_urdf(self, path: str | Path) -> None:
        """Write the calibrated URDF (the tool frame stays the chain's tool frame).

        Raises:
            CalibrationRefusedError: The model was refused.
        """
        if self.refusal is not None:
            raise CalibrationRefusedError(f"calibration refused: {self.refusal}")
        write_calibrated_urdf(path, self.chain, self.nominal, self.calibrated)
