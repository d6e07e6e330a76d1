"""The YAML that camera files are written in: OpenCV's FileStorage and plain YAML, strictly.

calib needs no YAML library (PyYAML is not among its dependencies, and it refuses OpenCV's
``%YAML:1.0`` header anyway). This reader takes the subset that intrinsics files use:

* an optional directive (``%YAML:1.0`` as OpenCV 4 writes it, ``%YAML 1.2`` as OpenCV 5
  does) and one ``---``; comments (``#``);
* block mappings (``key: value``, indented by spaces) and block sequences (``- value``);
* flow sequences and mappings (``[1, 2]``, ``{rows: 3}``), also over several lines;
* plain and quoted scalars: numbers (``1``, ``0.``, ``-2.5e-01``, ``.nan``, ``.inf``) are
  read as numbers, ``true``/``false`` as booleans, ``null``/``~`` as None, the rest as text;
* OpenCV's tags on a mapping (``!!opencv-matrix``: its ``rows``, ``cols``, ``dt``, ``data``).

Anything else (anchors, other tags, multi-line text, several documents, tabs) is refused with
one :class:`~calib.exceptions.DataError` naming the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..exceptions import DataError

__all__ = ["parse_yaml"]

_INT = re.compile(r"[-+]?\d+")
_FLOAT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
_SPECIAL = {".nan": float("nan"), ".inf": float("inf"), "+.inf": float("inf")}
_SPECIAL["-.inf"] = float("-inf")
_WORDS = {"true": True, "false": False, "null": None, "~": None}
_TAG = re.compile(r"!!opencv-[a-z-]+(\s|$)")
"""OpenCV's tags (``!!opencv-matrix``, ``!!opencv-nd-matrix``): read on a mapping, dropped."""


@dataclass(frozen=True)
class _Line:
    """A line with content: its number (from 1), indentation and text (comment removed)."""

    number: int
    indent: int
    text: str


def parse_yaml(text: str, source: str) -> dict:
    """The top-level mapping of a YAML text in the subset above.

    Args:
        text: The file's text.
        source: Its name, for messages.

    Returns:
        The mapping: nested dicts, lists, numbers, booleans, None and strings.

    Raises:
        DataError: What the subset does not hold, or no mapping at the top, naming the line.
    """
    lines = _content_lines(text, source)
    if not lines:
        raise DataError(source, "empty file: expected YAML keys (image_width, ...)")
    reader = _Block(lines, source)
    value = reader.node(0, lines[0].indent)
    if reader.pos < len(lines):
        raise DataError(source, "unexpected indentation", row=lines[reader.pos].number)
    if not isinstance(value, dict):
        raise DataError(source, "expected YAML keys (key: value) at the top", row=lines[0].number)
    return value


def _content_lines(text: str, source: str) -> list[_Line]:
    """The lines with content, after the directive and the document marker."""
    out: list[_Line] = []
    started = False
    for number, raw in enumerate(text.splitlines(), start=1):
        body = _uncommented(raw).rstrip()
        if not body.strip():
            continue
        if body.startswith("%") and not out and not started:
            if not re.fullmatch(r"%YAML[: ]\d\.\d+", body):
                raise DataError(source, f"unknown directive {body!r:.40}", row=number)
            continue
        if body in ("---", "..."):
            if out or started or body == "...":
                raise DataError(source, "one YAML document is read, not several", row=number)
            started = True
            continue
        stripped = body.lstrip(" ")
        if stripped.startswith("\t") or "\t" in body[: len(body) - len(stripped)]:
            raise DataError(source, "a tab in the indentation: indent with spaces", row=number)
        out.append(_Line(number, len(body) - len(stripped), stripped))
    return out


def _uncommented(line: str) -> str:
    """The line without its comment (a ``#`` at its start or after a space, outside quotes)."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1] in " \t"):
            return line[:i]
    return line


class _Block:
    """Reads block nodes from the lines, ``pos`` the next line to read."""

    def __init__(self, lines: list[_Line], source: str):
        self.lines = lines
        self.source = source
        self.pos = 0

    def fail(self, reason: str, line: _Line | None = None) -> DataError:
        """The error at a line (default: the current one)."""
        at = line or self.lines[min(self.pos, len(self.lines) - 1)]
        return DataError(self.source, reason, row=at.number)

    def node(self, pos: int, indent: int) -> object:
        """The mapping or sequence whose lines start at ``pos``, indented by ``indent``."""
        self.pos = pos
        if _is_item(self.lines[pos].text):
            return self.sequence(indent)
        return self.mapping(indent)

    def sequence(self, indent: int) -> list:
        """A block sequence's items (``- value``) at ``indent``."""
        items: list = []
        while self.pos < len(self.lines):
            line = self.lines[self.pos]
            if line.indent != indent or not _is_item(line.text):
                break
            rest = line.text[1:].strip()
            self.pos += 1
            if rest:
                items.append(self.inline(rest, line))
            else:
                items.append(self.nested(indent, line, in_sequence=True))
        return items

    def mapping(self, indent: int) -> dict:
        """A block mapping's keys and values at ``indent``."""
        out: dict = {}
        while self.pos < len(self.lines):
            line = self.lines[self.pos]
            if line.indent < indent:
                break
            if line.indent > indent:
                raise self.fail("unexpected indentation")
            if _is_item(line.text):
                raise self.fail("a sequence item (- ...) among keys")
            key, rest = self.key(line)
            if key in out:
                raise self.fail(f"key {key!r} given twice")
            self.pos += 1
            rest, tagged = _untagged(rest)
            if rest and tagged:
                raise self.fail("an !!opencv- tag is on a block of keys (rows, cols, ...)", line)
            out[key] = self.inline(rest, line) if rest else self.nested(indent, line)
            if tagged and not isinstance(out[key], dict):
                raise self.fail("an !!opencv- tag is on a block of keys (rows, cols, ...)", line)
        return out

    def key(self, line: _Line) -> tuple[str, str]:
        """The key of a ``key: value`` line and the text after the colon."""
        match = re.match(r"""("[^"]*"|'[^']*'|[^\s:#"'\[\]{},][^:]*?)\s*:(\s|$)""", line.text)
        if not match:
            raise self.fail(f"expected 'key: value', found {line.text!r:.40}", line)
        return match.group(1).strip("\"'"), line.text[match.end() :].strip()

    def nested(self, indent: int, line: _Line, in_sequence: bool = False) -> object:
        """The block under a key or item with nothing after it (None if there is none)."""
        if self.pos >= len(self.lines):
            return None
        nxt = self.lines[self.pos]
        if nxt.indent > indent:
            return self.node(self.pos, nxt.indent)
        if nxt.indent == indent and _is_item(nxt.text) and not in_sequence:
            return self.sequence(indent)  # "key:" then "- item" at the key's indentation
        return None

    def inline(self, rest: str, line: _Line) -> object:
        """A scalar, or a flow collection that may go on over the next lines."""
        if rest[0] in "&*|>!":
            raise self.fail(
                f"YAML's {rest[0]!r} is not read here (anchors, tags, text blocks)", line
            )
        if rest[0] not in "[{":
            return _scalar(rest, line, self.source)
        text = rest
        while _depth(text) > 0 and self.pos < len(self.lines):
            text += " " + self.lines[self.pos].text
            self.pos += 1
        flow = _Flow(text, line, self.source)
        value = flow.value()
        flow.end()
        return value


def _is_item(text: str) -> bool:
    """Whether a line is a block sequence item."""
    return text == "-" or text.startswith("- ")


def _untagged(rest: str) -> tuple[str, bool]:
    """The value's text without an OpenCV tag (``!!opencv-matrix``, ...), and whether it had one."""
    match = _TAG.match(rest)
    if not match:
        return rest, False
    return rest[match.end() :].strip(), True


def _depth(text: str) -> int:
    """How many brackets of a flow collection are still open at the end of ``text``."""
    depth, quote = 0, None
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
    return depth


def _scalar(text: str, line: _Line, source: str) -> object:
    """A plain or quoted scalar's value."""
    if text[0] in "\"'":
        if len(text) < 2 or text[-1] != text[0]:
            raise DataError(source, f"unclosed quote in {text!r:.40}", row=line.number)
        return text[1:-1].replace("''", "'") if text[0] == "'" else text[1:-1]
    low = text.lower()
    if low in _WORDS:
        return _WORDS[low]
    if low in _SPECIAL:
        return _SPECIAL[low]
    if _INT.fullmatch(text):
        return int(text)
    if _FLOAT.fullmatch(text):
        return float(text)
    return text


class _Flow:
    """Reads a flow collection (``[...]``, ``{...}``) from one string."""

    def __init__(self, text: str, line: _Line, source: str):
        self.text = text
        self.i = 0
        self.line = line
        self.source = source

    def fail(self, reason: str) -> DataError:
        """The error, at the collection's first line."""
        return DataError(self.source, reason, row=self.line.number)

    def skip(self) -> str:
        """Skip spaces; the next character ('' at the end)."""
        while self.i < len(self.text) and self.text[self.i] == " ":
            self.i += 1
        return self.text[self.i] if self.i < len(self.text) else ""

    def end(self) -> None:
        """Refuse what follows the collection."""
        if self.skip():
            raise self.fail(f"unexpected {self.text[self.i :]!r:.40} after the closing bracket")

    def value(self) -> object:
        """The value that starts here."""
        ch = self.skip()
        if ch in ("[", "{"):
            return self.collection(ch)
        start = self.i
        if ch in "\"'":
            close = self.text.find(ch, self.i + 1)
            if close < 0:
                raise self.fail("unclosed quote")
            self.i = close + 1
        else:
            while self.i < len(self.text) and self.text[self.i] not in ",]}:":
                self.i += 1
        token = self.text[start : self.i].strip()
        if not token:
            raise self.fail("an empty value in a flow collection")
        return _scalar(token, self.line, self.source)

    def collection(self, opening: str) -> object:
        """The list or dict whose bracket is at ``i``."""
        closing = "]" if opening == "[" else "}"
        self.i += 1
        items: list = []
        pairs: dict = {}
        if self.skip() == closing:
            self.i += 1
            return items if opening == "[" else pairs
        while True:
            item = self.value()
            if opening == "{":
                if self.skip() != ":":
                    raise self.fail("expected 'key: value' in a flow mapping")
                self.i += 1
                if str(item) in pairs:
                    raise self.fail(f"key {str(item)!r} given twice")
                pairs[str(item)] = self.value()
            else:
                items.append(item)
            ch = self.skip()
            self.i += 1
            if ch == closing:
                return items if opening == "[" else pairs
            if ch != ",":
                raise self.fail(f"expected ',' or '{closing}' in a flow collection")
