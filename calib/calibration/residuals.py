"""Errors of a calibrated model on measured rows (metres, radians): what every result reports."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..measurements.data import Measurements
from .report import errors_part, finite, held_entry, mm_or_deg

__all__ = ["ResidualStats", "Validation"]


@dataclass(frozen=True)
class ResidualStats:
    """Errors measured - model of a set of measurements.

    Attributes:
        configs: Number of configurations.
        position_rms: sqrt(mean |e_p|^2) over every measured point [m].
        position_max: Largest point error [m].
        orientation_rms: sqrt(mean |e_r|^2) of the rotation error [rad], or None.
        orientation_max: Largest rotation error [rad], or None.
    """

    configs: int
    position_rms: float
    position_max: float
    orientation_rms: float | None = None
    orientation_max: float | None = None

    @staticmethod
    def of(residual: np.ndarray, n_markers: int = 1) -> ResidualStats:
        """Statistics of residuals ``(m, 3 K)`` or, with orientations, ``(m, 3 K + 3)``.

        A marker not seen in a row (NaN: partial marker rows) is no point of the statistics.
        """
        residual = np.asarray(residual, dtype=float)
        m = len(residual)
        pos = np.linalg.norm(residual[:, : 3 * n_markers].reshape(m, n_markers, 3), axis=2)
        if np.isnan(pos).any():
            pos = pos[~np.isnan(pos)]
        rms, top = float(np.sqrt(np.mean(pos**2))), float(np.max(pos))
        if residual.shape[1] != 3 * n_markers + 3:
            return ResidualStats(m, rms, top)
        rot = np.linalg.norm(residual[:, 3 * n_markers :], axis=1)
        return ResidualStats(m, rms, top, float(np.sqrt(np.mean(rot**2))), float(np.max(rot)))

    def in_mm(self) -> dict:
        """The report's form (format 3): lengths in mm, angles in degrees, unit in each key."""
        out: dict = {"configs": self.configs}
        for key in _FIGURES:
            value = getattr(self, key)
            unit, scale = mm_or_deg("orient" in key)
            out[f"{key}_{unit}"] = None if value is None else finite(scale * value)
        return out

    def to_dict(self) -> dict:
        """JSON-ready form (metres, radians; format 2's)."""
        return {"configs": self.configs, **{k: finite(getattr(self, k)) for k in _FIGURES}}


_FIGURES = ("position_rms", "position_max", "orientation_rms", "orientation_max")  # in reports


@dataclass(frozen=True)
class Validation:
    """Errors on configurations the fit never saw.

    Attributes:
        source: ``holdout`` (rows set aside) or the validation file.
        registration: Errors of the registration alone (nominal geometry).
        calibrated: Errors of the calibrated model.
        predicted_std: Predicted position std of the calibrated model, RMS over them [m].
        urdf: Errors of the calibrated URDF alone (without joint compliance), or None.
        rows: The held-out measurements themselves (for per-configuration errors), or None.
    """

    source: str
    registration: ResidualStats
    calibrated: ResidualStats
    predicted_std: float
    urdf: ResidualStats | None = None
    rows: Measurements | None = None

    def in_mm(self) -> dict:
        """The report's ``errors.held_out`` (format 3): mm and degrees, the rows by line."""
        rows = None if self.rows is None else self.rows.file_rows().tolist()
        return {
            **held_entry(self.source, rows),
            **errors_part(self.registration, self.calibrated, self.urdf),
            "predicted_std_mm": finite(1e3 * self.predicted_std),
        }

    def to_dict(self) -> dict:
        """JSON-ready form (format 2's)."""
        return {
            "source": self.source,
            **errors_part(self.registration, self.calibrated, self.urdf, mm=False),
            "predicted_std": finite(self.predicted_std),
        }
