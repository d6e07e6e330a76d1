"""The checks of a tree's rows as a whole, before its joint fit (:mod:`.instrument`).

Each tool's rows get a single chain's checks in the joint fit; what only the whole tree sees is
checked here (:func:`prepare_tree`), on the closed-form registration of the nominal tree.
"""

from __future__ import annotations

import numpy as np

from ..identification.measures import POSITION
from ..kinematics.mdh import from_chain
from ..kinematics.tree import Tree
from ..measurements.data import Measurements
from . import determined, diagnosis, validation
from .chain_registration import MeasuredState
from .instrument import by_tool, shared_frame, tool_parts
from .model import nominal_state
from .residuals import ResidualStats

__all__ = ["prepare_tree"]


def prepare_tree(
    tree: Tree, data: Measurements, validate: Measurements | None, holdout: float, seed: int
):
    """Check a tree's rows as a whole; each tool's rows and held-out rows.

    Enough rows for the frame and every marker (``6 + 3 T`` unknowns, held-out rows apart);
    validation rows that are training rows refused; usual mistakes across the branches (two
    joints of different tools' chains swapped, degrees, millimetres: :func:`~.diagnosis.explain`)
    in the data and the validation rows; validation rows measured in another frame.

    The rows held out (``holdout``, seeded) are drawn among the tree's postures, every tool's
    together (:func:`~.validation.split`), as the validation rows are given. Returns each
    tool's rows and held-out rows (None: none, or a tool without held-out rows).

    Raises:
        DataError: Rows of other joints, pose or several-point rows, a tool no row measures,
            too few rows, a usual mistake (named), validation rows that are training rows or
            measured in another frame (validation rows with a holdout fraction: refused
            by :class:`~.problem.Problem` before).
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
    """``data`` registered on the ``nominal`` tree (:func:`~.instrument.shared_frame`), its errors.

    A DataError names the usual mistake that explains the registration's error, if one does.
    """

    def registered(d: Measurements) -> tuple[list, ResidualStats]:
        parts = by_tool(tree, d)
        states = shared_frame(nominal, parts)
        return states, _stats(states, parts)

    reg, first = registered(data)
    rms = lambda d: registered(d)[1].position_rms  # [m]  # noqa: E731
    diagnosis.explain(
        data, tree.sigma == 0, rms, first.position_rms, None, _WORDS, joints_only=False
    )
    return reg, first
