"""Names a package imports only when first used (PEP 562), to keep start-up short."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping

__all__ = ["attributes"]


def attributes(package: str, table: Mapping[str, str]) -> Callable[[str], object]:
    """A module ``__getattr__`` that imports ``package.<table[name]>`` when ``name`` is used.

    Args:
        package: The package's ``__name__``.
        table: Attribute name -> submodule (relative to the package) defining it.
    """

    def lookup(name: str) -> object:
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{table[name]}"), name)
        setattr(sys.modules[package], name, value)  # the next use is a plain attribute
        return value

    return lookup
