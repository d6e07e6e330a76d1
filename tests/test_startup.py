"""What a ``calib`` process imports: each command only the modules it needs (issue 22).

Structural checks, not timings: the installed ``calib`` script runs as a subprocess with
``PYTHONPROFILEIMPORTTIME=1``, and the interpreter itself lists every module it imported.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

CALIB = Path(sys.executable).parent / "calib"

_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "CALIB_THREADS")


def _clean_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in _THREAD_VARS}


def imported_by(*argv: str) -> tuple[set[str], str]:
    """The modules a whole ``calib`` process imported (as Python reports them), its stdout."""
    env = {**_clean_env(), "PYTHONPROFILEIMPORTTIME": "1"}
    proc = subprocess.run(
        [str(CALIB), *argv], capture_output=True, text=True, env=env, timeout=120, check=False
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    modules = {
        line.rsplit("|", 1)[1].strip()
        for line in proc.stderr.splitlines()
        if line.startswith("import time:") and line.count("|") == 2
    }
    assert "calib.cli.launcher" in modules  # the report is there and lists calib's own modules
    return modules, proc.stdout


NOT_FOR_ANALYZE = (
    "scipy",  # the QR factorisations load SciPy's LAPACK extension alone (calib.identification.qr)
    "matplotlib",
    "tqdm",
    "threadpoolctl",  # the launcher sets the one BLAS thread before numpy loads
    "importlib.metadata",  # example-robot-data's RECORD is read directly
    "importlib.resources",  # the models folder is found beside the package
    "calib.design.design",
    "calib.design.observability",
    "calib.design.exchange",
    "calib.design.constraints",
    "calib.design.configurations",
    "calib.measurements.csvfile",
    "calib.calibration.engine",
    "calib.calibration.solve",
    "calib.kinematics.elastic",
    "calib.outputs.sweep",
    "calib.outputs.plots",
)


def test_analyze_imports_neither_scipy_nor_the_other_commands():
    modules, out = imported_by("analyze", "ur5")
    assert "ur5" in out and "identifiable" in out.lower()
    identification = {"calib.identification.identifiability", "calib.identification.qr"}
    assert {"numpy", "pinocchio"} | identification <= modules
    loaded = sorted(
        m for m in modules if any(m == n or m.startswith(n + ".") for n in NOT_FOR_ANALYZE)
    )
    assert loaded == []


def test_version_reads_no_catalog():
    modules, out = imported_by("--version")
    assert out.startswith("calib ")
    assert not {"tomllib", "json", "numpy", "difflib"} & modules


def test_list_imports_no_numpy():
    modules, out = imported_by("list")
    assert "ur5" in out
    assert "tomllib" in modules
    assert not {"numpy", "pinocchio", "scipy", "importlib.metadata"} & modules


def test_the_robots_folder_is_the_one_importlib_metadata_finds():
    """The direct read of example-robot-data's RECORD against importlib.metadata's files."""
    import importlib.metadata

    from calib.kinematics.catalog import _erd_robots_from_record

    marker = "share/example-robot-data/robots/"
    dist = importlib.metadata.distribution("example-robot-data")
    first = next(f.as_posix() for f in dist.files if marker in f.as_posix())
    expected = Path(str(dist.locate_file(first[: first.find(marker) + len(marker)])))
    found = _erd_robots_from_record()
    assert found is not None
    assert found.resolve() == expected.resolve()
    assert (found / "ur_description").is_dir()


BLAS_SCRIPT = textwrap.dedent(
    """
    import json, sys
    from calib.cli.launcher import main
    sys.argv = ["calib", *sys.argv[1:]]
    code = main()
    tpc = "threadpoolctl" in sys.modules
    from threadpoolctl import threadpool_info
    blas = sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})
    print(json.dumps({"code": code, "threadpoolctl": tpc, "blas": blas}), file=sys.stderr)
    """
)


@pytest.mark.parametrize(("env", "threadpoolctl"), [({}, False), ({"CALIB_THREADS": "2"}, True)])
def test_the_command_runs_blas_on_one_thread_without_threadpoolctl(env, threadpoolctl):
    """As the command, the launcher sets one BLAS thread before numpy loads (still one after
    the command); ``CALIB_THREADS`` still goes through threadpoolctl."""
    proc = subprocess.run(
        [sys.executable, "-c", BLAS_SCRIPT, "analyze", "aid", "--configs", "20"],
        capture_output=True,
        text=True,
        env={**_clean_env(), **env},
        timeout=120,
        check=False,
    )
    seen = json.loads(proc.stderr.splitlines()[-1])
    assert seen["code"] == 0
    assert seen["threadpoolctl"] is threadpoolctl
    if not env:
        assert seen["blas"] == [1]


def test_the_models_folder_is_the_one_importlib_resources_finds():
    import importlib.resources

    from calib.kinematics.catalog import models_dir

    expected = Path(str(importlib.resources.files("calib.models")))
    assert models_dir().resolve() == expected.resolve()
    assert (models_dir() / "catalog.toml").is_file()


def test_calibrating_measured_points_imports_no_scipy_stats(tmp_path):
    """``scipy.stats`` takes about 1.5 s of CPU to import (it parses its docstrings): a
    measured chain's errors are 3-vectors, whose outlier factor needs no chi distribution
    (a contact's or a camera's may). ``calib calibrate ur5`` took 2 to 2.7 s, 975 ms before
    the outlier module imported it."""
    import warnings

    import calib

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        campaign = calib.simulate("ur5", 30, "position", marker=(0.01, 0.02, 0.05), seed=1)
    data = tmp_path / "m.csv"
    calib.write_measurements(data, campaign.measurements)
    out = str(tmp_path / "c.urdf")
    modules, text = imported_by("calibrate", "ur5", "--data", str(data), "--out", out)
    assert "accepted" in text
    assert "scipy.optimize" in modules and "calib.calibration.outliers" in modules
    assert "scipy.stats" not in modules
