"""A pixel calibration's report (format 3's keys), its printed summary, and the count.

The report has every key of :data:`~.report.REPORT_KEYS`; what is the camera's lives inside
them: ``frames.cameras`` (each camera's link and placement, xyz [m] and rpy [rad] as the URDF
writes them, and its intrinsics [px], fitted with ``--refine-intrinsics``),
``objects.targets`` (the target points used, fitted with ``--params complete`` or
``--refine-targets``), ``errors`` (reprojection errors [px] and the position error they mean
at the target's distance [mm], training and held out, per camera in ``terms``).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..measurements.pixel_simulation import simulate_pixels
from ..measurements.pixels import Target
from .pixel_calibration import PixelCalibration, PixelCamera, pixel_rows
from .pixel_term import PixelState, Unknowns, free_columns, pixel_jacobian
from .placements import COMPONENTS, Placements
from .report import REPORT_FORMAT, REPORT_KEYS

__all__ = ["pixel_count", "pixel_report", "pixel_summary"]


def _pose(T: np.ndarray) -> dict:
    return {
        "xyz": [float(v) for v in T[:3, 3]],
        "rpy": [float(v) for v in pin.rpy.matrixToRpy(T[:3, :3])],
    }


def _parameters(result: PixelCalibration) -> list[dict]:
    """Each moved joint's placement change ``E`` in its joint frame (mm, mrad)."""
    out = []
    for joint, E in result.fit.state.placements.errors().items():
        values = (*(1e3 * E[:3, 3]), *(1e3 * pin.log3(E[:3, :3])))
        for c, v in zip(COMPONENTS, values, strict=True):
            unit = "mrad" if c.startswith("r") else "mm"
            out.append(
                {
                    "name": f"{joint}:{c}",
                    "joint": joint,
                    "value": float(v),
                    "std": None,
                    "unit": unit,
                }
            )
    return out


def _camera(result: PixelCalibration, c: int) -> dict:
    """Camera c's link, placement and intrinsics (fitted with ``--refine-intrinsics``)."""
    state = result.fit.states[c]
    lens = state.lens
    intrinsics = dict(zip(lens.parameter_names, map(float, lens.parameters), strict=True))
    return {
        "link": result.cameras[c].link,
        **_pose(state.camera),
        "intrinsics": intrinsics,
        "intrinsics_fitted": result.what.intrinsics,
    }


def _terms(result: PixelCalibration) -> list[dict]:
    return [
        {
            "base": camera.link,
            "tool": view.chain.tool_frame,
            "kind": "pixels",
            "camera": camera.name,
            "configs": len(np.unique(view.rows.q, axis=0)),
            "rows": int(view.rows.m),
        }
        for camera, view in zip(result.cameras, result.views, strict=True)
    ]


def pixel_report(result: PixelCalibration, warnings: list[str]) -> dict:
    """The report of a pixel calibration (the keys of :data:`~.report.REPORT_KEYS`)."""
    state, chain = result.fit.state, result.chain
    targets = {f"p{i}": [float(v) for v in x] for i, x in enumerate(state.target)}
    cameras = {c.name: _camera(result, i) for i, c in enumerate(result.cameras)}
    report = {
        "format_version": REPORT_FORMAT,
        "deprecated": {},
        "robot": chain.name,
        "urdf": str(chain.urdf_path),
        "shape": "pixels",
        "terms": _terms(result),
        "params": "complete" if result.what.mount else "auto",
        "accepted": result.refusal is None,
        "refusal": result.refusal,
        "converged": True,
        "message": "",
        "iterations": None,
        "parameters": _parameters(result),
        "errors": result.errors(),
        "frames": {"cameras": cameras},
        "objects": {"targets": targets},
        "fit": {
            "determined": result.count,
            "unknowns": result.n_unknowns,
            "free": [result.fit.names[i] for i in result.fit.free],
        },
        "model_choice": None,
        "outliers": [{"row": line} for line in result.outliers],
        "compliance": None,
        "model": None,
        "warnings": list(warnings),
        "timings_ms": {},
    }
    return {key: report[key] for key in REPORT_KEYS}


def pixel_summary(result: PixelCalibration) -> str:
    """The text ``calibrate --measure pixels`` prints."""
    seen = sum(v.rows.m for v in result.views)
    lines = [
        f"{result.chain.name}: {len(result.cameras)} camera(s) see {result.chain.tool_frame}'s "
        f"target: {seen} pixels, {result.count} unknowns determined of {result.n_unknowns}"
    ]
    for camera, state in zip(result.cameras, result.fit.states, strict=True):
        pose = _pose(state.camera)
        xyz = " ".join(f"{v:.6f}" for v in pose["xyz"])
        rpy = " ".join(f"{v:.6f}" for v in pose["rpy"])
        lines.append(f"camera {camera.name} in {camera.link}: xyz {xyz} m, rpy {rpy} rad")
    for which, errors in result.errors().items():
        if errors is None:
            continue
        a, b = errors["registration"], errors["calibrated"]
        lines.append(
            f"{which.replace('_', ' ')}: reprojection rms {a['reprojection_rms_px']:.3f} -> "
            f"{b['reprojection_rms_px']:.3f} px ({a['position_rms_mm']:.3f} -> "
            f"{b['position_rms_mm']:.3f} mm at the target)"
        )
    if result.outliers:
        named = ", ".join(str(n) for n in result.outliers[:10])
        lines.append(f"{len(result.outliers)} observation(s) set aside as outliers: rows {named}")
    return "\n".join(lines)


def pixel_count(
    chain, camera: PixelCamera, target: Target, configs: int, seed: int, params: str | None
) -> dict:
    """The unknowns a camera's pixels determine at random postures where it sees the target.

    The rank of the rows' Jacobian on the nominal robot (``n_base``), with the target's
    mounting an unknown when ``params`` is ``complete``.
    """
    q = chain.random_configurations(configs, seed)
    obs = simulate_pixels(chain, camera.name, camera.placement, camera.intrinsics, target, q)
    rows = pixel_rows(chain, obs, target, camera.name)
    placements = Placements.of((chain,))
    mount = params == "complete"
    lens = camera.intrinsics.camera
    state = PixelState(placements, np.asarray(camera.placement), target.position, lens)
    J = pixel_jacobian(state, chain, rows, Unknowns(mount=mount))[1]
    free = free_columns(J.reshape(-1, J.shape[2]), placements, Unknowns(mount=mount))
    return {
        "kind": "pixels",
        "camera": camera.name,
        "link": camera.link,
        "tool": chain.tool_frame,
        "rows": int(rows.m),
        "postures": len(np.unique(rows.q, axis=0)),
        "mount": mount,
        "n_unknowns": 6 + placements.y.size + 6 * mount,
        "n_base": len(free),
    }
