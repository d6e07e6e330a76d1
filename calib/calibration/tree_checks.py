"""The checks of a tree's rows as a whole, before its joint fit (:mod:`.instrument`).

Each tool's rows get a single chain's checks in the joint fit; what only the whole tree
sees is checked here, on the closed-form registration of the nominal tree
(:func:`~.tree.register_tree`: one frame for every tool):

- enough rows for the frame and every marker (``6 + 3 T`` unknowns, held-out rows apart);
- validation rows that are training rows refused, or given with a holdout fraction;
- usual mistakes across the branches (two joints of different tools' chains swapped,
  degrees, millimetres: :func:`~.diagnosis.likely_cause`), in the data and the validation
  rows;
- validation rows measured in another frame (the training registration misses them by far).
"""

from __future__ import annotations

from ..exceptions import DataError
from ..kinematics.tree import Tree
from ..kinematics.tree_model import TreeMDH, from_tree
from ..measurements.data import Measurements
from . import determined, diagnosis, validation
from .instrument import tool_parts
from .tree import TreeState, register_tree

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
    nominal = from_tree(tree)
    if validate is not None:  # with a holdout too: refused by Problem
        validation.check_held_out(data, validate)
        if set(validate.tools) == set(tree.tool_frames) and 3 * validate.m > unknowns:
            _diagnosed(tree, nominal, validate)
    reg = _diagnosed(tree, nominal, data)
    if validate is not None:
        fitted, other = (validation.stats(reg, d, None) for d in (data, validate))
        validation.check_held_out_errors(fitted, other, validate.source)
    train, held = (
        (data, validate) if validate is not None else validation.split(data, holdout, seed)
    )
    return tool_parts(tree, train), tool_parts(tree, held, every=False)


def _diagnosed(tree: Tree, nominal: TreeMDH, data: Measurements) -> TreeState:
    """The closed-form registration of ``data``; the likely mistake if it cannot be.

    Raises:
        DataError: A usual mistake explains the registration's error (it is named).
    """
    reg = register_tree(nominal, data)
    first = validation.stats(reg, data, None).position_rms
    if not diagnosis.suspect(first, None):
        return reg

    def rms(d):  # the closed form only: every swap of two joints is tried
        return validation.stats(register_tree(nominal, d), d, None).position_rms

    cause = diagnosis.likely_cause(data, tree.sigma == 0, rms, first)
    if cause is not None:
        raise DataError(
            data.source,
            f"the data look like {cause[0]}: the registration error drops from "
            f"{1e3 * first:.4g} mm to {1e3 * cause[1]:.4g} mm RMS once corrected",
        )
    return reg
