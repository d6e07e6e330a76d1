"""The report of one chain touching (shape ``contacts``): the single chain's layout.

A joint fit of one contact term keeps the layout users' scripts, ``calib predict`` and
``load_calibrated`` read for one chain touching (:func:`single_contact_report`).
"""

from __future__ import annotations

from .contact_elastic import load_record
from .report import compliance_dict, fit_dict

__all__ = ["single_contact_report"]


def single_contact_report(part, fields: dict, legacy: dict) -> tuple[dict, dict]:
    """The report's fields and format 2's keys of one contact term's fit.

    Its own: ``shape`` ``contacts``, the term's errors as ``errors.train`` and
    ``errors.held_out``, ``frames.tool_link``, the angle rows' weight under ``fit``, each
    joint's compliance (0 where none was fitted) and its load, the chain's MDH rows under
    ``model``, and format 2's keys of a contact report.

    Args:
        part: The term's :class:`~.contact_chains_result.ChainContacts`.
        fields: The joint fit's format-3 fields (:data:`~.report.REPORT_KEYS`).
        legacy: Its format 2's keys.

    Returns:
        The fields and format 2's keys of the single chain's layout.
    """
    chain, kind = part.chain, part.kind
    errors, load = part.errors(), load_record(part)
    angles = any(kind.angular)
    fields = {
        **fields,
        "shape": "contacts",
        "errors": {**errors, "terms": [errors]},
        "frames": {**fields["frames"], "tool_link": chain.tool_frame},
        "fit": fit_dict(orientation_weight=part.weight if angles else None),
        "compliance": compliance_dict(chain, part.compliance),
        "model": {
            **fields["model"],
            "mdh_nominal": part.nominal.rows(),
            "mdh_calibrated": part.calibrated.rows(),
            "load": load,
        },
    }
    own = part.to_dict()  # format 2's chain entry: its contact and gaps as they were
    legacy = {
        "base": chain.base_frame,
        "tool": chain.tool_frame,
        "measure": kind.label,
        "free": legacy["free"],
        "selection": legacy["selection"],
        "tilt_weight": part.weight if angles else None,
        "contact": own["contact"],
        "gaps": own["gaps"],
        "load": load,
        "calibrated_mdh": part.calibrated.rows(),
        "notes": legacy["notes"],
    }
    return fields, legacy
