"""A tree measured by one instrument: one measured term per tool, the instrument's frame shared.

A tree (one base frame, several tools: TALOS's two hands below the torso) measured by one
instrument outside the robot (a laser tracker seeing a marker on each hand; the CSV's
``tool`` column says which) is a problem of the joint-placement engine
(:func:`~.contact_chains.calibrate_contact_chains` with ``instrument=True``): one measured
term (:mod:`.measured_term`) per tool, on the chain from the tree's base to that tool. The
terms share

- the joint placements of the joints they run through (one error per URDF joint, mimic
  joints included: a mimic joint's placement is its own, its position follows its master's),
- the instrument's frame: its 6 unknowns are one object of the fit (:func:`instrument_groups`),
  each tool's marker its own unknowns (:attr:`~.measured_term.MeasuredKind.instrument`).

Each tool's rows get a single chain's checks (registration, outliers set aside, usual
mistakes diagnosed); then the frame and markers are registered together in closed form
(:func:`shared_frame`: Horn/Umeyama over every tool's points, each marker by linear least
squares, alternated), refined by Levenberg-Marquardt with the engine's shared objects.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..kinematics.tree import Tree
from ..kinematics.urdf_links import marker_link_names
from ..measurements.data import Measurements
from ..measurements.limits import check_against_chain
from .measured_term import MeasuredState
from .registration import rigid_fit
from .report import pose_dict
from .residuals import ResidualStats

__all__ = [
    "REGISTRATION_ITERATIONS",
    "instrument_errors",
    "instrument_format2",
    "instrument_groups",
    "instrument_lines",
    "pooled",
    "shared_frame",
    "tool_parts",
    "tree_points",
]

REGISTRATION_ITERATIONS = 50
"""Most alternations of the closed-form registration (frame, then markers)."""


def tool_parts(
    tree: Tree, data: Measurements | None, every: bool = True
) -> list[Measurements | None]:
    """A tree's rows cut by tool: each tool's rows on its chain's joints (None: no data).

    ``every``: each tool must have rows (else a tool without rows gets None).

    Raises:
        DataError: Data of other joints, pose or several-point rows, a tool no row measures.
        InvalidArgumentError: ``data`` are not Measurements.
    """
    if data is None:
        return [None] * tree.n_tools
    if not isinstance(data, Measurements):
        raise InvalidArgumentError(f"data must be Measurements, got {type(data).__name__}")
    check_against_chain(data, tree)
    if data.quaternion is not None or data.n_markers != 1:
        raise DataError(
            data.source, "a tree is calibrated from one point per row (x, y, z and a tool)"
        )
    tools = np.array(data.tool if data.tool is not None else (tree.tool_frames[0],) * data.m)
    parts: list[Measurements | None] = []
    for chain, path in zip(tree.chains, tree.paths, strict=True):
        rows = np.flatnonzero(tools == chain.tool_frame)
        if not rows.size and not every:
            parts.append(None)
            continue
        if not rows.size:
            raise DataError(
                data.source,
                f"no row measures the tool {chain.tool_frame}: calibrate the tools the rows "
                f"measure (a tool for each)",
            )
        sub = data.subset(rows)
        parts.append(
            Measurements(
                chain.joint_names,
                sub.q[:, path],
                sub.position,
                None,
                sub.source,
                sub.rows,
                sub.tool,
            )
        )
    return parts


def instrument_groups(plane_of: tuple[int, ...], data, instrument: bool) -> tuple[int, ...]:
    """The objects of a joint fit with every measured term's frame one (``instrument``).

    Args:
        plane_of: Each term's object (:func:`~.contact_checks.plane_groups`).
        data: Each term's data.
        instrument: The measured terms share one instrument (else ``plane_of`` as it is).
    """
    if not instrument:
        return plane_of
    keys = [
        "instrument" if isinstance(d, Measurements) else p
        for p, d in zip(plane_of, data, strict=True)
    ]
    index = {k: i for i, k in enumerate(dict.fromkeys(keys))}
    return tuple(index[k] for k in keys)


def _points(state: MeasuredState, data: Measurements) -> tuple[np.ndarray, np.ndarray]:
    """Tool rotations ``(m, 3, 3)`` and origins ``(m, 3)`` in the base frame (its chain)."""
    kin = state.inner.mdh.kinematics(np.asarray(data.q, dtype=float))
    return kin.R[:, -1], kin.p[:, -1]


def shared_frame(states: list, train: list) -> list:
    """The instrument terms' frame and markers registered together in closed form.

    The frame by Horn/Umeyama on every tool's predicted points, each tool's markers by
    linear least squares in its tool frame, alternated until the markers move less than
    1e-12 m (at most :data:`REGISTRATION_ITERATIONS` times), from each term's own markers.

    Args:
        states: Each term's state; the :class:`MeasuredState` with ``instrument`` are
            registered together (the others are returned as they are).
        train: Each term's rows.

    Returns:
        The states, the instrument terms' with one frame and their markers.
    """
    terms = [c for c, s in enumerate(states) if isinstance(s, MeasuredState) and s.instrument]
    if not terms:
        return states
    kin = {c: _points(states[c], train[c]) for c in terms}
    markers = {c: states[c].inner.markers.copy() for c in terms}
    measured = np.concatenate([train[c].points.reshape(-1, 3) for c in terms])
    R, t = np.eye(3), np.zeros(3)
    for _ in range(REGISTRATION_ITERATIONS):
        predicted = [
            kin[c][1][:, None] + np.einsum("mij,kj->mki", kin[c][0], markers[c]) for c in terms
        ]
        R, t = rigid_fit(np.concatenate([p.reshape(-1, 3) for p in predicted]), measured)
        moved = 0.0
        for c in terms:
            Rt, pt = kin[c]
            local = (train[c].points - t) @ R - pt[:, None]  # R_tool m_k, base frame
            new = np.stack(
                [
                    np.linalg.lstsq(Rt.reshape(-1, 3), local[:, k].reshape(-1), rcond=None)[0]
                    for k in range(local.shape[1])
                ]
            )
            moved = max(moved, float(np.max(np.abs(new - markers[c]))))
            markers[c] = new
        if moved < 1e-12:
            break
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = R, t
    out = list(states)
    for c in terms:
        inner = dataclasses.replace(states[c].inner, frame=frame.copy(), markers=markers[c])
        out[c] = dataclasses.replace(states[c], inner=inner)
    return out


def instrument_format2(measured) -> dict:
    """Format 2's keys of a tree's report (written until format 4): frame and markers.

    Args:
        measured: The instrument terms' parts (:class:`~.contact_chains_result.MeasuredChain`).
    """
    first = measured[0]
    pairs = {
        k: (pooled(measured, f"{k}_registration"), pooled(measured, k))
        for k in ("train", "held_out")
    }
    both = {
        k: None
        if a is None or b is None
        else {"registration": a.to_dict(), "calibrated": b.to_dict()}
        for k, (a, b) in pairs.items()
    }
    return {
        "data": first.source,
        "rows": sum(c.stats["train"].m for c in measured),
        "residuals": both["train"],
        "per_tool": [_tool_errors(c) for c in measured],
        "validation": both["held_out"],
        "measure": "position",
        "base_frame": first.chain.base_frame,
        "tools": [c.chain.tool_frame for c in measured],
        "measurement_to_base": pose_dict(first.state.inner.frame),
        "markers": {c.chain.tool_frame: c.state.inner.markers[0].tolist() for c in measured},
        "marker_links": {
            t: marker_link_names(t, 1)[0] for t in (c.chain.tool_frame for c in measured)
        },
    }


def pooled(parts, key: str) -> ResidualStats | None:
    """Position errors of every tool's rows together, or None when no part has them.

    ``key``: ``train``, ``held_out`` or either's ``_registration``.

    Args:
        parts: The instrument terms' parts (each with ``stats``: :class:`GapStats` whose
            ``per_row`` are the point errors [mm]).
        key: Which rows.
    """
    rows = [c.stats[key].per_row for c in parts if key in c.stats]
    if not rows or any(r is None for r in rows):
        return None
    e = 1e-3 * np.concatenate(rows)  # [m]
    return ResidualStats(len(e), float(np.sqrt(np.mean(e**2))), float(np.max(e)))


def instrument_errors(parts) -> dict:
    """The report's ``errors.train`` and ``errors.held_out`` of every tool together (format 3).

    ``urdf``: the URDF alone, without a fitted compliance (else ``calibrated``).

    Args:
        parts: The instrument terms' parts (:class:`~.contact_chains_result.MeasuredChain`).
    """
    out: dict = {"train": None, "held_out": None}
    for key in out:
        before, after = pooled(parts, f"{key}_registration"), pooled(parts, key)
        if before is None or after is None:
            continue
        cal, alone = after.in_mm(), pooled(parts, f"{key}_urdf")  # with compliance: apart
        urdf = cal if alone is None else alone.in_mm()
        out[key] = {"registration": before.in_mm(), "calibrated": cal, "urdf": urdf}
        if key == "held_out":
            out[key] = {"source": parts[0].held_source, **out[key]}
    return out


def instrument_lines(parts) -> list[str]:
    """The summary's lines of every tool together: position RMS / max [mm], fitted, held out."""
    lines = []
    for key, label in (("train", "fitted rows"), ("held_out", "held-out rows")):
        before, after = pooled(parts, f"{key}_registration"), pooled(parts, key)
        if before is None or after is None:
            continue
        alone = pooled(parts, f"{key}_urdf")  # with compliance: the URDF alone too
        lines.append(
            f"{label} of every tool, position RMS / max [mm]: registration "
            f"{1e3 * before.position_rms:.4g} / {1e3 * before.position_max:.4g}, calibrated "
            f"{1e3 * after.position_rms:.4g} / {1e3 * after.position_max:.4g}"
            + (
                ""
                if alone is None
                else f", URDF alone (no compliance) {1e3 * alone.position_rms:.4g} / "
                f"{1e3 * alone.position_max:.4g}"
            )
        )
    return lines


def tree_points(parts, paths, q: np.ndarray) -> np.ndarray:
    """Each tool's marker predicted in the instrument's frame ``(m, T, 3)`` [m].

    Args:
        parts: The instrument terms' parts, in tool order
            (``result.chains`` of a tree's calibration).
        paths: Each tool's joints among the tree's (:attr:`~calib.kinematics.tree.Tree.paths`).
        q: The tree's joint positions ``(m, n)`` [rad or m].
    """
    q = np.asarray(q, dtype=float)
    return np.stack(
        [c.state.inner.predict(q[:, path])[0][:, 0] for c, path in zip(parts, paths, strict=True)],
        axis=1,
    )


def _tool_errors(part) -> dict:
    """Format 2's ``per_tool`` entry of one tool: its fitted rows' errors [m]."""
    errors = {k: pooled([part], key) for k, key in (("registration", "train_registration"),
              ("calibrated", "train"))}  # fmt: skip
    return {
        "tool": part.chain.tool_frame,
        **{k: None if v is None else v.to_dict() for k, v in errors.items()},
    }
