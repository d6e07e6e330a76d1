"""The result of a calibration of several chains from flush contacts: one robot, one URDF."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..exceptions import CalibrationRefusedError
from ..identification.contacts import Contact, PlaneContact
from ..kinematics.mdh import MDHModel
from ..kinematics.placement_export import moved_origins_urdf, write_moved_origins_urdf
from ..kinematics.robot import Chain
from .contact_frames import ContactFrames
from .contact_result import GapStats
from .placements import Placements
from .selection import Selection

__all__ = ["ChainContacts", "ContactChainsCalibration"]


@dataclass(frozen=True, eq=False)
class ChainContacts:
    """One chain's part of the result.

    Attributes:
        chain: The nominal chain.
        source: Its touches' file (or description).
        plane_id: The plane's (or the fixed pose's) id.
        plane: The plane in the chain's base frame ``(4, 4)``, z = normal (a
            ``fixed-pose`` chain: the fixed pose of its contact frame).
        contact: The contact frame in the tool frame ``(4, 4)``.
        nominal: The chain's nominal MDH model.
        calibrated: Its MDH model on the calibrated robot.
        weight: Weight of its tilt rows [m/rad].
        stats: ``train``, ``train_registration`` and, with held-out touches, ``held_out``
            and ``held_out_registration``.
        kind: The chain's contact kind (``plane`` or ``fixed-pose``).
        frames: Its fitted objects and contact frame (a ``fixed-pose`` chain's poses by
            id), or None.
    """

    chain: Chain
    source: str
    plane_id: str
    plane: np.ndarray
    contact: np.ndarray
    nominal: MDHModel
    calibrated: MDHModel
    weight: float
    stats: dict[str, GapStats]
    kind: Contact = field(default_factory=PlaneContact)
    frames: ContactFrames | None = None

    def objects(self) -> dict[str, np.ndarray]:
        """Each object (the plane, or each fixed pose) in the base frame ``(4, 4)``, by id."""
        if self.frames is None or isinstance(self.kind, PlaneContact):
            return {self.plane_id: self.plane}
        return {i: F.copy() for i, F in zip(self.frames.ids, self.frames.objects, strict=True)}

    def to_dict(self) -> dict:
        """JSON-ready form (metres, radians; gaps in mm and degrees)."""
        return {
            "base": self.chain.base_frame,
            "tool": self.chain.tool_frame,
            "data": self.source,
            "kind": self.kind.label,
            "tilt_weight": self.weight,
            "contact": {
                f"{self.kind.object_name}s": {
                    i: {"frame": self.chain.base_frame, "matrix": F.tolist()}
                    for i, F in self.objects().items()
                },
                "frames": {self.chain.tool_frame: {"matrix": self.contact.tolist()}},
            },
            "gaps": {k: v.to_dict() for k, v in self.stats.items()},
        }


@dataclass(frozen=True, eq=False)
class ContactChainsCalibration:
    """A calibration of several chains of one robot from flush contacts.

    Attributes:
        chains: Each chain's part, in the order given.
        placements: The fitted joint placement errors (one per URDF joint on any chain).
        shared: Joints on two chains or more (fitted once for all of them).
        planes: Objects fitted: planes (a plane shared by chains counts once) and the
            fixed poses of ``fixed-pose`` chains.
        free: The placement components fitted (``<joint>:x`` ... ``:rz``).
        selection: The automatic choice (``auto``), or None.
        refusal: Why the model must not be used, or None.
        notes: Remarks for the user.
        timings_ms: Stage timings [ms].
    """

    chains: tuple[ChainContacts, ...]
    placements: Placements
    shared: tuple[str, ...]
    planes: int
    free: tuple[str, ...]
    selection: Selection | None
    refusal: str | None
    notes: tuple[str, ...]
    timings_ms: dict[str, float]

    @property
    def accepted(self) -> bool:
        """The model may be used (not refused)."""
        return self.refusal is None

    def joint_errors(self) -> dict[str, np.ndarray]:
        """``E_j`` ``(4, 4)`` of every joint that moved (the new origin is ``O_j E_j``)."""
        return self.placements.errors()

    def to_dict(self) -> dict:
        """The JSON report (metres, radians; gaps in mm and degrees)."""
        first = self.chains[0].chain
        return {
            "robot": first.name,
            "urdf": str(first.urdf_path),
            "measure": "plane",
            "accepted": self.accepted,
            "refusal": self.refusal,
            "chains": [c.to_dict() for c in self.chains],
            "shared_joints": list(self.shared),
            "planes": self.planes,
            "free": list(self.free),
            "selection": None if self.selection is None else self.selection.to_dict(),
            "joint_origins": {
                name: {
                    "xyz": E[:3, 3].tolist(),
                    "rpy": pin.rpy.matrixToRpy(E[:3, :3]).tolist(),
                    "matrix": E.tolist(),
                }
                for name, E in self.joint_errors().items()
            },
            "notes": list(self.notes),
            "timings_ms": dict(self.timings_ms),
        }

    def _objects(self) -> str:
        """``2 plane(s)``, or ``1 plane(s) and 1 pose(s)`` with loops."""
        loops = [c for c in self.chains if not isinstance(c.kind, PlaneContact)]
        poses = sum(len(c.objects()) for c in loops)
        return f"{self.planes - len(loops)} plane(s)" + (f" and {poses} pose(s)" if poses else "")

    def text(self) -> str:
        """A terminal summary: each chain's gaps, then the shared joints."""
        lines = [
            f"{self.chains[0].chain.name}: {len(self.chains)} chains, {self._objects()}, "
            f"{len(self.free)} joint placement components fitted"
            + (f" (shared joints: {', '.join(self.shared)})" if self.shared else ""),
            "gaps (RMS): height [mm]  roll [deg]  pitch [deg]",
        ]
        for c in self.chains:
            head = f"{c.chain.base_frame} -> {c.chain.tool_frame}, {c.kind.object_name}"
            if not isinstance(c.kind, PlaneContact):
                units = [
                    f"{n} [{'deg' if a else 'mm'}]"
                    for n, a in zip(c.kind.row_names, c.kind.angular, strict=True)
                ]
                ids = ", ".join(f"'{i}'" for i in c.objects())
                head += f" {ids} (gaps: {', '.join(units)})"
                lines.append(head + ":")
            else:
                lines.append(f"{head} '{c.plane_id}':")
            for key, s in c.stats.items():
                rms = "  ".join(f"{v:8.3f}" for v in s.rms)
                lines.append(f"  {key:22s} {rms}  ({s.m} touches)")
        lines += [f"note: {n}" for n in self.notes]
        lines.append("accepted" if self.accepted else f"REFUSED: {self.refusal}")
        return "\n".join(lines)

    def urdf(self) -> bytes:
        """The calibrated URDF of the whole robot (the joint origins moved).

        Raises:
            CalibrationRefusedError: The model was refused.
        """
        if self.refusal is not None:
            raise CalibrationRefusedError(f"calibration refused: {self.refusal}")
        return moved_origins_urdf(self.chains[0].chain, self.joint_errors())

    def write_urdf(self, path: str | Path) -> None:
        """Write :meth:`urdf` atomically (never over the nominal URDF).

        Raises:
            CalibrationRefusedError: The model was refused.
        """
        if self.refusal is not None:
            raise CalibrationRefusedError(f"calibration refused: {self.refusal}")
        write_moved_origins_urdf(path, self.chains[0].chain, self.joint_errors())
