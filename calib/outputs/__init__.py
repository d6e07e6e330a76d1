"""Studies and figures over many robots: the identifiability sweep and its plots.

May import: :mod:`calib.design`, :mod:`calib.calibration`, :mod:`calib.measurements`,
:mod:`calib.identification`, :mod:`calib.kinematics` and the bottom modules.
"""

__all__: list[str] = []
