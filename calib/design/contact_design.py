"""Experiment design for contact campaigns: postures where the contact holds.

A contact campaign measures nothing but the joints (:mod:`calib.identification.contacts`):
each posture must hold the contact, so the candidates are random configurations within the
joint limits (less the margin) projected onto it by the kind's Newton projection
(:func:`~calib.identification.contact_postures.contact_postures`), and those that do not reach it
within the limits are dropped. The plane, point or pose is the nominal contact frame's
placement at a first seeded posture (given candidates: the first one), as
:func:`calib.analyze` takes it.

The observation model's columns are the complete model in the contact's frame (every joint
placement, the contact frame as the tool and the plane, point or pose as frame -1), reduced
to its independent columns at the candidates: their number is :func:`calib.analyze`'s count
for the contact (``params="complete"``). Its rows are the kind's gap rows (m and rad), and
the predicted error I and G is the gap's, per unit noise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..calibration.determined import determined_columns
from ..core.checks import check_count, check_work
from ..exceptions import InvalidArgumentError
from ..identification.contact_postures import contact_model, contact_postures, project
from ..identification.contacts import CONTACT_TOL, Contact
from ..identification.identifiability import preference_order
from ..identification.jacobian import identification_jacobian
from ..identification.parameters import parameter_set
from ..kinematics.mdh import MDHModel, from_chain
from ..kinematics.robot import Chain
from ..kinematics.tree import Tree
from .constraints import variable_bounds
from .observability import ObservationModel, characteristic_length

CONTACT_ROUNDS = 8
"""Draws of starting postures tried before a contact design gives up."""


@dataclass(frozen=True, eq=False)
class ContactCandidates:
    """Candidates of a contact design.

    Attributes:
        model: The chain's nominal model in the contact's frame (frame -1: the plane, point
            or pose).
        frame: The plane, point or pose in the chain's base frame ``(4, 4)``.
        q: Postures where the contact holds, within the limits ``(N, n)`` [rad or m].
        rows: For each posture, the index of the given candidate it comes from ``(N,)``
            (drawn candidates: ``0 .. N-1``).
    """

    model: MDHModel
    frame: np.ndarray
    q: np.ndarray
    rows: np.ndarray


def checked_contact_chain(chain: Chain | Tree, kind: Contact, markers, params: str) -> Chain:
    """The chain of a contact design, or a clear error.

    Raises:
        InvalidArgumentError: A tree, mimic joints, a marker, or a level other than complete.
    """
    if chain.is_tree or not isinstance(chain, Chain) or chain.coupling is not None:
        raise InvalidArgumentError(
            f"a {kind.label} contact is designed on one chain without mimic joints"
        )
    if markers is not None:
        raise InvalidArgumentError(
            f"a {kind.label} contact measures no point: give no marker (the contact frame is "
            f"the tool frame)"
        )
    if params != "complete":
        raise InvalidArgumentError(
            f"a {kind.label} contact design fits the complete model: use params='complete' "
            f"(the default)"
        )
    return chain


def contact_candidates(
    chain: Chain, kind: Contact, candidates: int | np.ndarray, seed: int, margin: float = 0.0
) -> ContactCandidates:
    """Postures on the contact within the joint limits less the margin.

    Args:
        chain: The chain (no mimic joints).
        kind: The contact.
        candidates: How many to draw, or starting configurations ``(N, n)`` (projected onto
            the contact; the first one places the plane, point or pose; those that do not
            reach it within the limits are dropped).
        seed: Seed of the draws.
        margin: Margin inside the joint limits [rad or m].

    Raises:
        InvalidArgumentError: Too few postures reach the contact within the limits.
    """
    lower, upper = variable_bounds(chain, margin)
    nominal = from_chain(chain).idealized()
    seed = check_count(seed, "the seed", 0)

    def draw(count: int, r: int) -> np.ndarray:
        rng = np.random.default_rng([seed, 7, r])
        return lower + (upper - lower) * rng.random((count, len(lower)))

    if isinstance(candidates, int | np.integer) and not isinstance(candidates, bool):
        n = check_count(candidates, "the number of candidates")
        check_work(n, chain.n, chain.name, 1, "candidates")
        q0 = draw(1, 0)[0]
        model = contact_model(nominal, q0, kind.label)
        q = contact_postures(
            model, kind, lambda c, r: draw(c, r + 1), n, CONTACT_ROUNDS, (lower, upper)
        )
        rows = np.arange(len(q))
    else:
        start = chain.check_configurations(candidates)
        q0 = np.clip(start[0], lower, upper)
        model = contact_model(nominal, q0, kind.label)
        q, gap = project(model, kind, np.clip(start, lower, upper), bounds=(lower, upper))
        rows = np.flatnonzero(gap < CONTACT_TOL)
        q = q[rows]
        if not len(q):
            raise InvalidArgumentError(
                f"none of the {len(start)} candidates reaches the {kind.label} contact within "
                f"the joint limits"
            )
    return ContactCandidates(model, nominal.forward(q0[None])[0], q, rows)


def contact_observation_model(
    chain: Chain, cands: ContactCandidates, kind: Contact
) -> ObservationModel:
    """The observation model of a contact campaign: the gap rows of the complete model.

    The columns are the complete model in the contact's frame (every joint placement, the
    contact frame as the tool, the plane, point or pose as frame -1), reduced to the
    independent ones at the candidates (postures on the contact): as many as
    :func:`calib.analyze` counts for the contact with ``params="complete"``. The rows are
    the kind's gap rows [m and rad]; the predicted errors I and G are the gap's, per unit
    noise.

    Args:
        chain: The chain that touches (its nominal model gives the characteristic length).
        cands: The candidates of the design (:func:`contact_candidates`).
        kind: The contact kind.

    Returns:
        The observation model, without markers (``n_markers`` 0).
    """
    model = cands.model
    pset = parameter_set(model, "complete")

    def jacobian_of(q: np.ndarray) -> np.ndarray:
        W = identification_jacobian(model, pset, q, kind)
        return W.reshape(len(q), kind.n_rows, -1)

    kept = determined_columns(jacobian_of(cands.q), preference_order(model, pset))
    nominal = from_chain(chain).idealized()
    return ObservationModel(
        names=tuple(pset.names[i] for i in kept),
        angular=np.array([pset.parameters[i].kind.is_rotation for i in kept], dtype=bool),
        length=characteristic_length(np.hypot(nominal.d, nominal.r), np.zeros((1, 3))),
        rows=kind.n_rows,
        n_markers=0,
        joint_names=chain.joint_names,
        jacobian_of=jacobian_of,
        columns=np.array(kept, dtype=int),
    )


__all__ = [
    "ContactCandidates",
    "checked_contact_chain",
    "contact_candidates",
    "contact_observation_model",
]
