"""The human-readable summary of a calibration (millimetres and milliradians)."""

from __future__ import annotations

import math

import pinocchio as pin

from .report import parameter_entries, parameter_lines
from .residuals import error_table
from .result import CalibrationResult

__all__ = ["calibration_text"]


def _mm(x: float | None) -> str:
    return "-" if x is None or not math.isfinite(x) else f"{1e3 * x:.3f}"


def _selection(r: CalibrationResult) -> list[str]:
    s = r.selection
    if s is None:
        return []
    steps = ", ".join(f"{st.name} {1e3 * st.loo:.3f}" for st in s.steps)
    lines = [f"selection (leave-one-configuration-out RMS per point [mm] after each step): {steps}"]
    verdict = "kept the registration alone" if s.guarded else f"kept {len(s.kept)} parameters"
    verdict += " (the complete fit)" if s.winner == "complete" else ""
    full = f", complete {1e3 * s.complete_cv:.3f} mm" if s.complete_cv == s.complete_cv else ""
    lines.append(
        f"cross-validated check: registration alone {1e3 * s.registration_cv:.3f} mm, "
        f"selection {1e3 * s.selection_cv:.3f} mm{full}: {verdict}"
        + (f"; prior strength {s.strength:.3g}" if s.strength else "")
    )
    return lines


def calibration_text(result: CalibrationResult) -> str:
    """Summary: level and selection, errors before/after, parameters, frame, markers, verdict."""
    r = result
    lines = [
        f"{r.robot}: {r.chain.base_frame} -> {r.chain.tool_frame}, {r.data.m} configurations, "
        f"{r.data.n_markers} point(s)"
        f"{' and orientation' if r.data.quaternion is not None else ''}, "
        f"level {r.level}, {len(r.names)} parameters",
        *_selection(r),
        ("converged" if r.converged else "NOT CONVERGED")
        + f" in {r.iterations} iterations ({r.message})",
        error_table(r.before, r.after, r.urdf_after, r.validation),
        f"predicted position std (parameter uncertainty): {_mm(r.predicted_std)} mm at the fitted "
        f"configurations"
        + (f", {_mm(r.validation.predicted_std)} mm held out" if r.validation is not None else ""),
    ]
    mdh = r.nominal
    lines += parameter_lines(
        parameter_entries(r.names, r.estimate, r.std, mdh.joint_names, mdh.sigma)
    )
    T = r.measurement_to_base
    rpy = pin.rpy.matrixToRpy(T[:3, :3])
    lines.append(
        f"measurement frame -> URDF base frame: xyz [{', '.join(f'{v:.6f}' for v in T[:3, 3])}] m, "
        f"rpy [{', '.join(f'{v:.6f}' for v in rpy)}] rad"
    )
    if r.state.tool_rotation is not None:
        X = r.tool_placement
        where = (
            "the URDF's tool joint"
            if r.urdf_tool_frame == r.chain.tool_frame
            else f"link {r.urdf_tool_frame} fixed to the tool link"
        )
        lines.append(
            f"measured frame in the calibrated tool frame (written into {where}): "
            f"xyz [{', '.join(f'{v:.6f}' for v in X[:3, 3])}] m, "
            f"rpy [{', '.join(f'{v:.6f}' for v in pin.rpy.matrixToRpy(X[:3, :3]))}] rad"
        )
    same = r.urdf_tool_frame == r.chain.tool_frame
    moved = "" if same else f" ({r.urdf_tool_frame})"
    for name, mk in zip(r.marker_links, r.urdf_markers, strict=True):
        lines.append(
            f"marker {name} in the URDF's tool frame{moved}: "
            f"[{', '.join(f'{v:.6f}' for v in mk)}] m"
        )
    lines += [
        f"outlier: {o.text()}, median "
        + (
            f"{math.degrees(o.median):.3g} deg"
            if o.kind == "orientation"
            else f"{1e3 * o.median:.3g} mm"
        )
        for o in r.outliers
    ]
    lines += [f"warning: {w}" for w in r.warnings]
    lines.append("accepted" if r.accepted else f"REFUSED: {r.refusal}")
    return "\n".join(lines)
