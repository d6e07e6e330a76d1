"""The checks of a tree's rows as a whole, before its joint fit (:mod:`.instrument`).

Each tool's rows get a single chain's checks in the joint fit; what only the whole tree
sees is checked here, on the closed-form registration of the nominal tree
(:func:`~.instrument.shared_frame`: one frame for every tool, one marker each):

- enough rows for the frame and every marker (``6 + 3 T`` unknowns, held-out rows apart);
- validation rows that are training rows refused, or given with a holdout fraction;
- usual mistakes across the branches (two joints of different tools' chains swapped,
  degrees, millimetres: :func:`~.diagnosis.explain`), in the data and the validation rows;
- validation rows measured in another frame (the training registration misses them by far).
"""

from __future__ import annotations

import numpy as np

from ..identification.measures import POSITION
from ..kinematics.mdh import from_chain
from ..kinematics.tree import Tree
from ..measurements.data import Measurements
from . import determined, diagnosis, validation
from .instrument import shared_frame, tool_parts
from .measured_term import MeasuredState
from .model import nominal_state
from .residuals import ResidualStats

__all__ = ["prepare_tree"]


def prepare_tree(
    tree: Tree, data: Measurements, validate: Measurements | None, holdout: float, seed: int
):
    """Check a tree's rows (module text); each tool's rows and held-out rows.

    The rows held out (``holdout``, seeded) are drawn among the tree's postures, every tool's
    together (:func:`~.validation.split`), as the validation rows are given.

    Returns:
        Each tool's rows, and each tool's held-out rows (None: none, or a tool without
        held-out rows).

    Raises:
        DataError: Rows of other joints, pose or several-point rows, a tool no row measures,
            too few rows, a usual mistake (named), validation rows that are training rows or
            measured in another frame (validation rows with a holdout fraction: refused
            by :class:`~.problem.Problem` before).
    """
    tool_parts(tree, data)
    out = round(holdout * data.m)
    unknowns = 6 + 3 * tree.n_tools
    what = "measurement frame and marker parameters"
    determined.check_equations(data.m - out, 3, unknowns, what, data.source, held=out, unit="rows")
    if validate is not None:  # with a holdout too: refused by Problem
        validation.check_held_out(data, validate)
        if set(validate.tools) == set(tree.tool_frames) and 3 * validate.m > unknowns:
            _diagnosed(tree, validate)
    reg = _diagnosed(tree, data)
    if validate is not None:
        fitted, other = (_stats(reg, _by_tool(tree, d)) for d in (data, validate))
        validation.check_held_out_errors(fitted, other, validate.source)
    train, held = (
        (data, validate) if validate is not None else validation.split(data, holdout, seed)
    )
    return tool_parts(tree, train), tool_parts(tree, held, every=False)


def _by_tool(tree: Tree, data: Measurements) -> list[Measurements | None]:
    """Each tool's rows on its chain's joints (None: no row), unchecked (data corrected)."""
    tools = np.array(data.tool if data.tool is not None else (tree.tool_frames[0],) * data.m)
    parts: list[Measurements | None] = []
    for chain, path in zip(tree.chains, tree.paths, strict=True):
        rows = tools == chain.tool_frame
        q, points = data.q[rows][:, path], data.position[rows]
        parts.append(Measurements(chain.joint_names, q, points) if rows.any() else None)
    return parts


def _registration(tree: Tree, data: Measurements) -> list[MeasuredState]:
    """The nominal tree's measurement frame and markers in closed form (one per tool)."""
    start = [
        MeasuredState(nominal_state(from_chain(c), np.zeros((1, 3)), POSITION), 1.0, True)
        for c in tree.chains
    ]
    parts = _by_tool(tree, data)
    return shared_frame(start, parts)


def _stats(states: list[MeasuredState], parts: list[Measurements | None]) -> ResidualStats:
    """The registration's errors on every tool's rows."""
    rows = [s.residuals(p) for s, p in zip(states, parts, strict=True) if p is not None]
    return ResidualStats.of(np.concatenate(rows))


_WORDS = diagnosis.Words(mistakes="swapped joint columns, degrees, millimetres")


def _diagnosed(tree: Tree, data: Measurements) -> list[MeasuredState]:
    """The closed-form registration of ``data``; the likely mistake if it cannot be.

    Raises:
        DataError: A usual mistake explains the registration's error (it is named).
    """
    reg = _registration(tree, data)
    first = _stats(reg, _by_tool(tree, data)).position_rms

    def rms(d):  # the closed form only: every swap of two joints is tried
        return _stats(_registration(tree, d), _by_tool(tree, d)).position_rms

    diagnosis.explain(data, tree.sigma == 0, rms, first, None, _WORDS, joints_only=False)
    return reg
