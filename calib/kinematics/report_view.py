"""A calibration report of any format, seen with the fields a compliance file has.

:func:`calib.kinematics.elastic.load_calibrated` (and so ``calib predict``) reads a compliance
file or a report. Format 3 reports (every shape and kind, :mod:`calib.calibration.report`)
hold the same facts under other keys: :func:`compliance_fields` maps them onto the compliance
file's (``base_frame``, ``tool_frame``, ``compliance``, ``gravity``, ``measurement_to_base``,
``markers``, ``load``, ``contact``). A format 2 report or a compliance file is returned as it
is. :func:`check_pairing` refuses a URDF other than the one a report was written with (its
``model.urdf_sha256``, :func:`urdf_digest`).
"""

from __future__ import annotations

import hashlib
import numbers

from ..exceptions import DataError, InvalidArgumentError

__all__ = ["READ_FORMATS", "STANDING_GRAVITY", "check_pairing", "compliance_fields", "urdf_digest"]

READ_FORMATS = (None, "1", "2", "3")
"""The ``format_version`` values read: reports of format 3 and 2 (or none, older), compliance
files of format 1."""

STANDING_GRAVITY = 9.81
"""Gravity [m/s^2] of a contact calibration without compliance (the robot standing on the
base frame, gravity along its -z): it enters no prediction, as every compliance is zero."""


_IDENTITY = [[float(i == j) for j in range(4)] for i in range(4)]
"""The measurement frame of a report whose instrument is in the URDF (on the robot, contacts)."""


def urdf_digest(urdf: bytes | str) -> str:
    """The SHA-256 (hex) of a URDF's bytes (text: UTF-8): a report's ``model.urdf_sha256``."""
    return hashlib.sha256(urdf.encode() if isinstance(urdf, str) else urdf).hexdigest()


def check_pairing(doc: dict, urdf: bytes, urdf_name: str, src: str) -> None:
    """Refuse a URDF whose bytes are not those the report was written with.

    A report written with its URDF (``Result.write``, ``calib calibrate``) records their
    digest in ``model.urdf_sha256``, a compliance file in ``urdf_sha256``; one without it
    (a report written alone, older, format 2) is not checked.

    Args:
        doc: The JSON document.
        urdf: The URDF's bytes.
        urdf_name: The URDF's name (its path), for the message.
        src: The document's path, for the message.

    Raises:
        DataError: The digests differ, or the recorded one is not a string.
    """
    model = doc.get("model")
    key = "model.urdf_sha256" if isinstance(model, dict) else "urdf_sha256"
    recorded = model.get("urdf_sha256") if isinstance(model, dict) else doc.get("urdf_sha256")
    if recorded is None:
        return
    if not isinstance(recorded, str):
        raise DataError(src, f"'{key}' is not a SHA-256 digest")
    if recorded != urdf_digest(urdf):
        raise DataError(
            src,
            f"written with another URDF than {urdf_name} ({key} differs: the nominal URDF, "
            f"another calibration's, or an edited copy): give the URDF written with it",
        )


def compliance_fields(
    doc: dict, src: str, tool: str | None = None, term: int | None = None
) -> dict:
    """The compliance file's fields of a report of format 3 (others: ``doc`` itself).

    A term is read as what it is: touching if it touched objects (``terms[k].objects``;
    reports without the key: if ``frames.contacts`` has its tool), else measured.

    Args:
        doc: The JSON document.
        src: Its path, for messages.
        tool: The tool frame of the term to read, in a report of several (a tree's tools,
            several terms); None: the report's one term (or ``term``'s).
        term: The index of the term to read in ``terms`` (from 0), or None: ``tool``'s.

    Raises:
        DataError: A ``format_version`` not in :data:`READ_FORMATS`, a refused
            calibration's report, a ``tool`` none of its terms (or its one chain) has, or
            two that predict points (choose by ``term``), a ``term`` not in ``terms`` or of
            another tool, a report of several terms without ``tool`` or ``term``, a camera's
            term, or a format 3 report whose ``terms`` or ``frames`` are malformed.
        InvalidArgumentError: A ``term`` that is no integer (a bool, a text, a float).
    """
    if term is not None:  # a Python or NumPy integer (np.argmax's)
        if isinstance(term, bool) or not isinstance(term, numbers.Integral):
            raise InvalidArgumentError(f"term must be a term's index (from 0), got {term!r:.60}")
        term = int(term)
    version = doc.get("format_version")
    if version not in READ_FORMATS:
        raise DataError(
            src,
            f"format_version {version!r} is not one this calib reads (reports 2 and 3, "
            f"compliance files 1): written by a newer calib?",
        )
    if doc.get("accepted") is False:
        raise DataError(
            src,
            f"the report of a refused calibration ({doc.get('refusal')}): calib wrote no URDF "
            f"for it, and its frames belong to no written model",
        )
    if version != "3":  # a format 2 report or a compliance file: one chain
        if term not in (None, 0):
            raise DataError(src, f"one chain's file: it has no term {term}")
        if tool not in (None, doc.get("tool_frame")):
            raise DataError(src, f"its chain's tool is {doc.get('tool_frame')}, not {tool}")
        return doc
    terms, frames = doc.get("terms"), doc.get("frames")
    if not (isinstance(terms, list) and terms and all(isinstance(t, dict) for t in terms)):
        raise DataError(src, "'terms' is not a list of terms")
    if not isinstance(frames, dict):
        raise DataError(src, "'frames' is missing or not {measurement, markers, ...}")
    chosen, several = _term(terms, tool, term, src), len(terms) > 1
    found = doc.get("model")
    model: dict = found if isinstance(found, dict) else {}
    out = {
        "urdf": doc.get("urdf"),
        "base_frame": chosen.get("base"),
        "tool_frame": (None if several else frames.get("tool_link")) or chosen.get("tool"),
        "compliance": None if several else doc.get("compliance"),
        "term_compliance": doc.get("compliance") if several else None,
        "load": model.get("load"),
    }
    if chosen.get("kind") == "pixels":
        raise DataError(src, f"{chosen.get('tool')}'s term is a camera's: predict reads points")
    if _touching(chosen, frames):
        return {**out, **_contact_fields(doc, frames, chosen, src)}
    return {**out, **_measured_fields(frames, chosen, model, several)}


def _term(terms: list, tool: str | None, index: int | None, src: str) -> dict:
    """The term ``index``, or of ``tool`` (the one term when both are None)."""
    names = [str(t.get("tool")) for t in terms]
    if index is not None:
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(terms):
            raise DataError(src, f"no term {index!r}: its terms are 0 to {len(terms) - 1}")
        if tool not in (None, names[index]):
            raise DataError(src, f"term {index}'s tool is {names[index]}, not {tool}")
        return terms[index]
    if tool is None and len(terms) == 1:
        return terms[0]
    if tool is None:
        raise DataError(
            src,
            f"a report of {len(terms)} terms: name the tool of one ({', '.join(names)}) or "
            "its index (term=)",
        )
    found = [k for k, n in enumerate(names) if n == tool]
    if len(found) > 1:  # a camera's term on the same tool predicts no points
        found = [k for k in found if terms[k].get("kind") != "pixels"] or found
    if len(found) > 1:
        raise DataError(
            src,
            f"terms {', '.join(map(str, found))} have the tool {tool}: choose one by its index "
            "(term=)",
        )
    if not found:
        raise DataError(src, f"no term with tool {tool!r} (the terms' tools: {', '.join(names)})")
    return terms[found[0]]


def _touching(term: dict, frames: dict) -> bool:
    """Whether a term touched objects: its own ``objects``, else (older) ``frames.contacts``."""
    objects = term.get("objects")
    if isinstance(objects, list):
        return bool(objects)
    contacts = frames.get("contacts")
    return isinstance(contacts, dict) and term.get("tool") in contacts


def _measured_fields(frames: dict, term: dict, model: dict, several: bool) -> dict:
    """A measured term's measurement frame, markers and gravity.

    In a report of several terms: its base's frame and its tool's markers, rigid unless its
    model records gravity.
    """
    measurement, markers = frames.get("measurement"), frames.get("markers")
    if several and isinstance(measurement, dict) and "matrix" not in measurement:
        measurement = measurement.get(term.get("base"))
    if several and isinstance(markers, dict):
        markers = markers.get(term.get("tool"))
    elif isinstance(markers, dict):
        markers = list(markers.values())
    standing = {"frame": term.get("base"), "vector": [0.0, 0.0, -STANDING_GRAVITY]}
    return {
        "gravity": model.get("gravity") or (standing if several else None),
        "measurement_to_base": _IDENTITY if frames.get("on_robot") else measurement,
        "markers": markers,
    }


def _contact_fields(doc: dict, frames: dict, term: dict, src: str) -> dict:
    """A contact term's contact frame, its first object in its base frame, no instrument.

    The term's objects are its own (``terms[k].objects``: ``<id>@<tool>`` where terms touch
    distinct objects of one id); a plane several terms share (one base) is in that base. A
    report without ``terms[k].objects``: the first object in the term's base frame.
    """
    contacts, objects = frames.get("contacts"), doc.get("objects")
    contact = contacts.get(term.get("tool")) if isinstance(contacts, dict) else None
    found = [
        o
        for g in (objects.values() if isinstance(objects, dict) else ())
        if isinstance(g, dict)
        for o in g.values()
        if isinstance(o, dict)
    ]
    if not isinstance(contact, dict) or not found:
        raise DataError(src, "'frames.contacts' or 'objects' is missing or malformed")
    base, touched = term.get("base"), term.get("objects")
    if isinstance(touched, list) and isinstance(objects, dict):  # the term's own (format 3)
        found = [
            o
            for g in objects.values()
            if isinstance(g, dict)
            for i, o in g.items()
            if i in touched and isinstance(o, dict)
        ]
    first = next((o for o in found if o.get("frame") in (None, base)), None)
    if first is None:
        raise DataError(
            src,
            f"the objects {term.get('tool')} touched are not in its base {base}'s frame: "
            f"predict the term whose base holds them",
        )
    return {
        "gravity": {"frame": term.get("base"), "vector": [0.0, 0.0, -STANDING_GRAVITY]},
        "measurement_to_base": _IDENTITY,
        "markers": [[row[3] for row in contact.get("matrix", [])[:3]]],
        "contact": {"frame": contact.get("matrix"), "plane": first.get("matrix")},
    }
