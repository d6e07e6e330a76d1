"""The result of a calibration from contacts: gaps, objects, contact frame, report.

The report (:meth:`ContactCalibration.to_dict`) holds, under ``contact``:

* ``planes.<id>`` (``plane``, ``plane-point``): ``{"frame": BASE, "matrix": 4x4}``, the plane
  in the chain's base frame, z its normal, origin the touches' centroid projected on it;
* ``points.<id>`` (``fixed-point``): ``{"frame": BASE, "matrix": 4x4}``, the point as the
  origin, the base frame's axes (a point has no orientation);
* ``poses.<id>`` (``fixed-pose``): ``{"frame": BASE, "matrix": 4x4}``, the fixed frame the
  contact frame is held on;
* ``frames.<tool>``: ``{"matrix": 4x4}``, the contact frame in the tool frame.

Under ``gaps``, for ``train``, ``train_registration`` and, with held-out touches,
``held_out`` and ``held_out_registration``: ``m``, then for each row of the kind
``<row>_rms_<unit>`` and ``<row>_max_<unit>`` (``mm`` for a length, ``deg`` for an angle;
e.g. ``height_rms_mm``, ``roll_max_deg``, ``x_rms_mm``, ``rz_rms_deg``), and
``weighted_mm``; with joint compliance (``elastic``), ``train_urdf`` and ``held_out_urdf``:
the URDF alone. ``compliance`` (by joint, 0 where none was fitted) and ``load`` (the standing
load, or None) describe the compliance; :meth:`ContactCalibration.compliance_document` is
its file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.fileio import json_text
from ..exceptions import CalibrationRefusedError, InvalidArgumentError
from ..identification.contacts import Contact
from ..kinematics.elastic import COMPLIANCE_FORMAT, nominal_masses, nominal_origins
from ..kinematics.mdh import MDHModel
from ..kinematics.robot import Chain
from ..kinematics.standing import StandingLoad
from ..kinematics.urdf_export import calibrated_urdf, write_calibrated_urdf
from ..kinematics.urdf_model import read_urdf_file
from .delivery import Delivered, RowErrors, compliance_path
from .outliers import Outlier
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

__all__ = [
    "ContactCalibration",
    "GapStats",
    "gap_errors_mm",
    "gap_rows",
    "gap_stats",
    "part_stats",
    "row_stats",
    "term_errors",
]


@dataclass(frozen=True)
class GapStats:
    """Gaps of touches: the kind's rows (lengths in mm, angles in degrees).

    Attributes:
        m: Touches.
        names: The kind's row names.
        angular: Whether each row is an angle.
        rms: RMS of each row [mm or deg].
        max: Largest absolute value of each row [mm or deg].
        weighted_mm: RMS over touches of the weighted gap's norm [mm] (angles times the
            orientation weight).
        per_row: Each touch's weighted gap norm ``(m,)`` [mm] (``weighted_mm`` is their
            RMS), or None.

    Each row's figures also read as attributes: ``height_rms_mm``, ``roll_max_deg``, ...
    """

    m: int
    names: tuple[str, ...]
    angular: tuple[bool, ...]
    rms: tuple[float, ...]
    max: tuple[float, ...]
    weighted_mm: float
    per_row: np.ndarray | None = field(default=None, compare=False, repr=False)

    def figures(self) -> tuple[str, ...]:
        """``<row>_rms_<unit>`` and ``<row>_max_<unit>`` of every row, in row order."""
        out = []
        for name, angle in zip(self.names, self.angular, strict=True):
            unit = "deg" if angle else "mm"
            out += [f"{name}_rms_{unit}", f"{name}_max_{unit}"]
        return tuple(out)

    def __getattr__(self, key: str) -> float:
        """A row's figure by its key (:meth:`figures`), e.g. ``height_rms_mm``."""
        if key.startswith("__") or key in ("names", "angular", "rms", "max", "figures", "per_row"):
            raise AttributeError(key)
        keys = self.figures()
        if key not in keys:
            raise AttributeError(f"GapStats has no {key!r}: {', '.join(keys)}")
        i = keys.index(key)
        return (self.max if i % 2 else self.rms)[i // 2]

    @property
    def length_rms_mm(self) -> float:
        """RMS over touches of the norm of the length rows [mm]."""
        lengths = [r for r, a in zip(self.rms, self.angular, strict=True) if not a]
        return math.sqrt(sum(v**2 for v in lengths))

    def in_mm(self) -> dict:
        """The report's form (format 3): ``configs``, each row's figures, ``weighted_mm``."""
        return {"configs": self.m, **{k: v for k, v in self.to_dict().items() if k != "m"}}

    def to_dict(self) -> dict:
        """JSON-ready form: ``m``, each row's RMS and largest value, ``weighted_mm``."""
        out: dict = {"m": self.m}
        for key in self.figures():
            out[key] = getattr(self, key)
        out["weighted_mm"] = self.weighted_mm
        return out


def gap_errors_mm(stats: dict[str, GapStats], part: str) -> dict:
    """``registration``, ``calibrated`` and ``urdf`` (no compliance) gaps of ``part``."""
    cal = stats[part]
    return {
        "registration": stats[f"{part}_registration"].in_mm(),
        "calibrated": cal.in_mm(),
        "urdf": stats.get(f"{part}_urdf", cal).in_mm(),
    }


def term_errors(stats: dict[str, GapStats], held_source: str | None) -> dict:
    """A term's ``errors.terms`` entry: ``train`` and ``held_out`` errors (format 3)."""
    out: dict = {"train": gap_errors_mm(stats, "train"), "held_out": None}
    if "held_out" in stats:
        out["held_out"] = {"source": held_source, **gap_errors_mm(stats, "held_out")}
    return out


def part_stats(stat, registered, state, train, held) -> dict:
    """``stat(s, rows)`` of the fitted and the registered states on a term's rows.

    Keys ``train``, ``train_registration`` and, with held-out rows (``held`` not None),
    ``held_out`` and ``held_out_registration``.
    """
    parts = {"train": train} if held is None else {"train": train, "held_out": held}
    return {key + suffix: stat(s, rows) for key, rows in parts.items()
            for suffix, s in (("", state), ("_registration", registered))}  # fmt: skip


def gap_stats(state, q: np.ndarray, ids=None, torque: np.ndarray | None = None) -> GapStats:
    """:class:`GapStats` of a :class:`~.contact_model.ContactState` at touches ``q`` of ``ids``.

    ``ids`` may be left out when the state has one object. ``torque``: the gravity torques
    ``(m, n)`` that deflect compliant joints (or None).
    """
    return row_stats(state.gaps(q, ids, torque), state.kind, state.row_weights())


def row_stats(g: np.ndarray, kind, weights: np.ndarray) -> GapStats:
    """:class:`GapStats` of rows ``g`` ``(m, rows)`` [m, rad] of a kind.

    ``kind``: its ``row_names`` and ``angular``; ``weights`` ``(rows,)`` [1, m/rad]: the
    rows' weights in ``weighted_mm``.
    """
    scale = np.where(np.array(kind.angular), math.degrees(1.0), 1e3)
    rms = np.sqrt(np.mean(g**2, axis=0)) * scale
    top = np.max(np.abs(g), axis=0) * scale
    per_row = 1e3 * np.linalg.norm(g * weights, axis=1)
    return GapStats(
        len(g),
        kind.row_names,
        kind.angular,
        tuple(float(v) for v in rms),
        tuple(float(v) for v in top),
        float(np.sqrt(np.mean(per_row**2))),
        per_row,
    )


def gap_rows(stats: dict[str, GapStats], name: str = "") -> RowErrors:
    """Each touch's weighted gap [mm] before (registration) and after, held-out ones marked.

    Args:
        stats: ``train``, ``train_registration`` and (optional) ``held_out`` and
            ``held_out_registration`` (as :attr:`ContactCalibration.stats`).
        name: The term's name (several terms), or empty.
    """
    parts = [p for p in ("train", "held_out") if p in stats]
    before, after = [], []
    for part in parts:
        reg, cal = stats[f"{part}_registration"].per_row, stats[part].per_row
        if reg is None or cal is None:
            raise InvalidArgumentError("these gap statistics keep no per-touch gaps")
        before.append(reg)
        after.append(cal)
    held = np.concatenate(
        [np.full(len(b), p == "held_out") for b, p in zip(before, parts, strict=True)]
    )
    return RowErrors(np.concatenate(before), np.concatenate(after), held, name=name)


@dataclass(frozen=True, eq=False, repr=False)
class ContactCalibration(Delivered):
    """A calibration from contacts.

    Attributes:
        chain: The nominal chain.
        kind: The contact kind.
        nominal: Its MDH model.
        calibrated: The calibrated MDH model (frame -1: the chain's base frame).
        contact: The contact frame in the tool frame ``(4, 4)``.
        objects: Each plane, point or pose in the base frame ``(4, 4)``, by id (see the
            module's text).
        free: The robot parameters fitted.
        selection: The automatic choice (``auto``), or None.
        stats: ``train``, ``train_registration`` and, with held-out touches, ``held_out``
            and ``held_out_registration`` (the nominal robot with its own objects and
            contact); with compliance, ``train_urdf`` and ``held_out_urdf``: the URDF alone.
        refusal: Why the model must not be used, or None.
        notes: Remarks for the user.
        weight: Weight of the angle rows [m/rad].
        timings_ms: Stage timings [ms].
        params: The parameter level (``auto``, ``frames``, ``offsets``, ``paper``,
            ``complete``).
        outliers: Touches set aside after the registration.
        compliance: Fitted joint compliance ``(n,)`` [rad/(N m) or m/N], or None (rigid).
        load: The gravity load the compliance acts under, or None.
        readings: The joints off the chain the load takes at their recorded positions.
        estimate: The fitted robot parameters' values (changes from the registration, in the
            order of ``free``) [rad, m, rad/(N m)], or None.
        std: Their standard deviations (NaN where undefined), or None.
        solver: ``(converged, message, Jacobian evaluations)`` of the final fit.
        sources: The touches' source and the held-out touches' (None without any).
    """

    chain: Chain
    kind: Contact
    nominal: MDHModel
    calibrated: MDHModel
    contact: np.ndarray
    objects: dict[str, np.ndarray]
    free: tuple[str, ...]
    selection: Selection | None
    stats: dict[str, GapStats]
    refusal: str | None
    notes: tuple[str, ...]
    weight: float
    timings_ms: dict[str, float]
    params: str = "auto"
    outliers: tuple[Outlier, ...] = ()
    compliance: np.ndarray | None = None
    load: StandingLoad | None = None
    readings: tuple[str, ...] = ()
    estimate: np.ndarray | None = None
    std: np.ndarray | None = None
    solver: tuple[bool, str, int] = (True, "", 0)
    sources: tuple[str, str | None] = ("", None)

    @property
    def elastic(self) -> bool:
        """Joint compliance was fitted: the URDF alone is not the whole model."""
        return self.compliance is not None

    @property
    def accepted(self) -> bool:
        """The model may be used (not refused)."""
        return self.refusal is None

    @property
    def plane_id(self) -> str:
        """The first object's id."""
        return next(iter(self.objects))

    @property
    def plane(self) -> np.ndarray:
        """The first object ``(4, 4)`` in the base frame (a plane: z = normal)."""
        return self.objects[self.plane_id]

    def to_dict(self) -> dict:
        """The JSON report (format 3, :mod:`calib.calibration.report`)."""
        chain, mdh = self.chain, self.nominal
        n = len(self.free)
        estimate = np.full(n, np.nan) if self.estimate is None else self.estimate
        std = np.full(n, np.nan) if self.std is None else self.std
        held = None
        if "held_out" in self.stats:
            held = {"source": self.sources[1], **gap_errors_mm(self.stats, "held_out")}
        train = gap_errors_mm(self.stats, "train")
        fields = {
            "robot": chain.name,
            "urdf": str(chain.urdf_path),
            "shape": "contacts",
            "terms": [
                term_dict(
                    chain.base_frame,
                    chain.tool_frame,
                    self.kind.label,
                    self.sources[0],
                    self.stats["train"].m,
                )
            ],
            **verdict(self.params, self.refusal, self.solver),
            "parameters": parameter_entries(self.free, estimate, std, mdh.joint_names, mdh.sigma),
            "errors": {
                "train": train,
                "held_out": held,
                "terms": [{"train": train, "held_out": held}],
            },
            "frames": {
                "measurement": None,
                "measured": None,
                "markers": {},
                "contacts": {chain.tool_frame: pose_dict(self.contact)},
                "world_link": None,
                "tool_link": chain.tool_frame,
                "on_robot": False,
            },
            "objects": self._objects(),
            "fit": fit_dict(orientation_weight=self.weight if any(self.kind.angular) else None),
            "model_choice": model_choice(self.selection),
            "outliers": [outlier_dict(o) for o in self.outliers],
            "compliance": self._compliance(),
            "model": {
                "mdh_nominal": mdh.rows(),
                "mdh_calibrated": self.calibrated.rows(),
                "load": None if self.load is None else self._load(),
            },
            "warnings": list(self.notes),
            "timings_ms": dict(self.timings_ms),
        }
        return build_report(fields, self._format2(), FORMAT2_MOVED)

    def _objects(self) -> dict:
        """The report's ``objects``: ``planes``, ``points`` or ``poses`` by id, in the base."""
        base = self.chain.base_frame
        return {
            f"{self.kind.object_name}s": {
                k: {"frame": base, **(pose_dict(T) or {})} for k, T in self.objects.items()
            }
        }

    def _compliance(self) -> dict:
        """Joint -> fitted compliance (0 where none was fitted)."""
        c = np.zeros(self.chain.n) if self.compliance is None else self.compliance
        return {j: float(v) for j, v in zip(self.chain.joint_names, c, strict=True)}

    def _format2(self) -> dict:
        """Format 2's keys that format 3 replaced (written until format 4)."""
        base = self.chain.base_frame
        angles = any(self.kind.angular)
        return {
            "base": base,
            "tool": self.chain.tool_frame,
            "measure": self.kind.label,
            "free": list(self.free),
            "selection": None if self.selection is None else self.selection.to_dict(),
            "tilt_weight": self.weight if angles else None,
            "contact": {
                f"{self.kind.object_name}s": {
                    k: {"frame": base, "matrix": T.tolist()} for k, T in self.objects.items()
                },
                "frames": {self.chain.tool_frame: {"matrix": self.contact.tolist()}},
            },
            "gaps": {k: v.to_dict() for k, v in self.stats.items()},
            "load": None if self.load is None else self._load(),
            "calibrated_mdh": self.calibrated.rows(),
            "notes": list(self.notes),
        }

    def _load(self) -> dict:
        """The load's record: standing, its support, the joints read off the chain."""
        if self.load is None:
            raise CalibrationRefusedError("no joint compliance was fitted: no load")
        support = self.load.support.to_dict()
        return {"kind": "standing", "support": support, "readings": list(self.readings)}

    def compliance_document(self, urdf: str) -> dict:
        """The compliance file of the calibrated URDF ``urdf`` (JSON-ready).

        :func:`calib.kinematics.elastic.load_calibrated` reads it back with the URDF.

        Raises:
            CalibrationRefusedError: No compliance was fitted.
        """
        if self.compliance is None or self.load is None:
            raise CalibrationRefusedError("no joint compliance was fitted: no compliance file")
        chain = self.chain
        g = float(np.linalg.norm(chain.model.gravity.linear))
        return {
            "format_version": COMPLIANCE_FORMAT,
            "model": "q' = q + c * tau(q): the URDF's joints see q' at commanded q; tau = gravity "
            "torques of the URDF's masses, the robot standing on the base frame (gravity along "
            "its -z; load), the joints off the chain at their recorded positions (load."
            "readings; the others at their neutral position)",
            "robot": chain.name,
            "urdf": urdf,
            "base_frame": chain.base_frame,
            "tool_frame": chain.tool_frame,
            "joints": list(chain.joint_names),
            "compliance": self.compliance.tolist(),
            "units": ["rad/(N m)" if s == 0 else "m/N" for s in chain.sigma],
            "gravity": {"frame": chain.base_frame, "vector": [0.0, 0.0, -g]},
            "load": self._load(),
            "contact": {
                "plane_id": self.plane_id,
                "frame": self.contact.tolist(),
                "plane": self.plane.tolist(),
            },
            "measurement_to_base": np.eye(4).tolist(),
            "markers": [self.contact[:3, 3].tolist()],
            "marker_links": [],
            "nominal_origins": nominal_origins(read_urdf_file(chain.urdf_path)),
            "nominal_masses": nominal_masses(read_urdf_file(chain.urdf_path)),
        }

    def summary(self) -> str:
        """The text ``calib calibrate`` prints: the gaps, compliance, parameters, verdict."""
        kind, chain = self.kind, self.chain
        ids = ", ".join(f"'{k}'" for k in self.objects)
        units = ["deg" if a else "mm" for a in kind.angular]
        lines = [
            f"{chain.name}: {chain.base_frame} -> {chain.tool_frame}, {kind.label} contact, "
            f"{kind.object_name}(s) {ids}, {len(self.free)} robot parameters fitted",
            "gaps (RMS): "
            + "  ".join(f"{n} [{u}]" for n, u in zip(kind.row_names, units, strict=True)),
        ]
        labels = {}
        for key in self.stats:
            label = key.replace("_urdf", ", URDF alone (no compliance)")
            if self.elastic and not key.endswith(("_urdf", "_registration")):
                label += ", whole model (URDF + compliance)"
            labels[key] = label
        width = max(map(len, labels.values()))
        for key, st in self.stats.items():
            values = "  ".join(f"{v:8.3f}" for v in st.rms)
            lines.append(f"  {labels[key]:{width}s} {values}  ({st.m} touches)")
        report = self.to_dict()
        if self.load is not None:
            read = f"; {len(self.readings)} joints off the chain as read" if self.readings else ""
            fitted = ", ".join(f"{k} {v:.3g}" for k, v in report["compliance"].items() if v)
            lines.append(
                f"joint compliance under gravity, standing on {chain.base_frame} "
                f"({self.load.support.label()}{read}): {fitted} [rad/(N m)]"
            )
        lines += parameter_lines(report["parameters"])
        lines += [f"note: {n}" for n in self.notes]
        lines.append("accepted" if self.accepted else f"REFUSED: {self.refusal}")
        return "\n".join(lines)

    def row_errors(self) -> RowErrors:
        """Each touch's weighted gap [mm] before and after, held-out touches marked."""
        return gap_rows(self.stats)

    def urdf(self) -> bytes:
        """The calibrated URDF (the tool frame stays the chain's tool frame)."""
        return calibrated_urdf(self.chain, self.nominal, self.calibrated)

    def compliance_files(self, out: Path) -> dict[Path, str]:
        """With fitted compliance, its file beside the URDF ``out`` (see :meth:`write`)."""
        if not self.elastic:
            return {}
        return {compliance_path(out): json_text(self.compliance_document(str(out)))}

    def write_urdf(self, path: str | Path) -> None:
        """Write the calibrated URDF (the tool frame stays the chain's tool frame).

        Raises:
            CalibrationRefusedError: The model was refused.
        """
        if self.refusal is not None:
            raise CalibrationRefusedError(f"calibration refused: {self.refusal}")
        write_calibrated_urdf(path, self.chain, self.nominal, self.calibrated)
