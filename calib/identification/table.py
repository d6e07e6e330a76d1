"""Plain-text tables for the terminal (standard library only: ``calib list`` uses it)."""

from __future__ import annotations

__all__ = ["format_table"]


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def format_table(header: list[str], rows: list[list[str]]) -> str:
    """Plain-text table: numeric columns right-aligned, text columns left-aligned."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    right = [all(_is_number(r[i]) or r[i] in ("-", "") for r in rows) for i in range(len(header))]

    def line(cells: list[str]) -> str:
        out = [
            c.rjust(w) if rj else c.ljust(w) for c, w, rj in zip(cells, widths, right, strict=True)
        ]
        return "  ".join(out).rstrip()

    return "\n".join([line(header), line(["-" * w for w in widths]), *(line(r) for r in rows)])
