"""A true robot for simulation: the nominal URDF with its joint origins moved, one file.

Several terms of one calibration (contact chains, a head camera measuring the hand) see one
robot. Their simulations share one truth when each is simulated, error-free, on chains loaded
from one perturbed URDF (:func:`true_robot`): every joint of the chains given has its origin
moved by a seeded random rigid error, and so has the fixed joint that places each measuring
frame given (a camera's placement on its link). :func:`~.simulation.simulate` (with
``error_mm=0, error_mrad=0``) then measures from the true camera frame, and
:func:`~.contact_campaign.simulate_contacts` touches with the true robot.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.checks import angle_mrad, check_count, length_mm
from ..exceptions import InvalidArgumentError
from ..kinematics.placement_export import write_moved_origins_urdf
from ..kinematics.robot import Chain
from ..kinematics.so3 import rotation_matrix
from ..kinematics.urdf_export import base_joint, read_urdf_source

__all__ = ["TrueRobot", "true_robot"]


@dataclass(frozen=True, eq=False)
class TrueRobot:
    """A perturbed copy of a robot, written as a URDF.

    Attributes:
        urdf: The true robot's URDF.
        errors: ``E_j`` ``(4, 4)`` by joint name: the true origin is the nominal one times
            ``E_j`` (the chains' joints, then the measuring frames' fixed joints).
    """

    urdf: Path
    errors: dict[str, np.ndarray]


def true_robot(
    chains: Sequence[Chain],
    path: str | Path,
    *,
    measuring: Sequence[Chain] = (),
    error_mm: float = 1.0,
    error_mrad: float = 1.0,
    seed: int = 0,
) -> TrueRobot:
    """Write a true robot: the joints of ``chains`` and the frames measuring moved.

    Args:
        chains: Chains of one robot (one URDF): each of their joints' origins is moved.
        path: The true URDF to write (not the nominal file).
        measuring: Chains whose base frame measures (a head camera): the fixed joint that
            places it on its link is moved too.
        error_mm: Standard deviation of each translation component [mm].
        error_mrad: Standard deviation of each rotation component [mrad].
        seed: Seed of the errors (an integer >= 0).

    Raises:
        InvalidArgumentError: No chain, chains of several robots, or a bad number.
        CalibError: A measuring frame not fixed to a link by a fixed joint.
    """
    if not isinstance(chains, Sequence) or not isinstance(measuring, Sequence) or not chains:
        raise InvalidArgumentError("give the true robot's chains as a non-empty list of Chain")
    if not all(isinstance(c, Chain) for c in (*chains, *measuring)):
        raise InvalidArgumentError("give the true robot's chains as a non-empty list of Chain")
    if len({c.urdf_resolved for c in (*chains, *measuring)}) != 1:
        raise InvalidArgumentError("the chains of a true robot must be chains of one URDF")
    seed = check_count(seed, "seed", 0)
    sd_m, sd_rad = (
        1e-3 * length_mm(error_mm, "error_mm"),
        1e-3 * angle_mrad(error_mrad, "error_mrad"),
    )
    names = list(dict.fromkeys(n for c in chains for n in c.joint_names))
    _, root = read_urdf_source(chains[0])
    names += [
        n
        for n in dict.fromkeys(base_joint(root, c).get("name", "") for c in measuring)
        if n not in names
    ]
    rng = np.random.default_rng([seed, 5])
    errors = {}
    for name in names:
        E = np.eye(4)
        E[:3, :3] = rotation_matrix(sd_rad * rng.standard_normal(3))
        E[:3, 3] = sd_m * rng.standard_normal(3)
        errors[name] = E
    write_moved_origins_urdf(path, chains[0], errors)
    return TrueRobot(Path(path), errors)
