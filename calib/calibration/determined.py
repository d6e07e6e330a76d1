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

from ..exceptions import DataError

__all__ = ["check_equations", "check_rank"]


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
