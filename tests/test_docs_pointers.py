"""The code's pointers into the developer pages (``docs/developers/PAGE.md#anchor``) land on a
heading: the rationale and measurements moved out of the docstrings stay findable when a
heading is renamed (MyST's heading anchors, ``myst_heading_anchors`` in docs/conf.py)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
POINTER = re.compile(r"docs/developers/([a-z_-]+\.md)#([A-Za-z0-9_-]+)")


def _anchors(page: Path) -> set[str]:
    """The anchors MyST gives the page's headings: lower case, punctuation but ``_`` and ``-``
    dropped, spaces as ``-`` (GitHub's rule)."""
    titles = re.findall(r"^#{1,6} (.+)$", page.read_text(), flags=re.M)
    return {re.sub(r"[^\w\s-]", "", t.lower()).strip().replace(" ", "-") for t in titles}


def test_every_pointer_of_the_code_lands_on_a_heading():
    pointers = {
        (m.group(1), m.group(2))
        for path in (ROOT / "calib").rglob("*.py")
        for m in POINTER.finditer(path.read_text())
    }
    assert len(pointers) >= 30  # the engine page's and the performance page's
    pages = {name: _anchors(ROOT / "docs" / "developers" / name) for name, _ in pointers}
    missing = sorted(f"{name}#{anchor}" for name, anchor in pointers if anchor not in pages[name])
    assert not missing, missing


def test_the_anchor_rule_is_the_one_the_pages_use():
    """A heading of each kind the pointers name, turned into its anchor by the rule above."""
    page = ROOT / "docs" / "developers" / "performance.md"
    assert "_levenberg_marquardt-solve" in _anchors(page)
    assert "twist_columns" in _anchors(ROOT / "docs" / "developers" / "engine.md")
