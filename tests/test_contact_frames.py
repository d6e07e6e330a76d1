"""ContactFrames' unknowns: the moved frames and their Jacobian against central differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib.calibration.contact_blocks import dense
from calib.calibration.contact_model import ContactFrames, row_weights
from calib.identification.contacts import (
    FixedPointContact,
    FixedPoseContact,
    PlaneContact,
    PlanePointContact,
)


def _frames(kind, seed: int) -> tuple[ContactFrames, np.ndarray, np.ndarray, np.ndarray]:
    """Frames of two objects, a contact, and six touches: tool rotations, origins, objects."""
    rng = np.random.default_rng(seed)

    def pose() -> np.ndarray:
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
        T[:3, 3] = rng.normal(size=3) * 0.3
        return T

    frames = ContactFrames(kind, pose(), np.stack([pose(), pose()]), ("a", "b"))
    Rt = Rotation.from_rotvec(rng.normal(size=(6, 3))).as_matrix()
    return frames, Rt, rng.normal(size=(6, 3)) * 0.5, np.array([0, 1, 0, 1, 1, 0])


KINDS = [PlaneContact(), PlanePointContact(), FixedPointContact(), FixedPoseContact()]


@pytest.mark.parametrize("kind", KINDS)
def test_parts_are_the_central_differences_of_the_moved_frames_gaps(kind):
    """Every kind's weighted gap rows (a fixed pose's: all six of the pose error)."""
    frames, Rt, pt, index = _frames(kind, 4)
    x = np.random.default_rng(5).normal(size=frames.size) * 0.2  # away from the start
    here = frames.moved(x)
    w = row_weights(kind, 0.3)
    W = dense(*frames.parts(*here.relative(Rt, pt, index), index, x, w), index, 2)
    h = 1e-6
    for k in range(frames.size):
        step = np.zeros(frames.size)
        step[k] = h
        ga, gb = (frames.moved(x + s * step).gaps(Rt, pt, index) * w for s in (1, -1))
        assert np.allclose(W[:, :, k], (ga - gb) / (2 * h), atol=1e-7), k


def test_moved_frames_are_each_frame_moved_alone():
    frames, *_ = _frames(PlaneContact(), 6)
    x = np.random.default_rng(7).normal(size=frames.size) * 0.3
    both = frames.moved(x)
    kind = frames.kind
    o = len(kind.object_dofs)
    for k in range(2):
        v = np.zeros(6)
        v[list(kind.object_dofs)] = x[o * k : o * k + o]
        T = frames.objects[k] @ _exp(v)
        assert np.allclose(both.objects[k], T, atol=1e-14)
    v = np.zeros(6)
    v[list(kind.contact_dofs)] = x[2 * o :]
    assert np.allclose(both.contact, frames.contact @ _exp(v), atol=1e-14)


def _exp(v: np.ndarray) -> np.ndarray:
    """``[Exp(r), t]`` of a twist ``(t, r)`` (scipy's rotation, not calib's)."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(v[3:]).as_matrix()
    T[:3, 3] = v[:3]
    return T
