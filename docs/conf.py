"""Sphinx configuration of calib's documentation site (``bash .ci/run docs``).

Markdown pages (MyST), the notebooks of ``notebooks/`` executed at build time (myst-nb), the
API reference from the Google docstrings (autodoc + napoleon), the command line from its
argparse parser (sphinx-argparse). Built with ``-W --keep-going -n``: every warning, broken
link and unresolved cross-reference fails the build.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")


def copy_tutorials(source: Path, target: Path) -> None:
    """Copy the notebooks of ``source`` into ``target``, the tutorials' folder of the site.

    A copy, not a symlink: Sphinx resolves a link's path through symlinks, so the links from
    one tutorial to another ([...](02_calibrate_from_a_tracker.ipynb)) would point outside the
    site. An unchanged notebook is not written again (its cached outputs and the incremental
    build stay valid); one removed from ``source`` is removed here.
    """
    if target.is_symlink():  # a checkout from before the copy
        target.unlink()
    target.mkdir(exist_ok=True)
    wanted = {nb.name: nb.read_bytes() for nb in source.glob("*.ipynb")}
    for old in target.glob("*.ipynb"):
        if old.name not in wanted:
            old.unlink()
    for name, text in wanted.items():
        copy = target / name
        if not copy.is_file() or copy.read_bytes() != text:
            copy.write_bytes(text)


copy_tutorials(ROOT / "notebooks", ROOT / "docs" / "tutorials" / "notebooks")

import calib  # noqa: E402

project = "calib"
author = "the calib authors"
copyright = "the calib authors, BSD-3-Clause"
release = version = calib.__version__

extensions = [
    "myst_nb",  # Markdown (MyST) pages and notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",
    "sphinx_copybutton",
]

source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
exclude_patterns = ["_build", "**.ipynb_checkpoints", "Thumbs.db", ".DS_Store"]

# MyST: anchors for headings (links such as [x](errors.md#bad-input)), definition lists.
myst_heading_anchors = 4
myst_enable_extensions = ["colon_fence", "deflist"]

# Notebooks: committed without outputs, executed at build time (cached between builds of one
# tree in docs/_build/.jupyter_cache); a cell that raises fails the build.
nb_execution_mode = "cache"
nb_execution_cache_path = str(ROOT / "docs" / "_build" / ".jupyter_cache")
nb_execution_timeout = 600
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True
nb_render_markdown_format = "gfm"  # tables in the notebooks' Markdown outputs (IPython Markdown)

# API reference: Google docstrings, types from the annotations, members in source order.
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
# Types in the text for the arguments an Args section documents, and the return value: a
# dataclass's fields are its Attributes (types from the annotations), not its constructor's
# parameters again (which named every internal type a field holds).
autodoc_typehints_description_target = "documented_params"
autodoc_preserve_defaults = True
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False

# Every cross-reference is checked (-n). Names outside calib (NumPy, Pinocchio, the standard
# library's typing helpers) have no inventory here (the build runs offline): they are not
# checked; calib's own names are.
nitpicky = True
_OUTSIDE = (
    "np|numpy|npt|pin|pinocchio|scipy|matplotlib|collections|typing|pathlib|os|io|types|enum|abc"
)
_BUILTIN = (
    "Path|PathLike|Sequence|Iterable|Iterator|Mapping|Callable|Any|NDArray|ArrayLike|Literal|Self|"
    "TypeAlias|Figure|Axes|TextIO|IO|Enum|optional|ndarray|array|float|int|str|bool|dict|list|"
    "tuple|object|None"
)
nitpick_ignore_regex = [(r"py:.*", rf"({_OUTSIDE})(\..*)?"), (r"py:class", rf"({_BUILTIN})")]

smartquotes = False  # "--params" stays two hyphens (option names in prose and notebook outputs)
html_theme = "furo"
html_title = f"calib {release}"
html_static_path: list[str] = []
copybutton_prompt_text = r"\$ "
copybutton_prompt_is_regexp = True
