"""The bottom of calib: what every wing may use, importing nothing of calib but its errors.

:mod:`.checks` validates arrays and counts (joint positions, memory budget), :mod:`.choices`
names the command line's choices and defaults, :mod:`.fileio` reads and writes files safely
(atomic outputs, inputs never overwritten), :mod:`.lazy` imports a package's names when first
used, :mod:`.words` says a count and its noun. The public errors stay at
:mod:`calib.exceptions`.

May import: :mod:`calib.exceptions` only (its modules do not import each other).
"""

__all__: list[str] = []
