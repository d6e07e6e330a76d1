"""A measured chain's options on the joint engine: ``fix``, ``free``, ``elastic``, ``marker``.

Each is checked before the fit, in one line that says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.words import counted
from ..exceptions import InvalidArgumentError
from ..identification.identifiability import independent_columns
from ..kinematics.robot import Chain
from .contact_model import ContactState
from .model import compliance_name
from .options import Options
from .placements import component_of, mdh_directions

__all__ = ["GROUPS", "NO_LOAD", "Asked", "compliance_torques", "level_offer", "marker_guess"]

GROUPS = ("frame", "markers", "tool")
"""Names of a measured term's own unknowns, by group."""

NO_LOAD = 1e-9
"""A joint's gravity torque under this fraction of the largest is round-off, no load: its
compliance is not offered. Rationale and measurements: docs/developers/engine.md#no_load"""


def _compliance(name: str) -> bool:
    return name[:1] == "c" and name[1:].isdigit()


def compliance_torques(chains, train, held, opts: Options, load):
    """Gravity torques of the fitted and held-out rows, and the joints whose compliance is offered.

    A measured chain's compliance is opt-in (``elastic``, or one in ``free``): the joints
    gravity loads (:data:`NO_LOAD`) less those fixed. ``(None, None)``: rigid joints.

    Raises:
        InvalidArgumentError: Compliance where gravity loads no joint, or a free one it never loads.
    """
    if load is not None:
        tau = [None if d is None else load.torques(d.q, d.readings) for d in (train[0], held[0])]
        return (tau[0], tau[1]), tuple(range(chains[0].n))
    forced = any(_compliance(n) for n in opts.free)
    if not (opts.elastic or (opts.elastic is None and forced)):
        return (None, None), ()
    chain = chains[0]
    tau = chain.gravity_torques(train[0].q)
    most = np.max(np.abs(tau), axis=0)
    loaded = [j for j in range(chain.n) if most[j] > NO_LOAD * np.max(most)]
    if not loaded:
        raise InvalidArgumentError(
            f"elastic (or a compliance in free) needs gravity torques, and {chain.urdf_path} "
            f"gives none on the chain (no masses beyond it): drop elastic and the compliances"
        )
    for name in opts.free:
        if _compliance(name) and int(name[1:]) - 1 not in loaded:
            raise InvalidArgumentError(
                f"free {name} cannot be fitted: gravity loads joint {name[1:]} at none of the "
                f"configurations (a compliance only shows under a torque); drop it from free"
            )
    joints = tuple(j for j in loaded if compliance_name(j) not in opts.fix)
    return (tau, None if held[0] is None else chain.gravity_torques(held[0].q)), joints


def marker_guess(marker, k: int) -> np.ndarray:
    """The markers' guess ``(k, 3)`` [m]: zeros, one point for all, or one per marker."""
    if marker is None:
        return np.zeros((k, 3))
    try:
        mk = np.array(marker, dtype=float).reshape(-1, 3)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"a marker is 3 numbers [m], got {marker!r}") from None
    if not np.all(np.isfinite(mk)) or np.max(np.abs(mk)) > 1e3:
        raise InvalidArgumentError(f"a marker is 3 finite numbers within 1000 m, got {marker!r}")
    if len(mk) == 1:
        mk = np.repeat(mk, k, axis=0)
    if len(mk) != k:
        guesses = counted(len(mk), "marker guesses")
        raise InvalidArgumentError(f"{guesses} for {counted(k, 'measured points')}")
    return mk


@dataclass(frozen=True)
class Asked:
    """Parameters a measured chain's ``fix`` and ``free`` name, as engine names.

    ``given``: each one's name as the user wrote it; ``extra``: directions ``(6 J,)`` of those.
    """

    fix: tuple[str, ...]
    free: tuple[str, ...]
    given: dict[str, str]
    extra: dict[str, np.ndarray]

    def offer(self, directions, names, offered):
        """The level's offer (directions, or None: components) with ``fix`` out, ``free`` in."""
        missing = [n for n in self.free if n in self.extra and n not in names]
        if missing:
            base = np.eye(len(names)) if directions is None else directions
            directions = np.vstack([base, *(self.extra[n] for n in missing)])
            offered = [*offered, *range(len(names), len(names) + len(missing))]
            names = (*names, *missing)
        held = [self.extra[n] / np.linalg.norm(self.extra[n]) for n in self.fix if n in self.extra]

        def fixed(k: int) -> bool:  # by name, or along a fixed parameter's direction
            if names[k] in self.fix:
                return True
            if directions is None:  # the components: k's own
                return any(abs(h[k]) >= 1.0 - 1e-9 for h in held)
            d = directions[k]
            return any(abs(d @ h) >= (1.0 - 1e-9) * np.linalg.norm(d) for h in held)

        offered = [k for k in offered if not fixed(k)]
        return directions, tuple(names), offered, self.free

    def check(self, wide, start, flush, kept) -> None:
        """Refuse a free parameter the data cannot fit on its own, saying why.

        Raises:
            InvalidArgumentError: The frame and markers carry it, or it is regrouped.
        """
        every, fixed = wide.names(), wide.fixed
        cand = [every[k] for k in kept]
        for name in self.free:
            if name in cand or name not in every:
                continue  # fitted; or no column of the model
            A = wide.jacobian(start, np.zeros(wide.size()), flush).reshape(-1, wide.size())
            cols = [*range(fixed), every.index(name)]
            _, _, ok, _ = independent_columns(A[:, cols], list(range(fixed + 1)))
            why = (
                "the measurement frame and markers carry it (the registration fits them)"
                if fixed not in ok
                else "it is regrouped with parameters kept before it (not identifiable on its own)"
            )
            given = self.given.get(name, name)
            raise InvalidArgumentError(f"free {given} cannot be fitted: {why}; drop it from free")


def level_offer(chain: Chain, start, instrument: bool, opts: Options):
    """What a joint fit offers at the options' level, and the :class:`Asked` (None: none named).

    A tree's ``complete`` offers every joint placement component.
    Names: docs/developers/engine.md#level_offer

    Raises:
        InvalidArgumentError: An unknown name, or ``fix`` of a group (touches: ``free`` too).
    """
    tree = instrument and len(start.chains) > 1  # one chain: its MDH directions (``auto``'s)
    offer = "components" if tree and opts.level == "complete" else opts.level
    if not (opts.fix or opts.free):
        return None, offer
    touching = isinstance(start.states[0], ContactState)
    named = [(w, n) for w in ("fix", "free") for n in getattr(opts, w) if touching]
    if group := [p for p in named if p[1] in GROUPS]:
        raise InvalidArgumentError(
            f"{' '.join(group[0])}: touches have no instrument frame or markers (the objects and "
            "the contact frame are always fitted); name joint parameters"
        )
    if spring := [p for p in named if _compliance(p[1])]:
        raise InvalidArgumentError(
            f"{' '.join(spring[0])}: with touches, fix and free name joint parameters; elastic "
            "fits every joint's compliance it offers"
        )
    if held := [n for n in opts.fix if n in GROUPS]:
        raise InvalidArgumentError(
            f"fix {held[0]}: the joint engine fits the instrument's frame and markers (and the "
            f"measured frame's rotation), holding at its given value only a marker coordinate "
            f"no posture separates from the frame (a gantry's first marker); fix joint "
            f"parameters or compliances"
        )
    placements = start.placements
    D, labels = mdh_directions(placements, chain, start.states[0].mdh, "complete")
    chart = dict(zip(labels, D, strict=True))
    components = dict(zip(placements.names(), np.eye(len(placements.names())), strict=True))
    bare = {label.split(":", 1)[1]: label for label in labels}
    alias = {  # a component that is a chart's parameter (``<joint>:rz``, ``theta2``): one name
        placements.names()[c]: label
        for label, d in chart.items()
        if offer != "components" and (c := component_of(d)) is not None
    }
    given: dict[str, str] = {}
    for name in (*opts.fix, *opts.free):
        known = name in GROUPS or name in chart or name in components
        if name in alias:
            given[alias[name]] = name
        elif known or (name not in bare and _compliance(name) and 1 <= int(name[1:]) <= chain.n):
            given[name] = name
        elif name in bare:
            given[bare[name]] = name
        else:
            example = labels[-1] if labels else placements.names()[-1]
            raise InvalidArgumentError(
                f"unknown parameter '{name}' for fix/free: give a joint's parameter as the "
                f"table prints it (e.g. {example}, or {example.split(':')[1]} alone), a joint "
                f"placement component (<joint>:x .. :rz), a compliance c1..c{chain.n}, or "
                f"frame, markers, tool (free only)"
            )
    engine = {v: k for k, v in given.items()}
    pick = {**components, **chart}
    fix = tuple(engine[n] for n in opts.fix)
    free = tuple(engine[n] for n in opts.free if n not in GROUPS)
    extra = {n: pick[n] for n in (*fix, *free) if n in pick}
    return Asked(fix, free, {k: v for k, v in given.items() if k != v}, extra), offer
