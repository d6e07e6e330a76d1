"""Every snippet of the README and of the documentation site runs, and prints what the page says.

The pages are README.md and docs/**/*.md. On each page, in document order and in one temporary
directory (holding a link to the repository's ``data/``):

- every fenced ``python`` block runs, the page's blocks in one namespace, unless the line
  before it says why it cannot (``% test: not run (REASON)``, ``<!-- test: not run (REASON) -->``
  in the README): a sketch that needs the reader's own files. A sentence after a block that
  says ``It prints `TEXT` `` is checked against what the block printed;
- a ``console`` block marked runnable (``% test: run``, ``<!-- test: run -->``) runs each of its
  ``$ calib ...`` commands with the installed ``calib``; every output line the page shows under
  a command (``...`` lines left out) must be a line of what it printed (spaces aside): the
  figure beside a reproduce line is the figure the command prints.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted([ROOT / "README.md", *(p for p in DOCS.rglob("*.md") if "_build" not in p.parts)])
FENCE = re.compile(r"^(`{3,})(\S*)\s*$")
MARK = re.compile(r"^(?:%|<!--)\s*test:\s*(run|not run \((?P<why>[^)]+)\))\s*(?:-->)?\s*$")
PRINTS = re.compile(r"[Ii]t prints `([^`]+)`")


@dataclass(frozen=True)
class Block:
    """A fenced block of a page: its language, text, line, mark and the prose after it."""

    lang: str
    text: str
    line: int
    mark: str | None
    after: str


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a Markdown page (MyST directives ``{...}`` left out)."""
    lines = page.read_text().splitlines()
    found, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        ticks, lang, start = m.group(1), m.group(2), i
        j = i + 1
        while j < len(lines) and lines[j].rstrip() != ticks:
            j += 1
        mark = MARK.match(lines[start - 1]) if start else None
        after = "\n".join(lines[j + 1 : j + 4])
        text = "\n".join(lines[start + 1 : j]) + "\n"
        found.append(Block(lang, text, start + 1, mark.group(1) if mark else None, after))
        i = j + 1
    return found


def runnable(page: Path) -> list[Block]:
    """The blocks of a page the test runs."""
    return [
        b
        for b in blocks(page)
        if (b.lang == "python" and b.mark is None) or (b.lang == "console" and b.mark == "run")
    ]


RUN_PAGES = [p for p in PAGES if runnable(p)]


def commands(text: str) -> list[tuple[str, list[str]]]:
    """A console block's ``$`` commands (``\\`` continued) and the output lines shown."""
    out: list[tuple[str, list[str]]] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        if not lines[i].startswith("$ "):
            i += 1
            continue
        cmd = lines[i][2:]
        while cmd.endswith("\\"):
            i += 1
            cmd = cmd[:-1] + " " + lines[i].strip()
        shown = []
        i += 1
        while i < len(lines) and not lines[i].startswith("$ "):
            if "..." not in lines[i] and lines[i].strip():
                shown.append(lines[i])
            i += 1
        out.append((cmd, shown))
    return out


def squeeze(line: str) -> str:
    return " ".join(line.split())


def console_env() -> dict[str, str]:
    """The environment of a page's commands: this tree's calib first (as test_cli_edges')."""
    return {**os.environ, "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg", "PYTHONPATH": str(ROOT)}


def run_console(block: Block, page: Path, tmp: Path) -> None:
    calib_exe = Path(sys.executable).parent / "calib"
    env = console_env()
    for cmd, shown in commands(block.text):
        argv = shlex.split(cmd, comments=True)
        assert argv[0] == "calib", f"{page.name}:{block.line}: not a calib command: {cmd}"
        done = subprocess.run(
            [str(calib_exe), *argv[1:]], cwd=tmp, env=env, capture_output=True, text=True
        )
        printed = {squeeze(x) for x in (done.stdout + done.stderr).splitlines()}
        assert done.returncode == 0, f"{page.name}:{block.line}: {cmd}\n{done.stderr}"
        missing = [x for x in shown if squeeze(x) not in printed]
        assert not missing, (
            f"{page.name}:{block.line}: {cmd}\nnot printed: {missing}\n{done.stdout}"
        )


def run_python(block: Block, page: Path, namespace: dict) -> None:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(block.text, f"{page.name}:{block.line}", "exec"), namespace)
    for want in PRINTS.findall(block.after):
        assert want in out.getvalue(), f"{page.name}:{block.line}: no `{want}` in\n{out.getvalue()}"


@pytest.mark.parametrize("page", RUN_PAGES, ids=[str(p.relative_to(ROOT)) for p in RUN_PAGES])
def test_page_snippets_run(page, tmp_path, monkeypatch):
    (tmp_path / "data").symlink_to(ROOT / "data")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    namespace: dict = {"__name__": "__docs__"}
    for block in runnable(page):
        if block.lang == "python":
            run_python(block, page, namespace)
        else:
            run_console(block, page, tmp_path)


def test_snippets_not_run_are_few_and_say_why():
    """The quickstart and the README run; a Python block left out names its reason."""
    assert any(p.name == "quickstart.md" for p in RUN_PAGES)
    assert ROOT / "README.md" in RUN_PAGES
    left_out = {
        (p.name, b.line): b.mark for p in PAGES for b in blocks(p) if b.lang == "python" and b.mark
    }
    assert all(m.startswith("not run (") for m in left_out.values()), left_out
    # Every Python block runs (the camera sketches on data simulated on their page); a block
    # left out is a deliberate choice, made here.
    assert not left_out, left_out


def test_marks_parse():
    text = "```python\nprint('a')\n```\nIt prints `a`\n"
    got = commands("$ calib list \\\n  --json\n...\nx  y\n$ calib demo\n")
    assert got == [("calib list  --json", ["x  y"]), ("calib demo", [])]
    assert MARK.match("% test: not run (needs your files)").group("why") == "needs your files"
    assert MARK.match("<!-- test: run -->").group(1) == "run"
    assert PRINTS.findall(text) == ["a"]


def test_every_command_has_its_reference_page():
    """docs/reference/cli holds one page per ``calib`` command, listed in its index."""
    from calib.cli.commands import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    index = (DOCS / "reference" / "cli" / "index.md").read_text()
    for name in sub.choices:
        page = DOCS / "reference" / "cli" / f"{name}.md"
        assert page.is_file(), f"no reference page for calib {name}"
        assert f":path: {name}\n" in page.read_text()
        assert f"\n{name}\n" in index


COMMAND = re.compile(r"`calib ([a-z]+)\b([^`]*)`|^\s*(?:\$ )?calib ([a-z]+)\b(.*)$", re.M)


def test_the_options_the_pages_give_a_command_are_its_own():
    """Every ``--option`` a page gives ``calib COMMAND`` (inline code, or a command line of
    a block, run or not) is one of that command's: contacts.md said ``calib predict --report
    r.json``, whose option is ``--compliance``."""
    from calib.cli.commands import build_parser

    sub = next(a for a in build_parser()._actions if a.dest == "command")
    options = {
        name: {o for action in parser._actions for o in action.option_strings}
        for name, parser in sub.choices.items()
    }
    wrong = []
    for page in PAGES:
        for m in COMMAND.finditer(page.read_text().replace("\\\n", " ")):
            name, rest = m.group(1, 2) if m.group(1) else m.group(3, 4)
            rest = rest.split("#")[0]
            given = re.findall(r"(?<![\w-])(--[a-z][a-z-]*)", rest) if name in options else []
            wrong += [f"{page.name}: calib {name} {o}" for o in given if o not in options[name]]
    assert not wrong


def test_page_commands_run_this_trees_calib(tmp_path):
    """In a worktree, the commands ran the editable install's calib (another tree's code)."""
    code = "import calib; print(calib.__file__)"
    done = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env=console_env(),
        capture_output=True,
        text=True,
    )
    assert Path(done.stdout.strip()) == ROOT / "calib" / "__init__.py"
