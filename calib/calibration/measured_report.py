"""One chain measured by an instrument: its calibrated tool as written, its report and table.

The URDF's calibrated tool is the measured frame at marker 1 (pose data) or the tool frame
(position data), the markers in it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ..identification.report import format_table
from ..kinematics.elastic import gravity_in_base
from ..kinematics.mdh import in_chart_of
from ..kinematics.placement_export import instrument_joint
from ..kinematics.urdf_export import read_urdf_source, urdf_tool_frame
from ..kinematics.urdf_links import marker_link_names
from .chain_counts import chain_name
from .model import State
from .report import URDF_ALONE, errors_part, fit_dict, one_term, pose_dict, selection_dict
from .residuals import ResidualStats

if TYPE_CHECKING:
    from .measured_view import ChainView, MeasuredChain

__all__ = ["chain_frames", "chain_lines", "chain_report", "chain_writing", "written_markers"]


def tool_pose(inner: State) -> np.ndarray:
    """The calibrated tool: the measured frame in the tool frame ``(4, 4)`` (or identity)."""
    T = np.eye(4)
    if inner.tool_rotation is not None:
        T[:3, :3], T[:3, 3] = inner.tool_rotation, inner.markers[0]
    return T


def written_markers(inner: State) -> np.ndarray:
    """The markers in the written URDF's calibrated tool frame ``(K, 3)`` [m]."""
    T = tool_pose(inner)
    return (inner.markers - T[:3, 3]) @ T[:3, :3]


def chain_frames(part: MeasuredChain, world_link: str | None, on_robot: bool = False) -> dict:
    """The report's ``frames`` of a chain's (one measurement frame, marker links by name)."""
    inner = part.state.inner
    links = marker_link_names(part.chain.tool_frame, inner.n_markers)
    return {
        "measurement": pose_dict(inner.frame),
        "measured": pose_dict(tool_pose(inner)),
        "markers": dict(zip(links, written_markers(inner).tolist(), strict=True)),
        "contacts": {},
        "world_link": world_link,
        "tool_link": urdf_tool_frame(part.chain),
        "on_robot": on_robot,
        "cameras": {},
    }


def chain_writing(part: MeasuredChain, errors: dict, on_robot: bool) -> tuple:
    """``marker_urdf``'s ``errors``, ``markers`` and ``tool`` of one chain measured.

    ``on_robot``: the base frame's fixed joint gets origin ``O F^-1`` (``F``: the base frame
    in the measuring frame), so that forward kinematics gives measured coordinates.

    Raises:
        CalibError: ``on_robot`` with a base frame not fixed to a link by a fixed joint.
    """
    inner = part.state.inner
    if on_robot:
        joint = instrument_joint(read_urdf_source(part.chain)[1], part.chain)
        errors = {**errors, joint.get("name", ""): np.linalg.inv(inner.frame)}
    return errors, ((part.chain, written_markers(inner)),), tool_pose(inner)


def chain_lines(view: ChainView) -> list[str]:
    """A chain's summary lines: its errors table (fitted, held out) and the predicted std [mm]."""
    held, what = view.validation, ("registration only", "calibrated", URDF_ALONE)
    parts = [("fitted", (view.before, view.after, view.urdf_after))]
    if held is not None:
        parts.append((f"held out ({held.source})", (held.registration, held.calibrated, held.urdf)))
    rows = [(f"{p}, {w}", st) for p, found in parts for w, st in zip(what, found, strict=True)]
    header = ["errors", "configs", "rms [mm]", "max [mm]"]
    if view.after.orientation_rms is not None:
        header += ["rot rms [mrad]", "rot max [mrad]"]
    std = (
        ""
        if held is None
        else " (of the fit of every row, not of the folds' fits)"  # every row held out once
        if view.folds
        else f", {1e3 * held.predicted_std:.3f} mm held out"
    )
    return [
        format_table(header, [_row(label, st) for label, st in rows if st is not None]),
        f"predicted position std (parameter uncertainty): {1e3 * view.predicted_std:.3f} mm "
        f"at the fitted configurations{std}",
    ]


def _row(label: str, st: ResidualStats) -> list[str]:
    """A row of the errors table [mm, mrad]."""
    figures: list[float | None] = [st.position_rms, st.position_max]
    if st.orientation_rms is not None:
        figures += [st.orientation_rms, st.orientation_max]
    return [label, str(st.configs)] + [
        "-" if x is None or not math.isfinite(x) else f"{1e3 * x:.3f}" for x in figures
    ]


def chain_report(
    view: ChainView, fields: dict, world_link: str | None, on_robot: bool = False
) -> tuple[dict, dict]:
    """One chain measured: the report's ``fields`` (a copy) completed, and format 2's keys."""
    part, held = view.one_chain(), view.validation
    train = (view.before, view.after, view.urdf_after)
    errors = {"train": errors_part(*train), "held_out": None if held is None else held.in_mm()}
    own = {p["name"] for p in part.parameters}  # named as the chain names them: frame.z
    nominal = view.nominal.rows()
    calibrated = in_chart_of(view.calibrated, view.nominal).rows()  # comparable row by row
    g = gravity_in_base(part.chain).tolist()  # [m/s^2]
    gravity = {"frame": part.chain.base_frame, "vector": g}
    std, weight = view.predicted_std, view.orientation_weight
    out = one_term(
        fields,
        errors,
        part.chain,
        part.compliance,
        frames=chain_frames(part, world_link, on_robot),
        parameters=[
            {**p, "name": chain_name(p["name"])} if p["name"] in own else p
            for p in fields["parameters"]
        ],
        model={
            "mdh_nominal": nominal,
            "mdh_calibrated": calibrated,
            **fields["model"],
            "gravity": gravity,
        },
        fit=fit_dict(view.sigma, view.condition, std, weight),
    )
    frames, data = out["frames"], view.data
    legacy = {
        "data": data.source,
        "base_frame": part.chain.base_frame,
        "tool_frame": part.chain.tool_frame,
        "measure": data.measure,
        "markers": list(frames["markers"].values()),
        "marker_links": list(frames["markers"]),
        "measured_frame": frames["measured"],
        "world_link": world_link,
        "configs": data.m,
        "orientation_weight": weight,
        "residuals": errors_part(*train, mm=False),
        "validation": None if held is None else held.to_dict(),
        "selection": selection_dict(view.selection),
        "sigma": view.sigma,
        "condition_number": view.condition,
        "predicted_std": std,
        "gravity": gravity,
        "measurement_to_base": frames["measurement"],
        "mdh_nominal": nominal,
        "mdh_calibrated": calibrated,
    }
    return out, legacy
