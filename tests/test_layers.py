"""The wings' layers (pyproject.toml, [tool.importlinter]) are enforced: an upward import fails.

lint-imports runs on copies of the package: the copy as it is passes, and the same copy with
one import from a low wing to a higher one (kinematics -> design) is refused, naming it.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINT = Path(sys.executable).parent / "lint-imports"


def lint(tmp: Path, upward: bool) -> subprocess.CompletedProcess[str]:
    shutil.copytree(ROOT / "calib", tmp / "calib", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp / "pyproject.toml")
    if upward:
        so3 = tmp / "calib" / "kinematics" / "so3.py"
        so3.write_text(so3.read_text() + "\n\ndef _upward():\n    from ..design import design\n")
    env = {**os.environ, "PYTHONPATH": str(tmp)}
    return subprocess.run(
        [str(LINT), "--no-cache"], cwd=tmp, env=env, capture_output=True, text=True, timeout=300
    )


def test_the_package_keeps_its_layers(tmp_path):
    run = lint(tmp_path, upward=False)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "Contracts: 3 kept, 0 broken." in run.stdout


def test_an_upward_import_is_caught(tmp_path):
    run = lint(tmp_path, upward=True)
    assert run.returncode != 0
    assert "wings along the data flow BROKEN" in run.stdout
    assert "calib.kinematics.so3 -> calib.design.design" in run.stdout
    # The import also closes a circle between the wings (design already imports kinematics).
    assert "no circles between the wings BROKEN" in run.stdout
