"""A term's checks before the joint fit: one sequence for every kind of term.

Each kind gives its :class:`Steps` on one set of rows; :func:`checked` runs them in one order
(register, set the outliers aside, diagnose), validation rows alike.
Rationale: docs/developers/engine.md#term_checks
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, Protocol, Self, TypeVar

import numpy as np

from . import outliers

__all__ = ["Aside", "FileRows", "Steps", "Subsets", "checked", "file_lines", "held_out"]

D = TypeVar("D")
S = TypeVar("S")


@dataclass(frozen=True)
class Aside(Generic[D, S]):
    """A registration (``state``) of the rows ``kept``, without the outlier rows ``bad`` (mask)."""

    state: S
    bad: np.ndarray
    kept: D
    found: tuple[outliers.Outlier, ...] = ()
    held: D | None = None
    notes: tuple[str, ...] = ()


class Steps(Protocol[D, S]):
    """A kind's steps on its rows, which :func:`checked` runs."""

    @property
    def rows(self) -> D:
        """The rows."""

    @property
    def diagnose_first(self) -> bool:
        """Whether every row is diagnosed before the outliers are set aside."""

    def register(self) -> S:
        """The registration of every row."""

    def set_aside(self, state: S) -> Aside[D, S]:
        """The registration (``state``: of every row) without the outlier rows."""

    def diagnose(self, rows: D, state: S) -> list[str]:
        """Raise the usual mistake the rows show (``state``: their registration); or notes."""


class FileRows(Protocol):
    """Rows read from a file (measurements, touches, a camera's points)."""

    @property
    def rows(self) -> tuple[int, ...] | None:
        """Each row's line in its file (the header is line 1), or None (no file)."""

    @property
    def m(self) -> int:
        """Number of rows."""


class Subsets(Protocol):
    """Rows that a mask or indices select (measurements, touches, a camera's points)."""

    def subset(self, index: np.ndarray, /) -> Self:
        """The rows ``index``."""


R = TypeVar("R", bound=Subsets)


def file_lines(data: FileRows) -> tuple[int, ...]:
    """Each row's line in its file; without a file, row i's is i + 1."""
    return data.rows or tuple(range(1, data.m + 1))


def checked(
    steps: Steps[D, S], validation: Sequence[tuple[Steps, str]] = ()
) -> tuple[Aside[D, S], list[str]]:
    """The rows registered, their outliers set aside, diagnosed (validation rows too); notes."""
    aside, notes = _sequence(steps)
    for other, label in validation:
        notes += [f"{label}: {n}" for n in _sequence(other)[1]]
    return aside, notes


def _sequence(steps: Steps[D, S]) -> tuple[Aside[D, S], list[str]]:
    """Register, set the outliers aside and diagnose (every row first, or the rows kept)."""
    first = steps.register()
    notes = steps.diagnose(steps.rows, first) if steps.diagnose_first else []
    aside = steps.set_aside(first)
    if not steps.diagnose_first:
        notes = steps.diagnose(aside.kept, aside.state)
    return aside, [*notes, *aside.notes]


def held_out(
    fitted: outliers.Errors,
    errors: outliers.Errors,
    held: R,
    rows: tuple[int, ...],
    notes: list[str],
    noise: float | None = None,
    words: tuple[str, str] = ("rows", "error"),
) -> R:
    """The held-out rows without the outliers the training rule finds among them (noted)."""
    m = len(fitted.position)
    rot = None
    if fitted.orientation is not None and errors.orientation is not None:
        rot = np.concatenate([fitted.orientation, errors.orientation])
    pooled = outliers.Errors(np.concatenate([fitted.position, errors.position]), rot, fitted.dims)
    units = (0,) * m + rows
    bad = outliers.find_outliers(pooled, noise, units)[0][m:]
    if not bad.any() or 2 * int(bad.sum()) >= len(bad):
        return held
    dropped = outliers.records(pooled, np.concatenate([np.zeros(m, dtype=bool), bad]), units)
    note = outliers.set_aside_note(dropped, *words)
    notes.append(f"held out: {note}; the held-out statistics leave them out")
    return held.subset(~bad)
