"""The CSV records and numbers every calib CSV reader shares.

Measurements (:mod:`.csvfile`, which re-exports these names), touches, loops, pixels,
detections and configurations are read as records (:func:`csv_records`: the first line of
each, blank lines skipped, one separator: commas) of cells holding strict decimal numbers
(:func:`parse_number`). Errors name the row the way a text editor or spreadsheet numbers it
(the header is row 1) and the column by its name. A file of named columns (pixels, targets)
is read as a table (:func:`csv_table`: its header and rows checked; :func:`text_cell`: a cell
holding a name).
"""

from __future__ import annotations

import csv
import math
import re
from collections.abc import Sequence

from ..exceptions import DataError

__all__ = [
    "NUMBER",
    "csv_records",
    "csv_table",
    "header_names",
    "is_nan_text",
    "parse_number",
    "text_cell",
]


NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
"""Strict decimal number grammar of a CSV cell (no ``1_0``, no ``0x10``, no ``nan``)."""


def parse_number(cell: str, src: str, line: int, column: str) -> float:
    """A finite number from a CSV cell (strict grammar); DataError naming its row and column."""
    text = cell.strip()
    if not text:
        raise DataError(src, "empty cell", row=line, column=column)
    if not NUMBER.fullmatch(text):
        if is_nan_text(text):
            why = f"{text!r}: a value not measured leaves the row out (start it with #)"
            raise DataError(src, why, row=line, column=column)
        raise DataError(src, f"not a number: {text!r}", row=line, column=column)
    value = float(text)
    if not math.isfinite(value):
        raise DataError(src, f"{text!r} is not a finite number", row=line, column=column)
    return value


def is_nan_text(text: str) -> bool:
    """Whether a cell's text is a NaN as NumPy, MATLAB or a spreadsheet writes a value missing."""
    return text.strip().lower().lstrip("+-") in ("nan", "#n/a")


def _lines(text: str):
    """The lines of ``text``, each with its newline, as ``io.StringIO`` gives them.

    A comment line (starting with ``#``, after spaces) is given as a blank one: the rows keep
    their numbers. Without its copy of the text (four bytes per character).
    """
    start = 0
    while start < len(text):
        end = text.find("\n", start) + 1 or len(text)
        yield "\n" if text[start:end].lstrip().startswith("#") else text[start:end]
        start = end


def csv_records(text: str, src: str):
    """(first line, cells) of each CSV record but blank and comment lines (malformed: its row).

    A line starting with ``#`` is a comment (an instrument's export, notes above the
    header, a row left out), skipped as a blank one. A header (the first record)
    of one cell holding ``;`` or tabs is refused: the file is not comma-separated (every
    calib CSV: measurements, touches, pixels, configurations); so is one of numbers only: the
    column names are not the first line (a header written as a ``#`` comment).
    """
    reader = csv.reader(_lines(text), strict=True)
    start, header = 1, True
    while True:
        try:
            cells = next(reader)
        except StopIteration:
            return
        except csv.Error as exc:
            raise DataError(src, f"malformed CSV: {exc}", row=start) from None
        if any(c.strip() for c in cells):
            if any("\n" in c or "\r" in c for c in cells):
                raise DataError(src, "a quoted cell spans several lines", row=start)
            if header:
                _check_separator(cells, src, start)
                header = False
            yield start, cells
        start = reader.line_num + 1


def _check_separator(cells: list[str], src: str, line: int) -> None:
    """Refuse a header of one cell holding ``;`` or tabs (not commas), or of numbers only."""
    for sep, what in ((";", "';'"), ("\t", "tabs")):
        if len(cells) == 1 and sep in cells[0]:
            why = f"the header has one column containing {what}: write the CSV comma-separated"
            raise DataError(src, why, row=line)
    if all(NUMBER.fullmatch(c.strip()) for c in cells):
        why = "the header holds numbers: the columns' names come first (not as a # comment)"
        raise DataError(src, why, row=line)


def header_names(cells: list[str], source: str, line: int) -> list[str]:
    """The names of a header's cells, stripped: none empty, none twice (DataError naming it).

    Every calib CSV of named columns checks its header here (:func:`csv_table`, the
    measurements read in chunks, the touches).
    """
    names = [c.strip() for c in cells]
    seen: set[str] = set()
    for j, name in enumerate(names):
        if not name:
            why = f"header cell {j + 1} is empty: every column needs a name"
            raise DataError(source, why, row=line)
        if name in seen:
            raise DataError(source, "duplicate column", row=line, column=name)
        seen.add(name)
    return names


def csv_table(text: str, source: str, what: str, required: Sequence[str]):
    """The header's names, the other records ``(line, cells)`` and the header's line; checked.

    A table of ``what`` (its rows, for messages): distinct, non-empty header names, at least
    one row, as many cells in every row as the header has. The ``required`` columns are
    looked for before the rows' cells are counted: another file given (an intrinsics YAML
    for the target) is named by its missing column.
    """
    records = list(csv_records(text, source))
    if not records:
        raise DataError(source, f"empty file: expected a header line and {what}")
    line, cells = records[0]
    names = header_names(cells, source, line)
    for column in required:
        if column not in names:
            raise DataError(source, "missing column", row=line, column=column)
    if len(records) == 1:
        raise DataError(source, f"no {what} after the header")
    for row, cells in records[1:]:
        if len(cells) != len(names):
            raise DataError(source, f"expected {len(names)} cells, found {len(cells)}", row=row)
    return names, records[1:], line


def text_cell(cells: list[str], j: int, source: str, line: int, column: str) -> str:
    """A cell holding a name (a camera, a point, a link): not empty."""
    value = cells[j].strip()
    if not value:
        raise DataError(source, "empty cell", row=line, column=column)
    return value
