"""The code-shape rules of the standards, checked on the source (no import of calib).

- every module of ``calib/`` is at most ``MODULE_LINES`` lines (all its lines, as ``wc -l``);
- every function or method (nested ones too) is at most ``FUNCTION_LINES`` lines of code:
  the lines from its ``def`` to its last line, less the lines of its docstring (the
  decorators are not counted; blank lines and comments are, as they take room too);
- no ``# fmt: skip`` or ``# fmt: off`` in ``FORMATTED`` (``calib/``, ``tests/``,
  ``benchmarks/``): the formatter's layout holds everywhere.
"""

from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
MODULE_LINES = 600
FUNCTION_LINES = 60
FORMATTER_OFF = ("fmt: skip", "fmt: off")
FORMATTED = ("calib", "tests", "benchmarks")


def _python_files(folder: str) -> list[Path]:
    return sorted((ROOT / folder).rglob("*.py"))


def _docstring_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> set[int]:
    first = node.body[0]
    if (
        isinstance(first, ast.Expr)
        and isinstance(first.value, ast.Constant)
        and isinstance(first.value.value, str)
    ):
        return set(range(first.lineno, (first.end_lineno or first.lineno) + 1))
    return set()


def code_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines from the ``def`` to the function's last line, less its docstring's."""
    span = set(range(node.lineno, (node.end_lineno or node.lineno) + 1))
    return len(span - _docstring_lines(node))


def long_functions(source: str, name: str) -> list[str]:
    """``name:line function (N lines)`` for every function over ``FUNCTION_LINES``."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            lines = code_lines(node)
            if lines > FUNCTION_LINES:
                found.append(f"{name}:{node.lineno} {node.name} ({lines} lines)")
    return found


def formatter_off(source: str, name: str) -> list[str]:
    """``name:line`` for every comment that turns the formatter off."""
    tokens = tokenize.generate_tokens(io.StringIO(source).readline)
    return [
        f"{name}:{tok.start[0]}"
        for tok in tokens
        if tok.type == tokenize.COMMENT and any(w in tok.string for w in FORMATTER_OFF)
    ]


def test_the_counts_are_the_ones_described():
    """A known function: 2 lines of docstring left out, blank lines and comments counted."""
    source = 'def f(x):\n    """Doc.\n\n    More."""\n    # a comment\n\n    return x\n'
    (node,) = ast.parse(source).body
    assert isinstance(node, ast.FunctionDef)
    assert code_lines(node) == 7 - 3
    long = "def g():\n" + "    x = 1\n" * FUNCTION_LINES
    assert long_functions(long, "m") == [f"m:1 g ({FUNCTION_LINES + 1} lines)"]
    assert long_functions("def h():\n" + "    x = 1\n" * (FUNCTION_LINES - 1), "m") == []
    assert formatter_off("x = [1,  2]  # fmt: skip\ny = '# fmt: off'\n", "m") == ["m:1"]


def test_every_module_of_calib_is_at_most_600_lines():
    long = [
        f"{p.relative_to(ROOT)} ({n} lines)"
        for p in _python_files("calib")
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MODULE_LINES
    ]
    assert not long, f"modules over {MODULE_LINES} lines: {long}"


def test_every_function_of_calib_is_at_most_60_lines_of_code():
    long = [
        found
        for p in _python_files("calib")
        for found in long_functions(p.read_text(encoding="utf-8"), str(p.relative_to(ROOT)))
    ]
    assert not long, f"functions over {FUNCTION_LINES} lines of code: {long}"


@pytest.mark.parametrize("folder", FORMATTED)
def test_the_formatter_is_never_turned_off(folder):
    off = [
        found
        for p in _python_files(folder)
        for found in formatter_off(p.read_text(encoding="utf-8"), str(p.relative_to(ROOT)))
    ]
    assert not off, f"# fmt: skip / # fmt: off in {folder}/: {off}"
