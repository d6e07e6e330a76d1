"""What a calibration can identify: the free parameters of the model at generic configurations.

The measurement frame (6), the markers (3 each; and the measured frame's rotation, 3, for
pose data) always come first; then the base parameters of the complete set that they do
not already carry, in the paper's order of preference.
"""

from __future__ import annotations

import numpy as np

from ..identifiability import DEFAULT_CONFIGS, independent_columns, preference_order
from ..mdh import from_chain
from ..measurements import Measurements
from ..parameters import complete_parameters
from ..robot import Chain, check_count
from .model import ErrorModel, registration_state, selection_lift
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
    nominal = from_chain(chain).idealized()
    q = chain.random_configurations(configs, seed)
    markers = 0.1 * np.random.default_rng([seed, 4]).uniform(-1.0, 1.0, (k, 3))
    pose = measure == "pose"
    state = registration_state(nominal, np.eye(4), markers, np.eye(3) if pose else None)
    pts, _ = state.predict(q)
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(q), 1)) if pose else None
    data = Measurements(chain.joint_names, q, pts.reshape(len(q), -1), quat)
    pset = complete_parameters(nominal)
    names = tuple(np.array(pset.names)[preference_order(nominal, pset)])
    model = ErrorModel(pset, names, selection_lift(pset, names), (), n_markers=k, pose=pose)
    J = model.jacobian(state, np.zeros(model.size()), data, None)
    J = J * row_weights(model, 1.0)[None, :, None]
    _, _, kept, _ = independent_columns(J.reshape(-1, J.shape[2]), list(range(J.shape[2])))
    all_names = model.names()
    return tuple(all_names[i] for i in sorted(kept))


__all__ = ["identifiable_parameters"]
