"""What every calibration result offers, whatever its shape: :class:`Result`.

:class:`RowErrors`: the error of each configuration, which ``plot`` draws.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.fileio import check_outputs, json_text, read_bytes_limited, write_files_atomic
from ..exceptions import CalibrationRefusedError, InvalidArgumentError, URDFError
from ..kinematics.origins import changed_origins, origins_document
from ..kinematics.report_view import urdf_digest
from ..kinematics.urdf_xml import MAX_URDF_BYTES
from .options import checked_arguments

__all__ = ["Result", "RowErrors", "compliance_path", "paired_files", "paired_report", "read_files"]

_NOMINAL_URDF = "the nominal URDF"  # its name among the files read (read_files)


@dataclass(frozen=True)
class RowErrors:
    """The error of each configuration, before and after calibration.

    A measured row's error is the RMS over its measured points (the report's
    ``position_rms_mm`` is the RMS of these); a touch's is its weighted gap norm (the
    report's ``weighted_mm`` is their RMS).

    Attributes:
        before: Error of the registration (nominal geometry, fitted frame, markers and
            objects) at each configuration ``(m,)`` [mm].
        after: Error of the calibrated model ``(m,)`` [mm], the same way.
        held_out: Which rows the fit never saw (``--holdout``, ``--validate``) ``(m,)``.
        term: Each row's term (index into ``names``) ``(m,)``, or None: one term.
        names: The terms' names (several terms), or empty.
    """

    before: np.ndarray
    after: np.ndarray
    held_out: np.ndarray
    term: np.ndarray | None = None
    names: tuple[str, ...] = ()

    @staticmethod
    def of(terms: list[tuple[str, Mapping]]) -> RowErrors:
        """Each term's rows (``terms``: name, statistics by part), held-out after fitted ones.

        Raises:
            InvalidArgumentError: Statistics without ``per_row`` errors.
        """
        parts = [
            (k, p, s) for k, (_, s) in enumerate(terms) for p in ("train", "held_out") if p in s
        ]
        rows = [(s[f"{p}_registration"].per_row, s[p].per_row) for _, p, s in parts]
        if any(r is None for pair in rows for r in pair):
            raise InvalidArgumentError("these statistics keep no per-row errors")
        m = [len(after) for _, after in rows]
        several = len(terms) > 1
        return RowErrors(
            np.concatenate([before for before, _ in rows]),
            np.concatenate([after for _, after in rows]),
            np.repeat([p == "held_out" for _, p, _ in parts], m),
            np.repeat([k for k, _, _ in parts], m) if several else None,
            tuple(name for name, _ in terms) if several else (),
        )

    def series(self) -> list[tuple[str, np.ndarray]]:
        """``(term name, row mask)`` of each term (one with an empty name for one term)."""
        if self.term is None:
            return [("", np.ones(len(self.after), dtype=bool))]
        return [(name, self.term == k) for k, name in enumerate(self.names)]


def compliance_path(out: Path) -> Path:
    """The compliance file written next to the URDF ``out``: ``<stem>.compliance.json``."""
    return out.with_name((out.stem if out.suffix == ".urdf" else out.name) + ".compliance.json")


def paired_report(doc: dict, urdf: bytes | str) -> dict:
    """The report written with the URDF ``urdf``: its digest in ``model.urdf_sha256``."""
    return {**doc, "model": {**doc["model"], "urdf_sha256": urdf_digest(urdf)}}


def read_files(
    robots: Sequence, data: Sequence, validate: Sequence | None = None
) -> tuple[tuple[str, str], ...]:
    """The files a calibration read, by what they are: what :meth:`Result.write` never overwrites.

    Each as resolved when read (absolute, links followed), else as named (``source``).
    """
    found = [(_NOMINAL_URDF, str(robots[0].urdf_resolved))]
    held = [None] * len(data) if validate is None else validate
    for k, (d, v) in enumerate(zip(data, held, strict=True), start=1):
        for what, given in zip(_term_files(k), (d, v), strict=True):
            parts = [] if given is None else [(what, getattr(given, "obs", given))]
            if given is not None and hasattr(given, "target"):  # a camera's pixels
                parts += [
                    (f"the target of term {k}", given.target),
                    (f"the intrinsics of term {k}", given.camera.intrinsics),
                ]
            found += [(name, part.path or part.source) for name, part in parts]
    return tuple(found)


def _term_files(k: int) -> tuple[str, str]:
    """The names of term ``k``'s data and validation data among the files read."""
    return f"the data of term {k}", f"the validation data of term {k}"


def _file_path(what: str, path: object) -> Path:
    """``path`` as a Path: InvalidArgumentError if it is not a file path."""
    if not isinstance(path, str | os.PathLike):
        raise InvalidArgumentError(f"{what} must be a file path, got {path!r:.60}")
    return Path(path)


def paired_files(files: Mapping[Path, str | bytes], out: Path) -> dict[Path, str | bytes]:
    """The files written with the URDF ``out``: its compliance file, if any, with its digest."""
    comp = compliance_path(out)
    if comp not in files:
        return dict(files)
    doc = json.loads(files[comp])
    return {**files, comp: json_text({**doc, "urdf_sha256": urdf_digest(files[out])})}


class Result:
    """A calibration's result, whatever the problem (:func:`~calib.calibrate`).

    A result (a chain measured by an instrument, a tree, one chain touching, several terms)
    provides ``to_dict``, ``urdf``, ``summary``, ``refusal``, ``compliance_files`` and
    ``row_errors``; ``write`` writes the URDF, its compliance file and the report at once
    (complete or not at all, never over an input).
    """

    refusal: str | None
    inputs: tuple[tuple[str, str], ...]
    """The files it read, by what they are (:func:`!read_files`); empty: those its report
    names."""

    def to_dict(self) -> dict:
        """The JSON report (format 3)."""
        raise NotImplementedError

    def urdf(self) -> bytes:
        """The calibrated URDF."""
        raise NotImplementedError

    def summary(self) -> str:
        """The text ``calib calibrate`` prints."""
        raise NotImplementedError

    def compliance_files(self, out: Path, on_robot: bool = False) -> dict[Path, str]:
        """Files written beside the URDF ``out`` (``on_robot``: the instrument in the URDF)."""
        raise NotImplementedError

    def row_errors(self) -> RowErrors:
        """The error of each configuration before and after calibration, held-out rows marked."""
        raise NotImplementedError

    @checked_arguments
    def plot(self):
        """A matplotlib Figure: errors per configuration before and after, and the parameters.

        See :func:`!calib.outputs.plots.calibration_figure` (needs matplotlib).
        """
        from ..outputs.plots import calibration_figure  # the one upward import (pyproject)

        return calibration_figure(self)

    @checked_arguments
    def origins(self, urdf: bytes | None = None) -> dict:
        """The joint origins the calibration moved or added, with the nominal ones beside them.

        What a xacro file reads (``xacro.load_yaml``) to carry the calibration into the
        robot's own description: ``joints`` maps each joint whose origin changed (and each
        joint the calibration added: markers, a camera, the world link) to its ``parent``,
        ``child``, calibrated ``xyz`` [m] and ``rpy`` [rad] as the calibrated URDF writes them,
        ``nominal_xyz`` and ``nominal_rpy`` (None for an added joint) and ``added``
        (:func:`!calib.kinematics.origins.origins_yaml` writes it as YAML).

        Args:
            urdf: The calibrated URDF they are read from (default: :meth:`urdf`; give a
                chain's ``result.urdf(world_link=...)`` to include its world link).

        Raises:
            CalibrationRefusedError: The model was refused.
            URDFError: The nominal URDF cannot be read.
        """
        self._accepted()
        doc = self.to_dict()
        read = dict(self.inputs).get(_NOMINAL_URDF, doc["urdf"])  # the file loaded
        try:
            nominal = read_bytes_limited(read, MAX_URDF_BYTES)
        except OSError as exc:
            raise URDFError(str(doc["urdf"]), f"cannot read: {exc.strerror or exc}") from None
        calibrated = self.urdf() if urdf is None else urdf
        return origins_document(
            doc["robot"], str(doc["urdf"]), changed_origins(nominal, calibrated)
        )

    @checked_arguments
    def write(self, out: str | Path, report: str | Path | None = None) -> None:
        """Write the calibrated URDF (and compliance file) and the report, all or none.

        A refused model writes the report only, then raises. The report and the compliance
        file record the URDF's digest (:func:`!paired_report`, :func:`!paired_files`). The
        outputs are checked before anything is written: never an input (the nominal URDF,
        each term's data and validation file, a pixel term's target and intrinsics:
        :attr:`inputs`, as resolved when they were read), never two the same.

        Args:
            out: The calibrated URDF to write.
            report: The JSON report to write, or None.

        Raises:
            CalibrationRefusedError: The model was refused (only the report is written).
            InvalidArgumentError: A path is not a path, or is an input.
            OutputError: A file cannot be written.
        """
        out = _file_path("out", out)
        report = None if report is None else _file_path("report", report)
        doc = self.to_dict()
        extra = {} if self.refusal is not None else self.compliance_files(out)
        outputs = {"out": out, "report": report, **{str(p): p for p in extra}}
        check_outputs(outputs, self._read(doc))
        urdf = None if self.refusal is not None else self.urdf()
        files = {} if urdf is None else paired_files({out: urdf, **extra}, out)
        if report is not None:
            files[report] = json_text(doc if urdf is None else paired_report(doc, urdf))
        write_files_atomic(files)
        self._accepted()

    @checked_arguments
    def write_urdf(self, path: str | Path) -> None:
        """Write :meth:`urdf` atomically (never over a file it read: :attr:`inputs`).

        Raises:
            CalibrationRefusedError: The model was refused.
            InvalidArgumentError: ``path`` is not a file path, or is an input.
        """
        urdf = self.urdf()
        path = _file_path("path", path)
        check_outputs({"path": path}, self._read())
        write_files_atomic({path: urdf})

    def _read(self, doc: dict | None = None) -> dict[str, str | None]:
        """The files it read: :attr:`inputs`, else those its report names."""
        return dict(self.inputs) if self.inputs else _inputs(doc or self.to_dict())

    def _verdict(self) -> str:
        return "accepted" if self.refusal is None else f"REFUSED: {self.refusal}"

    def _accepted(self) -> None:
        if self.refusal is not None:
            raise CalibrationRefusedError(f"calibration refused: {self.refusal}")

    def __repr__(self) -> str:
        doc = self.to_dict()
        terms = doc["terms"]
        what = ", ".join(f"{t['base']} -> {t['tool']} ({t['kind']})" for t in terms[:2])
        what += f" and {len(terms) - 2} more" if len(terms) > 2 else ""
        return (
            f"<{type(self).__name__} {doc['robot']} {doc['shape']}: {what}, "
            f"{len(doc['parameters'])} parameters, {self._verdict()}>"
        )


def _inputs(doc: dict) -> dict[str, str | None]:
    """The files a report names as read: the nominal URDF, each term's data and validation."""
    found: dict[str, str | None] = {_NOMINAL_URDF: doc.get("urdf")}
    for k, term in enumerate(doc["terms"], start=1):
        found[_term_files(k)[0]] = term.get("data")
    for k, errors in enumerate(doc["errors"].get("terms") or [], start=1):
        found[_term_files(k)[1]] = (errors.get("held_out") or {}).get("source")
    return found
