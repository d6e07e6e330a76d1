"""Likely causes of data that no calibration can fit: the usual mistakes, each tried.

Above ``SUSPECT`` the data are read again under each usual mistake; the one whose correction
leaves an RMS ``EXPLAINS`` times lower (and not on shuffled joints) is named.
Rationale and measurements: docs/developers/engine.md#diagnosis
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.words import noun
from ..exceptions import CalibError, DataError
from ..kinematics.frames import beyond_ends, end_joint_links
from ..kinematics.robot import Chain, load_chain
from ..measurements.csvfile import read_data_text
from ..measurements.data import MAX_COORDINATE
from ..measurements.joint_columns import logged_joints
from .report import mm_or_deg

__all__ = [
    "EXPLAINS",
    "NOISE_FACTOR",
    "ORIENTATION_SUSPECT",
    "SHUFFLE_SEED",
    "SUSPECT",
    "Words",
    "explain",
    "suspect",
]

SUSPECT = 0.02
"""Registration RMS error per point [m] above which the usual mistakes are tried."""

NOISE_FACTOR = 20.0
"""... or above this many times the instrument noise, when given and larger (the registration
leaves the robot's geometric errors, whatever the noise: a low noise never lowers the bar)."""

EXPLAINS = 5.0
"""A mistake explains the data if correcting it divides the RMS error by this."""


SHUFFLE_SEED = 29
"""Seed of the shuffle of the joint columns that a correction must not explain too."""


def _mistakes(data, chain, joints_only: bool) -> Iterator[tuple[str, object]]:
    """(description, corrected data) for each usual mistake (of the joints only, or all)."""
    names, revolute = data.joint_names, chain.sigma == 0
    for i in range(len(names)):
        for j in range(i + 1, len(names)):
            q = data.q.copy()
            q[:, [i, j]] = q[:, [j, i]]
            yield f"joint columns {names[i]} and {names[j]} swapped", dataclasses.replace(data, q=q)
    if np.any(revolute):
        q = data.q.copy()
        q[:, revolute] = np.deg2rad(q[:, revolute])
        yield "revolute joint positions in degrees, not radians", dataclasses.replace(data, q=q)
    yield from _still_ends(data, chain)
    if joints_only:
        return
    for unit, size in (("millimetres", 1e-3), ("centimetres", 1e-2)):
        yield (
            f"positions in {unit}, not metres (units {unit[0]}m)",
            dataclasses.replace(data, position=data.position * size),
        )
    if np.max(np.abs(data.position), initial=0.0) * 1e3 <= MAX_COORDINATE:  # else: not metres
        yield (
            "positions in metres read as millimetres (units m, the default)",
            dataclasses.replace(data, position=data.position * 1e3),
        )
    yield from _swapped_coordinates(data)
    if data.quaternion is not None:  # wrong orientations distort the points' registration too
        yield from _orientation_mistakes(data)


def _swapped_coordinates(data) -> Iterator[tuple[str, object]]:
    """(description, corrected data) for coordinate columns swapped: in every point, or one's."""
    k = data.position.shape[1] // 3
    mirrored = "mirrored points (two of the x, y, z columns swapped, or a left-handed frame)"
    pairs: tuple[tuple[int, int], ...] = ((0, 1), (0, 2), (1, 2))
    groups: list[tuple[tuple[int, ...], tuple[tuple[int, int], ...], str]]
    groups = [(tuple(range(k)), pairs[:1], mirrored)]
    if k > 1:
        groups += [((p,), pairs, f"point {p + 1}'s") for p in range(k)]
    for points, swaps, what in groups:
        for a, b in swaps:
            first = [3 * p + a for p in points]
            second = [3 * p + b for p in points]
            position = data.position.copy()
            position[:, first + second] = data.position[:, second + first]
            said = what if len(points) == k else f"{what} {'xyz'[a]} and {'xyz'[b]} columns swapped"
            yield said, dataclasses.replace(data, position=position)


def _still_ends(data, chain) -> Iterator[tuple[str, object]]:
    """Each end joint of a chain (not a tree) held at 0: a frame given one link too far."""
    if chain.is_tree:
        return
    ends = (chain.base_frame, chain.tool_frame)
    found = end_joint_links(chain.model, chain.joint_names, chain.sign, ends)
    for name, (frame, link) in found.items():
        if name not in data.joint_names:
            continue
        q = data.q.copy()
        q[:, data.joint_names.index(name)] = 0.0
        yield (
            f"a joint too many in the chain: {name} does not move what is fixed to {frame} "
            f"(is it on {link}?)",
            dataclasses.replace(data, q=q),
        )


Other = Callable[[Chain], Callable[[Any], float]]
"""The registration's RMS error of data on another chain (``other(chain)(data)``)."""


def _left_out(data, chain, other: Other, ends: tuple[str, str]):
    """(description, data, their RMS error) of each joint one step beyond a chain's end.

    A frame given one link too near leaves its joint out of the chain: each joint beyond an end
    of a chain (not a tree) that the data's file logs (read again) is tried, the chain moved to
    the link beyond it. ``ends``: what is at the base and at the tool end, in words.
    """
    path, rows = getattr(data, "path", None), data.rows
    ids = (chain.base_id, chain.tool_id)
    beyond = {} if chain.is_tree else beyond_ends(chain.model, chain.joint_ids, ids)
    if not beyond or path is None or rows is None:
        return
    try:
        logged = logged_joints(read_data_text(path), data.source, tuple(beyond), rows)
    except CalibError:  # the file gone or changed: no hypothesis
        return
    frames = (chain.base_frame, chain.tool_frame)
    for name, values in logged.items():
        end, link = beyond[name]
        longer = _longer(chain, end, link, name)
        if longer is None:
            continue
        q = np.insert(data.q, data.q.shape[1] if end else 0, values, axis=1)
        yield (
            f"a joint left out of the chain: the file logs {name} beyond {frames[end]} (is "
            f"the {ends[end]} on {link}?)",
            dataclasses.replace(data, joint_names=longer.joint_names, q=q),
            other(longer),
        )


def _longer(chain, end: int, link: str, joint: str):
    """The chain with its base (``end`` 0) or tool (1) moved to ``link``, or None.

    None too unless it is one joint longer, ``joint``, without mimic joints.
    """
    base, tool = (link, chain.tool_frame) if end == 0 else (chain.base_frame, link)
    try:
        longer = load_chain(chain.urdf_resolved, base=base, tool=tool)
    except CalibError:
        return None
    names = (joint, *chain.joint_names) if end == 0 else (*chain.joint_names, joint)
    return longer if longer.joint_names == names and longer.coupling is None else None


ORIENTATION_SUSPECT = 0.1
"""Registration RMS orientation error [rad] above which the orientation mistakes are tried."""


def _orientation_mistakes(data) -> Iterator[tuple[str, object]]:
    """(description, corrected data) for each usual mistake of the orientation columns."""
    angles, quat = data.angles, data.quaternion
    if angles is None:
        yield (
            "quaternions written w, x, y, z (orientation quat-wxyz)",
            dataclasses.replace(data, quaternion=quat[:, [1, 2, 3, 0]]),
        )
        yield (
            "quaternions written x, y, z, w (orientation quat-xyzw)",
            dataclasses.replace(data, quaternion=quat[:, [3, 0, 1, 2]]),
        )
        return

    def read_as(values: np.ndarray):
        fixed = dataclasses.replace(angles, values=values)
        return dataclasses.replace(data, quaternion=fixed.quaternions(), angles=fixed)

    kind = "rpy angles" if angles.format == "rpy" else "rotation vectors"
    yield f"{kind} in degrees, not radians", read_as(np.deg2rad(angles.values))
    if angles.format == "rpy":
        yield "rpy columns holding yaw, pitch, roll", read_as(angles.values[:, ::-1])
        # R = Rx(r) Ry(p) Rz(y) = (Rz(-y) Ry(-p) Rx(-r))^T: the same as a quaternion conjugate
        flipped = read_as(-angles.values)
        quat = flipped.quaternion * np.array([-1.0, -1.0, -1.0, 1.0])
        yield (
            "rpy angles composed x, y, z (URDF's rpy is z, y, x: R = Rz(yaw) Ry(pitch) Rx(roll))",
            dataclasses.replace(flipped, quaternion=quat),
        )


def suspect(rms: float, noise: float | None) -> bool:
    """Whether a registration RMS error [m] is too large for geometric errors."""
    limit = SUSPECT if noise is None else max(SUSPECT, NOISE_FACTOR * noise)
    return rms > limit


def _beats_shuffle(registration_rms: Callable[[object], float], fixed, rms: float) -> bool:
    """Whether corrected rows fit ``EXPLAINS`` times better than with shuffled joint columns."""
    rng = np.random.default_rng(SHUFFLE_SEED)
    try:
        q = np.column_stack([rng.permutation(col) for col in fixed.q.T])
        null = registration_rms(dataclasses.replace(fixed, q=q))
    except (CalibError, np.linalg.LinAlgError, ValueError):  # shuffled rows cannot be fitted
        return True
    return bool(rms * EXPLAINS < null)


def _likely_cause(
    data,
    chain,
    registration_rms: Callable[[object], float],
    before: float,
    orientation: bool = False,
    joints_only: bool = False,
    other: tuple[Other, tuple[str, str]] | None = None,
) -> tuple[str, float] | None:
    """(description, RMS [m or rad]) of the usual mistake that best explains the data, or None.

    ``registration_rms``: the registration's RMS error of some data [m, or rad with
    ``orientation``]; ``before``: that of ``data`` as they are; ``other``: the registration's
    on another chain and the ends' words (:func:`_left_out`), or None: not tried.
    """
    best = None
    limit = ORIENTATION_SUSPECT if orientation else SUSPECT
    mistakes = _orientation_mistakes(data) if orientation else _mistakes(data, chain, joints_only)
    tried: Iterator[tuple[str, Any, Callable]]
    tried = ((what, fixed, registration_rms) for what, fixed in mistakes)
    if other is not None and not orientation:  # one at a time: each a copy of the data
        tried = itertools.chain(tried, _left_out(data, chain, *other))
    for what, fixed, error in tried:
        try:
            rms = error(fixed)
        except (CalibError, np.linalg.LinAlgError, ValueError):  # no valid data: no explanation
            continue
        if rms * EXPLAINS < before and rms < limit and (best is None or rms < best[1]):
            if not _beats_shuffle(error, fixed, rms):
                continue  # nearly one posture: any fit there explains nothing
            best = (what, rms)
    return best


@dataclass(frozen=True)
class Words:
    """How a kind's rows, row, error, mistakes tried and what to check are named in messages."""

    data: str = "data"
    row: str = "row"
    error: str = "error"
    mistakes: str = (
        "swapped joint columns, degrees, a joint too many or left out (logged) at an end of the "
        "chain"
    )
    check: str = "the data and the chain"
    ends: tuple[str, str] = ("base frame", "tool")


def explain(
    data,
    chain,
    error,
    first: float,
    noise,
    words: Words,
    joints_only=True,
    orientation=False,
    other: Other | None = None,
) -> list[str]:
    """Raise the usual mistake behind a registration's absurd error; else a note of it.

    ``error``: the registration's RMS error [m] of corrected ``data``, ``first`` that of
    ``data`` (infinite: no registration); ``orientation``: errors [rad], its mistakes;
    ``other``: the registration's error on another chain (a joint left out tried), or None.

    Raises:
        DataError: Joint columns holding one value in every row, or the mistake named.
    """
    if not (first > ORIENTATION_SUSPECT if orientation else suspect(first, noise)):
        return []
    known = bool(np.isfinite(first))
    unit, scale = mm_or_deg(orientation)

    def amount(e: float) -> str:
        return f"{scale * e:.4g} {unit}"

    of = f" of {words.error}" if orientation else ""
    leaves = f"leaves {amount(first)} RMS{of}" if known else "fails"
    same = () if orientation or data.m < 2 else np.all(data.q == data.q[0], axis=0)
    still = [name for name, s in zip(data.joint_names, same, strict=False) if s]  # constant
    if still:
        raise DataError(
            data.source,
            f"the registration {leaves} and {noun(len(still), 'joint columns')} "
            f"{', '.join(still)} {noun(len(still), 'hold', 'holds')} one value in every "
            f"{words.row}: {noun(len(still), 'were those joints', 'was that joint')} logged?",
        )
    longer = None if other is None else (other, words.ends)
    cause = _likely_cause(data, chain, error, first, orientation, joints_only, longer)
    if cause is not None:
        before = amount(first) if known else "no registration"
        raise DataError(
            data.source,
            f"the {words.data} look like {cause[0]}: the "
            f"registration's {words.error} drops from {before} to "
            f"{amount(cause[1])} RMS once corrected",
        )
    return [
        f"the registration {leaves}, far above geometric errors, and no usual mistake "
        f"({words.mistakes}) explains it: check {words.check}"
    ]
