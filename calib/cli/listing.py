"""What ``calib list`` prints, from the catalog file alone (no numpy: the launcher uses it)."""

from __future__ import annotations

from ..kinematics.catalog import catalog

__all__ = ["catalog_listing"]


def catalog_listing(as_json: bool) -> str:
    """What ``calib list`` prints: the catalog as a table, or as JSON."""
    import json

    from ..identification.table import format_table

    if as_json:
        robots = [e.__dict__ | {"path": str(e.path)} for e in catalog()]
        return json.dumps({"robots": robots}, indent=2)
    rows = [
        [
            e.name,
            f"{e.base} -> {', '.join(e.tools)}",
            e.description + (f" [{e.expect_error}]" if e.expect_error else ""),
        ]
        for e in catalog()
    ]
    return format_table(["name", "chain", "description"], rows)
