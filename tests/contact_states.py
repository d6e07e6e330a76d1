"""A contact state built from a plane's normal and height, for the tests of the joint engine."""

from __future__ import annotations

import numpy as np

from calib.calibration.contact_model import ContactFrames, ContactState, plane_frame
from calib.identification.contacts import PlaneContact
from calib.kinematics.mdh import MDHModel


def plane_state(
    mdh: MDHModel,
    contact: np.ndarray,
    normal: np.ndarray,
    height: float,
    weight: float,
    plane_id: str = "table",
) -> ContactState:
    """A state of one plane (``plane`` kind) from its unit normal and height [m]."""
    plane = plane_frame(normal, height, np.zeros(3))[None]
    return ContactState(mdh, ContactFrames(PlaneContact(), contact, plane, (plane_id,)), weight)
