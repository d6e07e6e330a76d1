"""Names a package imports only when first used (PEP 562), to keep start-up short."""

from __future__ import annotations

import importlib
import sys
import warnings
from collections.abc import Callable, Mapping

__all__ = ["attributes", "moved"]


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


def moved(
    package: str,
    table: Mapping[str, str],
    until: str,
    aliases: Mapping[str, str] | None = None,
) -> Callable[[str], object]:
    """A module ``__getattr__`` for names that left ``package``'s top level.

    ``package.<name>`` still gives ``package.<table[name]>.<name>``, with a
    ``DeprecationWarning`` naming that path, once: the name is then a plain attribute (kept
    out of ``__all__`` and ``dir()``). An alias of a public name names that name instead
    (``calib.calibrate_tree is calib.calibrate: use calib.calibrate``).

    Args:
        package: The package's ``__name__``.
        table: Attribute name -> submodule (relative to the package) where it now lives.
        until: The version of ``package`` that removes the old names (``"0.2"``).
        aliases: Attribute name -> the public name of ``package`` it is another name of.
    """
    aliases = aliases or {}

    def lookup(name: str) -> object:
        path = f"{package}.{table[name]}"
        value = getattr(importlib.import_module(path), name)
        if name in aliases:
            new = f"{package}.{aliases[name]}"
            use = f"{new}: use {new}"
        else:
            use = f"{path}.{name}: import it from there"
        warnings.warn(
            f"{package}.{name} is {use} ({package}.{name} goes in {package} {until})",
            DeprecationWarning,
            stacklevel=3,  # the caller of the package's __getattr__: the user's line
        )
        setattr(sys.modules[package], name, value)  # warned once: the next use is plain
        return value

    return lookup
