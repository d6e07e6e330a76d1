"""Simulated measurement campaigns of a chain: a perturbed ("true") copy, measured.

The campaign is measured at seeded configurations. It lives apart from :mod:`.csvfile`, so
that reading a CSV does not import the identifiability analysis.

Simulated campaigns (:func:`simulate`): a "true" robot is the
nominal MDH model with every standard parameter of the chosen set perturbed by a seeded normal
error (standard deviation ``error_mm`` [mm] for lengths, ``error_mrad`` [mrad] for angles);
rows 0 and 1 carry the base error (the measurement frame is frame -1 of the true model) and row
n+1 the tool error. The measured point (and tool orientation) of the true robot are recorded at
seeded random configurations within the joint limits, then noise is added: isotropic Gaussian
of standard deviation ``noise_mm`` [mm] on x, y, z and, for poses, a rotation vector of
standard deviation ``noise_mrad`` [mrad] per axis (base frame), left-multiplied onto the true
orientation. Several markers (a sequence of points on the tool) are measured at each
configuration, each with noise of its own, drawn after marker 1's. One seed draws the
configurations, the errors and the noise; ``robot_seed`` draws the errors instead (the same
true robot at other configurations, or other true robots at the same ones).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np

from ..core.checks import angle_mrad, check_count, length_mm, read_only
from ..core.choices import DEFAULT_MEASURE, DEFAULT_SET
from ..exceptions import InvalidArgumentError
from ..identification.identifiability import Identifiability, analyze_model
from ..identification.jacobian import measured_point
from ..identification.kinds import campaign_kind
from ..identification.measures import MeasureKind, Measurement
from ..identification.parameters import ParameterSet, parameter_set
from ..kinematics.mdh import MDHModel, from_chain
from ..kinematics.robot import Chain
from ..kinematics.so3 import matrix_to_quaternion, rotation_matrix
from ..kinematics.tree import Tree, load_robot
from ..kinematics.tree_model import TreeMDH
from .data import Measurements
from .limits import check_limits, warn_default_ranges

_Model = TypeVar("_Model", MDHModel, TreeMDH)
"""A chain's or a tree's model (:func:`perturbed` returns the kind it is given)."""


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
        seed: Seed of the configurations and the noise, and of the errors unless
            ``robot_seed``.
        error_mm: Standard deviation of the length errors [mm].
        error_mrad: Standard deviation of the angle errors [mrad].
        noise_mm: Standard deviation of the position noise per axis [mm].
        noise_mrad: Standard deviation of the orientation noise per axis [mrad].
        markers: Every measured point in the tool frame ``(K, 3)`` [m], marker 1 first (the
            one ``measurement`` and ``analysis`` hold).
        robot_seed: Seed of the errors where it is not ``seed`` (``simulate(robot_seed=)``),
            else None.
    """

    robot: str
    base_frame: str
    tool_frame: str
    params: ParameterSet
    errors: np.ndarray
    true_mdh: MDHModel
    measurement: MeasureKind
    analysis: Identifiability
    base_values: np.ndarray
    seed: int
    error_mm: float
    error_mrad: float
    noise_mm: float
    noise_mrad: float
    markers: np.ndarray | None = None
    robot_seed: int | None = None

    def __repr__(self) -> str:
        """One line (the errors and the true model are attributes, ``to_dict()`` all of it)."""
        angles = any(row >= 3 for row in getattr(self.measurement, "rows", ()))
        noise = f"{self.noise_mm:g} mm" + (f", {self.noise_mrad:g} mrad" if angles else "")
        return (
            f"<SimulationTruth {self.robot}: {self.base_frame} -> {self.tool_frame}, measure "
            f"{self.measurement.label}, {len(self.params)} {self.params.label} parameters "
            f"perturbed ({self.error_mm:g} mm, {self.error_mrad:g} mrad), noise {noise}, "
            f"seed {self.seed}{robot_words(self.robot_seed)}>"
        )

    def to_dict(self) -> dict:
        """JSON-ready record of the truth (radians, metres)."""
        return {
            "robot": self.robot,
            "base_frame": self.base_frame,
            "tool_frame": self.tool_frame,
            "measure": self.measurement.label,
            "marker": list(self.measurement.marker),
            "markers": [list(self.measurement.marker)]
            if self.markers is None
            else self.markers.tolist(),
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
        } | robot_entry(self.robot_seed)


@dataclass(frozen=True, eq=False)
class Campaign:
    """A simulated measurement campaign: the data and the truth behind it.

    Attributes:
        measurements: What a calibration gets to see.
        truth: The true robot and errors, for checking.
    """

    measurements: Measurements
    truth: SimulationTruth

    def __repr__(self) -> str:
        """One line (the rows are ``measurements``, the errors ``truth``)."""
        t = self.truth
        return (
            f"<Campaign {t.robot}: {self.measurements.m} configurations, measure "
            f"{t.measurement.label}, noise {t.noise_mm:g} mm, seed {t.seed}>"
        )


def chain_argument(value: object, caller: str, tree_hint: str = "") -> Chain:
    """``value`` if it is a :class:`Chain`, or the chain a catalog name or URDF path names.

    A name or path loads as :func:`calib.analyze` loads it
    (:func:`~calib.kinematics.tree.load_robot`: the catalog's base and tool).

    Raises:
        InvalidArgumentError: Anything else (a tree, loaded or named), named with the
            function the user called (``caller``) and, for a tree, ``tree_hint``.
    """
    if isinstance(value, str | Path):
        value = load_robot(value)
    if isinstance(value, Chain):
        return value
    got = f"{type(value).__name__} {value!r:.60}"
    if getattr(value, "is_tree", False):  # a robot says what it is (no class dispatch)
        got = f"the tree {getattr(value, 'name', '')!r}{tree_hint}"
    raise InvalidArgumentError(
        f"{caller} takes a Chain (see load_chain), a catalog name or a URDF path, got {got}"
    )


def simulate(
    chain: Chain | str | Path,
    configs: int | np.ndarray = 100,
    measure: str | MeasureKind = DEFAULT_MEASURE,
    marker=None,
    error_mm: float = 1.0,
    error_mrad: float = 1.0,
    noise_mm: float = 0.0,
    noise_mrad: float | None = None,
    seed: int = 0,
    params: str = DEFAULT_SET,
    *,
    robot_seed: int | None = None,
) -> Campaign:
    """Simulate a measurement campaign on a perturbed ("true") copy of a chain.

    The configurations are those ``calib analyze --seed SEED`` draws (uniform within the
    joint limits); the errors and the noise come from two further streams of the same seed
    (the errors: of ``robot_seed``, when given).

    Args:
        chain: The nominal chain, or a catalog name or URDF path (loaded as
            :func:`calib.analyze` loads it: the catalog's base and tool).
        configs: Number of configurations m (an integer >= 1), or the configurations
            themselves ``(m, n)`` [rad or m] (a designed set).
        measure: ``position`` (default, as ``analyze`` and ``design``) or ``pose`` (a name
            or the kind).
        marker: Measured point in the tool frame, 3 numbers [m] (default: the tool origin),
            or several points, a sequence of K triples (markers on the tool, each with its
            own noise; the truth's ``analysis`` and ``base_values`` are marker 1's).
        error_mm: Standard deviation of every length error [mm].
        error_mrad: Standard deviation of every angle error [mrad].
        noise_mm: Standard deviation of the position noise per axis [mm].
        noise_mrad: Standard deviation of the orientation noise per axis [mrad] (default:
            the number given as ``noise_mm``, so that 1 mrad weighs like 1 mm); one above 0
            with a measure of no orientation is refused.
        seed: Seed (an integer >= 0; not None, a bool or a float).
        params: Parameter set perturbed: ``complete`` (default) or ``paper``.
        robot_seed: Seed of the true robot's errors (an integer >= 0), or None: ``seed``.
            ``seed=2, robot_seed=1``: the true robot of ``seed=1`` at the configurations
            (and with the noise) of ``seed=2``.

    Returns:
        The campaign.

    Raises:
        InvalidArgumentError: A bad argument.
    """
    tree_route = ": a tree's campaign is calib.measurements.tree_campaign.simulate_tree"
    chain = chain_argument(chain, "simulate", tree_route)
    markers = [campaign_kind(measure, mk, TOUCHES) for mk in _several(marker)]
    measurement = markers[0]
    given = isinstance(configs, np.ndarray | list | tuple)
    m = 0 if given else check_count(configs, "the number of configurations")
    seed = check_count(seed, "the seed", 0)
    robot = robot_of(seed, robot_seed)
    error_mm, error_mrad = length_mm(error_mm, "error_mm"), angle_mrad(error_mrad, "error_mrad")
    noise_mm, noise_mrad = _checked_noise(noise_mm, noise_mrad, measurement)
    nominal = from_chain(chain)
    pset = parameter_set(nominal, params)

    q = campaign_configurations(chain, configs if given else m, seed)
    errors, true_mdh = perturbed(nominal, pset, (error_mm, error_mrad), robot)
    position, quat = _measured(true_mdh.kinematics(q), markers, (noise_mm, noise_mrad), seed)

    analysis = analyze_model(nominal.idealized(), pset, measurement, q, robot=chain.name, seed=seed)

    data = Measurements(
        chain.joint_names,
        q,
        position,
        quat,
        f"<simulated {chain.name}>",
        coupling=chain.coupling,
    )
    truth = SimulationTruth(
        robot=chain.name,
        base_frame=chain.base_frame,
        tool_frame=chain.tool_frame,
        params=pset,
        errors=read_only(errors),
        true_mdh=true_mdh,
        measurement=measurement,
        analysis=analysis,
        base_values=read_only(_base_values(errors, pset, analysis)),
        seed=seed,
        error_mm=error_mm,
        error_mrad=error_mrad,
        noise_mm=noise_mm,
        noise_mrad=noise_mrad,
        markers=read_only(np.array([k.marker_array for k in markers])),
        robot_seed=None if robot == seed else robot,
    )
    return Campaign(data, truth)


def robot_of(seed: int, robot_seed: int | None) -> int:
    """The seed of a campaign's true robot: ``robot_seed`` checked, or ``seed`` (None)."""
    return seed if robot_seed is None else check_count(robot_seed, "robot_seed", 0)


def robot_words(robot_seed: int | None) -> str:
    """``, robot seed R`` for a true robot of another seed than the campaign's, else empty."""
    return "" if robot_seed is None else f", robot seed {robot_seed}"


def robot_entry(robot_seed: int | None) -> dict:
    """A truth record's ``robot_seed`` (a true robot of another seed), else nothing."""
    return {} if robot_seed is None else {"robot_seed": robot_seed}


def _checked_noise(noise_mm, noise_mrad, measurement: Measurement) -> tuple[float, float]:
    """The position and orientation noise [mm, mrad] (the latter: ``noise_mm``'s by default).

    Raises:
        InvalidArgumentError: A bad number, or an orientation noise given above 0 with a
            measure that records no orientation.
    """
    noise_mm = length_mm(noise_mm, "noise_mm")
    asked = None if noise_mrad is None else angle_mrad(noise_mrad, "noise_mrad")
    if asked and not measurement.is_pose:  # one given (noise_mm's too): as the command line's
        raise InvalidArgumentError(
            f"noise_mrad is the orientation noise of a pose: measure {measurement.label!r} "
            "records no orientation"
        )
    return noise_mm, noise_mm if asked is None else asked


def campaign_configurations(
    chain: Chain | Tree, configs: int | np.ndarray, seed: int
) -> np.ndarray:
    """A campaign's configurations: ``configs`` drawn (a count), or the given ones checked."""
    if isinstance(configs, int):
        warn_default_ranges(chain, "give your own configurations")
        return chain.random_configurations(configs, seed)
    q = chain.check_configurations(configs)
    # as a configurations file is read: far past a limit (degrees?) is an error
    check_limits(chain, q, "the configurations", np.arange(1, len(q) + 1), warn=False)
    return q


def perturbed(
    nominal: _Model, pset: ParameterSet, error: tuple[float, float], seed: int
) -> tuple[np.ndarray, _Model]:
    """The true errors (stream ``[seed, 1]``) and the true model; ``error``: [mm, mrad].

    Every parameter of ``pset`` is perturbed by a normal error of standard deviation
    ``error_mm`` (a length) or ``error_mrad`` (an angle).
    """
    error_mm, error_mrad = error
    rng_errors = np.random.default_rng([seed, 1])
    rotation = np.array([p.kind.is_rotation for p in pset.parameters])
    scale = np.where(rotation, 1e-3 * error_mrad, 1e-3 * error_mm)
    errors = scale * rng_errors.standard_normal(len(pset))
    return errors, pset.apply(nominal, errors)


def _measured(kin, markers: list, noise: tuple, seed: int):
    """The measured points ``(m, 3 K)`` and, for a pose, quaternions ``(m, 4)`` (else None).

    ``noise``: [mm, mrad], drawn from the stream ``[seed, 2]``. Marker 1's position noise is
    drawn first, then the orientation noise, then each other marker's: one marker's campaign
    is the same with or without others.
    """
    noise_mm, noise_mrad = noise
    rng_noise = np.random.default_rng([seed, 2])
    position = measured_point(kin, markers[0].marker_array)
    m = len(position)
    position = position + 1e-3 * noise_mm * rng_noise.standard_normal((m, 3))
    quat = None
    if markers[0].is_pose:
        rotation_noise = 1e-3 * noise_mrad * rng_noise.standard_normal((m, 3))
        quat = matrix_to_quaternion(rotation_matrix(rotation_noise) @ kin.R[:, -1])
    for other in markers[1:]:  # after marker 1's draws: one marker's campaign is unchanged
        point = measured_point(kin, other.marker_array)
        point = point + 1e-3 * noise_mm * rng_noise.standard_normal((m, 3))
        position = np.hstack([position, point])
    return position, quat


def _base_values(errors: np.ndarray, pset: ParameterSet, analysis: Identifiability) -> np.ndarray:
    """True value of each base parameter, ``dX1 + B dX2``, in the order of ``analysis.base``."""
    index = {n: i for i, n in enumerate(pset.names)}
    kept = errors[[index[n] for n in analysis.base]]
    others = errors[[index[n] for n in analysis.others]]
    return kept + analysis.B @ others if others.size else kept


TOUCHES = " (touches: calib.simulate_contacts)"
"""What :func:`simulate` says a contact's campaign is made by."""


def _several(marker) -> list:
    """The markers given: ``[marker]`` (3 numbers or None), or a sequence of triples."""
    sequence = list | tuple | np.ndarray
    if (
        isinstance(marker, sequence)
        and len(marker)
        and all(isinstance(k, sequence) for k in marker)
    ):
        return list(marker)
    return [marker]


__all__ = [
    "Campaign",
    "SimulationTruth",
    "campaign_configurations",
    "chain_argument",
    "perturbed",
    "robot_entry",
    "robot_of",
    "robot_words",
    "simulate",
]
