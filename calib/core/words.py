"""A count and its noun, singular for one, in the texts calib prints."""

from __future__ import annotations

__all__ = ["counted", "noun"]

_ES = ("ches", "shes", "sses", "xes")
"""Plurals that add ``es`` (touches, boxes): their singular drops two letters."""


def noun(n: int, plural: str, one: str | None = None) -> str:
    """The noun for ``n`` things, without the count: ``noun(1, "cameras")`` is ``camera``.

    Args:
        n: The count.
        plural: The noun in the plural; its last word loses its ``s`` (``es`` after ch, sh,
            ss, x) for one: ``joint placement components``, ``touches``.
        one: The singular, where that rule does not make it.
    """
    if n != 1:
        return plural
    if one is None:
        one = plural[:-2] if plural.endswith(_ES) else plural[:-1]
    return one


def counted(n: int, plural: str, one: str | None = None) -> str:
    """``n`` and its noun: ``counted(3, "rows")`` is ``3 rows``, ``counted(1, "rows")`` ``1 row``.

    Args:
        n: The count.
        plural: The noun in the plural (see :func:`noun`).
        one: The singular, where that rule does not make it.
    """
    return f"{n} {noun(n, plural, one)}"
