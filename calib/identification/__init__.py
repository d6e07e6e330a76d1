"""What a campaign can identify: parameter sets, identification Jacobians, QR, identifiability.

:mod:`.parameters` names the geometric parameters, :mod:`.jacobian` and :mod:`.tree_jacobian`
build the analytic identification Jacobians, :mod:`.qr` and :mod:`.base_columns` find the base
columns (rank, order of preference, regrouping), :mod:`.theory` the theoretical counts,
:mod:`.identifiability` the analysis of a chain or tree (:mod:`.rank_notes` its rank's warnings
and its set's gaps in words), :mod:`.report` and :mod:`.table` print them.

May import: :mod:`calib.kinematics` and the bottom modules.
"""

__all__: list[str] = []
