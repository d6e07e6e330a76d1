"""What `pip install .` builds is the whole package: every module of calib/ and of models/.

An editable install imports from the tree and hides a subpackage that the wheel leaves out, so
this builds the real wheel (no network: the build runs in this environment) and reads its
file list. `.ci/run` also installs that wheel in a clean venv and runs the CLI from it.
"""

from __future__ import annotations

import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wheel_files(tmp_path_factory) -> set[str]:
    out = tmp_path_factory.mktemp("wheel")
    build = tmp_path_factory.mktemp("build")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--quiet",
            "--no-deps",
            "--no-build-isolation",
            "--disable-pip-version-check",
            "-w",
            str(out),
            str(ROOT),
        ],
        check=True,
        capture_output=True,
        cwd=build,
    )
    (whl,) = out.glob("calib-*.whl")
    return set(zipfile.ZipFile(whl).namelist())


def test_wheel_holds_every_module_of_calib(wheel_files):
    want = {p.relative_to(ROOT).as_posix() for p in (ROOT / "calib").rglob("*.py")}
    assert len(want) > 30  # the walk found the package, not an empty folder
    missing = sorted(want - wheel_files)
    assert not missing, f"the wheel leaves out {missing}"
    assert "calib/py.typed" in wheel_files


def test_wheel_holds_the_models_as_calib_models(wheel_files):
    want = {f"calib/models/{p.name}" for p in (ROOT / "models").iterdir() if p.is_file()}
    assert "calib/models/catalog.toml" in want
    assert not sorted(want - wheel_files)


def test_wheel_ships_no_tests_or_data(wheel_files):
    assert not [n for n in wheel_files if n.startswith(("tests/", "data/", "notebooks/"))]
