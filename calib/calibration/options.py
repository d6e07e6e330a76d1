"""The options of a calibration, chain or tree: one value, one check; cheap to import.

The command line builds its parser from the constants here; what applies to some shapes only
is one table (:data:`APPLIES`).
"""

from __future__ import annotations

import dataclasses
import functools
import inspect
import numbers
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import ParamSpec, TypeVar

import numpy as np

from ..core.checks import shown
from ..core.words import noun
from ..exceptions import InvalidArgumentError

__all__ = [
    "APPLIES",
    "DEFAULT_LEVEL",
    "DEFAULT_MAX_ITERATIONS",
    "DEFAULT_TREE_LEVEL",
    "LEVELS",
    "LOSSES",
    "MAX_ITERATIONS",
    "SHAPE_LABELS",
    "TREE_LEVELS",
    "Options",
    "check_tree_level",
    "checked_arguments",
    "checked_init",
    "options_given",
]

LEVELS = ("auto", "frames", "offsets", "paper", "complete")
"""Parameter levels: ``frames`` = measurement frame + markers; ``offsets`` adds the joint
offsets; ``paper`` and ``complete`` add the base parameters of those sets; ``auto`` (the
default) keeps the ones the data support (:mod:`calib.calibration.selection`)."""

DEFAULT_LEVEL = "auto"

TREE_LEVELS = ("frames", "complete")
"""Parameter levels of a tree calibration."""

DEFAULT_TREE_LEVEL = "complete"

DEFAULT_MAX_ITERATIONS = 100
"""Most residual evaluations of each solver run (registration and fit); MINPACK reads it only to
stop.
Measurements: docs/developers/performance.md#default_max_iterations-options"""

MAX_ITERATIONS = 1_000_000
"""Most residual evaluations a fit may be given (hours of fitting; the solver's counter is a
C int, which a larger count overflows)."""

LOSSES = ("linear", "soft_l1", "huber")
"""Losses of the fit: least squares, or a robust loss (scipy's, scale ``--noise-mm``)."""

SHAPE_LABELS = {
    "chain": "one chain measured by an instrument",
    "tree": "a tree (several tools)",
    "contacts": "contact kinds (plane, plane-point, fixed-point, fixed-pose)",
    "chains": "several terms in one fit",
}
"""What a calibration problem is, by shape (:attr:`~.problem.Problem.shape`), in the words of
the messages."""

APPLIES: dict[str, tuple[str, ...]] = {
    "fix": ("chain", "contacts"),
    "free": ("chain", "contacts"),
    "loss": ("chain",),
    "noise_mm": ("chain",),
    "elastic": ("chain", "contacts"),
    "orientation_weight": ("chain", "contacts", "chains"),
    "pose_weight": ("chains",),
    "shared_planes": ("chains",),
    "known_planes": ("contacts", "chains"),
}
"""The one table of the options that apply to some shapes only: option -> the shapes it
applies to. Every other option applies to every shape; one given where it does not apply is
an error (:class:`~.problem.Problem`; the command line adds its own flags to it)."""


def check_tree_level(level: str) -> None:
    """Refuse a level a tree's calibration (or design) does not take.

    Raises:
        InvalidArgumentError: A level other than :data:`TREE_LEVELS`.
    """
    if not isinstance(level, str) or level not in TREE_LEVELS:
        raise InvalidArgumentError(
            f"unknown parameter level {shown(level)} for a tree: choose {', '.join(TREE_LEVELS)}"
        )


def _names(option: str, names: str | Iterable[str]) -> tuple[str, ...]:
    """``fix`` or ``free`` as a tuple of names (one name may be given alone)."""
    if isinstance(names, str):
        names = (names,)
    try:
        out = tuple(names)
    except TypeError:
        raise InvalidArgumentError(f"{option} takes parameter names, got {names!r:.60}") from None
    if not all(isinstance(n, str) for n in out):
        raise InvalidArgumentError(f"{option} takes parameter names, got {out!r:.60}")
    if len(set(out)) != len(out):
        raise InvalidArgumentError(f"{option} names a parameter twice: {', '.join(out)}")
    return out


@dataclass(frozen=True, kw_only=True)
class Options:
    """The options of a calibration, chain or tree, checked when made (by name).

    A :class:`~.problem.Problem` is its terms and these (and the joint fit's own), and the
    joint engine's run carries them (:class:`!register.Run`).

    Attributes:
        params: Parameter level, one of :data:`!LEVELS`, or None: the shape's default
            (``auto``, a tree's ``complete``: :attr:`!level`; a tree takes :data:`!TREE_LEVELS`,
            :func:`!check_tree_level`).
        fix: Parameter names (or ``frame``, ``markers``, ``tool``) held at their start.
        free: Parameter names (a compliance ``c1``.. included) always fitted.
        elastic: Fit joint compliance under gravity (None: only if ``free`` names one).
        loss: One of :data:`!LOSSES` (a robust one's scale: ``noise_mm``).
        noise_mm: Instrument noise [mm], or None (unknown).
        orientation_weight: Weight of the orientation rows [m/rad], or None: estimated.
        max_iterations: Most residual evaluations of each solver run.
        holdout: Fraction of the rows set aside, in [0, 1).
        seed: Seed of the holdout draw and of the generic configurations.

    Raises:
        InvalidArgumentError: A value out of its range or of the wrong type, a name given
            twice, or both fixed and free.
    """

    params: str | None = None
    fix: tuple[str, ...] = ()
    free: tuple[str, ...] = ()
    elastic: bool | None = None
    loss: str = "linear"
    noise_mm: float | None = None
    orientation_weight: float | None = None
    max_iterations: int = DEFAULT_MAX_ITERATIONS
    holdout: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        if self.params is not None and (
            not isinstance(self.params, str) or self.params not in LEVELS
        ):
            raise InvalidArgumentError(
                f"unknown parameter level {shown(self.params)}: choose {', '.join(LEVELS)}"
            )
        if not isinstance(self.loss, str) or self.loss not in LOSSES:
            raise InvalidArgumentError(
                f"unknown loss {shown(self.loss)}: choose {', '.join(LOSSES)}"
            )
        if isinstance(self.elastic, np.ndarray) or self.elastic not in (None, True, False):
            raise InvalidArgumentError(f"elastic is True, False or None, got {shown(self.elastic)}")
        from ..core.checks import MAX_ERROR_MM, MAX_WEIGHT, check_count, check_number

        for name, value, top in (
            ("orientation weight", self.orientation_weight, MAX_WEIGHT),
            ("noise", self.noise_mm, MAX_ERROR_MM),
        ):
            if value is not None:
                check_number(value, f"the {name}", 0.0, top, above=True)
        check_count(self.max_iterations, "max_iterations", 1, MAX_ITERATIONS)
        check_count(self.seed, "the seed", 0)
        h = self.holdout
        if isinstance(h, bool) or not isinstance(h, numbers.Real) or not (0.0 <= float(h) < 1.0):
            raise InvalidArgumentError(f"the holdout fraction must be in [0, 1), got {shown(h)}")
        object.__setattr__(self, "fix", _names("fix", self.fix))
        object.__setattr__(self, "free", _names("free", self.free))
        both = set(self.fix) & set(self.free)
        if both:
            raise InvalidArgumentError(f"{', '.join(sorted(both))} both fixed and free")

    @property
    def level(self) -> str:
        """The parameter level: ``params``, or :data:`DEFAULT_LEVEL` (a tree sets its own)."""
        return DEFAULT_LEVEL if self.params is None else self.params

    @property
    def noise(self) -> float | None:
        """Instrument noise [m], or None."""
        return None if self.noise_mm is None else 1e-3 * self.noise_mm


P = ParamSpec("P")
R = TypeVar("R")

_RENAMED = {"level": "params", "chain": "robot", "tree": "robot", "markers": "marker"}
"""Keywords users reach for, and the argument that takes what they mean."""


def options_given(values: dict[str, object]) -> list[str]:
    """The options among ``values`` (by name) that are not :class:`Options`'s defaults (or None)."""
    defaults = {f.name: f.default for f in dataclasses.fields(Options)}

    def default(value, given) -> bool:
        kind = isinstance(value, str | int | float | tuple) and type(value) is type(given)
        return value is given or (kind and value == given)

    return [n for n, v in values.items() if not default(v, defaults.get(n))]


def checked_arguments(function: Callable[P, R]) -> Callable[P, R]:
    """A calibration entry point whose wrong arguments are a one-line InvalidArgumentError.

    It names the argument (and the one meant, ``level=`` for ``params=``), not a bare TypeError.
    """
    signature = inspect.signature(function)

    @functools.wraps(function)
    def checked(*args: P.args, **kwargs: P.kwargs) -> R:
        try:
            signature.bind(*args, **kwargs)
        except TypeError as exc:
            message = _argument_error(function.__name__, signature, kwargs, exc)
            raise InvalidArgumentError(message) from None
        return function(*args, **kwargs)

    return checked


def checked_init(usage: str, hints: dict[str, str]) -> Callable[[type[R]], type[R]]:
    """A class decorator: wrong arguments of the class are a one-line InvalidArgumentError.

    It says ``usage`` (how the class is called) and, for an unknown keyword, its hint in
    ``hints`` (what the user meant, by keyword) if any.
    """

    def decorate(cls: type[R]) -> type[R]:
        init = cls.__init__
        signature = inspect.signature(init)

        @functools.wraps(init)
        def checked(self, *args, **kwargs) -> None:
            try:
                signature.bind(self, *args, **kwargs)
            except TypeError:
                unknown = sorted(set(kwargs) - set(signature.parameters))
                said = [f"unknown {noun(len(unknown), 'arguments')} {', '.join(unknown)}"]
                said += [hints[u] for u in unknown if u in hints]
                told = f": {'; '.join(said)}" if unknown else ""
                raise InvalidArgumentError(f"{usage}{told}") from None
            init(self, *args, **kwargs)

        cls.__init__ = checked  # type: ignore[method-assign]
        return cls

    return decorate


def _argument_error(name: str, signature: inspect.Signature, kwargs, exc: TypeError) -> str:
    unknown = sorted(set(kwargs) - set(signature.parameters))
    method = next(iter(signature.parameters), None) == "self"
    if unknown:
        hints = [f"{u} is called {_RENAMED[u]} here" for u in unknown if u in _RENAMED]
        if method:
            hints = [f"it takes {', '.join(list(signature.parameters)[1:]) or 'no argument'}"]
        hint = f" ({'; '.join(hints)})" if hints else ""
        return f"{name}: unknown {noun(len(unknown), 'arguments')} {', '.join(unknown)}{hint}"
    if "positional" in str(exc) and not method:
        return (
            f"{name} takes the robot and the data by position and every other argument by "
            f"name (e.g. params='complete'): {exc}"
        )
    return f"{name}: {exc}"
