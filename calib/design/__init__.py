"""Experiment design: which configurations to measure.

:mod:`.observability` scores a set of configurations, :mod:`.exchange` improves it,
:mod:`.design` drives both under the reachability and collision constraints of
:mod:`.constraints` and :mod:`.collision`; :mod:`.configurations` reads and writes them.

The package is callable: ``calib.design(chain, 30, ...)`` is
:func:`calib.design.design.design`, and ``calib.design.observability`` stays this package's
module (a function named ``calib.design`` would hide the package from
``import calib.design.observability as o``).

May import: :mod:`calib.calibration`, :mod:`calib.measurements`, :mod:`calib.identification`,
:mod:`calib.kinematics` and the bottom modules.
"""

import sys
import types

__all__: list[str] = []


class _Design(types.ModuleType):
    """This package, callable as its design function."""

    def __call__(self, *args, **kwargs):
        """:func:`calib.design.design.design` (its arguments and result)."""
        from .design import design

        return design(*args, **kwargs)


sys.modules[__name__].__class__ = _Design
