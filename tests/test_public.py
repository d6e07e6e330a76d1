"""The public line of calib/: every module says what it exports, and keeps to it.

- every module has ``__all__``, and every name in it exists;
- a module imports from another calib module only names of that module's ``__all__``;
- the lazy packages name their lazy names for type checkers too (``if TYPE_CHECKING:``);
- the library's errors speak of keyword arguments, not command-line flags (``--fix``): the
  command line (calib/cli/) words its own.
"""

from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

import calib

PACKAGE = Path(calib.__file__).parent
MODULES = sorted(PACKAGE.rglob("*.py"))


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def tree_of(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


def declared_all(path: Path) -> list[str] | None:
    """The literal ``__all__`` of a module's source, or None without one."""
    for node in tree_of(path).body:
        targets = (
            node.targets
            if isinstance(node, ast.Assign)
            else [node.target]
            if isinstance(node, ast.AnnAssign)
            else []
        )
        if any(isinstance(t, ast.Name) and t.id == "__all__" for t in targets):
            try:
                return list(ast.literal_eval(node.value))
            except ValueError:  # computed (sorted(_LAZY)): the imported module tells
                return list(importlib.import_module(module_name(path)).__all__)
    return None


def test_the_walk_sees_every_wing():
    names = {module_name(p) for p in MODULES}
    assert {"calib", "calib.cli.__main__", "calib.kinematics.robot", "calib.core.fileio"} <= names
    assert len(MODULES) > 50


@pytest.mark.parametrize("path", MODULES, ids=module_name)
def test_every_module_declares_all_and_every_name_exists(path):
    names = declared_all(path)
    assert names is not None, f"{module_name(path)} has no __all__"
    assert all(isinstance(n, str) for n in names)
    assert len(set(names)) == len(names), f"{module_name(path)}: a name twice in __all__"
    assert not [n for n in names if n.startswith("_")], "an internal name in __all__"
    if path.name == "__main__.py":  # running it is the command line
        assert names == []
        return
    module = importlib.import_module(module_name(path))
    missing = [n for n in names if not hasattr(module, n)]
    assert not missing, f"{module_name(path)}.__all__ names what it lacks: {missing}"


def imported_names(path: Path):
    """(source module, name) of each ``from ... import name`` of a calib module."""
    me = module_name(path)
    package = me if path.name == "__init__.py" else me.rpartition(".")[0]
    for node in ast.walk(tree_of(path)):
        if not isinstance(node, ast.ImportFrom):
            continue
        if node.level:
            base = package.split(".")[: len(package.split(".")) - node.level + 1]
            source = ".".join(base + ([node.module] if node.module else []))
        else:
            source = node.module or ""
        if source == "calib" or source.startswith("calib."):
            for alias in node.names:
                yield source, alias.name


def test_modules_import_only_public_names_of_each_other():
    modules = {module_name(p): p for p in MODULES}
    exported = {name: declared_all(p) or [] for name, p in modules.items()}
    crossing = []
    for path in MODULES:
        for source, name in imported_names(path):
            if f"{source}.{name}" in modules or (name.startswith("__") and name.endswith("__")):
                continue  # a submodule, or a dunder (__version__)
            if name not in exported[source]:
                crossing.append(f"{module_name(path)} imports {source}.{name}")
    assert not crossing, "\n".join(crossing)


def test_the_check_sees_a_private_import(tmp_path):
    """The walk above finds ``from .x import _y`` (not a test that cannot fail)."""
    path = PACKAGE / "calibration" / "model.py"
    found = list(imported_names(path))
    assert ("calib.calibration.options", "_integer") not in found
    assert ("calib.identification.parameters", "ParameterSet") in found
    fake = ast.parse("from ..options import _integer\n")
    node = fake.body[0]
    assert isinstance(node, ast.ImportFrom) and node.level == 2


LAZY_PACKAGES = ["calib", "calib.calibration", "calib.measurements", "calib.cli"]


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_lazy_names_are_typed(package):
    """``_LAZY`` (imported when first used) and the TYPE_CHECKING imports name the same."""
    module = importlib.import_module(package)
    path = Path(module.__file__)
    typed = {}
    for node in tree_of(path).body:
        if isinstance(node, ast.If) and getattr(node.test, "id", None) == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom) and imp.level == 1
                typed.update({a.name: imp.module for a in imp.names})
    assert typed == dict(module._LAZY)
    for name in module._LAZY:  # public (calib's other names are moved ones: they warn)
        assert name in module.__all__
        assert getattr(module, name) is not None


# ``raise SomeError("... --flag ...")`` outside calib/cli/: a library error naming a flag.
FLAG = re.compile(r"(^|[\s('\"`])--[a-z][a-z-]*")


def library_messages():
    """(module, line, text) of every string in a ``raise`` outside calib/cli/."""
    for path in MODULES:
        if "cli" in path.relative_to(PACKAGE).parts:
            continue
        for node in ast.walk(tree_of(path)):
            if isinstance(node, ast.Raise) and node.exc is not None:
                for part in ast.walk(node.exc):
                    if isinstance(part, ast.Constant) and isinstance(part.value, str):
                        yield module_name(path), part.lineno, part.value


def test_library_errors_name_no_command_line_flag():
    flagged = [f"{m}:{line}: {text!r}" for m, line, text in library_messages() if FLAG.search(text)]
    assert not flagged, "\n".join(flagged)


def test_the_flag_check_catches_a_flag():
    assert FLAG.search("--fix names a parameter twice")
    assert FLAG.search("measure fewer (--holdout)")
    assert not FLAG.search("fix names a parameter twice")
    assert not FLAG.search("x1..z3 -- and more")
    assert sum(1 for _ in library_messages()) > 100  # the walk sees the raise sites


def test_the_command_line_says_the_flag_where_the_library_says_the_keyword(tmp_path, capsys):
    """A base frame moved by a joint cannot take --world-link: calibrated_urdf's check names
    ``world_link`` (a keyword), ``calib calibrate`` names its flag; no file is written."""
    from calib.cli.commands import main
    from calib.exceptions import CalibError
    from calib.kinematics.robot import load_chain
    from calib.kinematics.urdf_export import check_base_fixed

    with pytest.raises(CalibError, match=r"^world_link: the base frame 'shoulder_link'"):
        check_base_fixed(load_chain("ur5", base="shoulder_link"))
    data, out = tmp_path / "m.csv", tmp_path / "c.urdf"
    chain = ["ur5", "--base", "shoulder_link"]
    assert main(["simulate", *chain, "--configs", "30", "--out", str(data)]) == 0
    capsys.readouterr()
    code = main(["calibrate", *chain, "--data", str(data), "--out", str(out), "--world-link", "w"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert err.startswith("calib: error: --world-link: the base frame 'shoulder_link' is moved")
    assert not out.exists()


INTRINSICS = (
    "image_width: 640\nimage_height: 480\n"
    "camera_matrix: [[{f}, 0.0, 319.5], [0.0, {f}, 239.5], [0.0, 0.0, 1.0]]\n"
    "distortion_coefficients: [-0.1, 0.05, 0.0, 0.0, 0.0]\n"
)


def test_calibrate_names_the_flags_of_the_refusals_ways_out(tmp_path, capsys):
    """The refusals of data no calibration explains name their way out by keyword (the
    data's position_only(), Unknowns(intrinsics=True)); ``calib calibrate`` printed those
    Python names: it says --measure position and --refine-intrinsics. The UR10's
    roll-pitch-yaw read as rotation vectors; pixels read with half the focal lengths."""
    from calib.cli.commands import main

    ur10 = Path(__file__).resolve().parents[1] / "data" / "realdata" / "ur10"
    chain = [str(ur10 / "ur10_robot.urdf"), "--base", "universe", "--tool", "wrist_3_link"]
    phi = ["--orientation", "rotvec", "--orientation-columns", "phix1", "phiy1", "phiz1"]
    out = tmp_path / "c.urdf"
    data = ["--data", str(ur10 / "calibration.csv"), "--out", str(out)]
    assert main(["calibrate", *chain, *data, *phi]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "orientations do not match" in err
    assert err.endswith("fit the positions alone (--measure position)\n")
    rows = [
        f"p{i}{j},{0.03 * i - 0.045:.3f},{0.03 * j - 0.03:.3f},0.02"
        for i in range(4)
        for j in range(3)
    ]
    (tmp_path / "target.csv").write_text("point,x,y,z\n" + "\n".join(rows) + "\n")
    for name, f in (("intr.yaml", 600.0), ("half.yaml", 300.0)):
        (tmp_path / name).write_text(INTRINSICS.format(f=f))
    cam = ["--camera", "cam", "world", str(tmp_path / "intr.yaml")]
    pixels = ["--measure", "pixels", "--target", str(tmp_path / "target.csv"), "--tool", "tool0"]
    obs = str(tmp_path / "obs.csv")
    place = ["1.6", "0.3", "0.8", "-1.8688", "0", "1.7561"]
    argv = [
        "simulate",
        "ur5",
        *pixels,
        *cam,
        *place,
        "--out",
        obs,
        "--configs",
        "100",
        "--seed",
        "1",
    ]
    assert main([*argv, "--noise-px", "0.5"]) == 0
    cam[-1] = str(tmp_path / "half.yaml")
    capsys.readouterr()
    assert main(["calibrate", "ur5", *pixels, *cam, "--data", obs, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the pixels do not match camera cam" in err
    assert "or fit them: --refine-intrinsics)" in err and "Unknowns" not in err
    assert not out.exists()


def test_a_library_error_names_the_keyword(tmp_path):
    """calibrate(holdout=...) that holds out no row says ``holdout``, not ``--holdout``."""
    from calib import calibrate, load_chain, simulate
    from calib.exceptions import InvalidArgumentError

    chain = load_chain("ur5")
    data = simulate(chain, 20, seed=3, measure="pose").measurements
    with pytest.raises(InvalidArgumentError, match=r"^holdout 0.01 of 20 rows holds out no row"):
        calibrate(chain, data, holdout=0.01)


def test_the_callable_design_package_shows_its_function_and_modules():
    """``calib.design`` is a callable package: a notebook's signature help said ``(*args,
    **kwargs)``, and ``calib.design.design.evaluate`` or ``calib.design.constraints`` (named by
    the design page) raised AttributeError after ``import calib``, in a fresh interpreter."""
    code = (
        "import inspect, calib\n"
        "print(inspect.signature(calib.design))\n"
        "print(calib.design.design.evaluate.__name__, calib.design.constraints.Constraints())\n"
        "print('constraints' in dir(calib.design), hasattr(calib.design, 'nope'))\n"
    )
    root = PACKAGE.parent
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root)
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].startswith("(chain: 'Chain | Tree | str | Path', configs: 'int', *, "), lines
    assert lines[1].startswith("evaluate Constraints(margin=0.0"), lines
    assert lines[2] == "True False", lines


def test_the_design_package_lists_its_modules_only():
    """``dir(calib.design)`` (tab completion) listed ``importlib``, ``sys`` and ``types``, its
    own imports, beside its modules; ``calib.design.sys`` resolved."""
    from calib import design

    modules = sorted(p.stem for p in (PACKAGE / "design").glob("*.py") if p.stem != "__init__")
    assert [n for n in dir(design) if not n.startswith("_")] == modules
    assert not [n for n in vars(design) if not n.startswith("_") and n not in modules]
    with pytest.raises(AttributeError, match="has no attribute 'sys'"):
        design.sys  # noqa: B018


PUBLIC = {
    "loading": {"load_robot", "load_chain", "catalog", "Chain", "Tree"},
    "models and analysis": {"from_chain", "from_tree", "analyze", "Measurement", "RankWarning"},
    "data": {
        "read_measurements",
        "Columns",
        "write_measurements",
        "simulate",
        "Measurements",
        "read_contacts",
        "simulate_contacts",
        "ContactData",
        "DataWarning",
    },
    "cameras": {
        "read_intrinsics",
        "read_target",
        "read_observations",
        "simulate_pixels",
        "PixelCamera",
        "PixelData",
    },
    "calibration": {"Problem", "Term", "calibrate", "cross_validate", "Result", "load_calibrated"},
    "design": {"design"},
    "errors": {"CalibError", "InvalidArgumentError", "DataError", "CalibrationRefusedError"},
}

# Left the top level in session 51 (issue 28 item 6), with the module they live in: the ten
# that left ``__all__`` (46 -> 36 names), documented at their path by the API page's blocks.
LEFT_ALL = {
    "AmbiguousFrameError": "calib.exceptions",
    "ChainError": "calib.exceptions",
    "ConvergenceError": "calib.exceptions",
    "FrameNotFoundError": "calib.exceptions",
    "OutputError": "calib.exceptions",
    "RobotNotFoundError": "calib.exceptions",
    "URDFError": "calib.exceptions",
    "UnsupportedJointError": "calib.exceptions",
    "Identifiability": "calib.identification.identifiability",
    "MDHModel": "calib.kinematics.mdh",
}
# ... and the names calib resolved silently outside ``__all__`` before (``_LAZY``, an eager
# import): the names it had before its public face, a camera's pieces, the types the public
# calls return. Written out here: the module whose ``__all__`` lists each.
SILENT = {
    "ProblemAnalysis": "calib.calibration.analysis",
    "ResidualStats": "calib.calibration",
    "residual_stats": "calib.calibration",
    "calibrate_contact_chains": "calib.calibration.engine",
    "ContactChainsCalibration": "calib.calibration.engine_result",
    "calibrate_tree": "calib.calibration.entry",
    "hand_eye": "calib.calibration.hand_eye",
    "Unknowns": "calib.calibration.pixel_chain",
    "analyze_model": "calib.identification.identifiability",
    "complete_jacobian": "calib.identification.jacobian",
    "identification_jacobian": "calib.identification.jacobian",
    "Kind": "calib.identification.parameters",
    "Parameter": "calib.identification.parameters",
    "ParameterSet": "calib.identification.parameters",
    "complete_parameters": "calib.identification.parameters",
    "paper_parameters": "calib.identification.parameters",
    "Pinhole": "calib.identification.pinhole",
    "tree_complete_jacobian": "calib.identification.tree_jacobian",
    "tree_jacobian": "calib.identification.tree_jacobian",
    "tree_parameters": "calib.identification.tree_jacobian",
    "CatalogEntry": "calib.kinematics.catalog",
    "ElasticModel": "calib.kinematics.elastic",
    "PARALLEL_TOL": "calib.kinematics.mdh",
    "from_lines": "calib.kinematics.mdh",
    "load_tree": "calib.kinematics.tree",
    "calibrated_tree_urdf": "calib.kinematics.tree_export",
    "write_calibrated_tree_urdf": "calib.kinematics.tree_export",
    "TreeMDH": "calib.kinematics.tree_model",
    "calibrated_urdf": "calib.kinematics.urdf_export",
    "measurement_to_base": "calib.kinematics.urdf_export",
    "write_calibrated_urdf": "calib.kinematics.urdf_export",
    "Intrinsics": "calib.measurements.intrinsics",
    "PixelObservations": "calib.measurements.pixels",
    "Target": "calib.measurements.pixels",
    "Campaign": "calib.measurements.simulation",
    "SimulationTruth": "calib.measurements.simulation",
    "TreeCampaign": "calib.measurements.tree_campaign",
    "simulate_tree": "calib.measurements.tree_campaign",
}
MOVED = {**LEFT_ALL, **SILENT}
# The moved names that are another name of a public one: what to call instead.
ALIASES = {"calibrate_tree": "calibrate"}
API_PAGE = PACKAGE.parent / "docs" / "reference" / "api.md"
ERRORS_PAGE = PACKAGE.parent / "docs" / "reference" / "errors.md"


def test_the_public_face_is_36_names_in_seven_groups():
    """Issue 28 item 6 asks for about 35 names, discoverable (``dir``, tab completion): the top
    level keeps what a user calls or catches in ordinary use, grouped as the issue and
    docs/reference/python.md list them. It had 46, 14 of them error and warning classes: a
    script catches ``CalibError`` (the base of all) or the three it tells apart (bad
    arguments, a bad file, a refused model); the rest of calib.exceptions, and the types of
    what ``from_chain`` and ``analyze`` return (``MDHModel``, ``Identifiability``, which no
    script builds), are public one level down."""
    groups = list(PUBLIC.values())
    assert sum(len(g) for g in groups) == len(set().union(*groups)) == 36  # no name twice
    assert sorted(calib.__all__) == sorted(set().union(*groups))
    assert sorted(dir(calib)) == sorted([*calib.__all__, "__version__"])
    classes = {n: getattr(calib, n) for n in calib.__all__ if isinstance(getattr(calib, n), type)}
    raised = {n for n, c in classes.items() if issubclass(c, BaseException)}
    assert raised == PUBLIC["errors"] | {"DataWarning", "RankWarning"}
    assert all(issubclass(classes[n], calib.CalibError) for n in PUBLIC["errors"])
    assert not set(MOVED) & set(calib.__all__)


# One user script per moved name, run one after the other in a fresh interpreter (one
# interpreter for all: a subprocess each took a second).
USE = """
import importlib, warnings, calib
listed = {name!r} in dir(calib) or {name!r} in calib.__all__
with warnings.catch_warnings(record=True) as seen:
    warnings.simplefilter('always')
    first = calib.{name}
    again = calib.{name}
    from calib import {name}
same = first is again is {name} is getattr(importlib.import_module({path!r}), {name!r})
print(listed or {name!r} in dir(calib), same, len(seen))
print(seen[0].category.__name__, seen[0].filename, seen[0].lineno)
print(seen[0].message)
"""


def fresh(code: str) -> str:
    """What ``code`` prints, run by this tree's calib in a fresh interpreter."""
    root = PACKAGE.parent
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.fixture(scope="module")
def moved_uses() -> dict[str, list[str]]:
    """Each moved name's three printed lines, from its own script (``<NAME>``, line 6)."""
    code = (
        f"for name, path in {MOVED!r}.items():\n"
        f"    text = {USE!r}.format(name=name, path=path)\n"
        "    try:\n"
        "        exec(compile(text, f'<{name}>', 'exec'), {})\n"
        "    except Exception as error:  # this name's test fails, not every name's\n"
        "        print('failed:', repr(error))\n"
        "    print('--', flush=True)\n"
    )
    out = fresh(code)
    printed = [part.strip().splitlines() for part in out.split("--\n")[:-1]]
    assert len(printed) == len(MOVED), out
    return dict(zip(MOVED, printed, strict=True))


@pytest.mark.parametrize("name", sorted(MOVED))
def test_a_name_that_left_the_top_level_still_reads_and_warns_once(name, moved_uses):
    """``calib.URDFError`` (and ``from calib import URDFError``) is still the class, until
    calib 0.2, with one DeprecationWarning at the user's line naming its new path; it is in
    neither ``__all__`` nor ``dir(calib)``, before or after. The first use warns, the name is
    then a plain attribute. So do the names calib resolved silently outside ``__all__``
    (``calib.tree_jacobian``, ``calib.Pinhole``, ...): public at their module's path, listed
    in its ``__all__``. An alias of a public name (``calib.calibrate_tree``) names that name,
    not the alias at its module's path."""
    path = MOVED[name]
    lines = moved_uses[name]
    assert lines[0] == "False True 1", lines
    assert lines[1] == f"DeprecationWarning <{name}> 6", lines
    assert name in importlib.import_module(path).__all__
    if name in ALIASES:
        new = f"calib.{ALIASES[name]}"
        assert lines[2].startswith(f"calib.{name} is {new}: use {new} "), lines
        assert getattr(importlib.import_module(path), name) is getattr(calib, ALIASES[name])
    else:
        assert lines[2].startswith(f"calib.{name} is {path}.{name}: import it from there"), lines
    assert lines[2].endswith(f"(calib.{name} goes in calib 0.2)"), lines


def test_calib_resolves_its_public_face_its_modules_and_the_moved_names_only():
    """``calib.X`` is a name of ``__all__``, a subpackage (the module paths), a moved name
    (warned), or an AttributeError: calib resolved 38 names outside ``__all__`` silently
    (``calibrate_tree``, ``Pinhole``, ``CatalogEntry``, ...), and its own helpers (``sys``,
    ``types``, ``attributes``, ``moved``, ``TYPE_CHECKING``). In a fresh interpreter, after
    every public name is used."""
    code = (
        "import types, calib\n"
        "for name in calib.__all__:\n"
        "    getattr(calib, name)\n"
        "names = [n for n in vars(calib) if not n.startswith('_')]\n"
        "print(sorted(n for n in names if not isinstance(getattr(calib, n), types.ModuleType)))\n"
        "print(sorted(n for n in names if isinstance(getattr(calib, n), types.ModuleType)))\n"
    )
    plain, modules = fresh(code).splitlines()
    assert plain == str(sorted(set(calib.__all__) - {"design"})), plain
    packages = {p.name for p in PACKAGE.iterdir() if (p / "__init__.py").exists()}
    assert set(ast.literal_eval(modules)) <= packages | {"exceptions", "design"}, modules
    for name in MOVED:
        assert name not in calib.__all__ and not name.startswith("_")


def moved_uses_in(source: str) -> list[tuple[int, str]]:
    """(line, name) of each ``calib.NAME`` and ``from calib import NAME`` of a moved name."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
            if node.value.id == "calib" and node.attr in MOVED:
                found.append((node.lineno, node.attr))
        elif isinstance(node, ast.ImportFrom) and node.module == "calib" and not node.level:
            found += [(node.lineno, a.name) for a in node.names if a.name in MOVED]
    return sorted(found)


def python_sources():
    """(where, source) of the repository's Python: calib/, tests/, benchmarks/, docs/ scripts,
    and the README's and the docs pages' ``python`` blocks (what tests/test_docs_snippets.py
    runs, and the blocks marked not run)."""
    root = PACKAGE.parent
    for folder in ("calib", "tests", "benchmarks", "docs"):
        for path in sorted((root / folder).rglob("*.py")):
            if "_build" not in path.parts:
                yield str(path.relative_to(root)), path.read_text(encoding="utf-8")
    pages = [root / "README.md", *sorted((root / "docs").rglob("*.md"))]
    fence = re.compile(r"^```python\n(.*?)^```$", re.MULTILINE | re.DOTALL)
    for page in pages:
        if "_build" in page.parts:
            continue
        text = page.read_text(encoding="utf-8")
        for block in fence.finditer(text):
            line = text.count("\n", 0, block.start()) + 1
            yield f"{page.relative_to(root)}:{line}", block.group(1)


def test_the_repository_uses_no_moved_name():
    """calib's own code, tests, benchmarks and the docs' examples reach each moved name at its
    module's path (``calib.tree_jacobian`` was in python.md's examples, ``calib.simulate_tree``
    in 14 test files): none warns for calib's own use. pyproject.toml's ``filterwarnings``
    turns the warning into an error in the suite, for what this reading cannot see."""
    sources = list(python_sources())
    assert len(sources) > 300
    uses = [
        f"{where}:{line} {name}" for where, text in sources for line, name in moved_uses_in(text)
    ]
    assert not uses, "\n".join(uses)
    assert moved_uses_in(
        "import calib\ncalib.tree_jacobian(m)\nfrom calib import Pinhole, Term\n"
    ) == [
        (2, "tree_jacobian"),
        (3, "Pinhole"),
    ]


def test_the_suite_turns_a_moved_name_into_an_error():
    """The filter pyproject.toml gives pytest matches the moved names' warning."""
    import tomllib
    import warnings

    config = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8"))
    filters = config["tool"]["pytest"]["ini_options"]["filterwarnings"]
    (ours,) = [f for f in filters if f.startswith("error:calib")]
    action, message, category = ours.split(":")
    assert category == "DeprecationWarning"
    try:
        with warnings.catch_warnings(), pytest.raises(DeprecationWarning, match=r"calib\.Kind is"):
            warnings.filterwarnings(action, message, DeprecationWarning)
            calib._moved("Kind")
    finally:
        vars(calib).pop("Kind", None)  # as before: the next use warns


def test_an_unknown_name_is_still_an_attribute_error():
    with pytest.raises(AttributeError, match="module 'calib' has no attribute 'URDFErrors'"):
        calib.URDFErrors  # noqa: B018


def test_the_api_page_documents_each_name_at_its_path():
    """docs/reference/api.md (Sphinx autodoc) names each public name as ``calib.NAME``, each
    moved one at its module's path (an alias, ``calib.calibrate_tree``: the name to call),
    and every error class of calib.exceptions; errors.md's
    table gives each one's import. The page had left out ``Columns`` and ``cross_validate``,
    and documented ``calib.ProblemAnalysis``, a silent name."""
    page = API_PAGE.read_text(encoding="utf-8")
    blocks = re.findall(r"^\.\. auto(?:function|class):: (calib\.[\w.]+)$", page, re.M)
    documented = set(blocks)
    assert len(blocks) == len(documented) > 40
    public = {f"calib.{n}" for n in calib.__all__} - {"calib.design"}
    assert public <= documented, public - documented
    assert "calib.design.design.design" in documented
    for name, path in LEFT_ALL.items():
        assert f"{path}.{name}" in documented and f"calib.{name}" not in documented, name
    listed = set(re.findall(r"`(calib\.[\w.]+)`", page)) | documented
    for name, path in SILENT.items():  # at their path (an alias: its name), listed or a block
        want = f"calib.{ALIASES[name]}" if name in ALIASES else f"{path}.{name}"
        assert want in listed and f"calib.{name}" not in documented, name
    from calib import exceptions

    errors = [
        n for n in exceptions.__all__ if isinstance(getattr(exceptions, n), type)
    ]  # warn_user is a function
    table = ERRORS_PAGE.read_text(encoding="utf-8").split("## The error classes in Python")[1]
    for name in errors:
        where = "calib" if name in calib.__all__ else "calib.exceptions"
        assert f"{where}.{name}" in documented, name
        assert f"`from {where} import {name}`" in table, name
    assert len(errors) == 13
