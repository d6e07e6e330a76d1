"""Partial marker rows: a marker not seen in some rows of a measurement CSV (occluded).

A marker's ``x, y, z`` cells all empty in a row: that marker was not seen there. It is read as
NaN in its three coordinates (:attr:`.data.Measurements.seen`); the row's other markers count.
One or two empty cells of a triple, a row that sees no marker and a marker no row sees are
errors that name the row or the column.
"""

from __future__ import annotations

import numpy as np

from ..exceptions import DataError
from .csv_text import is_nan_text, parse_number

__all__ = ["FIT_ROWS", "check_every_marker_seen", "left_blank", "marker_cells", "never_seen"]


def marker_cells(cells: list[str], index: list[int], names: list[str], src: str, line: int):
    """A row's coordinates of the markers at cell ``index`` (x, y, z each): NaN where unseen.

    A marker not seen has its three cells empty, or written ``NaN`` as MATLAB, NumPy and
    spreadsheets write a value missing.

    ``names``: the columns' names (messages).

    Raises:
        DataError: One or two empty cells of a marker's three, no marker seen, a bad number.
    """
    out = np.full(len(index), np.nan)
    for k in range(0, len(index), 3):
        empty = [left_blank(cells[j]) for j in index[k : k + 3]]
        if all(empty):
            continue
        if any(empty):
            first = k + empty.index(True)
            triple = ", ".join(names[k : k + 3])
            raise DataError(
                src,
                f"empty cell: a marker not seen leaves all of {triple} empty (or NaN), this "
                f"row has {sum(empty)} of them",
                row=line,
                column=names[first],
            )
        for a in range(k, k + 3):
            out[a] = parse_number(cells[index[a]], src, line, names[a])
    if np.isnan(out).all():
        several = "no marker (its x, y, z cells are empty)" if len(index) > 3 else "no point"
        raise DataError(
            src,
            f"empty cells: this row measures {several}: leave the row out (start it with #)",
            row=line,
        )
    return out


def left_blank(cell: str) -> bool:
    """Whether a marker's cell says the marker was not seen: empty, or ``NaN``."""
    return not cell.strip() or is_nan_text(cell)


def check_every_marker_seen(position: np.ndarray, names, src: str, rows=None) -> None:
    """Refuse a marker that no row sees (``position`` ``(m, 3 K)`` [m], NaN where unseen).

    ``rows``: the rows' numbers when every marker is needed in every row (a rigid set read
    as a pose, ``--orientation markers``), else None.

    Raises:
        DataError: Naming the marker's first column (and the row).
    """
    if rows is not None and np.isnan(position).any():
        i, j = (int(v) for v in np.argwhere(np.isnan(position))[0])
        why = "empty cell: orientation 'markers' needs every marker in every row"
        raise DataError(src, why, row=rows[i], column=names[j])
    k = never_seen(position)
    if k is not None:
        raise DataError(
            src,
            f"no row sees marker {k + 1} (its cells are all empty): fit the other points only "
            "(Columns' points)",
            column=names[3 * k],
        )


def never_seen(position: np.ndarray, least: int = 1) -> int | None:
    """The first marker (0-based) fewer than ``least`` rows see, or None.

    ``position`` ``(m, 3 K)`` [m], NaN where a marker is not seen.
    """
    rare = np.sum(~np.isnan(position[:, ::3]), axis=0) < least
    return int(np.argmax(rare)) if rare.any() else None


FIT_ROWS = 2
"""Fewest rows that must see a marker to fit it: one row's 3 equations only place the marker
(no redundancy), and the selection's folds that leave that row out could not place it."""
