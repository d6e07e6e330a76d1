"""A tree measured by one instrument: one measured term per tool, the instrument's frame shared.

Here: the rows cut by tool, the tree's checks before the joint fit, the shared frame's
registration, the report's errors of every tool together.
How it works: docs/developers/engine.md#instrument
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..exceptions import DataError
from ..identification.measures import POSITION
from ..kinematics.mdh import from_chain
from ..kinematics.tree import Tree
from ..kinematics.urdf_links import marker_link_names
from ..measurements.data import Measurements
from ..measurements.limits import check_against_chain
from . import determined, diagnosis, validation
from .chain_registration import MeasuredState
from .model import nominal_state
from .registration import register_points
from .report import URDF_ALONE, pose_dict, term_errors
from .residuals import ResidualStats

__all__ = [
    "by_tool",
    "instrument_errors",
    "instrument_format2",
    "instrument_lines",
    "pooled",
    "prepare_tree",
    "shared_frame",
    "tool_parts",
    "tree_points",
]


def tool_parts(
    tree: Tree, data: Measurements | None, every: bool = True
) -> list[Measurements | None]:
    """A tree's rows cut by tool on its chain's joints (None: none; ``every``: each tool has rows).

    Raises:
        DataError: Data of other joints, pose or several-point rows, a tool no row measures.
        InvalidArgumentError: ``data`` are not Measurements.
    """
    if data is None:
        return [None] * tree.n_tools
    check_against_chain(data, tree)
    if data.quaternion is not None or data.n_markers != 1:
        raise DataError(
            data.source, "a tree is calibrated from one point per row (x, y, z and a tool)"
        )
    parts = by_tool(tree, data)
    missing = [c.tool_frame for c, p in zip(tree.chains, parts, strict=True) if p is None]
    if every and missing:
        raise DataError(
            data.source,
            f"no row measures the tool {missing[0]}: calibrate the tools the rows measure "
            f"(a tool for each)",
        )
    return parts


def by_tool(tree: Tree, data: Measurements) -> list[Measurements | None]:
    """Each tool's rows on its chain's joints (None: no row), unchecked (:func:`tool_parts`)."""
    tools = np.array(data.tool if data.tool is not None else (tree.tool_frames[0],) * data.m)
    parts: list[Measurements | None] = []
    for chain, path in zip(tree.chains, tree.paths, strict=True):
        mask = tools == chain.tool_frame
        if not mask.any():
            parts.append(None)
            continue
        sub = data.subset(mask)
        q, rows, tool = sub.q[:, path], sub.rows, sub.tool
        parts.append(Measurements(chain.joint_names, q, sub.position, None, sub.source, rows, tool))
    return parts


def shared_frame(states: list, train: list) -> list:
    """The instrument terms' frame and markers registered together in closed form (others kept)."""
    terms = [c for c, s in enumerate(states) if isinstance(s, MeasuredState) and s.instrument]
    if not terms:
        return states
    kin = [states[c].frames_at(train[c]) for c in terms]  # the registration's, if made
    frame, markers = register_points(
        [k.R[:, -1] for k in kin],
        [k.p[:, -1] for k in kin],
        [train[c].points for c in terms],
        [states[c].inner.markers for c in terms],
        [states[c].held for c in terms],  # at their given value (one chain's gantry)
    )
    out = list(states)
    for c, mk in zip(terms, markers, strict=True):
        inner = dataclasses.replace(states[c].inner, frame=frame.copy(), markers=mk)
        out[c] = dataclasses.replace(states[c], inner=inner)
    return out


def instrument_format2(measured) -> dict:
    """Format 2's keys of a tree's report (written until format 4) of the instrument terms."""
    first, stats = measured[0], pooled(measured)

    def both(stats: dict[str, ResidualStats], k: str) -> dict:  # of rows k [m]
        keys = {"registration": f"{k}_registration", "calibrated": k}
        return {n: stats[key].to_dict() if key in stats else None for n, key in keys.items()}

    return {
        "data": first.source,
        "rows": sum(c.stats["train"].m for c in measured),
        "residuals": both(stats, "train") if "train" in stats else None,
        "per_tool": [{"tool": c.chain.tool_frame, **both(pooled([c]), "train")} for c in measured],
        "validation": both(stats, "held_out") if "held_out" in stats else None,
        "measure": "position",
        "base_frame": first.chain.base_frame,
        "tools": [c.chain.tool_frame for c in measured],
        "measurement_to_base": pose_dict(first.state.inner.frame),
        "markers": {c.chain.tool_frame: c.state.inner.markers[0].tolist() for c in measured},
        "marker_links": {
            t: marker_link_names(t, 1)[0] for t in (c.chain.tool_frame for c in measured)
        },
    }


def pooled(parts) -> dict[str, ResidualStats]:
    """Position errors of every tool's rows together, by part (those a tool has) [m]."""
    out = {}
    for key in dict.fromkeys(k for c in parts for k in c.stats):
        rows = [c.stats[key].per_row for c in parts if key in c.stats]
        if all(r is not None for r in rows):
            e = 1e-3 * np.concatenate(rows)  # [m]
            out[key] = ResidualStats(len(e), float(np.sqrt(np.mean(e**2))), float(np.max(e)))
    return out


def instrument_errors(parts) -> dict:
    """The report's ``errors.train`` and ``errors.held_out`` of every tool together."""
    if not parts:
        return {"train": None, "held_out": None}
    rows = [r for c in parts for r in c.held_rows or ()]  # every tool's (None: none held)
    return term_errors(pooled(parts), parts[0].held_source, rows or None)


def instrument_lines(parts) -> list[str]:
    """The summary's lines of every tool together: position RMS / max [mm], fitted, held out."""
    lines, stats = [], pooled(parts)
    for key, label in (("train", "fitted rows"), ("held_out", "held-out rows")):
        if key not in stats:
            continue
        figures = [
            f"{what} {1e3 * s.position_rms:.4g} / {1e3 * s.position_max:.4g}"
            for what, s in (
                ("registration", stats[f"{key}_registration"]),
                ("calibrated", stats[key]),
                (URDF_ALONE, stats.get(f"{key}_urdf")),
            )
            if s is not None
        ]
        lines.append(f"{label} of every tool, position RMS / max [mm]: {', '.join(figures)}")
    return lines


def tree_points(parts, paths, q: np.ndarray) -> np.ndarray:
    """Each tool's marker predicted in the instrument's frame ``(m, T, 3)`` [m]."""
    q = np.asarray(q, dtype=float)
    return np.stack(
        [c.state.inner.predict(q[:, path])[0][:, 0] for c, path in zip(parts, paths, strict=True)],
        axis=1,
    )


def prepare_tree(
    tree: Tree, data: Measurements, validate: Measurements | None, holdout: float, seed: int
):
    """Check a tree's rows as a whole; each tool's rows and held-out rows (None: none).

    Held-out rows are drawn among the tree's postures, every tool's together.

    Raises:
        DataError: Rows of other joints, pose or several-point rows, a tool no row measures,
            too few rows, a usual mistake (named), validation rows that are training rows or
            measured in another frame.
    """
    tool_parts(tree, data)
    out = round(holdout * data.m)
    unknowns = 6 + 3 * tree.n_tools
    what = determined.FRAMES  # one tool's point a row: no MeasuredKind's rows
    determined.check_equations(data.m - out, 3, unknowns, what, data.source, held=out, unit="rows")
    nominal = [  # every tool's chain on the nominal tree, its marker at its flange
        MeasuredState(nominal_state(from_chain(c), np.zeros((1, 3)), POSITION), 1.0, True)
        for c in tree.chains
    ]
    if validate is not None:  # with a holdout too: refused by Problem
        validation.check_held_out(data, validate)
        if set(validate.tools) == set(tree.tool_frames) and 3 * validate.m > unknowns:
            _diagnosed(tree, nominal, validate)
    reg, fitted = _diagnosed(tree, nominal, data)
    if validate is not None:
        other = _stats(reg, by_tool(tree, validate))
        validation.check_held_out_errors(fitted.position_rms, other.position_rms, validate.source)
    train, held = (
        (data, validate) if validate is not None else validation.split(data, holdout, seed)
    )
    return tool_parts(tree, train), tool_parts(tree, held, every=False)


def _stats(states: list[MeasuredState], parts: list[Measurements | None]) -> ResidualStats:
    """The registration's errors on every tool's rows."""
    rows = [s.residuals(p) for s, p in zip(states, parts, strict=True) if p is not None]
    return ResidualStats.of(np.concatenate(rows))


_WORDS = diagnosis.Words(mistakes="swapped joint columns, degrees, millimetres, centimetres")


def _diagnosed(tree: Tree, nominal: list, data: Measurements) -> tuple[list, ResidualStats]:
    """``data`` registered on the ``nominal`` tree (:func:`shared_frame`), its errors.

    Raises:
        DataError: The usual mistake that explains the registration's error, if one does.
    """

    def registered(d: Measurements) -> tuple[list, ResidualStats]:
        parts = by_tool(tree, d)
        states = shared_frame(nominal, parts)
        return states, _stats(states, parts)

    reg, first = registered(data)
    rms = lambda d: registered(d)[1].position_rms  # [m]  # noqa: E731
    diagnosis.explain(data, tree, rms, first.position_rms, None, _WORDS, joints_only=False)
    return reg, first
