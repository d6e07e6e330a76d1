"""Package discovery: every subpackage of calib/, and the project's models/ as calib.models.

Everything else is in pyproject.toml. A package list written by hand once left a subpackage
out of the wheel; found packages cannot drift.
"""

from setuptools import find_packages, setup

setup(packages=[*find_packages(include=["calib", "calib.*"]), "calib.models"])
