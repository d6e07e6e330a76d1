"""The one report (format 3) of every calibration: its keys, the entries every shape shares.

The layout: ``docs/reference/formats.md``; format 2's replaced keys are written beside them
until format 4 (:data:`FORMAT2_MOVED`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence

import numpy as np
import pinocchio as pin

from ..core.words import counted
from ..identification.parameters import ROW_NAME, joint_of

__all__ = [
    "REPORT_KEYS",
    "URDF_ALONE",
    "build_report",
    "errors_part",
    "finite",
    "fit_dict",
    "fold_lines",
    "held_entry",
    "mm_or_deg",
    "model_choice",
    "one_term",
    "outlier_dict",
    "parameter_entries",
    "parameter_lines",
    "pose_dict",
    "selection_dict",
    "term_errors",
    "with_folds",
]

REPORT_KEYS = (
    "format_version",
    "deprecated",
    "robot",
    "urdf",
    "shape",
    "terms",
    "params",
    "accepted",
    "refusal",
    "converged",
    "message",
    "iterations",
    "parameters",
    "errors",
    "frames",
    "objects",
    "fit",
    "model_choice",
    "outliers",
    "compliance",
    "model",
    "warnings",
    "timings_ms",
)
"""The top-level keys of every report (format 3), in order."""

URDF_ALONE = "URDF alone (no compliance)"
"""The summaries' name of the calibrated URDF without its fitted joint compliance."""

_ANGLES = ("alpha", "beta", "gamma", "theta")


def _unit(name: str, sigma: Sequence[int] | np.ndarray | None = None) -> str:
    """The unit of a parameter's value: ``rad``, ``m``, ``rad/(N m)`` or ``m/N``."""
    name = name.partition("@")[0]
    row = ROW_NAME.fullmatch(name)
    if row is not None:
        kind, k = row.group(1), int(row.group(2))
        prismatic = sigma is not None and 0 <= k < len(sigma) and sigma[k] == 1
        if kind == "c":
            return "m/N" if prismatic else "rad/(N m)"
        if kind == "offset":
            return "m" if prismatic else "rad"
        return "rad" if kind in _ANGLES else "m"
    axis = re.split(r"[.:]", name)[-1]
    direction = ROW_NAME.fullmatch(axis) if ":" in name else None  # <joint>:<MDH parameter>
    if direction is not None:
        return "rad" if direction.group(1) in (*_ANGLES, "offset") else "m"
    return "rad" if axis in ("rx", "ry", "rz") else "m"


def parameter_entries(
    names: Sequence[str],
    values: Sequence[float] | np.ndarray,
    stds: Sequence[float] | np.ndarray,
    joint_names: Sequence[str | None],
    sigma: Sequence[int] | np.ndarray | None = None,
) -> list[dict]:
    """The report's ``parameters``: ``name``, ``joint``, ``value``, ``std``, ``unit``, prior.

    ``values``: changes from the registration; ``prior_weight`` is written 0.0 (no route
    records the fit's prior weights here).
    """
    return [
        {
            "name": n,
            "joint": joint_of(n, joint_names),
            "value": finite(v),
            "std": finite(s),
            "unit": _unit(n, sigma),
            "prior_weight": 0.0,
        }
        for n, v, s in zip(names, values, stds, strict=True)
    ]


FORMAT2_MOVED = {
    "data": "terms[].data",
    "base_frame": "terms[].base",
    "tool_frame": "terms[].tool",
    "base": "terms[].base",
    "tool": "terms[].tool",
    "tools": "terms[].tool",
    "measure": "terms[].kind",
    "configs": "terms[].configs",
    "rows": "terms[].configs",
    "markers": "frames.markers",
    "marker_links": "frames.markers",
    "measured_frame": "frames.measured",
    "world_link": "frames.world_link",
    "measurement_to_base": "frames.measurement",
    "contact": "frames.contacts and objects",
    "orientation_weight": "fit.orientation_weight",
    "tilt_weight": "fit.orientation_weight",
    "sigma": "fit.sigma",
    "condition_number": "fit.condition_number",
    "predicted_std": "fit.predicted_std_mm",
    "residuals": "errors.train (mm, deg)",
    "gaps": "errors (mm, deg)",
    "validation": "errors.held_out (mm, deg)",
    "per_tool": "errors.terms",
    "chains": "terms and errors.terms",
    "selection": "model_choice",
    "free": "parameters[].name",
    "gravity": "model.gravity",
    "load": "model.load",
    "mdh_nominal": "model.mdh_nominal",
    "mdh_calibrated": "model.mdh_calibrated",
    "calibrated_mdh": "model.mdh_calibrated",
    "joint_origins": "model.joint_origins",
    "shared_joints": "model.shared_joints",
    "planes": "objects",
    "notes": "warnings",
}
"""Each format 2 key that format 3 replaced, and the key that replaces it."""


def errors_part(registration, calibrated, urdf=None, mm: bool = True) -> dict:
    """One part of the report's ``errors``: ``registration``, ``calibrated``, ``urdf``.

    In mm and degrees (``mm`` False: format 2's metres and radians); ``urdf`` None: ``calibrated``.
    """
    parts = (registration, calibrated, calibrated if urdf is None else urdf)
    return {
        key: s.in_mm() if mm else s.to_dict()
        for key, s in zip(("registration", "calibrated", "urdf"), parts, strict=True)
    }


def term_errors(
    stats: Mapping, held_source: str | None, held_rows: Sequence[int] | None = None
) -> dict:
    """A term's ``errors.terms`` entry (format 3): ``train`` and ``held_out`` (None: none).

    ``held_rows``: the held-out rows scored, by their line in ``held_source``'s file (None:
    unknown), written sorted as ``held_out.rows``.
    """
    out: dict = {"train": None, "held_out": None}
    for key in out:
        if key in stats:
            part = errors_part(stats[f"{key}_registration"], stats[key], stats.get(f"{key}_urdf"))
            out[key] = part if key == "train" else {**held_entry(held_source, held_rows), **part}
    return out


def held_entry(source: str | None, rows: Sequence[int] | None) -> dict:
    """A ``held_out`` entry's ``source`` and ``rows`` (the rows scored, sorted; None: unknown)."""
    return {"source": source, "rows": None if rows is None else sorted(int(r) for r in rows)}


def selection_dict(selection) -> dict | None:
    """Format 2's ``selection``: the automatic choice's record, errors in m (None: none)."""
    return None if selection is None else selection.to_dict()


def model_choice(selection) -> dict | None:
    """The report's ``model_choice``: the selection's record, errors in mm (None: none)."""
    out = selection_dict(selection)
    if out is None:
        return None
    out["steps"] = [
        {"name": s["name"], "loo_mm": finite(1e3 * s["loo"])} for s in out.get("steps", [])
    ]
    for key in [k for k in out if k.startswith("cv_")]:  # cross-validated errors [m]
        value = out.pop(key)
        out[f"{key}_mm"] = None if value is None else finite(1e3 * value)
    return out


def mm_or_deg(angle: bool) -> tuple[str, float]:
    """The report's unit of an error and its factor from SI: ``("mm", 1e3)`` or ``("deg", ...)``."""
    return ("deg", math.degrees(1.0)) if angle else ("mm", 1e3)


def outlier_dict(outlier, term: int = 0) -> dict:
    """One ``outliers`` entry: ``term`` (index in ``terms``), ``row``, ``kind``, error [mm, deg]."""
    unit, scale = mm_or_deg(outlier.kind == "orientation")
    return {
        "term": term,
        "row": outlier.row,
        "kind": outlier.kind,
        f"error_{unit}": finite(scale * outlier.error),
        f"median_{unit}": finite(scale * outlier.median),
    }


_DISPLAY = {"m": (1e3, "mm"), "rad": (1e3, "mrad")}
"""How the printed table shows a unit: lengths in mm, angles in mrad."""


def parameter_lines(entries: Sequence[Mapping]) -> list[str]:
    """The printed table of ``parameters`` entries: name, URDF joint, value +- std."""
    if not entries:
        return ["parameters: none fitted"]
    lines = ["parameters (change from the registration +- std), with their URDF joint:"]
    width = max(len(e["name"]) for e in entries)
    joints = [  # the joint, "-" for none, blank when the name says it
        "-" if e["joint"] is None else "" if e["name"].startswith(e["joint"] + ":") else e["joint"]
        for e in entries
    ]
    jw = max(len(j) for j in joints)
    for e, joint in zip(entries, joints, strict=True):
        scale, unit = _DISPLAY.get(e["unit"], (1.0, e["unit"]))
        value = "-" if e["value"] is None else f"{scale * e['value']:.4g}"
        sd = "-" if e["std"] is None else f"{scale * e['std']:.4g}"
        lines.append(f"  {e['name']:>{width}} {joint:<{jw}} = {value:>10} +- {sd:<9} {unit}")
    return lines


def pose_dict(T: np.ndarray | None) -> dict | None:
    """A pose ``(4, 4)`` as ``{xyz [m], rpy [rad], matrix}`` (None stays None)."""
    if T is None:
        return None
    T = np.asarray(T, dtype=float)
    return {
        "xyz": T[:3, 3].tolist(),
        "rpy": pin.rpy.matrixToRpy(T[:3, :3]).tolist(),
        "matrix": T.tolist(),
    }


def fit_dict(
    sigma: float | None = None,
    condition: float | None = None,
    predicted_std: float | None = None,
    orientation_weight: float | None = None,
) -> dict:
    """The report's ``fit``: noise [m], condition number, predicted std [mm], weight [m/rad]."""
    return {
        "sigma": finite(sigma),
        "condition_number": finite(condition),
        "predicted_std_mm": None if predicted_std is None else finite(1e3 * predicted_std),
        "orientation_weight": finite(orientation_weight),
    }


def build_report(fields: Mapping[str, object], legacy: Mapping[str, object]) -> dict:
    """A format-3 report: ``fields`` in the order of :data:`REPORT_KEYS`, then format 2's keys.

    ``fields``: every key but the first two; ``legacy``: format 2 keys (:data:`FORMAT2_MOVED`).
    KeyError for a missing key or a legacy key without replacement (tests pin the layout).
    """
    deprecated = {
        key: f"format 3 moved it to '{FORMAT2_MOVED[key]}'; written until format 4"
        for key in legacy
    }
    # format_version: raised when a key is renamed or removed (an added key keeps it)
    report: dict[str, object] = {"format_version": "3", "deprecated": deprecated}
    report.update({key: fields[key] for key in REPORT_KEYS[2:]})
    unexpected = set(fields) - set(REPORT_KEYS)
    if unexpected:
        raise KeyError(f"not a report key: {sorted(unexpected)}")
    for key, value in legacy.items():
        if key in report:
            raise KeyError(f"legacy key '{key}' is a format 3 key")
        report[key] = value
    return _finite_tree(report)


def finite(x: float | np.floating | None) -> float | None:
    """``float(x)``, or None for None, an infinity or NaN."""
    return float(x) if x is not None and math.isfinite(x) else None


def _finite_tree(value):
    """A copy of a JSON-ready tree with every non-finite float replaced by None."""
    if isinstance(value, dict):
        return {k: _finite_tree(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_tree(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return finite(value)
    return value


def one_term(fields: Mapping, errors: dict, chain, compliance: np.ndarray | None, **own) -> dict:
    """The report's ``fields`` of one term's layout (one chain measured or touching).

    ``errors``: the term's ``errors.terms`` entry, the report's too; ``compliance``
    [rad/(N m) or m/N], None: zeros; ``own``: the layout's other fields.
    """
    c = np.zeros(chain.n) if compliance is None else compliance
    joints = dict(zip(chain.joint_names, map(float, c), strict=True))
    return {**fields, "errors": {**errors, "terms": [errors]}, "compliance": joints, **own}


def with_folds(report: dict, folds) -> dict:
    """``report`` with each fold's held-out errors in every ``held_out`` entry (``folds``)."""
    if not folds:
        return report
    errors = report["errors"]
    for k, term in enumerate(errors["terms"]):
        term["held_out"]["folds"] = [errors_part(*fold[k]) for fold in folds]
    held = errors.get("held_out")
    if held is not None and len(errors["terms"]) == 1:
        held["folds"] = errors["terms"][0]["held_out"]["folds"]
    return report


def fold_lines(folds, chains) -> list[str]:
    """The summary's errors of each fold's held-out rows: weighted RMS [mm], a line a term."""
    terms = [f", {c.named(k)}" if len(chains) > 1 else "" for k, c in enumerate(chains)]
    lines = [
        f"  fold {k + 1}{terms[c]}: {b.weighted_mm:.3f} -> {a.weighted_mm:.3f} "
        f"({counted(a.m, 'rows')})"
        for k, fold in enumerate(folds)
        for c, (b, a) in enumerate(fold)
    ]
    head = "held out by fold (weighted RMS [mm], registration only -> calibrated):"
    return [head, *lines] if folds else []
