"""Measurement campaigns: the CSV format, its validation, and simulated campaigns.

CSV format (one header line, then one row per configuration; comma separated):

* one column per joint of the chain, named as the URDF joint, holding the URDF joint
  position [rad for revolute and continuous joints, m for prismatic ones];
* ``x, y, z``: the measured point in the measurement frame [m], each within
  ``MAX_COORDINATE`` (1 km) of its origin;
* for pose measurements also ``qx, qy, qz, qw``: the orientation of the tool frame in the
  measurement frame as a quaternion, scalar last (normalised on reading).

Columns may come in any order; blank lines are skipped. Errors name the row the way a
text editor or spreadsheet numbers it (the header is row 1) and the column by its name.

Simulated campaigns (:func:`simulate`): a "true" robot is the nominal MDH model with every
standard parameter of the chosen set perturbed by a seeded normal error (standard deviation
``error_mm`` [mm] for lengths, ``error_mrad`` [mrad] for angles); rows 0 and 1 carry the
base error (the measurement frame is frame -1 of the true model) and row n+1 the tool error.
The measured point (and tool orientation) of the true robot are recorded at seeded random
configurations within the joint limits, then noise is added: isotropic Gaussian of standard
deviation ``noise_mm`` [mm] on x, y, z and, for poses, a rotation vector of standard
deviation ``noise_mrad`` [mrad] per axis (base frame), left-multiplied onto the true
orientation.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .exceptions import DataError, InvalidArgumentError
from .fileio import write_atomic
from .identifiability import Identifiability, analyze_model
from .jacobian import Measurement, measured_point
from .mdh import MDHModel, from_chain
from .parameters import ParameterSet, parameter_set
from .robot import Chain
from .so3 import matrix_to_quaternion, quaternion_to_matrix, rotation_matrix

POSITION_COLUMNS = ("x", "y", "z")
"""Columns of the measured point [m]."""

MAX_COORDINATE = 1e3
"""Largest magnitude [m] of a measured coordinate: a point near a robot, not a kilometre away.

Larger values (a unit mix-up, a corrupt file) are rejected: squared in the residuals they
would overflow to infinity.
"""

QUATERNION_COLUMNS = ("qx", "qy", "qz", "qw")
"""Columns of the measured orientation, a quaternion with the scalar last."""

LIMIT_TOL = 1e-9
"""Slack [rad or m] allowed beyond a joint limit (values written at the limit, rounded)."""

CAMPAIGN_MEASURES = ("pose", "position")
"""What a campaign can measure."""


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Measurements:
    """Measured tool points (and orientations) at joint configurations, a value object.

    Attributes:
        joint_names: URDF joint of each column of ``q``, base to tool.
        q: Joint positions ``(m, n)`` [rad or m].
        position: Measured point in the measurement frame ``(m, 3)`` [m], every coordinate
            within ``MAX_COORDINATE``.
        quaternion: Measured tool orientation ``(m, 4)`` (qx, qy, qz, qw; unit norm), or
            None for position-only data.
        source: Where the data came from (a file path), for messages.
    """

    joint_names: tuple[str, ...]
    q: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray | None = None
    source: str = "<measurements>"

    def __post_init__(self) -> None:
        q = np.atleast_2d(np.asarray(self.q, dtype=float))
        m = q.shape[0]
        pos = np.asarray(self.position, dtype=float)
        if q.ndim != 2 or q.shape[1] != len(self.joint_names) or m == 0:
            raise InvalidArgumentError(
                f"joint positions must have shape (m >= 1, {len(self.joint_names)}), got "
                f"{np.shape(self.q)}"
            )
        if pos.shape != (m, 3):
            raise InvalidArgumentError(f"positions must have shape ({m}, 3), got {pos.shape}")
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(pos))):
            raise InvalidArgumentError("measurements contain NaN or infinity")
        if np.any(np.abs(pos) > MAX_COORDINATE):
            i, j = (int(v) for v in np.argwhere(np.abs(pos) > MAX_COORDINATE)[0])
            raise InvalidArgumentError(
                f"measured {POSITION_COLUMNS[j]} = {pos[i, j]:.9g} (configuration {i + 1}) is "
                f"not a plausible measurement in metres: coordinates are within "
                f"{MAX_COORDINATE:g} m"
            )
        if self.quaternion is not None:
            quat = np.asarray(self.quaternion, dtype=float)
            if quat.shape != (m, 4):
                raise InvalidArgumentError(
                    f"quaternions must have shape ({m}, 4), got {quat.shape}"
                )
            if not np.all(np.isfinite(quat)):
                raise InvalidArgumentError("quaternions must be finite and non-zero")
            # The norm of the quaternion scaled by its largest component first: (1e300, 0,
            # 0, 1e300) is a rotation too, and its plain norm overflows.
            big = np.max(np.abs(quat), axis=1)
            unit = quat / np.where(big > 0, big, 1.0)[:, None]
            if np.any(big * np.linalg.norm(unit, axis=1) < 1e-12):
                raise InvalidArgumentError("quaternions must be finite and non-zero")
            unit /= np.linalg.norm(unit, axis=1)[:, None]
            object.__setattr__(self, "quaternion", _frozen(unit))
        object.__setattr__(self, "joint_names", tuple(self.joint_names))
        object.__setattr__(self, "q", _frozen(q))
        object.__setattr__(self, "position", _frozen(pos))

    @property
    def m(self) -> int:
        """Number of configurations (rows)."""
        return self.q.shape[0]

    @property
    def measure(self) -> str:
        """``pose`` when orientations are present, else ``position``."""
        return "position" if self.quaternion is None else "pose"

    @property
    def rotations(self) -> np.ndarray | None:
        """Measured tool orientations as rotation matrices ``(m, 3, 3)``, or None."""
        if self.quaternion is None:
            return None
        return quaternion_to_matrix(self.quaternion)

    def position_only(self) -> Measurements:
        """The same data without the orientations."""
        return Measurements(self.joint_names, self.q, self.position, None, self.source)

    @property
    def columns(self) -> tuple[str, ...]:
        """CSV header of this data."""
        quat = QUATERNION_COLUMNS if self.quaternion is not None else ()
        return (*self.joint_names, *POSITION_COLUMNS, *quat)

    def table(self) -> np.ndarray:
        """The values in the order of :attr:`columns`, ``(m, len(columns))``."""
        parts = [self.q, self.position]
        if self.quaternion is not None:
            parts.append(self.quaternion)
        return np.hstack(parts)


def joint_bounds(chain: Chain) -> tuple[np.ndarray, np.ndarray]:
    """Limits a measured joint position must respect [rad or m]: infinite for continuous joints."""
    lower = np.where(chain.continuous, -np.inf, chain.lower)
    upper = np.where(chain.continuous, np.inf, chain.upper)
    return lower, upper


def _unit(sigma: int) -> str:
    return "m" if sigma == 1 else "rad"


def check_against_chain(data: Measurements, chain: Chain) -> None:
    """Check that measurements belong to a chain: same joints, values within the limits.

    Raises:
        DataError: Other joints, or a joint value outside its limits (row numbers count
            data rows from 1 here; :func:`read_measurements` reports file rows instead).
    """
    if data.joint_names != chain.joint_names:
        raise DataError(
            data.source,
            f"joints {', '.join(data.joint_names)} do not match the chain's "
            f"{', '.join(chain.joint_names)}",
        )
    _check_limits(chain, data.q, data.source, np.arange(1, data.m + 1))


def _check_limits(chain: Chain, q: np.ndarray, source: str, rows: np.ndarray) -> None:
    """Raise a DataError naming the first joint value outside its limits (row-major order)."""
    lower, upper = joint_bounds(chain)
    bad = (q < lower - LIMIT_TOL) | (q > upper + LIMIT_TOL)
    if not np.any(bad):
        return
    i, k = (int(v) for v in np.argwhere(bad)[0])
    unit = _unit(int(chain.sigma[k]))
    raise DataError(
        source,
        f"joint value {q[i, k]:.9g} {unit} is outside the joint limits "
        f"[{chain.lower[k]:.9g}, {chain.upper[k]:.9g}] {unit}",
        row=int(rows[i]),
        column=chain.joint_names[k],
    )


def _header(cells: list[str], chain: Chain, src: str, line: int) -> tuple[list[str], bool]:
    """Validate the header; return the column names and whether orientations are present."""
    names = [c.strip() for c in cells]
    allowed = (*chain.joint_names, *POSITION_COLUMNS, *QUATERNION_COLUMNS)
    seen: set[str] = set()
    for j, name in enumerate(names):
        if not name:
            raise DataError(
                src, f"header cell {j + 1} is empty: every column needs a name", row=line
            )
        if name in seen:
            raise DataError(src, "duplicate column", row=line, column=name)
        if name not in allowed:
            raise DataError(
                src,
                f"unknown column: expected the chain's joints ({', '.join(chain.joint_names)}), "
                f"x, y, z and, for poses, qx, qy, qz, qw",
                row=line,
                column=name,
            )
        seen.add(name)
    for name in (*chain.joint_names, *POSITION_COLUMNS):
        if name not in seen:
            kind = "joint" if name in chain.joint_names else "position"
            raise DataError(src, f"missing {kind} column", row=line, column=name)
    present = [c in seen for c in QUATERNION_COLUMNS]
    if any(present) and not all(present):
        missing = QUATERNION_COLUMNS[present.index(False)]
        raise DataError(
            src,
            "missing quaternion column: orientations need qx, qy, qz, qw",
            row=line,
            column=missing,
        )
    return names, all(present)


def _number(cell: str, src: str, line: int, column: str) -> float:
    text = cell.strip()
    if not text:
        raise DataError(src, "empty cell", row=line, column=column)
    try:
        value = float(text)
    except ValueError:
        raise DataError(src, f"not a number: {text!r}", row=line, column=column) from None
    if not math.isfinite(value):
        raise DataError(src, f"{text!r} is not a finite number", row=line, column=column)
    return value


def parse_measurements(text: str, chain: Chain, source: str = "<text>") -> Measurements:
    """Parse and validate CSV text (see the module docstring for the format).

    Args:
        text: The CSV content.
        chain: The chain the data belongs to (joint names and limits).
        source: Name of the data in messages (a file path).

    Returns:
        The measurements, joints in chain order.

    Raises:
        DataError: Missing, unknown or duplicate column, a row of the wrong length, an empty,
            non-numeric or non-finite cell, a joint value outside its limits, a measured
            coordinate beyond ``MAX_COORDINATE`` [m], a zero quaternion, or no data row.
    """
    reader = csv.reader(io.StringIO(text))
    names: list[str] | None = None
    has_quat = False
    values: list[list[float]] = []
    lines: list[int] = []
    try:
        for cells in reader:
            line = reader.line_num
            if not any(c.strip() for c in cells):
                continue
            if names is None:
                names, has_quat = _header(cells, chain, source, line)
                continue
            if len(cells) != len(names):
                raise DataError(
                    source, f"expected {len(names)} cells, found {len(cells)}", row=line
                )
            values.append([_number(c, source, line, n) for c, n in zip(cells, names, strict=True)])
            lines.append(line)
    except csv.Error as exc:
        raise DataError(source, f"malformed CSV: {exc}", row=reader.line_num) from None
    if names is None:
        raise DataError(source, "empty file: expected a header line and measurement rows")
    if not values:
        raise DataError(source, "no measurement rows after the header")
    table = np.array(values)
    col = {n: j for j, n in enumerate(names)}
    q = table[:, [col[n] for n in chain.joint_names]]
    _check_limits(chain, q, source, np.array(lines))
    position = table[:, [col[n] for n in POSITION_COLUMNS]]
    far = np.abs(position) > MAX_COORDINATE
    if np.any(far):
        i, j = (int(v) for v in np.argwhere(far)[0])
        raise DataError(
            source,
            f"{position[i, j]:.9g} is not a plausible measurement in metres (coordinates are "
            f"within {MAX_COORDINATE:g} m)",
            row=lines[i],
            column=POSITION_COLUMNS[j],
        )
    quat = None
    if has_quat:
        quat = table[:, [col[n] for n in QUATERNION_COLUMNS]]
        big = np.max(np.abs(quat), axis=1)
        zero = big * np.linalg.norm(quat / np.where(big > 0, big, 1.0)[:, None], axis=1) < 1e-12
        if np.any(zero):
            raise DataError(
                source,
                "the quaternion (qx, qy, qz, qw) has zero norm",
                row=lines[int(np.argmax(zero))],
            )
    return Measurements(chain.joint_names, q, position, quat, source)


def read_measurements(path: str | Path, chain: Chain) -> Measurements:
    """Read and validate a measurement CSV file (see the module docstring for the format).

    Args:
        path: The CSV file.
        chain: The chain the data belongs to (joint names and limits).

    Returns:
        The measurements, joints in chain order.

    Raises:
        DataError: The file is missing or unreadable, or its content is invalid (see
            :func:`parse_measurements`).
    """
    src = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise DataError(src, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DataError(src, f"cannot read the file: {exc}") from None
    return parse_measurements(text, chain, src)


def measurements_csv(data: Measurements) -> str:
    """The CSV text of measurements, full precision (``repr`` of every float)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(data.columns)
    for row in data.table():
        writer.writerow([repr(float(v)) for v in row])
    return out.getvalue()


def write_measurements(path: str | Path, data: Measurements) -> None:
    """Write measurements as CSV atomically (the file is complete or not written at all)."""
    write_atomic(path, measurements_csv(data))


@dataclass(frozen=True, eq=False)
class SimulationTruth:
    """What a simulated campaign hides from the calibration: the true robot and errors.

    Attributes:
        robot: Robot name.
        base_frame: Frame -1 of the nominal model (the true model's is the measurement frame).
        tool_frame: Frame n+1.
        params: The standard parameter set that was perturbed.
        errors: True error of every parameter of ``params`` [rad or m].
        true_mdh: The true MDH model (nominal + errors).
        measurement: What was measured (rows and marker).
        analysis: Identifiability of the nominal model (URDF round-off removed, as in
            :func:`calib.analyze`) at the campaign's configurations.
        base_values: True value of each base parameter, ``dX1 + B dX2`` [rad or m], in the
            order of ``analysis.base`` (first order: exact where the regrouping is exact).
        seed: Seed of the configurations, the errors and the noise.
        error_mm: Standard deviation of the length errors [mm].
        error_mrad: Standard deviation of the angle errors [mrad].
        noise_mm: Standard deviation of the position noise per axis [mm].
        noise_mrad: Standard deviation of the orientation noise per axis [mrad].
    """

    robot: str
    base_frame: str
    tool_frame: str
    params: ParameterSet
    errors: np.ndarray
    true_mdh: MDHModel
    measurement: Measurement
    analysis: Identifiability
    base_values: np.ndarray
    seed: int
    error_mm: float
    error_mrad: float
    noise_mm: float
    noise_mrad: float

    def to_dict(self) -> dict:
        """JSON-ready record of the truth (radians, metres)."""
        return {
            "robot": self.robot,
            "base_frame": self.base_frame,
            "tool_frame": self.tool_frame,
            "measure": self.measurement.label,
            "marker": list(self.measurement.marker),
            "params": self.params.label,
            "configs": self.analysis.n_configs,
            "seed": self.seed,
            "error_mm": self.error_mm,
            "error_mrad": self.error_mrad,
            "noise_mm": self.noise_mm,
            "noise_mrad": self.noise_mrad,
            "parameter_names": list(self.params.names),
            "errors": {n: float(v) for n, v in zip(self.params.names, self.errors, strict=True)},
            "base_parameters": {
                n: float(v) for n, v in zip(self.analysis.base, self.base_values, strict=True)
            },
            "regrouping": self.analysis.regrouping(),
            "true_mdh": self.true_mdh.rows(),
        }


@dataclass(frozen=True, eq=False)
class Campaign:
    """A simulated measurement campaign: the data and the truth behind it.

    Attributes:
        measurements: What a calibration gets to see.
        truth: The true robot and errors, for checking.
    """

    measurements: Measurements
    truth: SimulationTruth


def _integer(what: str, value, minimum: int) -> int:
    """``value`` as an int, if it is an integer (not a bool) >= ``minimum``.

    Raises:
        InvalidArgumentError: None, a bool, a float, a string or a smaller integer.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InvalidArgumentError(f"{what} must be an integer >= {minimum}, got {value!r}")
    return int(value)


def _non_negative(name: str, value: float) -> float:
    number = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, bool
    )
    if not number or not math.isfinite(float(value)) or float(value) < 0:
        raise InvalidArgumentError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


def simulate(
    chain: Chain,
    configs: int = 100,
    measure: str = "pose",
    marker=None,
    error_mm: float = 1.0,
    error_mrad: float = 1.0,
    noise_mm: float = 0.0,
    noise_mrad: float | None = None,
    seed: int = 0,
    params: str = "complete",
) -> Campaign:
    """Simulate a measurement campaign on a perturbed ("true") copy of a chain.

    The configurations are those ``calib analyze --seed SEED`` draws (uniform within the
    joint limits); the errors and the noise come from two further streams of the same seed.

    Args:
        chain: The nominal chain.
        configs: Number of configurations m (an integer >= 1).
        measure: ``pose`` or ``position``.
        marker: Measured point in the tool frame, 3 numbers [m] (default: the tool origin).
        error_mm: Standard deviation of every length error [mm].
        error_mrad: Standard deviation of every angle error [mrad].
        noise_mm: Standard deviation of the position noise per axis [mm].
        noise_mrad: Standard deviation of the orientation noise per axis [mrad] (default:
            the number given as ``noise_mm``, so that 1 mrad weighs like 1 mm).
        seed: Seed (an integer >= 0; not None, a bool or a float).
        params: Parameter set perturbed: ``complete`` (default) or ``paper``.

    Returns:
        The campaign.

    Raises:
        InvalidArgumentError: A bad argument.
    """
    if measure not in CAMPAIGN_MEASURES:
        raise InvalidArgumentError(f"unknown measure '{measure}': choose pose or position")
    m = _integer("the number of configurations", configs, 1)
    seed = _integer("the seed", seed, 0)
    error_mm = _non_negative("error_mm", error_mm)
    error_mrad = _non_negative("error_mrad", error_mrad)
    noise_mm = _non_negative("noise_mm", noise_mm)
    noise_mrad = noise_mm if noise_mrad is None else _non_negative("noise_mrad", noise_mrad)
    measurement = Measurement.of(measure, marker)
    nominal = from_chain(chain)
    pset = parameter_set(nominal, params)

    q = chain.random_configurations(m, seed)
    rng_errors = np.random.default_rng([seed, 1])
    rng_noise = np.random.default_rng([seed, 2])
    rotation = np.array([p.kind.is_rotation for p in pset.parameters])
    scale = np.where(rotation, 1e-3 * error_mrad, 1e-3 * error_mm)
    errors = scale * rng_errors.standard_normal(len(pset))
    true_mdh = pset.apply(nominal, errors)

    kin = true_mdh.kinematics(q)
    position = measured_point(kin, measurement.marker_array)
    position = position + 1e-3 * noise_mm * rng_noise.standard_normal((m, 3))
    quat = None
    if measure == "pose":
        noise = 1e-3 * noise_mrad * rng_noise.standard_normal((m, 3))
        quat = matrix_to_quaternion(rotation_matrix(noise) @ kin.R[:, -1])

    analysis = analyze_model(nominal.idealized(), pset, measurement, q, robot=chain.name, seed=seed)
    index = {n: i for i, n in enumerate(pset.names)}
    kept = errors[[index[n] for n in analysis.base]]
    others = errors[[index[n] for n in analysis.others]]
    base_values = kept + analysis.B @ others if others.size else kept

    data = Measurements(chain.joint_names, q, position, quat, f"<simulated {chain.name}>")
    truth = SimulationTruth(
        robot=chain.name,
        base_frame=chain.base_frame,
        tool_frame=chain.tool_frame,
        params=pset,
        errors=_frozen(errors),
        true_mdh=true_mdh,
        measurement=measurement,
        analysis=analysis,
        base_values=_frozen(base_values),
        seed=seed,
        error_mm=error_mm,
        error_mrad=error_mrad,
        noise_mm=noise_mm,
        noise_mrad=noise_mrad,
    )
    return Campaign(data, truth)
