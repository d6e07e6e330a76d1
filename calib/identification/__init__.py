"""What a campaign can identify: parameter sets, identification Jacobians, QR, identifiability.

:mod:`.parameters` names the geometric parameters, :mod:`.jacobian` and :mod:`.tree_jacobian`
build the analytic identification Jacobians, :mod:`.qr` and :mod:`.identifiability` find the
base parameters, :mod:`.report` and :mod:`.table` print them.

May import: :mod:`calib.kinematics` and the bottom modules.
"""

__all__: list[str] = []
