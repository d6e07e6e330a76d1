"""Every benchmark script imports: a name it takes from calib that went away fails here, not
the day someone re-measures a figure (talos_contact_*.py imported a helper removed in session
49, ``ContactData.subset`` replacing it). Their ``main`` is not run (the figures are measured
by hand, docs/developers/performance.md). The peers' own scripts (``*_peer.py``) run in the
peer's environment, not calib's: they are not imported here."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
SCRIPTS = sorted(p for p in BENCHMARKS.glob("*.py") if not p.stem.endswith("_peer"))


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.stem)
def test_the_benchmark_script_imports(path, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    spec = importlib.util.spec_from_file_location(f"_bench_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)
