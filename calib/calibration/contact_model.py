"""A contact term's state: the robot, the contact frame and the objects touched.

Its own unknowns are the objects' and the contact's; the robot's columns are the joint
engine's (:mod:`.contact_chains_model`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import InvalidArgumentError
from ..identification.contacts import Contact
from ..kinematics.mdh import Kinematics, MDHModel
from ..kinematics.so3 import skew
from .contact_blocks import dense
from .contact_frames import ContactFrames, row_weights
from .placements import JointFrames

__all__ = ["ContactState"]


@dataclass(frozen=True, eq=False)
class ContactState:
    """The robot (``mdh``, frame -1 the base), the contact frame and the objects (``frames``).

    ``weight``: the angle rows' [m/rad]; ``compliance`` ``(n,)`` [rad/(N m) or m/N], or None.
    """

    mdh: MDHModel
    frames: ContactFrames
    weight: float
    compliance: np.ndarray | None = None

    @property
    def kind(self) -> Contact:
        """The contact kind."""
        return self.frames.kind

    @property
    def contact(self) -> np.ndarray:
        """The contact frame in the tool frame ``(4, 4)``."""
        return self.frames.contact

    def joints(self, q: np.ndarray, torque: np.ndarray | None = None) -> np.ndarray:
        """Joint positions the geometry sees: ``q + c * tau`` [rad or m] (``q`` without torque)."""
        q = np.asarray(q, dtype=float)
        if torque is None or self.compliance is None or not np.any(self.compliance):
            return q
        return q + np.asarray(torque, dtype=float) * self.compliance

    def kinematics(self, q: np.ndarray, torque: np.ndarray | None = None) -> Kinematics:
        """The robot's frames at ``q`` ``(m, n)``, deflected by gravity ``torque`` [N m or N]."""
        return self.mdh.kinematics(self.joints(q, torque))

    def gaps(
        self,
        q: np.ndarray,
        ids: Sequence[str] | None = None,
        torque: np.ndarray | None = None,
        kin: Kinematics | JointFrames | None = None,
    ) -> np.ndarray:
        """The kind's gap ``(m, rows)`` [m, rad] of touches ``q`` of ``ids`` (None: one object)."""
        if kin is None:
            kin = self.kinematics(q, torque)
        index = self._index(ids, len(kin.p))
        return self.frames.gaps(kin.R[:, -1], kin.p[:, -1], index)

    def _index(self, ids: Sequence[str] | None, m: int, source: str = "<contacts>") -> np.ndarray:
        if ids is None:
            if len(self.frames.ids) != 1:
                raise InvalidArgumentError("give the touches' ids: there are several objects")
            return np.zeros(m, dtype=int)
        return self.frames.index(ids, source)

    def row_weights(self) -> np.ndarray:
        """Weight of each gap row: 1 for a length, :attr:`weight` for an angle."""
        return row_weights(self.kind, self.weight)

    def residuals(
        self, data, torque: np.ndarray | None = None, kin: Kinematics | JointFrames | None = None
    ) -> np.ndarray:
        """Weighted ``0 - gap`` ``(m, rows)`` of contact data (lengths [m], weighted angles)."""
        return -self.gaps(data.q, data.ids, torque, kin) * self.row_weights()

    def moved(self, x: np.ndarray) -> ContactState:
        """The state with its objects' and contact's unknowns moved by ``x`` (x = 0: self)."""
        return dataclasses.replace(self, frames=self.frames.moved(self._own(x)))

    def _own(self, x: np.ndarray) -> np.ndarray:
        return np.asarray(x, dtype=float)[: self.frames.size]

    def blocks(
        self, x: np.ndarray, data, kin=None, moved: ContactState | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Weighted d(gap)/dx by block (:meth:`ContactFrames.parts`) and each touch's object.

        ``kin``: the robot's frames at the touches, or None (rigid); ``moved``: at x, if made.
        """
        s = self.moved(x) if moved is None else moved
        if kin is None:
            kin = s.kinematics(data.q)
        index = s._index(data.ids, len(kin.p), data.source)
        R, p = s.frames.relative(kin.R[:, -1], kin.p[:, -1], index)
        return (*s.frames.parts(R, p, index, self._own(x), s.row_weights()), index)

    def own_rows(self, x: np.ndarray, data, kin, moved: ContactState | None = None) -> np.ndarray:
        """:meth:`blocks` as one matrix ``(m, rows, size)`` (as a measured term's own rows)."""
        return dense(*self.blocks(x, data, kin, moved), len(self.frames.ids))

    def motion_rows(self, kin, data, lin: np.ndarray, ang: np.ndarray) -> np.ndarray:
        """Weighted gap rows ``(m, r, k)`` of k motions ``lin``, ``ang`` of the tool side."""
        R, p = kin.R[:, -1], kin.p[:, -1]
        point = p + R @ self.contact[:3, 3]
        W6 = np.concatenate([lin - skew(point) @ ang, ang], axis=1)  # the contact point's motion
        index = self.frames.index(data.ids, data.source)
        Rc, _ = self.frames.relative(R, p, index)
        FRt = np.swapaxes(self.frames.objects[index, :3, :3], 1, 2)  # seen in each object
        rows = self.kind.jacobian_rows(np.concatenate([FRt @ W6[:, :3], FRt @ W6[:, 3:]], 1), Rc)
        return rows * self.row_weights()[None, :, None]
