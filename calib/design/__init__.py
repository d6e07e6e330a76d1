"""Experiment design: which configurations to measure.

:mod:`.observability` scores a set of configurations, :mod:`.exchange` improves it (on
:mod:`.blocks`, many small matrices at once), :mod:`.design` drives both under the
reachability and collision constraints of :mod:`.constraints` and :mod:`.collision`;
:mod:`.configurations` reads and writes them.
:mod:`.folds` scores a campaign's calibration by K-fold cross-validation (K + 1 fits).

The package is callable: ``calib.design(chain, 30, ...)`` is
:func:`calib.design.design.design` (its signature; ``help(calib.design.design.design)``
gives every argument), and ``calib.design.observability`` stays this package's
module (a function named ``calib.design`` would hide the package from
``import calib.design.observability as o``).

May import: :mod:`calib.calibration`, :mod:`calib.measurements`, :mod:`calib.identification`,
:mod:`calib.kinematics` and the bottom modules.
"""

import importlib as _importlib  # private: dir(calib.design) is its modules
import sys as _sys
import types as _types

__all__: list[str] = []

_MODULES = (
    "blocks",
    "collision",
    "configurations",
    "constraints",
    "contact_design",
    "design",
    "exchange",
    "folds",
    "observability",
    "tree_error_model",
)
"""The package's modules: attributes of ``calib.design`` once used (imported then)."""


class _Design(_types.ModuleType):
    """This package, callable as its design function."""

    def __call__(self, *args, **kwargs):
        """:func:`calib.design.design.design` (its arguments and result)."""
        return self.design.design(*args, **kwargs)

    def __getattr__(self, name: str) -> _types.ModuleType:
        """A module of the package, imported when first used (``calib.design.constraints``)."""
        if name not in _MODULES:
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        return _importlib.import_module(f".{name}", __name__)

    def __dir__(self) -> list[str]:
        """The package's names and modules (tab completion)."""
        return sorted({*super().__dir__(), *_MODULES})

    @property
    def __signature__(self):
        """The design function's signature (``help``, ``inspect.signature``, a notebook's)."""
        import inspect

        return inspect.signature(self.design.design)


_sys.modules[__name__].__class__ = _Design
