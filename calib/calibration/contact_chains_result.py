"""The result of a calibration of several chains from flush contacts: one robot, one URDF."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..exceptions import CalibrationRefusedError
from ..identification.contacts import Contact, PlaneContact
from ..kinematics.mdh import MDHModel
from ..kinematics.placement_export import moved_origins_urdf, write_moved_origins_urdf
from ..kinematics.robot import Chain
from .contact_frames import ContactFrames
from .contact_result import GapStats, gap_errors_mm
from .delivery import Delivered
from .outliers import Outlier
from .placements import Placements
from .report import (
    FORMAT2_MOVED,
    build_report,
    fit_dict,
    model_choice,
    outlier_dict,
    parameter_entries,
    parameter_lines,
    pose_dict,
    term_dict,
    verdict,
)
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
        held_source: Its held-out touches' source (``holdout`` or the validation file), or
            None.
        outliers: Its touches set aside after its registration.
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
    held_source: str | None = None
    outliers: tuple[Outlier, ...] = ()

    def objects(self) -> dict[str, np.ndarray]:
        """Each object (the plane, or each fixed pose) in the base frame ``(4, 4)``, by id."""
        if self.frames is None or isinstance(self.kind, PlaneContact):
            return {self.plane_id: self.plane}
        return {i: F.copy() for i, F in zip(self.frames.ids, self.frames.objects, strict=True)}

    def errors(self) -> dict:
        """The report's ``errors.terms`` entry: ``train`` and ``held_out`` gaps (format 3)."""
        out: dict = {"train": gap_errors_mm(self.stats, "train"), "held_out": None}
        if "held_out" in self.stats:
            out["held_out"] = {"source": self.held_source, **gap_errors_mm(self.stats, "held_out")}
        return out

    def to_dict(self) -> dict:
        """JSON-ready form (metres, radians; gaps in mm and degrees; format 2's)."""
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


@dataclass(frozen=True, eq=False, repr=False)
class ContactChainsCalibration(Delivered):
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
        params: The parameter level.
        estimate: The fitted components' values, in the order of ``fitted`` [m, rad].
        std: Their standard deviations (NaN where undefined).
        fitted: The names of ``estimate`` (``free``, or every component after a polish).
        solver: ``(converged, message, Jacobian evaluations)`` of the final fit.
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
    params: str = "auto"
    estimate: np.ndarray = field(default_factory=lambda: np.zeros(0))
    std: np.ndarray = field(default_factory=lambda: np.zeros(0))
    fitted: tuple[str, ...] = ()
    solver: tuple[bool, str, int] = (True, "", 0)

    @property
    def accepted(self) -> bool:
        """The model may be used (not refused)."""
        return self.refusal is None

    def joint_errors(self) -> dict[str, np.ndarray]:
        """``E_j`` ``(4, 4)`` of every joint that moved (the new origin is ``O_j E_j``)."""
        return self.placements.errors()

    def to_dict(self) -> dict:
        """The JSON report (format 3, :mod:`calib.calibration.report`).

        ``errors.train`` and ``errors.held_out`` are None: each chain's gaps are its own rows
        (``errors.terms``, in the order of ``terms``).
        """
        first = self.chains[0].chain
        names = tuple(first.model.names)
        fields = {
            "robot": first.name,
            "urdf": str(first.urdf_path),
            "shape": "chains",
            "terms": [
                term_dict(
                    c.chain.base_frame,
                    c.chain.tool_frame,
                    c.kind.label,
                    c.source,
                    c.stats["train"].m,
                )
                for c in self.chains
            ],
            **verdict(self.params, self.refusal, self.solver),
            "parameters": parameter_entries(self.fitted, self.estimate, self.std, names),
            "errors": {
                "train": None,
                "held_out": None,
                "terms": [c.errors() for c in self.chains],
            },
            "frames": {
                "measurement": None,
                "measured": None,
                "markers": {},
                "contacts": {c.chain.tool_frame: pose_dict(c.contact) for c in self.chains},
                "world_link": None,
                "tool_link": None,
                "on_robot": False,
            },
            "objects": self._object_poses(),
            "fit": fit_dict(),
            "model_choice": model_choice(self.selection),
            "outliers": [
                outlier_dict(o, term) for term, c in enumerate(self.chains) for o in c.outliers
            ],
            "compliance": {},
            "model": {
                "joint_origins": {n: pose_dict(E) for n, E in self.joint_errors().items()},
                "shared_joints": list(self.shared),
            },
            "warnings": list(self.notes),
            "timings_ms": dict(self.timings_ms),
        }
        return build_report(fields, self._format2(), FORMAT2_MOVED)

    def _object_poses(self) -> dict:
        """Planes and poses by id, each in its chain's base frame (format 3's ``objects``)."""
        out: dict[str, dict] = {}
        for c in self.chains:
            group = out.setdefault(f"{c.kind.object_name}s", {})
            for i, F in c.objects().items():
                group[i] = {"frame": c.chain.base_frame, **(pose_dict(F) or {})}
        return out

    def _format2(self) -> dict:
        """Format 2's keys that format 3 replaced (written until format 4)."""
        return {
            "measure": "plane",
            "chains": [c.to_dict() for c in self.chains],
            "shared_joints": list(self.shared),
            "planes": self.planes,
            "free": list(self.free),
            "selection": None if self.selection is None else self.selection.to_dict(),
            "joint_origins": {n: pose_dict(E) for n, E in self.joint_errors().items()},
            "notes": list(self.notes),
        }

    def _objects(self) -> str:
        """``2 plane(s)``, or ``1 plane(s) and 1 pose(s)`` with loops."""
        loops = [c for c in self.chains if not isinstance(c.kind, PlaneContact)]
        poses = sum(len(c.objects()) for c in loops)
        return f"{self.planes - len(loops)} plane(s)" + (f" and {poses} pose(s)" if poses else "")

    def summary(self) -> str:
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
        names = tuple(self.chains[0].chain.model.names)
        lines += parameter_lines(parameter_entries(self.fitted, self.estimate, self.std, names))
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
