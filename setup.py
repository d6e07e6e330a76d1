"""Package discovery: calib/ and its subpackages, models/ as calib.models, the entry point.

The entry point _calib_entry is a top-level module (see its docstring).

Everything else is in pyproject.toml. A package list written by hand once left a subpackage
out of the wheel; found packages cannot drift.
"""

from setuptools import find_packages, setup

setup(
    packages=[*find_packages(include=["calib", "calib.*"]), "calib.models"],
    py_modules=["_calib_entry"],  # the command's entry point, importable before calib
)
