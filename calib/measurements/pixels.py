"""Pixel observations and their targets: the files of the camera kind (issue 32), read and written.

``OBS.csv`` (one header line, then one row per point seen in an image; comma separated):

* one column per joint of the chains involved, named as the URDF joint [rad or m] (a joint
  named like another column, ``camera``, ``point``, ``u`` or ``v``, is written
  ``joint:NAME``, as in every calib file: :mod:`.joint_columns`);
* ``camera``: the camera's name (one of the cameras given, with their intrinsics);
* ``point``: the target point's id, as in ``TARGET.csv`` (text);
* ``u``, ``v``: where the camera sees the point [px], ``u`` the column and ``v`` the row,
  the centre of the top-left pixel at ``(0, 0)`` (OpenCV's convention).

``TARGET.csv`` (one row per point): ``point``, ``x``, ``y``, ``z`` [m], the point in its
link's frame; optionally ``link`` (the link it is fixed to; without the column every point is
on the tool) and ``nx``, ``ny``, ``nz`` (the outward normal of the surface it is on; scaled
to unit length on reading).

Refused with one :class:`~calib.exceptions.DataError` naming the row: an unknown camera, a
pixel outside its camera's image, pixels that look normalised (every ``|u|``, ``|v|`` below
:data:`NORMALISED_BOUND` for an image hundreds of pixels wide), a point id the target does
not have, a point seen twice in one image (one camera, the same joint positions), a target
point given twice, a target that looks like millimetres (a point farther than
:data:`MAX_TARGET_DISTANCE` from its link's origin, or a link's points spread wider), a zero
normal. The joint positions are read as numbers; their limits are checked where the robot
is known.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.checks import check_size, real_array
from ..core.fileio import csv_text, write_atomic
from ..core.words import noun
from ..exceptions import DataError, InvalidArgumentError, warn_user
from .csv_text import csv_table, text_cell
from .csvfile import parse_number, read_data_text
from .data import JOINT_PREFIX, DataWarning
from .intrinsics import Intrinsics
from .joint_columns import column_keys

__all__ = [
    "MAX_OBSERVATIONS",
    "MAX_TARGET_DISTANCE",
    "MAX_TARGET_POINTS",
    "NORMALISED_BOUND",
    "OBSERVATION_COLUMNS",
    "PixelObservations",
    "Target",
    "observations_csv",
    "on_link",
    "parse_observations",
    "parse_target",
    "read_observations",
    "read_target",
    "target_csv",
    "write_observations",
    "write_target",
]

OBSERVATION_COLUMNS = ("camera", "point", "u", "v")
"""The columns of ``OBS.csv`` besides the joints."""

_TARGET_XYZ = ("x", "y", "z")
_NORMAL = ("nx", "ny", "nz")
_LINK = "link"

MAX_OBSERVATIONS = 1_000_000
"""Most rows of an observation file (a thousand images of a thousand corners)."""

MAX_TARGET_POINTS = 10_000
"""Most points of a target file."""

MAX_TARGET_DISTANCE = 5.0
"""Farthest a target point may be from its link's origin, and widest a link's points may
spread [m]: beyond, the file is in millimetres, most likely."""

NORMALISED_BOUND = 2.0
"""Pixels all within this of 0 [px], in an image of at least :data:`_WIDE_IMAGE` pixels a
side, are normalised coordinates (``x/z``, ``y/z``), not pixels."""

_WIDE_IMAGE = 100


@dataclass(frozen=True, eq=False)
class Target:
    """Points fixed to the robot's links, which cameras see.

    Attributes:
        point: Each point's id ``(k,)``, distinct.
        position: Each point in its link's frame ``(k, 3)`` [m].
        link: Each point's link ``(k,)``, or None: every point is on the tool.
        normal: Each point's outward unit normal in its link's frame ``(k, 3)``, or None.
        source: Where the target came from (a file path), for messages.
        rows: Each point's row in the source file (the header is row 1), or None.
        path: The file read, resolved when it was read (absolute, links followed), or None
            (not read from a file): what ``Result.write`` never overwrites, wherever the
            working directory is then.
    """

    point: tuple[str, ...]
    position: np.ndarray
    link: tuple[str, ...] | None = None
    normal: np.ndarray | None = None
    source: str = "<target>"
    rows: tuple[int, ...] | None = None
    path: str | None = None

    def __post_init__(self) -> None:
        k = len(self.point)
        if (
            not isinstance(self.point, tuple)
            or not k
            or not all(isinstance(p, str) and p for p in self.point)
        ):
            raise InvalidArgumentError("a target's point ids must be a tuple of non-empty text")
        if len(set(self.point)) != k:
            raise InvalidArgumentError("a target's point ids must be distinct")
        position = real_array(self.position, "target positions", (k, 3))
        position.flags.writeable = False
        object.__setattr__(self, "position", position)
        if self.link is not None and (
            not isinstance(self.link, tuple)
            or len(self.link) != k
            or not all(isinstance(n, str) and n for n in self.link)
        ):
            raise InvalidArgumentError(f"a target's links must be {k} non-empty names")
        if self.normal is not None:
            normal = real_array(self.normal, "target normals", (k, 3))
            length = np.linalg.norm(normal, axis=1)
            if np.any(length < 1e-12):
                raise InvalidArgumentError("a target's normals must not be zero")
            # unit normals stay as given (a written target reads back equal)
            unit = np.where(np.abs(length - 1) > 1e-15, length, 1.0)[:, None]
            unit = normal / unit
            unit.flags.writeable = False
            object.__setattr__(self, "normal", unit)

    def __repr__(self) -> str:
        """One line (the arrays are in the attributes)."""
        links = "the tool" if self.link is None else ", ".join(dict.fromkeys(self.link))
        return f"<Target {self.source}: {len(self.point)} points on {links}>"

    @property
    def index(self) -> dict[str, int]:
        """Each point id's index."""
        return {p: i for i, p in enumerate(self.point)}


@dataclass(frozen=True, eq=False)
class PixelObservations:
    """Target points seen by cameras at joint positions, one row per point in an image.

    Attributes:
        joint_names: The joint of each column of ``q``.
        q: Joint positions ``(m, n)`` [rad or m].
        camera: The camera of each row ``(m,)``.
        point: The target point of each row ``(m,)``.
        pixels: ``(u, v)`` of each row ``(m, 2)`` [px]: column, row.
        source: Where the observations came from (a file path), for messages.
        rows: Each row's line in the source file (the header is row 1), or None.
        path: The file read, resolved when it was read (absolute, links followed), or None
            (not read from a file): what ``Result.write`` never overwrites, wherever the
            working directory is then.
    """

    joint_names: tuple[str, ...]
    q: np.ndarray
    camera: tuple[str, ...]
    point: tuple[str, ...]
    pixels: np.ndarray
    source: str = "<observations>"
    rows: tuple[int, ...] | None = None
    path: str | None = None

    def __post_init__(self) -> None:
        m = len(self.camera)
        columns = (self.joint_names, self.camera, self.point)
        if not all(isinstance(c, tuple) for c in columns) or not m or len(self.point) != m:
            raise InvalidArgumentError(
                "observations need tuples of joints, and of a camera and a point for each row"
            )
        names = (*self.camera, *self.point, *self.joint_names)
        if not all(isinstance(n, str) and n for n in names):
            raise InvalidArgumentError("cameras, points and joints are named by non-empty text")
        q = real_array(self.q, "joint positions", (m, len(self.joint_names)))
        pixels = real_array(self.pixels, "pixels", (m, 2))
        for name, value in (("q", q), ("pixels", pixels)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)

    def __repr__(self) -> str:
        """One line (the arrays are in the attributes)."""
        return (
            f"<PixelObservations {self.source}: {self.m} pixels of {len(set(self.point))} "
            f"points, {noun(len(self.cameras), 'cameras')} {', '.join(self.cameras)}, "
            f"{len(self.joint_names)} joints>"
        )

    @property
    def m(self) -> int:
        """Number of rows."""
        return len(self.camera)

    @property
    def cameras(self) -> tuple[str, ...]:
        """The cameras, in order of first appearance."""
        return tuple(dict.fromkeys(self.camera))


def on_link(target: Target, link: str) -> Target:
    """The target's points on ``link`` (all of them for a target without a ``link`` column).

    Raises:
        InvalidArgumentError: No point on ``link``.
    """
    if target.link is None:
        return target
    keep = [i for i, n in enumerate(target.link) if n == link]
    if not keep:
        raise InvalidArgumentError(f"{target.source}: no target point on {link}")
    normal = None if target.normal is None else target.normal[keep]
    return Target(
        tuple(target.point[i] for i in keep),
        target.position[keep],
        (link,) * len(keep),
        normal,
        target.source,
    )


def _checked_text(text: object) -> str:
    """The text of a file; InvalidArgumentError for anything else (a path, bytes)."""
    if not isinstance(text, str):
        raise InvalidArgumentError(f"text must be the file's content (str), got {text!r:.60}")
    return text


def _warn_ignored(names: Sequence[str], source: str, what: str) -> None:
    """One note naming the columns a file has that are not read."""
    if names:
        warn_user(f"{source}: columns ignored (not {what}): {', '.join(names)}", DataWarning)


def parse_target(text: str, source: str = "<text>", path: str | None = None) -> Target:
    """A target from the text of a target CSV file: points fixed to the robot's links.

    The format is :func:`read_target`'s.

    Args:
        text: The CSV content.
        source: Name of the data in messages (a file path).
        path: The file read, resolved (:func:`read_target`), or None.

    Returns:
        The target's points, in the file's order.

    Raises:
        DataError: A missing column, a bad cell, a point given twice, a zero normal, or a
            target in millimetres, naming the row.
    """
    text = _checked_text(text)
    names, records, head = csv_table(text, source, "target points", ["point", *_TARGET_XYZ])
    check_size(len(records), MAX_TARGET_POINTS, "target points", source)
    wanted = ["point", *_TARGET_XYZ]
    has_normal = [c in names for c in _NORMAL]
    if any(has_normal):
        wanted += _NORMAL
    for column in wanted:
        if column not in names:
            raise DataError(source, "missing column", row=head, column=column)
    has_link = _LINK in names
    _warn_ignored(
        [n for n in names if n not in (*wanted, _LINK)], source, "point, x, y, z, link, nx, ny, nz"
    )
    col = {n: j for j, n in enumerate(names)}
    seen: dict[str, int] = {}
    points, links, values, lines = [], [], [], []
    for line, cells in records:
        point = text_cell(cells, col["point"], source, line, "point")
        if point in seen:
            raise DataError(
                source, f"point '{point}' is given twice (rows {seen[point]} and {line})", row=line
            )
        seen[point] = line
        points.append(point)
        if has_link:
            links.append(text_cell(cells, col[_LINK], source, line, _LINK))
        values.append([parse_number(cells[col[c]], source, line, c) for c in wanted[1:]])
        lines.append(line)
    table = np.array(values)
    normal = table[:, 3:] if any(has_normal) else None
    if normal is not None and np.any(np.linalg.norm(normal, axis=1) == 0):
        i = int(np.argmax(np.linalg.norm(normal, axis=1) == 0))
        raise DataError(source, "a zero normal (nx, ny, nz)", row=lines[i])
    link = tuple(links) if has_link else None
    _check_metres(table[:, :3], link, source, lines)
    return Target(tuple(points), table[:, :3], link, normal, source, tuple(lines), path)


def _check_metres(position: np.ndarray, link, source: str, lines: list[int]) -> None:
    """Refuse a target whose points are too far or too spread out to be metres."""
    distance = np.linalg.norm(position, axis=1)
    if np.max(distance) > MAX_TARGET_DISTANCE:
        i = int(np.argmax(distance))
        raise DataError(
            source,
            f"the point is {distance[i]:.4g} m from its link's origin (over "
            f"{MAX_TARGET_DISTANCE:g} m): a target is in metres, is this file in millimetres?",
            row=lines[i],
        )
    groups = np.unique(np.array(link), return_inverse=True)[1] if link else np.zeros(len(position))
    for g in np.unique(groups):
        mine = position[groups == g]
        spread = float(np.linalg.norm(mine.max(axis=0) - mine.min(axis=0)))
        if spread > MAX_TARGET_DISTANCE:
            raise DataError(
                source,
                f"the points of one link spread over {spread:.4g} m (over "
                f"{MAX_TARGET_DISTANCE:g} m): a target is in metres, is this file in millimetres?",
            )


def read_target(path: str | Path) -> Target:
    """Read and check a target CSV file: points fixed to the robot's links.

    One header line, then one row per point: ``point`` (its id, text), ``x``, ``y``, ``z`` [m], the
    point in its link's frame; optionally ``link`` (the link it is fixed to; without the column
    every point is on the tool) and ``nx``, ``ny``, ``nz`` (the outward normal of its surface,
    scaled to unit length). The module ``calib.measurements.pixels`` has the long form.

    Args:
        path: The target file.

    Returns:
        The target's points, in the file's order, ``path`` resolved.

    Raises:
        DataError: The file is missing or unreadable, or its content is not valid
            (:func:`!parse_target`).
    """
    return parse_target(read_data_text(path), str(path), str(Path(path).resolve()))


def _observation_columns(
    names: list[str], joints: Sequence[str], source: str, line: int
) -> dict[str, int]:
    """Column index of each joint and of camera, point, u, v; DataError for a missing one."""
    keys = column_keys(names, joints)
    wanted = [*OBSERVATION_COLUMNS, *(JOINT_PREFIX + j for j in joints)]
    missing = next((c for c in wanted if c not in keys), None)
    if missing is not None:
        what = "missing joint column" if missing.startswith(JOINT_PREFIX) else "missing column"
        raise DataError(source, what, row=line, column=missing.removeprefix(JOINT_PREFIX))
    used = set(wanted)
    _warn_ignored(
        [n for n, k in zip(names, keys, strict=True) if k not in used],
        source,
        "joints of the chains, camera, point, u or v",
    )
    return {k: j for j, k in enumerate(keys) if k in used}


def _checked_arguments(joints, cameras, target) -> tuple[str, ...]:
    """The joints as a tuple; InvalidArgumentError for arguments of the wrong kind."""
    if isinstance(joints, str) or not all(isinstance(j, str) and j for j in joints):
        raise InvalidArgumentError(f"joints must be a sequence of joint names, got {joints!r:.60}")
    if len(set(joints)) != len(joints):
        raise InvalidArgumentError("joints must be distinct")
    if not isinstance(cameras, Mapping) or not cameras:
        raise InvalidArgumentError(f"cameras must map names to Intrinsics, got {cameras!r:.60}")
    for name, value in cameras.items():
        if not isinstance(name, str) or not name or not isinstance(value, Intrinsics):
            raise InvalidArgumentError(
                f"cameras must map names to Intrinsics, got {name!r:.30}: {value!r:.30}"
            )
    if target is not None and not isinstance(target, Target):
        raise InvalidArgumentError(f"target must be a Target (or None), got {target!r:.60}")
    return tuple(joints)


@dataclass(frozen=True)
class _Known:
    """The target's point ids (None: not checked) and its source."""

    points: frozenset[str] | None
    source: str


def _ids(cells, col, cameras, target: _Known, source: str, line: int) -> tuple[str, str]:
    """The camera and the point of a row; DataError for an unknown one."""
    camera = text_cell(cells, col["camera"], source, line, "camera")
    if camera not in cameras:
        raise DataError(
            source,
            f"unknown camera '{camera}': the cameras are {', '.join(sorted(cameras))}",
            row=line,
            column="camera",
        )
    point = text_cell(cells, col["point"], source, line, "point")
    if target.points is not None and point not in target.points:
        raise DataError(source, f"point '{point}' is not in the target {target.source}", row=line)
    return camera, point


def parse_observations(
    text: str,
    joints: Sequence[str],
    cameras: Mapping[str, Intrinsics],
    target: Target | None = None,
    source: str = "<text>",
) -> PixelObservations:
    """Pixel observations from the text of an observation CSV (``OBS.csv``).

    The format is :func:`read_observations`'s.

    Args:
        text: The CSV content.
        joints: The joints whose columns are read (those of the chains involved).
        cameras: Each camera's intrinsics, by the name the ``camera`` column gives.
        target: The target, whose point ids the ``point`` column names; None: not checked.
        source: Name of the data in messages (a file path).

    Returns:
        The observations, joints in the order of ``joints``.

    Raises:
        DataError: A missing column, a bad cell, an unknown camera or point, pixels outside
            the image or normalised, a point seen twice in one image, naming the row.
        InvalidArgumentError: Arguments of the wrong kind.
    """
    joint_names = _checked_arguments(joints, cameras, target)
    names, records, head = csv_table(
        _checked_text(text), source, "observations", OBSERVATION_COLUMNS
    )
    check_size(len(records), MAX_OBSERVATIONS, "observations", source)
    col = _observation_columns(names, joint_names, source, head)
    numbers = [col[JOINT_PREFIX + j] for j in joint_names] + [col["u"], col["v"]]
    known = _Known(None, "") if target is None else _Known(frozenset(target.point), target.source)
    ids, values, lines = [], [], []
    for line, cells in records:
        ids.append(_ids(cells, col, cameras, known, source, line))
        values.append([parse_number(cells[j], source, line, names[j]) for j in numbers])
        lines.append(line)
    camera, point = (tuple(c) for c in zip(*ids, strict=True))
    table = np.array(values)
    obs = PixelObservations(
        joint_names, table[:, :-2], camera, point, table[:, -2:], source, tuple(lines)
    )
    _check_pixels(obs, cameras)
    _check_repeats(obs)
    return obs


def _check_pixels(obs: PixelObservations, cameras: Mapping[str, Intrinsics]) -> None:
    """Refuse normalised coordinates and pixels outside their camera's image."""
    rows = obs.rows or tuple(range(2, obs.m + 2))
    names = np.array(obs.camera)
    for name in obs.cameras:
        intr = cameras[name]
        mine = np.flatnonzero(names == name)
        uv = obs.pixels[mine]
        wide = min(intr.width, intr.height) >= _WIDE_IMAGE
        if wide and np.max(np.abs(uv)) < NORMALISED_BOUND:
            raise DataError(
                obs.source,
                f"every u, v of camera '{name}' is within {NORMALISED_BOUND:g} of 0 while its "
                f"image is {intr.width}x{intr.height} px: these look like normalised "
                f"coordinates (x/z, y/z), give pixels",
                row=rows[mine[0]],
            )
        outside = ~intr.inside(uv)
        if np.any(outside):
            i = mine[int(np.argmax(outside))]
            u, v = obs.pixels[i]
            swapped = intr.inside(uv[:, ::-1]).all()
            raise DataError(
                obs.source,
                f"pixel ({u:g}, {v:g}) is outside the {intr.width}x{intr.height} image of "
                f"camera '{name}' (u from -0.5 to {intr.width - 0.5:g}, v from -0.5 to "
                f"{intr.height - 0.5:g})"
                + (
                    ": u and v swapped (u is the column, v the row), or the intrinsics' "
                    "image_width and image_height? every pixel fits with them exchanged"
                    if swapped
                    else ""
                ),
                row=rows[i],
            )
        if hint := intr.half_size_hint(uv):
            warn_user(f"{obs.source}: camera '{name}': {hint}", DataWarning)


def _check_repeats(obs: PixelObservations) -> None:
    """Refuse a point seen twice in one image (one camera, the same joint positions)."""
    rows = obs.rows or tuple(range(2, obs.m + 2))
    first: dict[tuple, int] = {}
    for i, (camera, point) in enumerate(zip(obs.camera, obs.point, strict=True)):
        key = (camera, point, obs.q[i].tobytes())
        if key in first:
            raise DataError(
                obs.source,
                f"camera '{camera}' sees point '{point}' twice at the same joint positions "
                f"(rows {rows[first[key]]} and {rows[i]}): a point id names one point of an image",
                row=rows[i],
            )
        first[key] = i


def read_observations(
    path: str | Path,
    joints: Sequence[str],
    cameras: Mapping[str, Intrinsics],
    target: Target | None = None,
) -> PixelObservations:
    """Read and check an observation CSV file (``OBS.csv``): where cameras see target points.

    One header line, then one row per point seen in an image: one column per joint of ``joints``
    [rad or m] (``joint:NAME`` for a joint named like another column), ``camera`` (a name of
    ``cameras``), ``point`` (a target point's id) and ``u``, ``v`` [px] (the column and the row, the
    centre of the top-left pixel at ``(0, 0)``, as OpenCV has them). The module
    ``calib.measurements.pixels`` has the long form.

    Args:
        path: The observation CSV file.
        joints: The joints whose columns are read (those of the chains involved).
        cameras: Each camera's intrinsics, by the name the ``camera`` column gives.
        target: The target, whose point ids the ``point`` column names; None: not checked.

    Returns:
        The observations, joints in the order of ``joints``.

    Raises:
        DataError: The file is missing or unreadable, or its content is not valid.
        InvalidArgumentError: Arguments of the wrong kind.
    """
    _checked_arguments(joints, cameras, target)  # before reading the file
    obs = parse_observations(read_data_text(path), joints, cameras, target, str(path))
    return dataclasses.replace(obs, path=str(Path(path).resolve()))


def observations_csv(obs: PixelObservations) -> str:
    """The CSV text of observations, full precision (``repr`` of every number).

    A joint named like another column (``camera``, ``point``, ``u``, ``v``) is written
    ``joint:NAME``.
    """
    if not isinstance(obs, PixelObservations):
        raise InvalidArgumentError(f"observations must be PixelObservations, got {obs!r:.60}")
    joints = [JOINT_PREFIX + j if j in OBSERVATION_COLUMNS else j for j in obs.joint_names]
    rows = (
        [*(repr(float(v)) for v in q), camera, point, repr(float(uv[0])), repr(float(uv[1]))]
        for q, camera, point, uv in zip(obs.q, obs.camera, obs.point, obs.pixels, strict=True)
    )
    return csv_text([*joints, *OBSERVATION_COLUMNS], rows)


def target_csv(target: Target) -> str:
    """The CSV text of a target, full precision (``repr`` of every number)."""
    if not isinstance(target, Target):
        raise InvalidArgumentError(f"target must be a Target, got {target!r:.60}")
    header = ["point", *_TARGET_XYZ]
    header += [_LINK] if target.link is not None else []
    header += list(_NORMAL) if target.normal is not None else []
    rows = []
    for i, point in enumerate(target.point):
        row = [point, *(repr(float(v)) for v in target.position[i])]
        row += [target.link[i]] if target.link is not None else []
        row += [repr(float(v)) for v in target.normal[i]] if target.normal is not None else []
        rows.append(row)
    return csv_text(header, rows)


def write_observations(path: str | Path, obs: PixelObservations) -> None:
    """Write observations as CSV atomically (the file is complete or not written at all).

    Raises:
        InvalidArgumentError: ``obs`` is no :class:`PixelObservations`.
        OutputError: The file cannot be written.
    """
    write_atomic(path, observations_csv(obs))


def write_target(path: str | Path, target: Target) -> None:
    """Write a target as CSV atomically (the file is complete or not written at all).

    Raises:
        InvalidArgumentError: ``target`` is no :class:`Target`.
        OutputError: The file cannot be written.
    """
    write_atomic(path, target_csv(target))
