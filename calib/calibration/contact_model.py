"""A contact term's model: the objects touched, the contact frame, the gaps and the state.

Rationale: docs/developers/engine.md#contact_model
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..identification.contacts import Contact
from ..kinematics.mdh import Kinematics, MDHModel
from ..kinematics.so3 import left_jacobian, rotation_matrix, skew
from ..measurements.contact_objects import plane_rotation
from .contact_blocks import dense
from .placements import JointFrames

__all__ = [
    "DOF_NAMES",
    "ContactFrames",
    "ContactState",
    "plane_frame",
    "plane_frames",
    "row_weights",
]

DOF_NAMES = ("x", "y", "z", "rx", "ry", "rz")
"""Names of a twist's components in a frame's own axes: translation [m], rotation [rad]."""


def _moved(T: np.ndarray, v: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Frames ``T [Exp(r), t]`` ``(..., 4, 4)`` by twists ``v = (t, r)``, ``R = Exp(r)`` made."""
    out = np.array(T, dtype=float, copy=True)
    out[..., :3, :3] = T[..., :3, :3] @ R
    out[..., :3, 3] = T[..., :3, 3] + (T[..., :3, :3] @ v[..., :3, None])[..., 0]
    return out


def _twist_maps(v: np.ndarray) -> np.ndarray:
    """Local twist ``(Exp(-r) dt, Jr(r) dr)`` of frames moved by ``v`` per unit ``(..., 6, 6)``."""
    A = np.zeros((*v.shape[:-1], 6, 6))
    A[..., :3, :3] = rotation_matrix(-v[..., 3:])
    A[..., 3:, 3:] = left_jacobian(-v[..., 3:])  # Jr(r) = Jl(-r)
    return A


@dataclass(frozen=True, eq=False)
class ContactFrames:
    """A kind's contact frame ``(4, 4)`` (tool frame) and objects ``(K, 4, 4)`` (base frame)."""

    kind: Contact
    contact: np.ndarray
    objects: np.ndarray
    ids: tuple[str, ...]

    @property
    def size(self) -> int:
        """Unknowns: the objects' then the contact's."""
        return len(self.ids) * len(self.kind.object_dofs) + len(self.kind.contact_dofs)

    def names(self) -> tuple[str, ...]:
        """Column names, e.g. ``plane_table_z``, ``contact_rx``."""
        obj = tuple(
            f"{self.kind.object_name}_{name}_{DOF_NAMES[d]}"
            for name in self.ids
            for d in self.kind.object_dofs
        )
        return obj + tuple(f"contact_{DOF_NAMES[d]}" for d in self.kind.contact_dofs)

    def index(self, ids: Sequence[str], source: str = "<contacts>") -> np.ndarray:
        """The object of each touch ``(m,)`` (DataError: an object these frames do not hold)."""
        where = {name: k for k, name in enumerate(self.ids)}
        unknown = [i for i in dict.fromkeys(ids) if i not in where]
        if unknown:
            raise DataError(
                source,
                f"touches of '{unknown[0]}', which the fitted touches do not touch: each "
                f"{self.kind.object_name} is fitted from its own touches",
            )
        return np.array([where[i] for i in ids], dtype=int)

    def moved(self, x: np.ndarray) -> ContactFrames:
        """The frames at unknowns x (:attr:`size`; x = 0 is these frames)."""
        v = self._twists(x)  # the objects' and the contact's rotations made at once
        R = rotation_matrix(v[:, 3:])
        objects = _moved(self.objects, v[:-1], R[:-1])
        return ContactFrames(self.kind, _moved(self.contact, v[-1], R[-1]), objects, self.ids)

    def _twists(self, x: np.ndarray) -> np.ndarray:
        """The objects' twists, then the contact's ``(K + 1, 6)``, at unknowns x."""
        x = np.asarray(x, dtype=float)
        o, K = len(self.kind.object_dofs), len(self.ids)
        v = np.zeros((K + 1, 6))
        v[:K, list(self.kind.object_dofs)] = x[: K * o].reshape(K, o)
        v[K, list(self.kind.contact_dofs)] = x[K * o :]
        return v

    def relative(
        self, Rt: np.ndarray, pt: np.ndarray, index: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The contact frame in its object's frame ``(m, 3, 3)``, ``(m, 3)``, from the tool's."""
        F = self.objects[index]
        FRt = np.swapaxes(F[:, :3, :3], 1, 2)
        R = FRt @ Rt @ self.contact[:3, :3]
        x = pt + Rt @ self.contact[:3, 3]
        return R, (FRt @ (x - F[:, :3, 3])[:, :, None])[:, :, 0]

    def gaps(self, Rt: np.ndarray, pt: np.ndarray, index: np.ndarray) -> np.ndarray:
        """The kind's gap of each touch ``(m, rows)`` [m, rad]."""
        return self.kind.residual(*self.relative(Rt, pt, index))

    def parts(
        self, R: np.ndarray, p: np.ndarray, index: np.ndarray, x: np.ndarray, w: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Weighted gap rows by block at ``x``: own object's ``(m, rows, o)``, contact's."""
        m, o = len(p), len(self.kind.object_dofs)
        A = _twist_maps(self._twists(x))  # the objects' and the contact's at once
        own = np.zeros((m, 6, o))
        if o:
            # F -> F exp(d): the contact seen from F moves by exp(-d): dp = -dt + [p]x dr
            E = np.zeros((m, 6, 6))
            E[:, :3, :3] = -np.eye(3)
            E[:, :3, 3:] = skew(p)
            E[:, 3:, 3:] = -np.eye(3)
            own = E @ A[:-1][..., list(self.kind.object_dofs)][index]
        shared = np.zeros((m, 6, len(self.kind.contact_dofs)))
        if self.kind.contact_dofs:
            # C -> C exp(d): the contact moves by R dt and turns by R dr in F
            E = np.zeros((m, 6, 6))
            E[:, :3, :3] = R
            E[:, 3:, 3:] = R
            shared = E @ A[-1][..., list(self.kind.contact_dofs)]
        rows = w[None, :, None]
        return self.kind.jacobian_rows(own, R) * rows, self.kind.jacobian_rows(shared, R) * rows

    def centred(self, Rt: np.ndarray, pt: np.ndarray, index: np.ndarray) -> ContactFrames:
        """The planes, each origin its touches' contact points' centroid (other kinds: self)."""
        if self.kind.object_name != "plane":
            return self
        normals = self.objects[:, :3, 2]
        heights = np.einsum("ki,ki->k", normals, self.objects[:, :3, 3])
        planes = plane_frames(normals, heights, pt + Rt @ self.contact[:3, 3], index)
        return ContactFrames(self.kind, self.contact, planes, self.ids)


def row_weights(kind: Contact, weight: float) -> np.ndarray:
    """Weight of each gap row: 1 for a length, ``weight`` [m/rad] for an angle."""
    if not (np.isfinite(weight) and weight > 0):
        raise InvalidArgumentError(f"the orientation weight must be positive, got {weight}")
    return np.where(np.array(kind.angular), float(weight), 1.0)


def plane_frame(normal: np.ndarray, height: float, centre: np.ndarray) -> np.ndarray:
    """The plane ``(4, 4)``: z = normal, origin the projected ``centre`` [m], x the base x."""
    n = np.asarray(normal, dtype=float)
    T = np.eye(4)
    T[:3, :3] = plane_rotation(n)
    T[:3, 3] = centre - (n @ centre - height) * n
    return T


def plane_frames(normals, heights, x: np.ndarray, index: np.ndarray) -> np.ndarray:
    """Planes ``(K, 4, 4)`` (:func:`plane_frame`), each origin its points ``x``' centroid."""
    pairs = enumerate(zip(normals, heights, strict=True))
    return np.array([plane_frame(n, h, x[index == k].mean(axis=0)) for k, (n, h) in pairs])


@dataclass(frozen=True, eq=False)
class ContactState:
    """The robot (``mdh``), the contact frame and objects, angle ``weight`` [m/rad], compliance."""

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
        """Weighted d(gap)/dx by block (:meth:`ContactFrames.parts`) and each touch's object."""
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
