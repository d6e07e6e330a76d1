"""A calibration report of any format, seen with the fields a compliance file has.

:func:`calib.kinematics.elastic.load_calibrated` (and so ``calib predict``) reads a compliance
file or a report. Format 3 reports (every shape and kind, :mod:`calib.calibration.report`)
hold the same facts under other keys: :func:`compliance_fields` maps them onto the compliance
file's (``base_frame``, ``tool_frame``, ``compliance``, ``gravity``, ``measurement_to_base``,
``markers``, ``load``, ``contact``). A format 2 report or a compliance file is returned as it
is.
"""

from __future__ import annotations

from ..exceptions import DataError

__all__ = ["STANDING_GRAVITY", "compliance_fields"]

STANDING_GRAVITY = 9.81
"""Gravity [m/s^2] of a contact calibration without compliance (the robot standing on the
base frame, gravity along its -z): it enters no prediction, as every compliance is zero."""


_IDENTITY = [[float(i == j) for j in range(4)] for i in range(4)]
"""The measurement frame of a report whose instrument is in the URDF (on the robot, contacts)."""


def compliance_fields(doc: dict, src: str) -> dict:
    """The compliance file's fields of a report of format 3 (others: ``doc`` itself).

    Args:
        doc: The JSON document.
        src: Its path, for messages.

    Raises:
        DataError: A report of a tree or of several chains (one URDF, no chain to predict
            along), or a format 3 report whose ``terms`` or ``frames`` are malformed.
    """
    if doc.get("format_version") != "3":
        return doc
    shape = doc.get("shape")
    terms = doc.get("terms")
    if shape in ("tree", "chains"):
        raise DataError(
            src,
            f"a report of {'a tree' if shape == 'tree' else 'several chains'}: the calibrated "
            f"URDF is the whole model (load it with Pinocchio); calib predict and "
            f"load_calibrated take the report of one chain",
        )
    frames = doc.get("frames")
    if not (isinstance(terms, list) and len(terms) == 1 and isinstance(terms[0], dict)):
        raise DataError(src, "'terms' is not a list of one chain's term")
    if not isinstance(frames, dict):
        raise DataError(src, "'frames' is missing or not {measurement, markers, ...}")
    term, model = terms[0], doc.get("model")
    model = model if isinstance(model, dict) else {}
    out = {
        "urdf": doc.get("urdf"),
        "base_frame": term.get("base"),
        "tool_frame": frames.get("tool_link") or term.get("tool"),
        "compliance": doc.get("compliance"),
        "load": model.get("load"),
    }
    if shape == "contacts":
        return {**out, **_contact_fields(doc, frames, term, src)}
    markers = frames.get("markers")
    return {
        **out,
        "gravity": model.get("gravity"),
        "measurement_to_base": _IDENTITY if frames.get("on_robot") else frames.get("measurement"),
        "markers": list(markers.values()) if isinstance(markers, dict) else markers,
    }


def _contact_fields(doc: dict, frames: dict, term: dict, src: str) -> dict:
    """A contact report's contact frame and first object, the identity for the instrument."""
    contacts, objects = frames.get("contacts"), doc.get("objects")
    contact = contacts.get(term.get("tool")) if isinstance(contacts, dict) else None
    first = None
    if isinstance(objects, dict):
        groups = [g for g in objects.values() if isinstance(g, dict) and g]
        first = next(iter(groups[0].values())) if groups else None
    if not isinstance(contact, dict) or not isinstance(first, dict):
        raise DataError(src, "'frames.contacts' or 'objects' is missing or malformed")
    return {
        "gravity": {"frame": term.get("base"), "vector": [0.0, 0.0, -STANDING_GRAVITY]},
        "measurement_to_base": _IDENTITY,
        "markers": [[row[3] for row in contact.get("matrix", [])[:3]]],
        "contact": {"frame": contact.get("matrix"), "plane": first.get("matrix")},
    }
