"""What the identifiability analysis says of its rank and of its set's gaps, in words.

:func:`rank_notes` warns of a rank that is ill-defined, limited by too few rows or separated
by a weak gap; :func:`missing_errors` names the complete set's parameters a smaller set
cannot represent (:func:`explain`: a y rotation or translation between parallel or
collinear axes).
"""

from __future__ import annotations

import numpy as np

from ..kinematics.mdh import MDHModel
from ..kinematics.tree_model import TreeMDH
from . import qr
from .base_columns import numerical_rank, pivoted_diagonal
from .parameters import Kind, Parameter

__all__ = ["explain", "missing_errors", "rank_notes"]


def explain(p: Parameter, mdh: MDHModel | TreeMDH) -> str:
    """Why the set cannot represent the complete set's parameter ``p`` (one line)."""
    k, a = p.row, int(mdh.antecedent[p.row])
    prev = "the base z axis (z_-1)" if a == 0 else f"axis {a}"
    this = f"axis {k}"
    if k in mdh.tool_rows:
        tool = mdh.tool_frame_of(k) if isinstance(mdh, TreeMDH) else None  # a chain's: unnamed
        this = f"the z axis of tool {tool}" if tool else "the tool z axis"
    if p.kind is Kind.BETA:
        return (
            f"{p.name}: {prev} is parallel to {this} and the set has no beta there, so a "
            f"rotation about y_{a} cannot be represented"
        )
    return (
        f"{p.name}: {prev} and {this} lie on one line, so a translation along y_{a} "
        f"cannot be represented"
    )


def missing_errors(mdh, W_all, pset, extras, kept, n_complete: int, n_rows: int) -> list[str]:
    """Why the set reaches fewer independent errors than the complete set (one line each)."""
    if len(kept) >= n_complete:
        return []
    R_all = qr.triangular(W_all)
    missing = []
    for j, p in enumerate(extras):
        cols = [*kept, len(pset) + j]
        r_x, _ = numerical_rank(pivoted_diagonal(R_all[:, cols]), n_rows)
        if r_x > len(kept):
            missing.append(explain(p, mdh))
    return missing or [
        f"the set reaches {len(kept)} of the {n_complete} independent errors for a "
        f"reason calib does not diagnose"
    ]


def rank_notes(diag: np.ndarray, n_rows: int, n_kept: int, n_params: int) -> list[str]:
    """Warnings about the rank: ill-defined, too few rows, a weak gap."""
    notes = []
    rank, _ = numerical_rank(diag, n_rows)
    if n_kept != rank:
        notes.append(
            f"{n_kept} independent columns were selected for a numerical rank of {rank}: "
            f"the rank is ill-defined at this geometry"
        )
    if n_rows < n_params:
        notes.append(
            f"only {n_rows} measurement rows for {n_params} parameters: the rank cannot "
            f"exceed {n_rows}; draw more configurations"
        )
    b = rank
    if 0 < b < len(diag) and diag[b] > 0 and diag[b - 1] / diag[b] < 1e4:
        notes.append(
            f"weak rank gap: |R_bb| = {diag[b - 1]:.3g} vs |R_b+1| = {diag[b]:.3g}; the "
            f"rank may change with more or other configurations"
        )
    return notes
