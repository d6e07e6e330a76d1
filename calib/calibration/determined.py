"""No silent overfit: the rows must determine the parameters a level fits, or calib refuses.

Before any fit, two counts are compared (chains and trees alike):

1. equations: the residual rows of the fitted data (3 per measured point, 3 more per
   measured orientation) must outnumber the unknowns, else the fit interpolates the data and
   its errors say nothing (and the noise cannot be estimated);
2. rank: the parameters the level fits at *generic* configurations (random ones inside the
   joint limits, with the same markers and measurements) must all be determined at the
   *measured* configurations too (the rank of the identification Jacobian W_b there).

A level the rows cannot determine is refused in one line that says how many configurations
it needs; calib never silently cuts the level down to what the rows can carry.
"""

from __future__ import annotations

from ..exceptions import DataError, InvalidArgumentError

__all__ = ["SELECTION_WORK", "check_equations", "check_rank", "check_selection_work"]


def _configs_needed(unknowns: int, rows: int) -> int:
    """Fewest configurations of ``rows`` equations each with more equations than ``unknowns``."""
    return unknowns // rows + 1


def _fitted(m: int, held: int, unit: str) -> str:
    out = f"{m} {unit} to fit"
    return out + (f" ({held} held out)" if held else "")


def check_equations(
    m: int, rows: int, unknowns: int, what: str, source: str, *, held: int = 0, unit: str = ""
) -> None:
    """Refuse fitting ``unknowns`` parameters from ``m`` configurations of ``rows`` equations.

    Args:
        m: Configurations (or, for a tree, rows of the file) fitted.
        rows: Equations each gives.
        unknowns: Parameters fitted.
        what: The parameters, for the message (e.g. ``parameters of params 'complete'``).
        source: The data, for the message.
        held: Configurations held out (``holdout``), for the message.
        unit: What ``m`` counts (default: configurations).

    Raises:
        DataError: ``m * rows <= unknowns``.
    """
    if m * rows > unknowns:
        return
    unit = unit or "configurations"
    raise DataError(
        source,
        f"{_fitted(m, held, unit)} give {m * rows} equations for the {unknowns} {what}: it "
        f"needs at least {_configs_needed(unknowns, rows)} {unit} (more equations than "
        f"unknowns)",
    )


def check_rank(
    determined: int, generic: int, m: int, rows: int, level: str, source: str, unit: str = ""
) -> None:
    """Refuse a level the measured configurations do not determine (rank of W_b there).

    Args:
        determined: Parameters the measured configurations determine.
        generic: Parameters the level fits at generic configurations.
        m: Configurations (or rows) fitted; ``rows`` equations each.
        rows: Equations per configuration.
        level: The parameter level.
        source: The data, for the message.
        unit: What ``m`` counts (default: configurations).

    Raises:
        DataError: ``determined < generic`` or too few equations.
    """
    check_equations(m, rows, generic, f"parameters of params {level!r}", source, unit=unit)
    if determined >= generic:
        return
    unit = unit or "configurations"
    raise DataError(
        source,
        f"the {m} {unit} determine only {determined} of the {generic} parameters of params "
        f"{level!r} (rank of the identification Jacobian): measure at least "
        f"{_configs_needed(generic, rows)} {unit} that move every joint, or choose a lower "
        f"level or fix parameters",
    )


SELECTION_WORK = 4e9
"""Largest ``rows x (fixed + candidates)^2 x candidates`` the selection of ``--params auto``
is run on (its forward paths cost about this). Measured on one core under a load of 8 to 12
on 2 cores (benchmarks/bench_selection_memory.py): a UR5's 10,000 positions (3.9e8) take 3.5
to 18 s, its 10,000 poses (1.1e9) 22 s, its 100,000 positions (3.9e9) 118 s. Before issue 30
(1.2e9; QR factorisations per fold) 20,000 positions took 45 s."""


def check_selection_work(m: int, rows: int, fixed: int, candidates: int) -> None:
    """Refuse, before it starts, a selection (``--params auto``) too long to wait for.

    Args:
        m: Configurations.
        rows: Rows per configuration (3 per marker, 3 more for an orientation).
        fixed: Frame and marker columns.
        candidates: Candidate parameters.

    Raises:
        InvalidArgumentError: The work exceeds :data:`SELECTION_WORK`; says what to do.
    """
    work = m * rows * (fixed + candidates) ** 2 * candidates
    if work > SELECTION_WORK:
        raise InvalidArgumentError(
            f"params 'auto' would cross-validate {candidates} parameters on {m} configurations "
            f"x {rows} rows with {fixed} frame and marker columns: {work / SELECTION_WORK:.3g} "
            f"times the work calib runs it on (about a minute on one core); give a level "
            f"(params complete, paper, offsets or frames), or fewer configurations or markers"
        )
