"""Simulated measurement campaigns of a tree: every tool measured at each configuration.

As for a chain (:func:`.simulation.simulate`): the "true" tree is the nominal one with
every parameter of its standard set perturbed by a seeded normal error (``error_mm`` [mm]
for lengths, ``error_mrad`` [mrad] for angles); a point on each tool (``markers``, in the
tool's frame) is recorded at seeded random configurations, one row per configuration and
tool (the ``tool`` column names it), and isotropic Gaussian noise of ``noise_mm`` [mm] is
added. The measurement frame is the true tree's frame -1. The errors come from ``robot_seed``
when it is given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.checks import angle_mrad, check_count, length_mm
from ..exceptions import InvalidArgumentError
from ..identification.parameters import ParameterSet
from ..identification.tree_jacobian import tree_parameters
from ..kinematics.tree import Tree
from ..kinematics.tree_model import TreeMDH, from_tree
from .data import Measurements
from .simulation import campaign_configurations, perturbed, robot_of

__all__ = ["TreeCampaign", "simulate_tree", "true_points"]


@dataclass(frozen=True, eq=False)
class TreeCampaign:
    """A simulated campaign of a tree and the truth behind it.

    Attributes:
        measurements: One row per configuration and tool (configuration-major).
        params: The perturbed standard set.
        errors: The true error of each of its parameters [rad or m].
        true_mdh: The true tree.
        markers: The true point on each tool ``(T, 3)`` [m].
        robot_seed: Seed of the errors where it is not the campaign's, else None.
    """

    measurements: Measurements
    params: ParameterSet
    errors: np.ndarray
    true_mdh: TreeMDH
    markers: np.ndarray
    robot_seed: int | None = None

    def __repr__(self) -> str:
        """One line (the rows are ``measurements``, the truth the other attributes)."""
        tools = self.true_mdh.tool_frames
        return (
            f"<TreeCampaign {self.measurements.source}: {self.measurements.m // len(tools)} "
            f"configurations x {len(tools)} tools ({', '.join(tools)}), "
            f"{len(self.params)} {self.params.label} parameters perturbed>"
        )


def true_points(mdh: TreeMDH, q: np.ndarray, markers: np.ndarray) -> np.ndarray:
    """The point of every tool at each configuration ``(m, T, 3)`` [m], base frame."""
    T = mdh.forward(q)
    return T[..., :3, 3] + np.einsum("mtij,tj->mti", T[..., :3, :3], markers)


def simulate_tree(
    tree: Tree,
    configs: int | np.ndarray = 100,
    markers=None,
    error_mm: float = 1.0,
    error_mrad: float = 1.0,
    noise_mm: float = 0.0,
    seed: int = 0,
    params: str = "complete",
    *,
    robot_seed: int | None = None,
) -> TreeCampaign:
    """Simulate a campaign measuring every tool of a tree at random configurations.

    Args:
        tree: The nominal tree.
        configs: Number of random configurations m (the data has m T rows), or the joint
            positions themselves ``(m, n)`` (a designed campaign).
        markers: Point on each tool ``(T, 3)`` or one for all ``(3,)`` [m] (default: origins).
        error_mm: Std of the length errors [mm].
        error_mrad: Std of the angle errors [mrad].
        noise_mm: Std of the measurement noise per axis [mm].
        seed: Seed of every draw (the errors': unless ``robot_seed``).
        params: Standard set to perturb (``paper`` or ``complete``).
        robot_seed: Seed of the true tree's errors, or None: ``seed`` (as
            :func:`~.simulation.simulate`).

    Raises:
        InvalidArgumentError: A bad argument.
    """
    if not isinstance(tree, Tree):
        raise InvalidArgumentError(f"tree must be a Tree (see load_tree), got {tree!r:.60}")
    n_tools = tree.n_tools
    mk = np.zeros((n_tools, 3)) if markers is None else np.array(markers, dtype=float)
    mk = np.broadcast_to(mk, (n_tools, 3)).copy() if mk.shape == (3,) else mk
    if mk.ndim == 2 and mk.shape[1] == 3 and len(mk) != n_tools:  # the words of design's
        raise InvalidArgumentError(
            f"a tree of {n_tools} tools takes one marker for all or one per tool, got {len(mk)}"
        )
    if mk.shape != (n_tools, 3) or not np.all(np.isfinite(mk)):
        raise InvalidArgumentError(f"markers must be (3,) or ({n_tools}, 3) finite numbers [m]")
    error_mm, error_mrad = length_mm(error_mm, "error_mm"), angle_mrad(error_mrad, "error_mrad")
    noise_mm = length_mm(noise_mm, "noise_mm")
    robot = robot_of(check_count(seed, "the seed", 0), robot_seed)
    nominal = from_tree(tree)
    pset = tree_parameters(nominal, params)
    count = isinstance(configs, int | np.integer) and not isinstance(configs, bool)
    q = campaign_configurations(tree, int(configs) if count else configs, seed)
    errors, true_mdh = perturbed(nominal, pset, (error_mm, error_mrad), robot)
    points = true_points(true_mdh, q, mk).reshape(-1, 3)
    points = points + 1e-3 * noise_mm * np.random.default_rng([seed, 2]).standard_normal(
        points.shape
    )
    data = Measurements(
        tree.joint_names,
        np.repeat(q, n_tools, axis=0),
        points,
        source=f"<simulated {tree.name}>",
        tool=tree.tool_frames * len(q),
        coupling=tree.coupling,
    )
    return TreeCampaign(data, pset, errors, true_mdh, mk, None if robot == seed else robot)
