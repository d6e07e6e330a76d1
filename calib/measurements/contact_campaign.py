"""Contact campaigns: touches recorded by the joint encoders alone.

CSV format (one header line, then one row per touch): an id column naming what each touch
touches, ``plane`` for the plane kinds (``plane``, ``plane-point``) or ``point`` for the
point kinds (``fixed-point``, ``fixed-pose``), several ids per file; one column per joint of
the chain [rad or m]. The robot's other joints (one degree of freedom each) are read too:
they do not move the tool, but they load its joints, and a calibration with joint compliance
(``elastic``) takes them at their recorded positions
(:class:`~calib.kinematics.standing.JointReadings`). Other columns (a spot id) are ignored,
with one note. A contact file has no coordinates: an ``x``, ``y``, ``z`` or quaternion column
is an error, and so is an id column that does not match the kind.

:func:`simulate_contacts` makes such a campaign on a perturbed ("true") copy of a chain, as
:func:`calib.simulate` does for measured ones: every touch satisfies the true contact (Newton
projection onto it, :func:`calib.identification.contact_postures.contact_postures`), within
the joint limits.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.checks import MAX_OBJECTS, MAX_TOUCHES, angle_mrad, check_count, check_size, length_mm
from ..core.fileio import write_atomic
from ..core.words import counted
from ..exceptions import DataError, InvalidArgumentError, warn_user
from ..identification.contact_postures import contact_model, contact_postures, in_frame
from ..identification.contacts import Contact
from ..identification.kinds import kind_of
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.mdh import MDHModel, from_chain
from ..kinematics.robot import Chain, check_chain
from ..kinematics.standing import JointReadings
from .contact_objects import given_objects
from .csv_text import csv_table
from .csvfile import parse_number, read_data_text
from .data import JOINT_PREFIX, DataWarning
from .joint_columns import column_keys
from .limits import check_limits, joint_bounds, warn_default_ranges
from .simulation import chain_argument, perturbed, robot_entry, robot_of, robot_words

ID_COLUMNS = {
    "plane": "plane",
    "plane-point": "plane",
    "fixed-point": "point",
    "fixed-pose": "point",
}
"""The id column of each contact kind."""

_ID_NAMES = frozenset(ID_COLUMNS.values())
"""A joint named like an id column is written ``joint:NAME``."""

TRUTH_POINTS_NOTE = (
    "a fixed-pose campaign's objects are 'poses', as in the calibration report; 'points' is "
    "written too until the next format"
)
"""Why a fixed-pose truth also holds ``points`` (the deprecated name of its ``poses``)."""

SIMULATION_ROUNDS = 24
"""Draws of starting configurations :func:`simulate_contacts` tries per contact."""

_COORDINATE = re.compile(r"([xyz]|q[xyzw])\d*")
"""A measured coordinate's column (``x``, ``y2``, ``qw``): not in a contact file."""


@dataclass(frozen=True, eq=False)
class ContactData:
    """Touches of one contact kind: joint positions and what each touch touches.

    Attributes:
        joint_names: The chain's joints, in chain order.
        q: Joint positions per touch ``(m, n)`` [rad or m].
        ids: The plane or point each touch touches ``(m,)``.
        kind: The contact kind.
        source: File name (or a description) for messages.
        rows: The file row of each touch, or None.
        readings: Recorded positions of the robot's joints off the chain, or None.
        path: The file read, resolved when it was read (absolute, links followed), or None
            (not read from a file): what ``Result.write`` never overwrites, wherever the
            working directory is then.
    """

    joint_names: tuple[str, ...]
    q: np.ndarray
    ids: tuple[str, ...]
    kind: Contact
    source: str = "<contacts>"
    rows: tuple[int, ...] | None = None
    readings: JointReadings | None = None
    path: str | None = None

    def __post_init__(self) -> None:
        """Refuse touches whose columns disagree (an IndexError deep in the fit before).

        Raises:
            InvalidArgumentError: ``ids`` (or ``rows``) not one per row of ``q``.
        """
        m = np.shape(self.q)[0] if np.ndim(self.q) == 2 else None
        ids = len(self.ids) if isinstance(self.ids, list | tuple) else None
        if m is None or ids != m:
            got = f"{ids} ids" if ids is not None else f"ids of type {type(self.ids).__name__}"
            raise InvalidArgumentError(
                f"touches need joint positions (m, n) and one id per touch, got positions "
                f"of shape {np.shape(self.q)} and {got}"
            )
        object.__setattr__(self, "ids", tuple(self.ids))
        if self.rows is not None and len(self.rows) != m:
            raise InvalidArgumentError(f"{len(self.rows)} file rows for {m} touches")

    def __repr__(self) -> str:
        """One line (the arrays are in the attributes)."""
        return f"<ContactData {self.source}: {self.touches}, {len(self.joint_names)} joints>"

    def subset(self, index: np.ndarray) -> ContactData:
        """The touches ``index`` (an integer array or a boolean mask), in its order."""
        rows = np.arange(self.m)[index]
        return dataclasses.replace(
            self,
            q=self.q[rows],
            ids=tuple(self.ids[i] for i in rows),
            rows=None if self.rows is None else tuple(self.rows[i] for i in rows),
            readings=None if self.readings is None else self.readings.take(rows),
        )

    @property
    def touches(self) -> str:
        """How many touches of which kind on how many contacts, in words."""
        objects = counted(len(self.contacts), f"{self.id_column}s")
        return f"{self.m} {self.kind.label} touches of {objects}"

    @property
    def m(self) -> int:
        """Number of touches."""
        return len(self.q)

    @property
    def id_column(self) -> str:
        """``plane`` or ``point``."""
        return ID_COLUMNS[self.kind.label]

    @property
    def contacts(self) -> tuple[str, ...]:
        """The planes or points, in order of first appearance."""
        return tuple(dict.fromkeys(self.ids))


def _contact(measure) -> Contact:
    kind = kind_of(measure)
    if not isinstance(kind, Contact):
        raise InvalidArgumentError(
            f"'{kind.label}' is not a contact: choose {', '.join(ID_COLUMNS)}"
        )
    return kind


def _checked_header(
    names: list[str], chain: Chain, kind: Contact, src: str, line: int
) -> dict[str, int]:
    """Column index of the id and of every chain joint; DataError for a wrong layout.

    Joint columns are read as in every calib file (``joint:NAME`` for a joint named like the
    id column, :func:`~.joint_columns.column_keys`): the chain's joints and the robot's
    other one-degree-of-freedom joints. ``names``: the header's (:func:`.csv_text.csv_table`:
    none empty, none twice).
    """
    model = chain.model
    robot_joints = [n for j, n in enumerate(model.names) if j and model.joints[j].nv == 1]
    keys = column_keys(names, (*chain.joint_names, *robot_joints))
    for key in keys:
        if _COORDINATE.fullmatch(key):
            raise DataError(
                src,
                f"a contact file has no coordinates, found '{key}': the joints alone record a "
                f"touch",
                row=line,
            )
    want = ID_COLUMNS[kind.label]
    other = "point" if want == "plane" else "plane"
    if want not in keys:
        kinds = ", ".join(k for k, c in ID_COLUMNS.items() if c == other)
        hint = f": it names {other}s, for {kinds}" if other in keys else ""
        raise DataError(src, f"a {kind.label} contact needs a '{want}' column{hint}", row=line)
    if other in keys:
        raise DataError(
            src, f"both 'plane' and 'point' columns for a {kind.label} contact", row=line
        )
    missing = [j for j in chain.joint_names if JOINT_PREFIX + j not in keys]
    if missing:
        raise DataError(
            src,
            f"no column for joint {missing[0]} of the chain {chain.base_frame} -> "
            f"{chain.tool_frame} (its base and tool frames choose the joints read)",
            row=line,
        )
    index = {k.removeprefix(JOINT_PREFIX): i for i, k in enumerate(keys)}
    off = [k for k in keys if k != want and k.removeprefix(JOINT_PREFIX) not in chain.joint_names]
    joints = [k.removeprefix(JOINT_PREFIX) for k in off if k.startswith(JOINT_PREFIX)]
    ignored = [
        n for n, k in zip(names, keys, strict=True) if k in off and not k.startswith(JOINT_PREFIX)
    ]
    if off:
        read = f"{len(joints)} other joints ({_listed(joints)}), read for the gravity load of "
        read += "elastic only" + ("; " if ignored else "")
        warn_user(
            f"{src}: {len(off)} columns not on the chain: {read if joints else ''}"
            + (f"{len(ignored)} ignored ({_listed(ignored)})" if ignored else ""),
            DataWarning,
        )
    return {"id": keys.index(want), **{j: index[j] for j in (*chain.joint_names, *joints)}}


def _listed(names: list[str]) -> str:
    return ", ".join(names[:6]) + (", ..." if len(names) > 6 else "")


def parse_contacts(text: str, chain: Chain, measure, source: str = "<contacts>") -> ContactData:
    """Parse a contact CSV for a chain and a contact kind.

    Raises:
        DataError: Coordinates, an id column that does not match the kind, a missing joint,
            an empty id, a non-numeric cell or a joint value far outside its limits.
        InvalidArgumentError: Not a contact kind, or a chain with mimic joints.
    """
    kind = _contact(measure)
    if check_chain(chain, "chain").coupling is not None:
        raise InvalidArgumentError("contact files are read for chains without mimic joints")
    names, records, head = csv_table(text, source, "touches", ())
    check_size(len(records), MAX_TOUCHES, "touches", source)
    cols = _checked_header(names, chain, kind, source, head)
    others = tuple(n for n in cols if n != "id" and n not in chain.joint_names)
    ids, q, rows = [], [], []
    for line, cells in records:
        name = cells[cols["id"]].strip()
        if not name:
            raise DataError(source, "empty id", row=line, column=ID_COLUMNS[kind.label])
        ids.append(name)
        q.append([parse_number(cells[cols[j]], source, line, j) for j in chain.joint_names])
        rows.append(line)
    check_size(len(set(ids)), MAX_OBJECTS, f"{ID_COLUMNS[kind.label]}s", source)
    qa = np.array(q, dtype=float)
    check_limits(chain, qa, source, np.array(rows))
    _warn_repeats(qa, ids, rows, source)
    qa.setflags(write=False)
    readings = _readings(records, others, cols, source)
    return ContactData(chain.joint_names, qa, tuple(ids), kind, source, tuple(rows), readings)


def _warn_repeats(q: np.ndarray, ids: list[str], rows: list[int], source: str) -> None:
    """Warn when touches repeat an earlier one (same object and joint positions).

    As the measurement reader warns of repeated configurations: not independent touches.
    """
    key = np.column_stack([q, np.unique(np.array(ids), return_inverse=True)[1]])
    _, first = np.unique(key, axis=0, return_index=True)
    repeats = len(q) - len(first)
    if repeats:
        row = rows[int(np.flatnonzero(~np.isin(np.arange(len(q)), first))[0])]
        warn_user(
            f"{source}: {repeats} of {len(q)} touches repeat an earlier touch of the same "
            f"object at the same joint positions (first: row {row}): repeated touches are not "
            f"independent, the reported uncertainty is overconfident",
            DataWarning,
        )


def _readings(records, names: tuple[str, ...], cols: dict[str, int], source: str):
    """The other joints' readings: the columns with a number in every row.

    A note names the others, which are left out (they only load the joints of ``elastic``).
    """
    kept, values = [], []
    for name in names:
        try:
            column = [
                parse_number(cells[cols[name]], source, line, name) for line, cells in records
            ]
        except DataError:
            continue
        kept.append(name)
        values.append(column)
    if len(kept) < len(names):
        left = [n for n in names if n not in kept]
        warn_user(
            f"{source}: {len(left)} joint columns off the chain hold a cell that is not a "
            f"number ({_listed(left)}): not read (their joints stay at neutral under elastic)",
            DataWarning,
        )
    if not kept:
        return None
    read = np.array(values, dtype=float).T
    read.setflags(write=False)
    return JointReadings(tuple(kept), read)


def read_contacts(path: str | Path, chain: Chain, measure) -> ContactData:
    """Read and check a contact CSV file: the joint positions of each touch.

    One header line, then one row per touch. The robot's other joints (one degree of freedom each)
    are read too (their positions load the joints of ``elastic``); other columns are ignored with
    one note, but a coordinate column (``x``, ``y``, ``z``, a quaternion) is an error: a touch
    measures nothing but the joints. The module ``calib.measurements.contact_campaign`` has the long
    form.

    Args:
        path: The CSV file: an id column (``plane`` or ``point``, by the kind) naming what
            each touch touches, and the chain's joint positions [rad or m], one touch per line.
        chain: The chain that touches (without mimic joints).
        measure: The contact kind, as its label (``plane``, ``plane-point``,
            ``fixed-point``, ``fixed-pose``) or a contact kind object.

    Returns:
        The touches, ``path`` resolved.

    Raises:
        DataError: The file is missing, unreadable or too large, or its content is not valid
            (a missing joint, an id column that does not match the kind, a bad cell).
        InvalidArgumentError: Not a contact kind, or a chain with mimic joints.
    """
    data = parse_contacts(read_data_text(path), chain, measure, str(path))
    return dataclasses.replace(data, path=str(Path(path).resolve()))


def contacts_csv(data: ContactData) -> str:
    """The CSV text of touches, full precision (the other joints' readings after the chain's)."""
    if not isinstance(data, ContactData):
        raise InvalidArgumentError(f"data must be ContactData, got {data!r:.60}")
    extra = () if data.readings is None else data.readings.names
    values = data.q if data.readings is None else np.hstack([data.q, data.readings.values])
    joints = [JOINT_PREFIX + n if n in _ID_NAMES else n for n in (*data.joint_names, *extra)]
    lines = [",".join((data.id_column, *joints))]
    for name, qi in zip(data.ids, values, strict=True):
        lines.append(",".join((name, *(repr(float(v)) for v in qi))))
    return "\n".join(lines) + "\n"


@dataclass(frozen=True, eq=False)
class ContactTruth:
    """What a simulated contact campaign hides: the true robot and the true planes or points.

    Attributes:
        robot: Robot name.
        kind: The contact kind.
        params: The parameter set that was perturbed.
        errors: True error of every parameter [rad or m].
        true_mdh: The true MDH model (frame -1: the chain's base frame).
        frames: Each plane's or point's frame in the base frame ``(4, 4)``, by id (z: the
            plane's normal; the contact frame coincides with it at the reference touch).
        seed: Seed of everything drawn (the errors: unless ``robot_seed``).
        error_mm: Standard deviation of the length errors [mm].
        error_mrad: Standard deviation of the angle errors [mrad].
        noise_mrad: Standard deviation of the joint noise [mrad, or mm for a prismatic joint].
        robot_seed: Seed of the errors where it is not ``seed``, else None.
    """

    robot: str
    kind: Contact
    params: ParameterSet
    errors: np.ndarray
    true_mdh: MDHModel
    frames: dict[str, np.ndarray]
    seed: int
    error_mm: float
    error_mrad: float
    noise_mrad: float
    robot_seed: int | None = None

    def __repr__(self) -> str:
        """One line (the errors, the true model and the objects are attributes)."""
        objects = counted(len(self.frames), f"{self.kind.object_name}s")
        return (
            f"<ContactTruth {self.robot}: {objects} ({', '.join(self.frames)}), "
            f"{len(self.params)} {self.params.label} parameters perturbed ({self.error_mm:g} mm, "
            f"{self.error_mrad:g} mrad), joint noise {self.noise_mrad:g} mrad, seed {self.seed}"
            f"{robot_words(self.robot_seed)}>"
        )

    def to_dict(self) -> dict:
        """JSON-ready record (radians, metres)."""
        key = f"{self.kind.object_name}s"
        objects = {name: T.tolist() for name, T in self.frames.items()}
        old = {"points": objects} if key == "poses" else {}  # the name before format 2
        return {
            "robot": self.robot,
            "measure": self.kind.label,
            "params": self.params.label,
            "seed": self.seed,
            "error_mm": self.error_mm,
            "error_mrad": self.error_mrad,
            "noise_mrad": self.noise_mrad,
            "errors": {n: float(v) for n, v in zip(self.params.names, self.errors, strict=True)},
            key: objects,
            **old,
            "deprecated": {"points": TRUTH_POINTS_NOTE} if old else {},
            "true_mdh": self.true_mdh.rows(),
        } | robot_entry(self.robot_seed)


@dataclass(frozen=True, eq=False)
class ContactCampaign:
    """A simulated contact campaign: the touches and the truth behind them."""

    data: ContactData
    truth: ContactTruth

    def __repr__(self) -> str:
        """One line (the touches are ``data``, the errors and contacts ``truth``)."""
        return f"<ContactCampaign {self.truth.robot}: {self.data.touches}, seed {self.truth.seed}>"


def simulate_contacts(
    chain: Chain | str | Path,
    configs: int = 100,
    measure: str = "plane",
    *,
    contacts: int = 1,
    error_mm: float = 1.0,
    error_mrad: float = 1.0,
    noise_mrad: float = 0.0,
    seed: int = 0,
    params: str = "complete",
    objects: Mapping | None = None,
    robot_seed: int | None = None,
) -> ContactCampaign:
    """Simulate touches of a perturbed ("true") copy of a chain on planes or points.

    Each plane (point, pose) is the true contact frame's placement at a seeded random
    configuration, or the one given in ``objects``; ``configs`` touches are shared between
    them (in turn), each a random configuration projected onto its contact on the true model,
    kept within the joint limits.

    Args:
        chain: The nominal chain (no mimic joints), or a catalog name or URDF path (as
            :func:`~calib.simulate`).
        configs: Number of touches (>= 1).
        measure: ``plane``, ``plane-point``, ``fixed-point`` or ``fixed-pose``.
        contacts: Number of planes or points (>= 1, at most ``configs``: each is touched).
        error_mm: Standard deviation of every length error [mm].
        error_mrad: Standard deviation of every angle error [mrad].
        noise_mrad: Standard deviation of the recorded joints' noise [mrad; mm for prismatic].
        seed: Seed (an integer >= 0).
        params: Parameter set perturbed: ``complete`` or ``paper``.
        objects: The objects touched, by name, in the base frame (a floor, a known table:
            ``{"floor": (x, y, z, nx, ny, nz)}``; :mod:`!contact_objects`), instead of
            ``contacts`` drawn ones. With ``error_mm=0, error_mrad=0`` on a chain of a
            :func:`!true_robot.true_robot`'s URDF, several chains touch one floor of one
            true robot.
        robot_seed: Seed of the true robot's errors, or None: ``seed`` (as
            :func:`~calib.simulate`): the touches start from the same random configurations,
            projected onto the contact on that robot.

    Raises:
        InvalidArgumentError: A bad argument, or a contact the chain cannot hold often enough
            within its limits (a given object out of its reach).
    """
    kind = _contact(measure)
    chain = chain_argument(chain, "simulate_contacts", ": contacts are simulated on one chain")
    if chain.coupling is not None:
        raise InvalidArgumentError("contact campaigns are simulated on chains without mimic joints")
    given = None if objects is None else given_objects(objects, kind)
    if given is not None and contacts not in (1, len(given)):
        raise InvalidArgumentError(
            f"contacts={contacts} for {counted(len(given), 'objects')} given: give as many "
            "objects, or leave contacts out"
        )
    contacts = contacts if given is None else len(given)
    configs, seed = check_count(configs, "configs"), check_count(seed, "seed", 0)
    robot = robot_of(seed, robot_seed)
    contacts = check_count(contacts, "contacts", 1, configs)  # each touched at least once
    check_size(int(configs), MAX_TOUCHES, "touches")
    check_size(int(contacts), MAX_OBJECTS, f"{ID_COLUMNS[kind.label]}s")
    error_mm, error_mrad = length_mm(error_mm, "error_mm"), angle_mrad(error_mrad, "error_mrad")
    noise_mrad = angle_mrad(noise_mrad, "noise_mrad")
    nominal = from_chain(chain)
    pset = parameter_set(nominal, params)
    warn_default_ranges(chain)
    errors, true_mdh = perturbed(nominal, pset, (error_mm, error_mrad), robot)
    frames, ids, q = _every_touch(chain, true_mdh, kind, (configs, contacts, seed), given)
    q = q + 1e-3 * noise_mrad * np.random.default_rng([seed, 2]).standard_normal(q.shape)
    q.setflags(write=False)
    data = ContactData(chain.joint_names, q, tuple(ids), kind, f"<simulated {chain.name}>")
    errors.setflags(write=False)
    truth = ContactTruth(
        chain.name,
        kind,
        pset,
        errors,
        true_mdh,
        frames,
        int(seed),
        error_mm,
        error_mrad,
        noise_mrad,
        None if robot == seed else robot,
    )
    return ContactCampaign(data, truth)


def _every_touch(chain: Chain, true_mdh: MDHModel, kind: Contact, draw: tuple, given):
    """Every contact's frame by name, the contact of each touch and the touches ``(m, n)``.

    ``draw``: ``(configs, contacts, seed)``, the touches shared between the contacts in turn;
    ``given``: the objects by name, or None (drawn).
    """
    configs, contacts, seed = draw
    frames, ids, qs = {}, [], []
    for j in range(contacts):
        count = configs // contacts + (1 if j < configs % contacts else 0)
        object_ = None if given is None else list(given.items())[j]
        name, frame, q = _touches(chain, true_mdh, kind, (j, count, seed), object_)
        frames[name] = frame
        qs.append(q)
        ids += [name] * len(q)
    return frames, ids, np.concatenate(qs)


def _touches(chain: Chain, true_mdh: MDHModel, kind: Contact, draw: tuple, given=None):
    """Contact j of a simulation: its name, its frame in the base frame and its touches.

    ``draw``: ``(j, count, seed)``; ``given``: its name and frame, or None (drawn).
    """
    j, count, seed = draw
    lower, upper = joint_bounds(chain)
    column = ID_COLUMNS[kind.label]
    start = int(np.random.default_rng([seed, 3, j]).integers(2**31))
    q0 = chain.random_configurations(1, start)[0]
    name = f"{'table' if column == 'plane' else 'point'}{j + 1}"
    frame = true_mdh.forward(q0[None])[0]
    model = contact_model(true_mdh, q0, name)
    if given is not None:
        name, frame = given
        model = in_frame(true_mdh, frame)
    if count == 0:
        return name, frame, np.zeros((0, chain.n))
    try:
        q = contact_postures(
            model,
            kind,
            lambda c, r: chain.random_configurations(c, start + 1 + r),
            count,
            rounds=SIMULATION_ROUNDS,
            bounds=(lower, upper),
        )
    except InvalidArgumentError as exc:
        reach = " (is the given one within the chain's reach, in its base frame?)" if given else ""
        raise InvalidArgumentError(f"{ID_COLUMNS[kind.label]} {name}: {exc}{reach}") from None
    return name, frame, q


def write_contacts(path: str | Path, data: ContactData) -> None:
    """Write touches as CSV atomically."""
    write_atomic(path, contacts_csv(data))


__all__ = [
    "ID_COLUMNS",
    "ContactCampaign",
    "ContactData",
    "ContactTruth",
    "contacts_csv",
    "parse_contacts",
    "read_contacts",
    "simulate_contacts",
    "write_contacts",
]
