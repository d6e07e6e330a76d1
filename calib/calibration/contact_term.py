"""A contact term of the joint engine: what its touches need beside the engine's model.

The contact frame's guess (:func:`contact_frame`), the touches held out by object
(:func:`split_contacts`), the objects as reported (:func:`contact_objects`), the equations a
level needs and the held-out touches that are another object's (the checks).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..kinematics.so3 import rotation_matrix
from ..measurements.contact_campaign import ContactData
from ..measurements.postures import count as count_postures
from ..measurements.postures import posture_groups
from . import determined
from .contact_checks import subset
from .contact_model import ContactState
from .contact_registration import MIN_TOUCHES
from .diagnosis import suspect

__all__ = [
    "check_held_out_gaps",
    "check_level_equations",
    "contact_frame",
    "contact_objects",
    "split_contacts",
]


def check_level_equations(train, unknowns: int, level: str) -> None:
    """One chain's touches must give more equations than a level's unknowns (not ``auto``).

    Distinct touches count (a touch recorded again adds no equation); the selection of
    ``auto`` keeps what the touches support. A DataError otherwise.
    """
    if level == "auto" or len(train) != 1 or not isinstance(train[0], ContactData):
        return
    d = train[0]
    what = f"parameters of params '{level}' (with the contact's unknowns)"
    touches = count_postures(d.q, d.ids)
    determined.check_equations(touches, d.kind.n_rows, unknowns, what, d.source, unit="touches")


def contact_frame(contact) -> np.ndarray:
    """The contact frame ``(4, 4)`` in the tool frame from a 4x4, 3 or 6 numbers (m, rad).

    Six numbers are ``X Y Z RX RY RZ`` (a rotation vector); None is the tool frame.
    """
    if contact is None:
        return np.eye(4)
    try:
        C = np.asarray(contact, dtype=float)
    except (TypeError, ValueError):
        raise InvalidArgumentError("the contact frame takes X Y Z [RX RY RZ] (m, rad)") from None
    if C.shape == (4, 4):
        if not np.allclose(C[:3, :3] @ C[:3, :3].T, np.eye(3), atol=1e-9):
            raise InvalidArgumentError("the contact frame must be a rigid transform (4, 4)")
        return C.copy()
    if C.shape not in ((3,), (6,)) or not np.all(np.isfinite(C)):
        raise InvalidArgumentError("the contact frame takes X Y Z [RX RY RZ] (m, rad)")
    T = np.eye(4)
    T[:3, 3] = C[:3]
    if C.shape == (6,):
        T[:3, :3] = rotation_matrix(C[3:])
    return T


def split_contacts(
    data: ContactData, holdout: float, seed: int
) -> tuple[ContactData, ContactData | None]:
    """Training and held-out touches: ``holdout`` of each object's, seeded, >= MIN_TOUCHES kept.

    A touch recorded several times (the same posture on the same object) is held out whole.
    ``holdout`` in (0, 1) (:class:`~.options.Options` checks it).
    """
    rng = np.random.default_rng([seed, 21])
    ids = np.array(data.ids)
    groups = posture_groups(data.q, data.ids)  # a touch repeated is held out whole
    held = np.zeros(data.m, dtype=bool)
    for name in data.contacts:
        touches = np.unique(groups[ids == name])  # in order of first appearance
        out = min(round(holdout * len(touches)), len(touches) - MIN_TOUCHES)
        if out > 0:
            held[np.isin(groups, touches[rng.permutation(len(touches))[:out]])] = True
    if not held.any():
        raise DataError(data.source, f"too few touches to hold {holdout:g} of them out")
    return subset(data, ~held), subset(data, held)


def contact_objects(state: ContactState, train: ContactData, torque=None) -> dict[str, np.ndarray]:
    """The objects by id; a plane's origin at its touches' contact points, projected."""
    kin = state.kinematics(train.q, torque)
    frames = state.frames.centred(kin.R[:, -1], kin.p[:, -1], state.frames.index(train.ids))
    return {k: frames.objects[i].copy() for i, k in enumerate(frames.ids)}


def check_held_out_gaps(stats, source: str) -> None:
    """Held-out touches the registration misses absurdly while it fits the data: a DataError."""
    held, fitted = stats["held_out_registration"], stats["train_registration"]
    far, near = 1e-3 * held.length_rms_mm, 1e-3 * fitted.length_rms_mm
    if suspect(far, None) and not suspect(near, None):
        raise DataError(
            source,
            f"the held-out touches are {1e3 * far:.4g} mm RMS from the registered contact (the "
            f"data {1e3 * near:.4g} mm): touched another object, or on another robot?",
        )
