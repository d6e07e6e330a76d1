"""Experiment design: which configurations to measure.

:mod:`.observability` scores a set of configurations, :mod:`.exchange` improves it,
:mod:`.design` drives both under the reachability and collision constraints of
:mod:`.constraints` and :mod:`.collision`; :mod:`.configurations` reads and writes them.

May import: :mod:`calib.calibration`, :mod:`calib.measurements`, :mod:`calib.identification`,
:mod:`calib.kinematics` and the bottom modules.
"""

__all__: list[str] = []
