"""What a measured chain's structure lets rows determine, and the joint engine's counts of it.

A level measured by an instrument offers the directions generic configurations determine
(:class:`Generic`): the reduction the structure forces is the level's, not the data's.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..core.choices import DEFAULT_CONFIGS
from ..exceptions import DataError
from ..kinematics.tree import tree_of_chains
from ..measurements.data import Measurements
from ..measurements.postures import count, posture_groups, sample_postures
from . import determined
from .engine_model import ChainsData, ChainsModel, ChainsState

__all__ = ["GENERIC_EXCESS", "Generic", "assess", "chain_name", "sampled"]


GENERIC_EXCESS = 3
"""Equations per unknown of the generic configurations' Jacobian whose rank is the structure's.
Rationale and measurements: docs/developers/engine.md#generic_excess"""


def chain_name(name: str) -> str:
    """A one-chain fit's unknown as a chain names it: ``instrument.frame.z`` -> ``frame.z``."""
    head, _, rest = name.partition(".")
    return rest if rest and (head == "instrument" or head.startswith("term")) else name


def rows_like(data: Measurements, joint_names, q: np.ndarray) -> Measurements:
    """Rows of ``data``'s kind at the joints ``q`` (zeros: a Jacobian's rank does not read them)."""
    m = len(q)
    turn = None if data.quaternion is None else np.tile([0.0, 0.0, 0.0, 1.0], (m, 1))
    return Measurements(joint_names, q, np.zeros((m, 3 * data.n_markers)), turn)


@dataclass(frozen=True)
class Generic:
    """Generic configurations of the terms an instrument measures (``start``: linearised at)."""

    start: ChainsState
    train: tuple[Measurements, ...]
    seed: int

    @property
    def one(self) -> bool:
        """One chain (the counts and checks of a chain's, :mod:`.determined`)."""
        return len(self.start.chains) == 1

    def rows(self, q: np.ndarray | None = None, size: int = 0, elastic=False) -> ChainsData:
        """Rows of each term's kind at ``q``; None: drawn, ``GENERIC_EXCESS`` per unknown."""
        chains = self.start.chains
        per = sum(d.kind.rows_of(d.n_markers) for d in self.train)
        m = min(DEFAULT_CONFIGS, max(1, -(-GENERIC_EXCESS * size // per)))
        if self.one:  # its own joints (a chain whose base is not above its tool is no tree)
            q = chains[0].random_configurations(m, self.seed) if q is None else q
            torques = (chains[0].gravity_torques(q),) if elastic else None
            return ChainsData((rows_like(self.train[0], chains[0].joint_names, q),), torques)
        tree = tree_of_chains(chains[0].name, chains[0].urdf_path, tuple(chains))
        q = tree.random_configurations(m, self.seed) if q is None else q
        pairs = zip(chains, self.train, tree.paths, strict=True)
        return ChainsData(tuple(rows_like(d, c.joint_names, q[:, path]) for c, d, path in pairs))

    def _jacobian(self, wide: ChainsModel) -> np.ndarray:
        """``wide``'s Jacobian at the generic configurations ``(m, rows, size)``."""
        size, elastic = wide.size(), bool(wide.compliance)
        return wide.jacobian(self.start, np.zeros(size), self.rows(None, size, elastic))

    def columns(self, wide: ChainsModel) -> list[int]:
        """The columns of ``wide`` generic configurations determine (in column order)."""
        return determined.determined_columns(self._jacobian(wide))

    def fewest(self, wide: ChainsModel, generic: list[int]) -> int:
        """Fewest generic configurations (every point seen) that determine ``generic``.

        The first ones of the draw :meth:`columns` reads (the rank only grows with rows).
        """
        J = self._jacobian(wide)[:, :, generic]
        lo, hi = 0, len(J)  # hi determine them (the whole draw), lo do not
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if len(determined.determined_columns(J[:mid])) == len(generic):
                hi = mid
            else:
                lo = mid
        return hi

    def check(self, wide, kept, generic, flush, level: str) -> None:
        """Refuse a level (not ``auto``) the rows do not determine, before the fit.

        ``kept``, ``generic``: the columns of ``wide`` the rows (``flush``), and generic
        configurations, determine.

        Raises:
            DataError: Rows that do not determine the frame and markers, too few equations,
                or fewer unknowns than generic configurations (those lost named).
        """
        d = self.train[0]
        if len(kept) < wide.fixed:
            raise DataError(
                d.source,
                "the configurations do not even determine the measurement frame and markers",
            )
        if level == "auto" or (not self.one and level != "components"):
            return
        lost: tuple[str, ...] = ()
        fewest = None
        if self.one and len(kept) < len(generic):
            fewest = self.fewest(wide, generic)
            A = wide.jacobian(self.start, np.zeros(wide.size()), flush).reshape(-1, wide.size())
            names = tuple(chain_name(wide.names()[c]) for c in generic)
            found = determined.ill_posed(A[:, generic], names, overwrite=True)
            lost = tuple(dict.fromkeys(n for f in found for n in f.names))
        # one chain: its postures; a tree's complete (every component): its rows
        m = count(d.q, d.tool) if self.one else sum(t.m for t in self.train)
        level, unit = (level, "") if self.one else ("complete", "rows")
        rows = d.kind.rows_of(d.n_markers)
        seen = determined.seen_equations(d, rows, True) if self.one else None  # a tree: seen
        determined.check_rank(
            len(kept), len(generic), m, rows, level, d.source, unit, lost, seen, fewest
        )

    def note(self, wide: ChainsModel, kept: int, generic: list[int]) -> str:
        """The note of rows that determine ``kept`` of the ``generic`` columns (``auto``).

        One chain: with the fewest generic configurations that determine them all.
        """
        d = self.train[0]
        rows = f"{d.m} configurations" if self.one else f"{sum(t.m for t in self.train)} rows"
        more = ""
        if self.one:
            more = (
                f"; {self.fewest(wide, generic)} configurations at generic postures determine "
                "them all (calib design plans them)"
            )
        return (
            f"the {rows} determine {kept} of the {len(generic)} parameters generic "
            f"configurations would: params 'auto' chooses among those only{more}"
        )

    def groups(self, keep: np.ndarray | None) -> np.ndarray | None:
        """One chain's posture of each row ``keep`` (a repeat counts once), or None (a tree)."""
        if not self.one:
            return None
        d = self.train[0] if keep is None else self.train[0].subset(keep)
        return posture_groups(d.q, d.tool)

    def sample(self, fixed: int, candidates: int, notes: list[str]) -> np.ndarray | None:
        """The rows ``auto`` chooses on beyond the work bound (whole postures, seeded), or None.

        Raises:
            InvalidArgumentError: A sample within the bound too small to choose on
                (:func:`~.determined.selection_configurations`).
        """
        if not self.one:
            return None
        d = self.train[0]
        size = determined.selection_configurations(
            d.m, d.kind.rows_of(d.n_markers), fixed, candidates
        )
        if size >= d.m:
            return None
        keep = sample_postures(posture_groups(d.q, d.tool), size, self.seed, d.tool)
        notes.append(
            f"params 'auto' chose the parameters on {int(keep.sum())} of the {d.m} "
            f"configurations (whole postures drawn with seed {self.seed}: the selection's "
            f"work bound); the fit uses all of them"
        )
        return keep


def assess(
    generic: Generic | None, fitted, cov: np.ndarray, polished: bool
) -> tuple[str | None, list[determined.Direction]]:
    """One chain's refusal for fitted unknowns its rows cannot separate, and those combinations.

    The refusal (None: none) names the random posture that separates them best. Not
    assessed: a converged fit without ``generic`` (the rank rule's), a tree's, a ``polished``
    one. docs/developers/engine.md#chain_counts
    """
    skipped = fitted.converged if generic is None else not generic.one
    if skipped or polished:
        return None, []
    with np.errstate(invalid="ignore"):
        std = np.sqrt(np.diag(cov))  # of each column [m or rad] (NaN: undetermined)
    names = tuple(n if generic is None else chain_name(n) for n in fitted.model.names())
    found = determined.undetermined(fitted.J, names, std)
    spread = dict(zip(names, std, strict=True))
    if not found or generic is None:
        return determined.ill_posed_text(found, spread), found
    chain = generic.start.chains[0]
    q = chain.random_configurations(DEFAULT_CONFIGS, generic.seed)

    def jacobian_at(q: np.ndarray) -> np.ndarray:
        rows = generic.rows(q, elastic=bool(fitted.model.compliance))
        return fitted.model.jacobian(fitted.start, fitted.x, rows)

    where = determined.separating_text(jacobian_at, q, names, found[0], chain.joint_names)
    return determined.ill_posed_text(found, spread, where), found


def sampled(data: ChainsData, keep: np.ndarray | None) -> ChainsData:
    """One chain's rows ``keep`` (None: all)."""
    first = data.parts[0]
    if keep is None or not isinstance(first, Measurements):
        return data
    return dataclasses.replace(data, parts=(first.subset(keep),))
