"""The notebooks in notebooks/ run from top to bottom and are committed without outputs.

Each notebook is executed with nbclient in a temporary copy of notebooks/ (nothing is
written into the repository), by a kernel that runs this very interpreter: a private
kernelspec named ``python3`` whose argv is ``sys.executable``, so a ``python3`` kernelspec
installed elsewhere (user or system Jupyter) cannot pick another Python without calib.
The notebooks are tutorials: they carry no test ``assert`` (their figures are checked by
tests/test_study_*.py), no issue numbers, and import only calib's public face (``import
calib``; ``calib.__all__`` and ``calib.design``).
"""

from __future__ import annotations

import json
import re
import shutil
import sys
import types
from pathlib import Path

import nbclient
import nbformat
import pytest
from jupyter_client import KernelManager
from jupyter_client.kernelspec import KernelSpecManager

NOTEBOOKS_DIR = Path(__file__).resolve().parent.parent / "notebooks"
DATA_DIR = NOTEBOOKS_DIR.parent / "data"
NOTEBOOKS = sorted(NOTEBOOKS_DIR.glob("*.ipynb"))
TIMEOUT_S = 600


def _kernel_manager(tmp_path: Path):
    """A kernel manager whose only ``python3`` kernelspec runs ``sys.executable``."""
    spec_dir = tmp_path / "kernels" / "python3"
    spec_dir.mkdir(parents=True)
    spec = {
        "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
        "display_name": "Python 3 (calib tests)",
        "language": "python",
        # this tree's calib, not an editable install's (another tree's in a git worktree)
        "env": {"PYTHONPATH": str(NOTEBOOKS_DIR.parent)},
    }
    (spec_dir / "kernel.json").write_text(json.dumps(spec))
    ksm = KernelSpecManager(kernel_dirs=[str(tmp_path / "kernels")], ensure_native_kernel=False)
    return KernelManager(kernel_name="python3", kernel_spec_manager=ksm)


def _execute(nb: nbformat.NotebookNode, cwd: Path, tmp_path: Path) -> nbformat.NotebookNode:
    client = nbclient.NotebookClient(
        nb,
        km=_kernel_manager(tmp_path),
        kernel_name="python3",
        timeout=TIMEOUT_S,
        resources={"metadata": {"path": str(cwd)}},
    )
    return client.execute()


def _outputs_of(nb: nbformat.NotebookNode) -> list:
    return [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 2, f"no notebooks found in {NOTEBOOKS_DIR}"


def test_kernel_runs_this_interpreter(tmp_path):
    nb = nbformat.v4.new_notebook()
    nb.cells.append(nbformat.v4.new_code_cell("import sys\nprint(sys.executable)"))
    _execute(nb, tmp_path, tmp_path)
    (out,) = _outputs_of(nb)
    assert out.output_type == "stream"
    assert Path(out.text.strip()) == Path(sys.executable)


def test_kernel_imports_this_trees_calib(tmp_path):
    """In a worktree, the notebooks ran the editable install's calib (another tree's code)."""
    nb = nbformat.v4.new_notebook()
    nb.cells.append(nbformat.v4.new_code_cell("import calib\nprint(calib.__file__)"))
    _execute(nb, tmp_path, tmp_path)
    (out,) = _outputs_of(nb)
    assert Path(out.text.strip()) == NOTEBOOKS_DIR.parent / "calib" / "__init__.py"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_committed_without_outputs(path: Path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code, f"{path.name} has no code cell"
    dirty = [i for i, c in enumerate(nb.cells) if c.cell_type == "code" and c.outputs != []]
    counted = [
        i for i, c in enumerate(nb.cells) if c.cell_type == "code" and c.execution_count is not None
    ]
    assert not dirty, f"{path.name}: cells {dirty} have outputs (clear them before committing)"
    assert not counted, f"{path.name}: cells {counted} have execution counts"


ASSERT = re.compile(r"^\s*assert\b", re.MULTILINE)
ISSUE = re.compile(r"\bissues?\s+#?\d+", re.IGNORECASE)
DEEP_IMPORT = re.compile(r"^\s*(from|import)\s+calib\.(?!design\b)", re.MULTILINE)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_a_tutorial(path: Path):
    """No test asserts, no issue numbers, only the public API (``import calib``)."""
    nb = nbformat.read(path, as_version=4)
    code = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
    text = "\n".join(c.source for c in nb.cells)
    assert not ASSERT.findall(code), f"{path.name}: test asserts belong in tests/"
    assert not ISSUE.findall(text), f"{path.name}: mentions {ISSUE.findall(text)}"
    deep = [m.group(0).strip() for m in DEEP_IMPORT.finditer(code)]
    assert not deep, f"{path.name} imports calib's modules: {deep}"
    names = set(re.findall(r"\bcalib\.((?!__)\w+)", code))  # dunders (__file__) are fine
    import calib

    private = sorted(names - set(calib.__all__) - {"design"})
    assert not private, f"{path.name} uses calib names outside calib.__all__: {private}"


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path: Path, tmp_path: Path):
    # Run in a copy of the whole folder, so a notebook may read its neighbours (and the
    # repository's data/ as ../data, as it does from a clone) and anything it writes lands in
    # tmp_path.
    work = tmp_path / "notebooks"
    shutil.copytree(NOTEBOOKS_DIR, work, ignore=shutil.ignore_patterns(".ipynb_checkpoints"))
    shutil.copytree(DATA_DIR, tmp_path / "data")
    nb = nbformat.read(work / path.name, as_version=4)
    _execute(nb, work, tmp_path)  # raises CellExecutionError on a failing cell or assert
    outputs = _outputs_of(nb)
    errors = [o for o in outputs if o.output_type == "error"]
    assert not errors, errors
    missing = _stated_but_not_printed(nb, path)
    assert not missing, f"{path.name}: figures its prose or the tutorials page state: {missing}"
    # Figures (calib's plots, ``result.plot()``, matplotlib's) must show inline as images, not
    # as "<Figure size ...>" text.
    code = "".join(c.source for c in nb.cells if c.cell_type == "code")
    if any(k in code for k in ("_figure(", ".plot()", "Figure(")):
        assert any("image/png" in o.get("data", {}) for o in outputs), (
            f"{path.name} builds figures but displays none"
        )


FIGURE = re.compile(r"(?<![\w.])\d+\.(\d+)(?![\w.])")
TUTORIALS_PAGE = NOTEBOOKS_DIR.parent / "docs" / "tutorials" / "index.md"


def _stated_but_not_printed(nb: nbformat.NotebookNode, path: Path) -> list[str]:
    """The figures (3 significant digits or more) a notebook's prose, or its item of
    docs/tutorials/index.md, states that none of its code cells holds or its outputs print
    (to one unit of the stated last digit: 4.87 for a printed 4.875).

    Notebook 03 said random sets were "poorer" in the box than over the whole joint space, 0.0667
    against 0.06658 mm: a claim whose figures are printed beside it can be checked, and is."""
    items = re.findall(r"^\d\. (.*?)(?=^\d\. |^\S)", TUTORIALS_PAGE.read_text(), re.S | re.M)
    prose = [c.source for c in nb.cells if c.cell_type == "markdown"]
    prose.append(items[NOTEBOOKS.index(NOTEBOOKS_DIR / path.name)])
    code = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
    printed = "\n".join(str(o.get("text", "")) for o in _outputs_of(nb))
    values = [float(m.group(0)) for m in FIGURE.finditer(printed)]
    missing = []
    for m in FIGURE.finditer("\n".join(prose)):
        stated, places = m.group(0), len(m.group(1))
        if len(stated.replace(".", "").lstrip("0")) < 3 or stated in code:
            continue
        if not any(abs(v - float(stated)) <= 10.0**-places for v in values):
            missing.append(stated)
    return missing


REAL_DATA = [p for p in NOTEBOOKS if "data/realdata" in p.read_text()]


@pytest.mark.parametrize("path", REAL_DATA, ids=lambda p: p.name)
def test_notebook_without_the_real_data_says_where_to_run_it(path, tmp_path, monkeypatch):
    """Run outside a clone (a pip-installed calib), the data cell names the way out.

    It raised a bare StopIteration.
    """
    nb = nbformat.read(path, as_version=4)
    cell = next(c.source for c in nb.cells if "REAL =" in c.source)
    code = "\n".join(line for line in cell.splitlines() if not line.startswith("%"))
    installed = types.ModuleType("calib")
    installed.__file__ = str(tmp_path / "site-packages" / "calib" / "__init__.py")
    monkeypatch.setitem(sys.modules, "calib", installed)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(FileNotFoundError, match="notebooks/ folder of a clone"):
        exec(compile(code, path.name, "exec"), {})


SUMMARY_PROSE = ["02_calibrate_from_a_tracker.ipynb", "04_humanoid_contacts.ipynb"]


@pytest.mark.parametrize("name", SUMMARY_PROSE)
def test_the_lines_the_prose_names_are_the_printed_ones(name, monkeypatch, capsys):
    """Notebook 04's prose named the lines **held out, registration only** and **held out,
    calibrated**, a tracker's summary's: a contact fit prints ``held_out_registration`` and
    ``held_out``. The first cell naming summary lines in bold names lines of the text the
    code cells before it print (run here in-process, the notebooks' folder as the cwd; the
    tracker's ``held out (FILE), registration only`` is named without its file)."""
    nb = nbformat.read(NOTEBOOKS_DIR / name, as_version=4)
    k = next(
        i for i, c in enumerate(nb.cells) if c.cell_type == "markdown" and "**held" in c.source
    )
    monkeypatch.chdir(NOTEBOOKS_DIR)
    namespace: dict = {}
    for cell in nb.cells[:k]:
        if cell.cell_type == "code":
            code = "\n".join(line for line in cell.source.splitlines() if not line.startswith("%"))
            exec(compile(code, name, "exec"), namespace)
    out = capsys.readouterr().out  # "held out (FILE), registration only" is named without FILE
    printed = {re.sub(r" \([^)]*\)", "", line).strip() for line in out.splitlines()}
    named = re.findall(r"\*\*(.+?)\*\*", nb.cells[k].source)
    assert named, nb.cells[k].source
    missing = [n for n in named if not any(line.startswith(n + " ") for line in printed)]
    assert not missing, (missing, sorted(printed))
