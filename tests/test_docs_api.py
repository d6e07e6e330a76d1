"""docs/reference/api.md renders: each object it documents is a Sphinx object description (a
signature, the parameters with their types, the docstring's sections), never the raw
``.. py:function::`` text that MyST's ``{autofunction}`` blocks left on the page (autodoc writes
reStructuredText, which MyST read as Markdown: the page never rendered before session 51).

The page alone is built (Sphinx with docs/conf.py, notebooks off: about 20 s), into a temporary
folder; the whole site is ``bash .ci/run docs``, where every warning fails the build.
"""

from __future__ import annotations

import html
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import calib

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
API_PAGE = DOCS / "reference" / "api.md"
DIRECTIVE = re.compile(r"^\.\. auto(function|class):: (calib\.[\w.]+)$", re.M)
# The page links to pages of the site that this build leaves out.
OTHER_PAGES = re.compile(r"WARNING: unknown document: '(python|errors)'")


@pytest.fixture(scope="module")
def built(tmp_path_factory) -> tuple[str, list[str]]:
    """The API page's HTML, and the warnings of its build but the links to other pages."""
    pytest.importorskip("sphinx")
    pytest.importorskip("myst_nb")
    pytest.importorskip("furo")
    work = tmp_path_factory.mktemp("api_page")
    source = work / "src"
    source.mkdir()
    shutil.copy(API_PAGE, source / "api.md")
    warnings = work / "warnings.txt"
    command = [sys.executable, "-m", "sphinx", "-b", "html", "-q", "-E", "-n", "-c", str(DOCS)]
    command += ["-D", "nb_execution_mode=off", "-D", "root_doc=api", "-w", str(warnings)]
    done = subprocess.run(
        [*command, str(source), str(work / "html")], capture_output=True, text=True, cwd=ROOT
    )
    assert done.returncode == 0, done.stderr
    found = [w for w in warnings.read_text().splitlines() if "WARNING" in w or "ERROR" in w]
    return (work / "html" / "api.html").read_text(encoding="utf-8"), found


def _rendered(page: str) -> set[str]:
    """The ids of the object descriptions Sphinx rendered (``<dt class="sig sig-object py"``)."""
    ids = re.findall(r'<dt class="sig sig-object py[^"]*" id="([\w.]+)"', page)
    return set(ids)


def test_every_public_name_renders_as_an_object(built):
    """Each name of ``calib.__all__`` (``calib.design`` as the function it calls), and every
    object the page's directives name, has its object description on the built page."""
    page, _ = built
    rendered = _rendered(page)
    public = {f"calib.{n}" for n in calib.__all__} - {"calib.design"}
    assert "calib.calibrate" in public and len(public) == 35
    assert public <= rendered, sorted(public - rendered)
    assert "calib.design.design.design" in rendered
    named = {name for _, name in DIRECTIVE.findall(API_PAGE.read_text(encoding="utf-8"))}
    assert len(named) > 60
    assert named <= rendered, sorted(named - rendered)


def test_no_raw_restructured_text_is_left_on_the_page(built):
    """The page of the ``{autofunction}`` blocks showed ``.. py:function:: load_robot(...)`` and
    ``:param robot: ...`` as paragraphs."""
    text = html.unescape(re.sub(r"<[^>]+>", "", built[0]))
    for raw in (".. py:", ".. auto", ":param ", ":type ", ":rtype:", ":returns:", ":raises "):
        assert raw not in text, raw


def test_a_function_renders_its_signature_parameters_and_units(built):
    """``calib.simulate``: its signature (the parameters and their defaults), its Args with
    their types and units, its Returns and Raises sections."""
    page = built[0]
    start = page.index('id="calib.simulate"')
    entry = page[start : page.index('<dt class="sig sig-object py', start)]  # the next object
    text = html.unescape(re.sub(r"<[^>]+>", "", entry))
    signature = re.sub(r"\s+", "", text.split(")")[0] + ")")
    assert signature.endswith(
        "calib.simulate(chain,configs=100,measure=DEFAULT_MEASURE,"
        "marker=None,error_mm=1.0,error_mrad=1.0,noise_mm=0.0,"
        "noise_mrad=None,seed=0,params=DEFAULT_SET,*,robot_seed=None)"
    ), text
    for field in ("Parameters:", "Returns:", "Raises:"):
        assert field in text, field
    assert "noise_mm (float) -- Standard deviation" in text
    assert "[mm]" in text


def test_the_page_builds_without_a_warning(built):
    """Every docstring on the page is valid markup (Google sections, no ``|x|`` read as a
    substitution) and every cross-reference (``-n``) lands on an object the site documents:
    calib's own names are checked, only those outside calib are not (docs/conf.py)."""
    _, warnings = built
    left = [w for w in warnings if not OTHER_PAGES.search(w)]
    assert not left, "\n".join(left)
