"""The result of every calibration (one robot, one URDF), and a chain touching's part of it.

One term keeps its shape's report layout (``contacts`` here, a chain's: :mod:`.measured_report`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import ClassVar, TypeVar

import numpy as np
from scipy.linalg import block_diag

from ..core.fileio import json_text
from ..core.words import counted
from ..exceptions import CalibrationRefusedError, InvalidArgumentError
from ..identification.contacts import Contact, PlaneContact
from ..kinematics.elastic import compliance_document as chain_compliance_document
from ..kinematics.mdh import MDHModel, in_chart_of
from ..kinematics.placement_export import camera_urdf, marker_urdf, moved_origins_urdf
from ..kinematics.robot import Chain
from ..kinematics.standing import StandingLoad
from .contact_elastic import compliance_document, compliance_line, load_record
from .contact_result import GapStats, TermPart, units
from .delivery import Result, RowErrors, compliance_path
from .instrument import instrument_errors, instrument_format2, instrument_lines
from .measured_report import chain_lines, chain_report, chain_writing
from .measured_view import ChainView, MeasuredChain, Solution, world_of
from .options import checked_arguments
from .outliers import Outlier
from .pixel_chain_result import PixelChain
from .placements import Placements
from .report import (
    build_report,
    fit_dict,
    fold_lines,
    model_choice,
    one_term,
    outlier_dict,
    parameter_entries,
    parameter_lines,
    pose_dict,
    selection_dict,
    with_folds,
)
from .selection import Selection

__all__ = ["ChainContacts", "ContactChainsCalibration", "nothing_fitted"]

_T = TypeVar("_T")


@dataclass(frozen=True, eq=False)
class ChainContacts(TermPart):
    """One chain touching's part of the result (besides :class:`~.contact_result.TermPart`'s).

    Attributes:
        plane_id, plane: The first object's id and pose in the base frame ``(4, 4)`` (a
            plane's z: its normal; a ``fixed-pose`` chain's: the pose of its contact frame).
        contact: The contact frame in the tool frame ``(4, 4)``.
        nominal, calibrated: The chain's MDH model, nominal and on the calibrated robot.
        weight: Weight of its tilt rows [m/rad].
        outliers: Its touches set aside after its registration.
        placed: Each object in the base frame ``(4, 4)`` by id, as reported (a plane's
            origin at its touches' contact points, projected).
        load: The gravity load the compliance acts under, or None.
        readings: The joints off the chain the load takes at their recorded positions.
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
    kind: Contact
    placed: dict[str, np.ndarray]
    held_source: str | None = None
    held_rows: tuple[int, ...] | None = None
    outliers: tuple[Outlier, ...] = ()
    compliance: np.ndarray | None = None
    load: StandingLoad | None = None
    readings: tuple[str, ...] = ()

    def objects(self) -> dict[str, np.ndarray]:
        """Each object (a plane, a point, a pose) in the base frame ``(4, 4)``, by id."""
        return {i: F.copy() for i, F in self.placed.items()}

    rows: ClassVar[str] = "touches"

    def heading(self) -> str:
        """Its objects (the planes, points or poses it touches) and its gaps' units."""
        ids = ", ".join(f"'{i}'" for i in self.objects())
        return f"{self.kind.object_name} {ids} (gaps: {units(self.kind)}):"

    def _own(self) -> dict:
        """Its weight, contact (objects and contact frame) and gaps (mm, degrees)."""
        return {
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


def _single_contact_report(result, fields: dict) -> tuple[dict, dict]:
    """One chain touching's report fields (a copy of ``fields``) and format 2's keys."""
    part = result.chains[0]
    chain, weight = part.chain, part.weight if any(part.kind.angular) else None
    errors, load = part.errors(), load_record(part)
    fields = one_term(
        fields,
        errors,
        chain,
        part.compliance,
        shape="contacts",
        frames={**fields["frames"], "tool_link": chain.tool_frame},
        fit=fit_dict(orientation_weight=weight),
        model={
            **fields["model"],
            "mdh_nominal": part.nominal.rows(),
            "mdh_calibrated": in_chart_of(part.calibrated, part.nominal).rows(),
            "load": load,
        },
    )
    own = part.to_dict()  # format 2's chain entry: its contact and gaps as they were
    legacy = {
        "base": chain.base_frame,
        "tool": chain.tool_frame,
        "measure": part.kind.label,
        "free": list(result.free),
        "selection": selection_dict(result.selection),
        "tilt_weight": weight,
        "contact": own["contact"],
        "gaps": own["gaps"],
        "load": load,
        "calibrated_mdh": fields["model"]["mdh_calibrated"],
        "notes": list(result.notes),
    }
    return fields, legacy


@dataclass(frozen=True, eq=False, repr=False)
class ContactChainsCalibration(Result, ChainView):
    """Every calibration's result: a chain measured, a tree, contacts, pixels, several terms.

    Attributes:
        chains: Each chain's part, in the order given.
        placements: The fitted joint placement errors (one per URDF joint on any chain).
        shared: Joints on two chains or more (fitted once for all of them).
        planes: The touching chains' sets of objects: one per chain, a plane shared by chains
            once (format 2's ``planes``; the summary counts the objects themselves).
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
        unknowns: The unknowns the data determine at the nominal robot: the objects',
            contacts' and measured terms' own, and the joint placement directions ``free``.
        shape: The problem's (``Problem.shape``): ``chain``, ``tree`` (a tree's tools
            measured by one instrument: :mod:`!instrument`), ``contacts`` (one chain
            touching) or ``chains``.
        identifiable: What the data determine whatever the parameters offered: the rank of
            the rows' Jacobian by every unknown and joint placement component, at the nominal
            robot (``unknowns`` at ``complete`` may miss combinations of shared joints).
        inputs: The files it read (:func:`!delivery.read_files`), which ``write`` never
            overwrites; empty: those the report names.
        stalled: A fit made did not converge (the last, or one ``auto`` held a parameter
            after): the outlier loop reads no outliers from its errors.
        folds: Cross-validated (:func:`calib.cross_validate`): each fold's
            held-out errors, term by term ``(registration, calibrated)``; empty: not.
    """

    chains: tuple[ChainContacts | MeasuredChain | PixelChain, ...]
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
    unknowns: int = 0
    identifiable: int = 0
    shape: str = "chains"
    solution: Solution | None = None
    inputs: tuple[tuple[str, str], ...] = ()
    stalled: bool = False
    folds: tuple[tuple[tuple[GapStats, GapStats], ...], ...] = ()

    @property
    def accepted(self) -> bool:
        """The model may be used (not refused)."""
        return self.refusal is None

    @property
    def elastic(self) -> bool:
        """Joint compliance was fitted (one chain touching): the URDF alone is not the model."""
        return any(c.compliance is not None for c in self.chains)

    @checked_arguments
    def compliance_files(self, out: Path, on_robot: bool = False) -> dict[Path, str]:
        """With fitted compliance, its file beside the URDF ``out`` (``<stem>.compliance.json``).

        One chain measured: the file of the URDF :meth:`urdf` writes (its calibrated tool,
        markers and measurement frame; ``on_robot``: the instrument in the URDF).
        """
        if not self.elastic:
            return {}
        part = self.chains[0]
        if isinstance(part, MeasuredChain):
            frame = np.eye(4) if on_robot else self.measurement_to_base
            document = chain_compliance_document(
                self.chain,
                self.state.compliance,
                str(out),
                tool_frame=self.urdf_tool_frame,
                measured=(frame, self.urdf_markers, self.marker_links),
            )
        else:
            document = compliance_document(part, str(out))
        return {compliance_path(out): json_text(document)}

    def entries(self) -> list[dict]:
        """``fitted``'s report entries with their joints (one chain: as its MDH rows name them)."""
        part, sigma = self.chains[0], None
        if len(self.chains) == 1 and isinstance(part, ChainContacts | MeasuredChain):
            nominal = part.nominal if isinstance(part, ChainContacts) else part.registered.inner.mdh
            names, sigma = tuple(nominal.joint_names), nominal.sigma
        else:
            names = tuple(part.chain.model.names)
        return parameter_entries(self.fitted, self.estimate, self.std, names, sigma)

    def check(self) -> ContactChainsCalibration:
        """Return self if accepted, else raise :class:`CalibrationRefusedError`."""
        if self.refusal is not None:
            raise CalibrationRefusedError(self.refusal)
        return self

    @property
    def stats(self) -> dict[str, GapStats]:
        """A fit of one term: its errors (``chains[0].stats``; a single chain's ``stats``).

        Raises:
            InvalidArgumentError: Several terms: each has its own (``chains[k].stats``).
        """
        if len(self.chains) != 1:
            raise InvalidArgumentError(
                f"a fit of {len(self.chains)} terms: each term's errors are chains[k].stats"
            )
        return self.chains[0].stats

    def joint_errors(self) -> dict[str, np.ndarray]:
        """``E_j`` ``(4, 4)`` of every joint that moved (the new origin is ``O_j E_j``).

        A measured term's measuring frame moves its fixed joint (:class:`MeasuredChain`): its
        ``E`` is the inverse of the base frame's pose in the measuring frame.
        """
        out = self.placements.errors()
        for c in self._of(MeasuredChain):
            if c.joint is not None:
                out[c.joint] = np.linalg.inv(c.state.inner.frame)
        return out

    def _of(self, kind: type[_T]) -> tuple[_T, ...]:
        """The terms of one kind."""
        return tuple(c for c in self.chains if isinstance(c, kind))

    def _instrument(self) -> tuple[MeasuredChain, ...]:
        """The terms measured by an instrument outside the robot (a tree's tools)."""
        return tuple(c for c in self._of(MeasuredChain) if c.joint is None)

    def _frames(self) -> dict:
        """The report's ``frames``: contact frames, measuring frames' placements, ``cameras``."""
        measured = self._of(MeasuredChain)
        cameras = {c.name: c.camera_dict() for c in self._of(PixelChain)}
        return {
            "measurement": {c.chain.base_frame: pose_dict(c.state.inner.frame) for c in measured}
            or None,
            "measured": {
                c.chain.tool_frame: pose_dict(block_diag(c.state.inner.tool_rotation, 1.0))
                for c in measured
                if c.state.inner.tool_rotation is not None
            }
            or None,
            "markers": {c.chain.tool_frame: c.state.inner.markers.tolist() for c in measured},
            "contacts": {c.chain.tool_frame: pose_dict(c.contact) for c in self._of(ChainContacts)},
            "world_link": None,
            "tool_link": None,
            "on_robot": any(c.joint is not None for c in measured) or bool(cameras),
            "cameras": cameras,
        }

    @checked_arguments
    def to_dict(self, world_link: str | None = None, on_robot: bool = False) -> dict:
        """The JSON report (format 3, :mod:`calib.calibration.report`).

        ``errors.train`` and ``errors.held_out``: the one term's, or the instrument's terms'
        together (a tree's tools), else None (each term's: ``errors.terms``). One chain
        measured by an instrument or touching: the single chain's layout (``frames``,
        ``compliance``, ``model``, ``fit``).

        Args:
            world_link: The ``world_link`` the URDF was written with (None: none).
            on_robot: The URDF was written with the instrument on the robot (one chain: its
                base frame's placement calibrated, ``frames.measurement`` is in the URDF).

        Raises:
            InvalidArgumentError: ``world_link`` or ``on_robot`` for another shape, or both.
        """
        frame = self._frame()
        world_of(self.shape, frame, world_link, on_robot)
        origins = {n: pose_dict(E) for n, E in self.joint_errors().items()}
        fields = self._fields(origins)
        if frame is not None:  # one chain measured by an instrument
            fields, legacy = chain_report(self, fields, world_link, on_robot)
        elif self.shape == "contacts":
            fields, legacy = _single_contact_report(self, fields)
        else:
            legacy = self._format2(origins)
        return with_folds(build_report(fields, legacy), self.folds)

    def _fields(self, origins: dict) -> dict:
        """The report's fields of every shape (``origins``: ``model.joint_origins``)."""
        first = self.chains[0].chain
        solver = self.solver
        names = self._object_names()
        return {
            "robot": first.name,
            "urdf": str(first.urdf_path),
            "shape": self.shape,
            "terms": [
                {
                    "base": c.chain.base_frame,
                    "tool": c.chain.tool_frame,
                    "kind": c.kind.label,
                    "data": c.source,
                    "configs": int(c.configs()),
                    "objects": list(names.get(id(c), {}).values()),
                }
                for c in self.chains
            ],
            "params": self.params,
            "accepted": self.refusal is None,
            "refusal": self.refusal,
            "converged": bool(solver[0]),
            "message": solver[1],
            "iterations": int(solver[2]),
            "parameters": [
                *{p["name"]: p for c in self._of(MeasuredChain) for p in c.parameters}.values(),
                *(p for c in self._of(PixelChain) for p in c.parameters),
                *self.entries(),
            ],
            "errors": {
                **instrument_errors(self._instrument()),
                "terms": [c.errors() for c in self.chains],
            },
            "frames": self._frames(),
            "objects": self._object_poses(names),
            "fit": fit_dict(),
            "model_choice": model_choice(self.selection),
            "outliers": [
                outlier_dict(o, term) for term, c in enumerate(self.chains) for o in c.outliers
            ],
            "compliance": {},
            "model": {"joint_origins": origins, "shared_joints": list(self.shared)},
            "warnings": list(self.notes),
            "timings_ms": dict(self.timings_ms),
        }

    def _object_names(self) -> dict[int, dict[str, str]]:
        """Each touching term's objects' names in the report, by term (``id``) and object id.

        Distinct objects of one id (each arm its own ``table``) are ``<id>@<tool>``
        (``@<base>-><tool>`` where terms share their tool); a plane shared keeps its id.
        """
        parts = self._of(ChainContacts)
        seen = [(c, i, F) for c in parts for i, F in c.objects().items()]

        def one(a, b) -> bool:  # one object: a shared plane (same base, normal and offset)
            (c, _, F), (d, _, G) = a, b
            planes = isinstance(c.kind, PlaneContact) and isinstance(d.kind, PlaneContact)
            return (
                planes
                and c.chain.base_frame == d.chain.base_frame
                and np.allclose(F[:3, 2], G[:3, 2], rtol=0.0, atol=1e-12)
                and abs(F[:3, 2] @ (F[:3, 3] - G[:3, 3])) <= 1e-12
            )

        names: dict[int, dict[str, str]] = {}
        for a in seen:
            c, i, _ = a
            others = [b[0].chain for b in seen if b[1] == i and b is not a and not one(a, b)]
            tool = c.chain.tool_frame
            own = (
                f"{c.chain.base_frame}->{tool}" if tool in {o.tool_frame for o in others} else tool
            )
            names.setdefault(id(c), {})[i] = f"{i}@{own}" if others else i
        return names

    def _object_poses(self, names: dict[int, dict[str, str]]) -> dict:
        """Planes and poses by name, each in its chain's base frame (format 3's ``objects``)."""
        out: dict[str, dict] = {}
        for c in self._of(ChainContacts):
            group = out.setdefault(f"{c.kind.object_name}s", {})
            for i, F in c.objects().items():
                group[names[id(c)][i]] = {"frame": c.chain.base_frame, **(pose_dict(F) or {})}
        return out

    def _format2(self, origins: dict) -> dict:
        """Format 2's keys that format 3 replaced."""
        if self.shape == "tree":  # a tree's own keys of format 2
            return instrument_format2(self._instrument())
        return {
            "measure": "plane",
            "chains": [c.to_dict() for c in self.chains],
            "shared_joints": list(self.shared),
            "planes": self.planes,
            "free": list(self.free),
            "selection": selection_dict(self.selection),
            "joint_origins": origins,
            "notes": list(self.notes),
        }

    def _headline(self) -> str:
        """The summary's first line: the chains, the objects by kind, what is fitted, determined."""
        names = self._object_names()
        objects: dict[str, set[str]] = {}
        for c in self._of(ChainContacts):
            objects.setdefault(c.kind.object_name, set()).update(names[id(c)].values())
        measured, cameras = len(self._of(MeasuredChain)), len(self._of(PixelChain))
        parts = [counted(len(self.chains), "chains")]
        parts += [counted(len(ids), f"{kind}s") for kind, ids in objects.items()]
        parts += [counted(measured, "measured terms")] if measured else []
        parts += [counted(cameras, "cameras")] if cameras else []
        parts += [f"{counted(len(self.free), 'joint placement components')} fitted"]
        parts += [f"{counted(self.unknowns, 'unknowns')} determined"]
        shared = f" (shared joints: {', '.join(self.shared)})" if self.shared else ""
        return f"{self.chains[0].chain.name}: {', '.join(parts)}{shared}"

    @checked_arguments
    def summary(self) -> str:
        """A terminal summary: each chain's gaps, then the shared joints."""
        lines = [self._headline()]
        one = self._frame() is not None  # one chain measured by an instrument: a chain's table
        lines += [line for c in (() if one else self.chains) for line in c.lines()]
        lines += chain_lines(self) if one else instrument_lines(self._instrument())
        lines += [line for c in self._of(ChainContacts) for line in compliance_line(c)]
        lines += parameter_lines(self.entries())
        lines += [f"note: {n}" for n in self.notes]
        lines += fold_lines(self.folds, self.chains)
        lines.append(self._verdict())
        return "\n".join(lines)

    @checked_arguments
    def row_errors(self) -> RowErrors:
        """Each term's rows before and after [mm] (touches: weighted gaps), term after term."""
        return RowErrors.of(
            [
                (f"{k + 1}: {c.chain.tool_frame} ({c.kind.label})", c.stats)
                for k, c in enumerate(self.chains)
            ]
        )

    def _frame(self) -> np.ndarray | None:
        """One chain measured by an instrument: :attr:`measurement_to_base`; else None."""
        try:
            return self.measurement_to_base
        except InvalidArgumentError:
            return None

    @checked_arguments
    def urdf(self, world_link: str | None = None, on_robot: bool = False) -> bytes:
        """The calibrated URDF of the whole robot (the joint origins moved).

        Args:
            world_link: One chain measured by an instrument: add the instrument frame as
                this root link (None: not added).
            on_robot: One chain measured by an instrument on the robot (a head camera): its
                fitted placement is written into the base frame's fixed joint.

        Raises:
            CalibrationRefusedError: The model was refused.
            InvalidArgumentError: ``world_link`` or ``on_robot`` for another shape, or both.
            CalibError: ``on_robot`` with a base frame not fixed to a link by a fixed joint.
        """
        frame = self._frame()
        world = world_of(self.shape, frame, world_link, on_robot)
        self._accepted()
        robot, errors = self.chains[0].chain, self.joint_errors()
        cameras = {  # each camera once: name, link, optical frame in the link (4, 4) [m]
            c.name: (c.name, c.chain.base_frame, c.state.camera) for c in self._of(PixelChain)
        }
        if cameras:
            return camera_urdf(robot, errors, tuple(cameras.values()))
        if frame is not None:  # one chain: its calibrated tool, its markers on it
            errors, marks, tool = chain_writing(self.one_chain(), errors, on_robot)
            return marker_urdf(robot, errors, marks, tool, world)
        if self._instrument():  # each tool's markers as links (a tree's)
            marks = tuple((c.chain, c.state.inner.markers) for c in self._instrument())
            return marker_urdf(robot, errors, marks, None, world)
        return moved_origins_urdf(robot, errors)


def nothing_fitted(result: ContactChainsCalibration, fixed: bool) -> str | None:
    """The note of an accepted fit that moved no joint placement (``frames`` not asked), or None.

    ``fixed``: ``fix`` named some.
    """
    if result.free or result.elastic or result.params == "frames" or not result.accepted:
        return None
    auto = result.params == "auto"
    why = (
        "params 'auto' kept none (the data support none over the registration alone)"
        if auto
        else f"params '{result.params}'{' with fix' if fixed else ''} left none to fit"
    )
    frames = []
    for part in result._of(MeasuredChain):
        where = f"in its fixed joint {part.joint}" if part.joint else "with world_link"
        frames.append(f"the markers as links on the tool, the measurement frame {where}")
    if result._of(PixelChain):
        frames.append("the cameras' placements")
    added = "; ".join(dict.fromkeys(frames))
    urdf = f"with only the registered frames added ({added})" if frames else "as is"
    hint = (
        "measure more or more varied postures (auto keeps what held-out errors support); "
        "params='complete' fits every parameter the data determine, noise included (check it "
        "on rows it did not see: folds)"
        if auto
        else "name fewer parameters in fix"
        if fixed
        else "measure postures that determine some"
    )
    return (
        f"no joint placement was fitted: {why}; the URDF written is the nominal robot's {urdf}; "
        f"if you expected a fit, {hint}"
    )
