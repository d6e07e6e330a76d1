"""Checks of the numbers that enter through the API: counts, arrays, and the memory they cost."""

from __future__ import annotations

import math

import numpy as np

from ..exceptions import InvalidArgumentError

__all__ = [
    "BYTES_PER_CONFIG_JOINT",
    "DESIGN_BYTES_PER_CANDIDATE_JOINT",
    "MAX_ERROR_MM",
    "MAX_ERROR_MRAD",
    "MAX_JOINT_POSITION",
    "MAX_OBJECTS",
    "MAX_ROWS",
    "MAX_TOUCHES",
    "MAX_WEIGHT",
    "MAX_WORK_BYTES",
    "angle_mrad",
    "check_count",
    "check_number",
    "check_size",
    "check_work",
    "joint_positions",
    "least_configurations",
    "length_mm",
    "read_only",
    "real_array",
    "shown",
]

MAX_JOINT_POSITION = 1e4
"""Largest joint position accepted [rad or m]; beyond it a value is not a robot's motion."""

MAX_WORK_BYTES = 2 << 30
"""Most memory [B] an analysis or a simulation may need (2 GB); larger ones are refused."""

MAX_ERROR_MM = 1000.0
"""Largest length error, noise or noise scale accepted [mm] (1 m): beyond it the first-order
model and a simulated robot mean nothing, and points leave the 1 km measurement range."""

MAX_ERROR_MRAD = 1000.0
"""Largest angle error or noise accepted [mrad] (1 rad)."""

MAX_WEIGHT = 1e4
"""Largest orientation or pose weight accepted [m/rad, or a factor]: 1 mm of noise against
0.1 urad; beyond it the squared weights lose the position rows to round-off."""

BYTES_PER_CONFIG_JOINT = 3000
"""Memory [B] the analysis needs per configuration and joint (Jacobians of the paper, complete
and reference sets, their QR copies and the kinematics), with a margin: the measured peak is
1.9 kB (UR5, 50000 configurations) and 1.6 kB (100 joints, 2000 configurations); a test
checks that the estimate covers a real run."""


MAX_ROWS = 100_000
"""Most configurations (rows) of measured data calib reads or calibrates on: a UR5's 100,000
poses calibrate with the default options in under a minute and 1 GB on one core
(benchmarks/bench_selection_memory.py)."""

MAX_TOUCHES = 50_000
"""Most touches of contact data calib reads or calibrates on."""

MAX_OBJECTS = 2_000
"""Most planes, points or poses of contact data (each brings its own unknowns)."""


def shown(value, width: int = 60) -> str:
    """A value as an error message shows it: one line of at most ``width`` characters.

    An array is shown by its shape (its repr spans lines: ``calib.analyze(chain,
    configs=q)`` printed ``q``'s rows into the one-line message).
    """
    if isinstance(value, np.ndarray):
        return f"an array of shape {value.shape}"
    text = " ".join(repr(value).split())
    return text if len(text) <= width else f"{text[: width - 3]}..."


def check_size(count: int, limit: int, what: str, where: str | None = None) -> None:
    """Refuse, before any work, more than ``limit`` rows, touches or objects.

    Args:
        count: How many there are.
        limit: The stated maximum (:data:`MAX_ROWS`, :data:`MAX_TOUCHES`, :data:`MAX_OBJECTS`).
        what: What is counted, plural ("touches").
        where: The data's source, for the message, or None.

    Raises:
        InvalidArgumentError: ``count`` exceeds ``limit``.
    """
    if count > limit:
        place = f"{where}: " if where else ""
        raise InvalidArgumentError(
            f"{place}{count} {what}: calib handles at most {limit} (split the campaign, or "
            f"keep a subset)"
        )


def least_configurations(parameters: int, rows: int) -> int:
    """The fewest configurations whose ``rows`` rows each reach ``parameters`` rows.

    ``calib design``'s least K (it refuses fewer) and ``calib analyze``'s ``next:`` line's.
    """
    return -(-parameters // rows)


def check_count(value, what: str, minimum: int = 1, maximum: int | None = None) -> int:
    """Validate an integer argument (a count or a seed).

    Args:
        value: The argument.
        what: How the message names it ("the seed").
        minimum: Smallest accepted value.
        maximum: Largest accepted value, or None.

    Raises:
        InvalidArgumentError: Not an integer, a bool, or outside ``[minimum, maximum]``.
    """
    ok = isinstance(value, int | np.integer) and not isinstance(value, bool) and value >= minimum
    if not ok or (maximum is not None and value > maximum):
        span = f">= {minimum}" if maximum is None else f"in [{minimum}, {maximum}]"
        raise InvalidArgumentError(f"{what} must be an integer {span}, got {shown(value)}")
    return int(value)


def check_number(
    value,
    what: str,
    minimum: float = 0.0,
    maximum: float | None = None,
    *,
    above: bool = False,
) -> float:
    """Validate a real argument (a noise, an error size, a weight): a finite number in range.

    Args:
        value: The argument (an int or a float, NumPy's included; not a bool or a string).
        what: How the message names it ("noise_mm").
        minimum: Smallest accepted value (excluded with ``above``).
        maximum: Largest accepted value, or None.
        above: The value must be strictly greater than ``minimum``.

    Returns:
        The value as a float.

    Raises:
        InvalidArgumentError: Not a number, NaN or infinite, or out of range.
    """
    number = isinstance(value, int | float | np.integer | np.floating) and not isinstance(
        value, bool | np.bool_
    )
    x = float(value) if number else math.nan
    low_ok = x > minimum if above else x >= minimum
    if not (math.isfinite(x) and low_ok and (maximum is None or x <= maximum)):
        span = f"{'>' if above else '>='} {minimum:g}"
        span += "" if maximum is None else f" and at most {maximum:g}"
        raise InvalidArgumentError(f"{what} must be a finite number {span}, got {shown(value)}")
    return x


def length_mm(value, what: str) -> float:
    """A length error or noise [mm]: a finite number in [0, :data:`MAX_ERROR_MM`].

    Raises:
        InvalidArgumentError: Not a number, NaN, infinite, negative or too large.
    """
    return check_number(value, what, 0.0, MAX_ERROR_MM)


def angle_mrad(value, what: str) -> float:
    """An angle error or noise [mrad]: a finite number in [0, :data:`MAX_ERROR_MRAD`].

    Raises:
        InvalidArgumentError: Not a number, NaN, infinite, negative or too large.
    """
    return check_number(value, what, 0.0, MAX_ERROR_MRAD)


def real_array(
    value, what: str, shape: tuple[int | None, ...], bound: float | None = None
) -> np.ndarray:
    """``value`` as a new float array of the given shape, finite and within ``bound``.

    Args:
        value: Array-like input.
        what: What the value is, for the message ("joint positions").
        shape: Expected shape; None for a dimension of any size.
        bound: Largest accepted absolute value, or None.

    Returns:
        The array (a copy).

    Raises:
        InvalidArgumentError: Not numbers, wrong shape, NaN or infinity, or beyond ``bound``.
    """
    try:
        a = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"{what} must be numbers, got {value!r:.60}") from None
    fits = a.ndim == len(shape) and all(
        s is None or s == d for s, d in zip(shape, a.shape, strict=False)
    )
    if not fits:
        wanted = "(" + ", ".join("m" if s is None else str(s) for s in shape) + ")"
        raise InvalidArgumentError(f"{what} must have shape {wanted}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidArgumentError(f"{what} must be finite numbers, got NaN or infinity")
    if bound is not None and a.size and float(np.max(np.abs(a))) > bound:
        raise InvalidArgumentError(f"{what} must be within {bound:g} in absolute value")
    return a


def joint_positions(q, n: int) -> np.ndarray:
    """Joint positions ``(m, n)`` from ``(m, n)`` or ``(n,)`` [rad or m], checked.

    Raises:
        InvalidArgumentError: Wrong shape, NaN or infinity, or beyond
            :data:`MAX_JOINT_POSITION`.
    """
    try:
        one = np.ndim(q) == 1
    except ValueError:  # ragged nested lists: real_array says so
        one = False
    shape = (n,) if one else (None, n)
    return real_array(q, "joint positions", shape, bound=MAX_JOINT_POSITION).reshape(-1, n)


DESIGN_BYTES_PER_CANDIDATE_JOINT = 1500
"""Memory [B] a design needs per candidate and joint (the candidates' Jacobian rows, kept
twice by the exchange, and the Jacobians they come from), with a margin: the measured peak is
1.2 kB (TIAGo, 8 joints, 100,000 candidates: 941 MB); a test checks that the estimate covers a
real run."""


def check_work(
    m: int,
    n: int,
    chain: str | None = None,
    per_config: int = 1,
    what: str = "configurations",
    per_joint: int = BYTES_PER_CONFIG_JOINT,
) -> None:
    """Refuse, before any work, an analysis that would need more than :data:`MAX_WORK_BYTES`.

    Args:
        m: Number of configurations (the user's count).
        n: Number of joints of the chain or tree.
        chain: How the message names the chain (default: "a chain of n joints").
        per_config: Tool placements per configuration (a tree's tools): the work of one
            configuration is that of ``per_config`` chains.
        what: What ``m`` counts in the message ("configurations", "candidates").
        per_joint: Memory [B] per configuration and joint (default: an analysis's).

    Raises:
        InvalidArgumentError: The estimate exceeds the budget; the message names ``m`` and
            how many fit.
    """
    per = max(n, 1) * max(per_config, 1) * per_joint
    need = m * per
    if need > MAX_WORK_BYTES:
        raise InvalidArgumentError(
            f"{m} {what} of {chain or f'a chain of {n} joints'} need about "
            f"{need / 2**30:.3g} GB; calib "
            f"allows {MAX_WORK_BYTES / 2**30:g} GB: use at most {MAX_WORK_BYTES // per} {what}"
        )


def read_only(a: np.ndarray) -> np.ndarray:
    """A float copy of ``a`` that cannot be written (the arrays of frozen values)."""
    a = np.array(a, dtype=float)
    a.setflags(write=False)
    return a
