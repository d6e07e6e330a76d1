"""Joint compliance in a calibration from contacts (``elastic``): load, torques, URDF alone.

Rationale: docs/developers/engine.md#contact_elastic
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..core.words import counted
from ..exceptions import CalibrationRefusedError, InvalidArgumentError
from ..identification.contacts import PlaneContact
from ..kinematics import elastic
from ..kinematics.standing import StandingLoad, Support, standing_load
from ..measurements.contact_campaign import ContactData
from . import validation
from .contact_model import ContactState
from .contact_result import gap_stats

__all__ = [
    "compliance_document",
    "compliance_line",
    "fitted_compliance",
    "load_record",
    "none_kept_note",
    "readings_note",
    "term_load",
    "urdf_alone",
]


def term_load(chains, data, elastic: bool | None, support) -> StandingLoad | None:
    """The standing load of a fit of one chain touching planes (``elastic``), or None (rigid).

    InvalidArgumentError: ``elastic`` but for one chain touching planes; a wrong ``support``.
    """
    if elastic and (len(chains) != 1 or not isinstance(data[0], ContactData)):
        raise InvalidArgumentError("elastic (joint compliance) is for one chain touching planes")
    if support is not None and not isinstance(support, Support):
        raise InvalidArgumentError(f"support must be a Support, got {type(support).__name__}")
    if support is not None and not elastic:
        raise InvalidArgumentError("support (the load split between feet) needs elastic=True")
    if not elastic:
        return None
    if not isinstance(data[0].kind, PlaneContact):
        raise InvalidArgumentError(
            "elastic (joint compliance) is available for plane contacts only, not "
            f"'{data[0].kind.label}'"
        )
    return standing_load(chains[0], support)


def readings_note(load, train, held) -> str | None:
    """A note when the held-out touches record other joints off the chain than the training."""
    if load is None or held is None:
        return None
    names = [() if d.readings is None else d.readings.names for d in (train, held)]
    if names[0] == names[1]:
        return None
    return (
        f"elastic: the held-out touches record {len(names[1])} joints off the chain, the "
        f"fitted ones {len(names[0])}: the load puts those a file lacks at neutral"
    )


def none_kept_note(part, offered: tuple[int, ...], load) -> list[str]:
    """The note when ``elastic`` offered compliances (joints, 0-based) and the fit kept none."""
    if not offered or part.compliance is not None:
        return []
    if load is not None:
        return ["elastic: no joint compliance was kept; the URDF is the whole model"]
    names = ", ".join(part.chain.joint_names[j] for j in offered)
    return [
        f"elastic: the compliance of {counted(len(offered), 'joints')} was offered ({names}) "
        f"and none was kept; the URDF is the whole model (no compliance file)"
    ]


def fitted_compliance(
    state: ContactState, sets, stats: dict, notes: list[str]
) -> np.ndarray | None:
    """The fitted compliance ``(n,)`` (None: none kept); the URDF alone scored into ``stats``."""
    if state.compliance is None or not np.any(state.compliance):
        return None
    rigid = dataclasses.replace(state, compliance=None)
    urdf_alone(lambda d: gap_stats(rigid, d.q, d.ids), sets, stats, notes, "touches")
    return state.compliance


def urdf_alone(score, sets, stats: dict, notes: list[str], rows: str) -> None:
    """The URDF alone (``score``) of a fit with compliance on ``sets``, into ``stats``, noted."""
    notes.append(
        "joint compliance was fitted: the calibrated URDF cannot hold it; it is written to the "
        "compliance file (apply it with calib predict or calib.load_calibrated)"
    )
    for label, key, d in (("the fitted", "train", sets[0]), ("held-out", "held_out", sets[1])):
        if d is None:
            continue
        alone, reg = score(d), stats[f"{key}_registration"]
        stats[f"{key}_urdf"] = alone
        if validation.worse(alone.weighted_mm, reg.weighted_mm, 1e-3):
            notes.append(
                f"on {label} {rows} the calibrated URDF alone (without the fitted joint "
                f"compliance) is worse than the registration alone ({alone.weighted_mm:.3f} > "
                f"{reg.weighted_mm:.3f} mm weighted RMS): use it only with its compliance file"
            )


def load_record(part) -> dict | None:
    """The load's record of a fit with compliance (standing, support, joints read), or None."""
    if part.load is None:
        return None
    support = part.load.support.to_dict()
    return {"kind": "standing", "support": support, "readings": list(part.readings)}


def compliance_line(part) -> list[str]:
    """The summary's line of a fitted compliance of a chain touching (none: rigid joints)."""
    if part.compliance is None or part.load is None:
        return []
    chain = part.chain
    read = f"; {len(part.readings)} joints off the chain as read" if part.readings else ""
    pairs = zip(chain.joint_names, part.compliance, strict=True)
    fitted = ", ".join(f"{j} {v:.3g}" for j, v in pairs if v)
    return [
        f"joint compliance under gravity, standing on {chain.base_frame} "
        f"({part.load.support.label()}{read}): {fitted} [rad/(N m)]"
    ]


def compliance_document(part, urdf: str) -> dict:
    """The compliance file of the calibrated URDF ``urdf`` (CalibrationRefusedError: none)."""
    if part.compliance is None or part.load is None:
        raise CalibrationRefusedError("no joint compliance was fitted: no compliance file")
    contact = {
        "plane_id": part.plane_id,
        "frame": part.contact.tolist(),
        "plane": part.plane.tolist(),
    }
    return elastic.compliance_document(
        part.chain,
        part.compliance,
        urdf,
        tool_frame=part.chain.tool_frame,
        measured=(np.eye(4), part.contact[None, :3, 3], ()),
        touching=(load_record(part), contact),
    )
