"""Matplotlib figures: counts across robots, the |R_ii| spectrum, calibration errors.

Every function returns a ``matplotlib.figure.Figure``; notebooks show it inline and the CLI
saves it with :func:`save_figure`.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..calibration.delivery import Result
from ..core.fileio import write_atomic
from ..exceptions import InvalidArgumentError
from ..identification.identifiability import Identifiability
from .sweep import SweepRow

__all__ = [
    "FIGURE_FORMATS",
    "calibration_figure",
    "counts_figure",
    "errors_figure",
    "figure_bytes",
    "figure_format",
    "save_figure",
    "spectrum_figure",
]


OTHER_GROUP = "other URDF files"
"""The group of sweep rows that are no catalog entry (``calib sweep --urdf``)."""


def _groups(rows: Sequence[SweepRow]) -> dict[str, list[SweepRow]]:
    """The rows by kind of robot (the catalog's sections, in file order; others last)."""
    from ..kinematics.catalog import catalog_groups

    of = catalog_groups()
    out: dict[str, list[SweepRow]] = {g: [] for g in dict.fromkeys(of.values())}
    for r in rows:
        out.setdefault(of.get(r.robot, OTHER_GROUP), []).append(r)
    return {g: rs for g, rs in out.items() if rs}


def counts_figure(
    rows: Sequence[SweepRow], title: str = "", theory: str = "4R+2P+6 or +3"
) -> Figure:
    """Base-parameter counts per robot (paper and complete sets) against the theory.

    One panel per kind of robot (the catalog's sections: arms, arms of humanoids, legs,
    trees, ...; rows of other URDF files last), two panels a row, so that the names stay
    readable (the whole catalog: about 1,400 pixels wide at 120 dpi, not one row of 3,000).
    ``theory``: the formula the legend names (a sweep of K markers: ``4R+2P+3K``); rows
    without a paper count (K markers) have no paper bar.
    """
    groups = _groups([r for r in rows if r.error is None]) or {"": []}
    ncols = 2 if len(groups) > 1 else 1
    nrows = -(-len(groups) // ncols)
    widest = max(len(rs) for rs in groups.values())
    fig = Figure(
        figsize=(max(6.0, ncols * (0.2 * widest + 1.2)), 3.0 * nrows + 0.6), layout="constrained"
    )
    axes = fig.subplots(nrows, ncols, squeeze=False).ravel()
    for ax, (group, rs) in zip(axes, groups.items(), strict=False):
        _counts_panel(ax, rs, widest, theory)
        ax.set_title(f"{group} ({len(rs)})" if group else "", fontsize=9, wrap=True)
    for ax in axes[len(groups) :]:
        ax.set_visible(False)
    axes[0].legend(fontsize=7)
    fig.suptitle(title or "Identifiable parameters per chain")
    return fig


def _counts_panel(ax, rows: Sequence[SweepRow], width: int, formula: str) -> None:
    """One kind's bars: the paper and complete sets' base parameters, and the theory."""
    x = np.arange(len(rows))
    paper = np.array([np.nan if r.n_base_paper is None else r.n_base_paper for r in rows])
    if not np.all(np.isnan(paper)):
        ax.bar(x - 0.2, paper, 0.4, label="paper set")
    complete = np.array([r.n_base_complete for r in rows], dtype=float)
    ax.bar(x + 0.2, complete, 0.4, label="complete set", color="C1")
    theory = np.array([np.nan if r.n_theory is None else r.n_theory for r in rows], dtype=float)
    ax.scatter(x, theory, marker="_", s=120, color="k", zorder=3, label=f"theory ({formula})")
    ax.set_xticks(x, [r.robot for r in rows], rotation=90, fontsize=6)
    ax.set_xlim(-0.6, max(width, 1) - 0.4)  # every panel at the same scale per robot
    ax.set_ylabel("base parameters", fontsize=8)


def spectrum_figure(res: Identifiability) -> Figure:
    """|R_ii| of the pivoted QR on a log scale, with tau and the rank gap."""
    fig = Figure(figsize=(6.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    diag = np.maximum(res.diag, np.finfo(float).tiny)
    i = np.arange(1, len(diag) + 1)
    ax.semilogy(i[: res.n_base], diag[: res.n_base], "o", label=f"kept ({res.n_base})")
    ax.semilogy(
        i[res.n_base :], diag[res.n_base :], "x", label=f"dropped ({len(diag) - res.n_base})"
    )
    ax.axhline(res.tolerance, color="k", ls="--", lw=1, label=r"$\tau = r\,\epsilon\,|R_{11}|$")
    ax.set_xlabel("i (pivot order)")
    ax.set_ylabel(r"$|R_{ii}|$")
    ax.set_title(f"{res.robot}: {res.params.label} set, {res.measurement.label}")
    ax.legend(fontsize=8)
    return fig


def errors_figure(before: np.ndarray, after: np.ndarray, title: str = "") -> Figure:
    """Position error per configuration before and after calibration [mm]."""
    fig = Figure(figsize=(6.0, 3.6), layout="constrained")
    ax = fig.add_subplot()
    before = 1e3 * np.asarray(before)
    after = 1e3 * np.asarray(after)
    bins = np.linspace(0.0, max(float(before.max(initial=0.0)), 1e-9), 30).tolist()
    ax.hist(
        before, bins=bins, alpha=0.6, label=f"nominal (RMS {np.sqrt(np.mean(before**2)):.3g} mm)"
    )
    ax.hist(
        after, bins=bins, alpha=0.8, label=f"calibrated (RMS {np.sqrt(np.mean(after**2)):.3g} mm)"
    )
    ax.set_xlabel("position error [mm]")
    ax.set_ylabel("configurations")
    ax.set_title(title or "Calibration")
    ax.legend(fontsize=8)
    return fig


def calibration_figure(result) -> Figure:
    """A calibration to look at: errors per configuration before and after, and the parameters.

    Top: the error of every configuration [mm] (a measured row's RMS point error, a touch's
    weighted gap), registration (nominal geometry, fitted frame, markers and objects) in red
    and calibrated in blue, fitted rows as dots and held-out rows as crosses after them, term
    after term (each series labelled ``[term name ]fitted|held out: registration|calibrated``).
    Bottom: each fitted parameter's change from the registration with its standard
    deviation, named with its URDF joint (lengths in mm, angles in mrad).

    Args:
        result: A calibration result (:class:`calib.Result`: ``row_errors`` and ``to_dict``).

    Raises:
        InvalidArgumentError: Not a calibration result, or one that keeps no
            per-configuration errors.
    """
    if not isinstance(result, Result):
        raise InvalidArgumentError(
            f"calibration_figure takes a calibration result (calib.calibrate's), got {result!r:.60}"
        )
    rows = result.row_errors()
    doc = result.to_dict()
    params = doc["parameters"]
    fig = Figure(figsize=(8.0, 4.0 + 0.16 * len(params)), layout="constrained")
    top, bottom = fig.subplots(2, 1, height_ratios=[3.0, max(1.0, 0.12 * len(params))])
    start = 0
    for name, rows_of_term in rows.series():
        for part, marker, mask in (
            ("fitted", "o", ~rows.held_out),
            ("held out", "x", rows.held_out),
        ):
            mask = mask & rows_of_term
            x = start + np.arange(int(mask.sum()))
            start += len(x)
            for stage, values, color in (
                ("registration", rows.before, "tab:red"),
                ("calibrated", rows.after, "tab:blue"),
            ):
                label = f"{name} {part}: {stage}".strip()
                if len(x):
                    top.plot(x, values[mask], marker, ms=4, color=color, ls="", label=label)
        if name:
            top.axvline(start - 0.5, color="0.5", lw=0.8, ls="--")
    positive = rows.before.min(initial=1.0) > 0 and rows.after.min(initial=1.0) > 0
    top.set_yscale("log" if positive else "linear")
    top.set_xlabel(
        "configuration (fitted rows, then held-out rows"
        + (", term by term)" if rows.names else ")")
    )
    top.set_ylabel("error [mm]")
    verdict = "accepted" if doc["accepted"] else "REFUSED"
    top.set_title(f"{doc['robot']} ({doc['shape']}): {verdict}")
    top.legend(fontsize=6, ncol=2)
    _parameters_panel(bottom, params)
    return fig


def _parameters_panel(ax, params: list[dict]) -> None:
    """Each parameter's value +- std, named by its joint (lengths in mm, angles in mrad)."""
    scale = {"m": 1e3, "rad": 1e3}
    shown = {"m": "mm", "rad": "mrad"}
    values = np.array([scale.get(p["unit"], 1.0) * (p["value"] or 0.0) for p in params])
    stds = np.array([scale.get(p["unit"], 1.0) * (p["std"] or 0.0) for p in params])
    y = np.arange(len(params))
    ax.errorbar(values, y, xerr=stds, fmt="o", ms=3, color="k", ecolor="0.4", capsize=2)
    labels = [
        f"{p['name']} ({p['joint']}) [{shown.get(p['unit'], p['unit'])}]"
        if p["joint"]
        else f"{p['name']} [{shown.get(p['unit'], p['unit'])}]"
        for p in params
    ]
    ax.set_yticks(y, labels, fontsize=6)
    ax.invert_yaxis()
    ax.axvline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("change from the registration +- std [mm, mrad]")


FIGURE_FORMATS = ("png", "svg", "pdf")
"""File formats a figure is saved in, chosen by the file's extension."""


def figure_format(path: str | Path, option: str = "the figure file") -> str:
    """The format a figure file is written in, from its extension (``.png``, ``.svg``, ``.pdf``).

    Args:
        path: The file the figure goes to.
        option: What names the file in the error (``--plot``).

    Raises:
        InvalidArgumentError: The extension is missing or not one of :data:`FIGURE_FORMATS`.
    """
    ext = Path(path).suffix.lower().lstrip(".")
    if ext not in FIGURE_FORMATS:
        given = f"extension '.{ext}'" if ext else "no extension"
        raise InvalidArgumentError(
            f"{option} {path}: {given}; give a file ending in "
            + ", ".join(f".{f}" for f in FIGURE_FORMATS)
        )
    return ext


def figure_bytes(fig: Figure, fmt: str = "png") -> bytes:
    """The figure as the bytes of a PNG (120 dpi), SVG or PDF file (no date: reproducible).

    Raises:
        InvalidArgumentError: ``fmt`` is not one of :data:`FIGURE_FORMATS`.
    """
    if fmt not in FIGURE_FORMATS:
        raise InvalidArgumentError(f"figure format '{fmt}': expected one of {FIGURE_FORMATS}")
    metadata = {} if fmt == "png" else {"Date": None} if fmt == "svg" else {"CreationDate": None}
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=120, metadata=metadata)
    return buf.getvalue()


def save_figure(fig: Figure, path: str | Path) -> None:
    """Save in the format of the extension (png, svg, pdf); no partial file is ever left.

    Raises:
        InvalidArgumentError: Unknown or missing extension.
        OutputError: The file cannot be written.
    """
    write_atomic(path, figure_bytes(fig, figure_format(path)))
