"""Closed loops through a robot as ``fixed-pose`` touches: e.g. a humanoid's two soles.

A humanoid standing on both feet holds its right sole at one pose in its left sole's frame
(both flat on the ground, neither slipping) at every posture: the chain ``left_sole_link`` ->
``right_sole_link`` through both legs is a closed loop, a ``fixed-pose`` contact
(:class:`~calib.identification.contacts.FixedPoseContact`) whose touches are the recorded
postures themselves. Any file that records the loop's joints at such postures makes its
touches: the CSV of plane touches (its ``plane`` id column, TALOS's
``data/realdata/talos_contact/*.csv`` hold every joint) or a ``fixed-pose`` contact CSV (its
``point`` id column). Every row of a file is a touch of one fixed pose, named ``pose_id``.
Sessions recorded apart (the feet placed anew) are each their own pose: read each with its
own id and :func:`join_loops` them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..exceptions import DataError, InvalidArgumentError
from ..identification.contacts import FixedPoseContact
from ..kinematics.robot import Chain
from .contact_campaign import ID_COLUMNS, ContactData, parse_contacts
from .csvfile import csv_records, read_data_text

__all__ = ["LOOP_ID", "as_loop", "join_loops", "read_loop"]

LOOP_ID = "loop"
"""The default id of a loop's fixed pose."""


def as_loop(data: ContactData, pose_id: str = LOOP_ID) -> ContactData:
    """Touches of any kind on a loop's joints as ``fixed-pose`` touches of one pose.

    Args:
        data: Touches read for the loop's chain (its joints, any kind).
        pose_id: The fixed pose's id.

    Raises:
        InvalidArgumentError: Not contact data, or an empty id.
    """
    if not isinstance(data, ContactData):
        raise InvalidArgumentError(f"touches must be ContactData, got {type(data).__name__}")
    if not isinstance(pose_id, str) or not pose_id.strip():
        raise InvalidArgumentError("the loop's pose id must be a non-empty string")
    return ContactData(
        data.joint_names, data.q, (pose_id,) * data.m, FixedPoseContact(), data.source, data.rows
    )


def join_loops(parts: Sequence[ContactData], source: str | None = None) -> ContactData:
    """One loop's touches from several sets (e.g. several sessions' postures), in order.

    Each set keeps its pose ids: give each session its own (the feet stood elsewhere, the
    loop's fixed pose is another), one id for sessions that share the feet's placement.

    Raises:
        InvalidArgumentError: No sets, not ``fixed-pose`` touches, or other joints.
    """
    if not parts or not all(
        isinstance(p, ContactData) and isinstance(p.kind, FixedPoseContact) for p in parts
    ):
        raise InvalidArgumentError("join fixed-pose touches (as_loop, read_loop)")
    first = parts[0]
    if any(p.joint_names != first.joint_names for p in parts):
        raise InvalidArgumentError("the loops joined must be touches of one chain (its joints)")
    q = np.concatenate([p.q for p in parts])
    q.setflags(write=False)
    name = source if source is not None else " + ".join(p.source for p in parts)
    ids = tuple(i for p in parts for i in p.ids)
    return ContactData(first.joint_names, q, ids, first.kind, name)


def read_loop(path: str | Path, chain: Chain, pose_id: str = LOOP_ID) -> ContactData:
    """A loop's touches from a contact CSV (module text): each row, one touch of one pose.

    Args:
        path: A plane contact CSV (``plane`` id column) or a ``fixed-pose`` one (``point``).
        chain: The loop's chain (e.g. ``left_sole_link`` -> ``right_sole_link``).
        pose_id: The fixed pose's id.

    Raises:
        DataError: An unreadable file, no id column, or a bad cell (as ``read_contacts``).
    """
    src = str(path)
    text = read_data_text(path)
    records = list(csv_records(text, src))
    header = [c.strip() for c in records[0][1]] if records else []
    if ID_COLUMNS["plane"] in header or len(records) < 2:  # (an empty file: its own error)
        measure = "plane"
    elif ID_COLUMNS["fixed-pose"] in header:
        measure = "fixed-pose"
    else:
        raise DataError(src, "a loop's file needs a 'plane' or 'point' id column")
    loop = as_loop(parse_contacts(text, chain, measure, src), pose_id)
    return dataclasses.replace(loop, path=str(Path(path).resolve()))
