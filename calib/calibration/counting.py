"""What a calibration can identify: the free parameters of the model at generic configurations.

The measurement frame (6), the markers (3 each; and the measured frame's rotation, 3, for
pose data) always come first; then the base parameters of the complete set that they do
not already carry, in the paper's order of preference.
"""

from __future__ import annotations

import numpy as np

from ..core.checks import MAX_WORK_BYTES
from ..core.choices import DEFAULT_CONFIGS
from ..exceptions import InvalidArgumentError
from ..identification.base_columns import independent_columns, preference_order
from ..identification.kinds import campaign_kind
from ..identification.measures import Measurement
from ..identification.parameters import complete_parameters
from ..kinematics.mdh import from_chain
from ..kinematics.robot import Chain, check_count
from .model import ErrorModel, generic_measurements, nominal_state, selection_lift
from .solve import row_weights


def identifiable_parameters(
    chain: Chain,
    n_markers: int = 1,
    measure: str = "position",
    configs: int = DEFAULT_CONFIGS,
    seed: int = 0,
) -> tuple[str, ...]:
    """Names of the parameters a calibration with K markers identifies (generic configurations).

    Args:
        chain: The chain.
        n_markers: Points measured per configuration K (markers at generic, distinct places).
        measure: ``position`` or ``pose`` (the orientation of the tool is measured too).
        configs: Random configurations m.
        seed: Seed of the configurations and of the marker places.

    Returns:
        Frame, marker (and tool) parameters, then the MDH base parameters.
    """
    k = check_count(n_markers, "the number of markers")
    check_count(configs, "the number of configurations")
    nominal = from_chain(chain).idealized()
    kind = campaign_kind(measure)
    check_marker_work(configs, k, len(complete_parameters(nominal)), kind)
    q = chain.random_configurations(configs, seed)
    markers = 0.1 * np.random.default_rng([seed, 4]).uniform(-1.0, 1.0, (k, 3))
    state = nominal_state(nominal, markers, kind)
    data = generic_measurements(state, chain.joint_names, q)
    pset = complete_parameters(nominal)
    names = tuple(np.array(pset.names)[preference_order(nominal, pset)])
    model = ErrorModel(pset, names, selection_lift(pset, names), n_markers=k, kind=kind)
    J = model.jacobian(state, np.zeros(model.size()), data, None)
    J = J * row_weights(model, 1.0)[None, :, None]
    _, _, kept, _ = independent_columns(J.reshape(-1, J.shape[2]), list(range(J.shape[2])))
    all_names = model.names()
    return tuple(all_names[i] for i in sorted(kept))


MARKER_WORK_COPIES = 4
"""Copies of the identification Jacobian the count holds at once (J, its weighted copy, the
QR's factors), in the estimate of :func:`check_marker_work`."""


def marker_work_bytes(m: int, k: int, n_params: int, kind: Measurement) -> int:
    """Memory [B] of counting K markers at m configurations: the Jacobian's copies.

    Rows: the kind's rows at K markers per configuration (``3 K``, + 3 for pose); columns:
    the kind's unknown constants (the frame 6, the markers ``3 K``, + 3 for pose) and the
    ``n_params`` geometric parameters.
    """
    rows = m * kind.rows_of(k)
    cols = kind.unknown_constants(k) + n_params
    return MARKER_WORK_COPIES * 8 * rows * cols


def check_marker_work(m: int, k: int, n_params: int, kind: Measurement) -> None:
    """Refuse, before any work, K markers whose count would need more than MAX_WORK_BYTES.

    Raises:
        InvalidArgumentError: Names K, the memory needed and the most markers that fit.
    """
    need = marker_work_bytes(m, k, n_params, kind)
    if need <= MAX_WORK_BYTES:
        return
    lo, hi = 0, k  # the most markers that fit: lo fits (or is 0), hi does not
    while hi - lo > 1:
        mid = (lo + hi) // 2
        lo, hi = (
            (mid, hi) if marker_work_bytes(m, mid, n_params, kind) <= MAX_WORK_BYTES else (lo, mid)
        )
    per_config = marker_work_bytes(1, k, n_params, kind)
    fit = [f"at most {lo} markers"] if lo else []
    if MAX_WORK_BYTES // per_config:
        fit.append(f"at most {MAX_WORK_BYTES // per_config} configurations (configs)")
    raise InvalidArgumentError(
        f"{k} markers at {m} configurations need about {need / 2**30:.3g} GB; calib allows "
        f"{MAX_WORK_BYTES / 2**30:g} GB: use {' or '.join(fit)}"
    )


__all__ = ["check_marker_work", "identifiable_parameters", "marker_work_bytes"]
