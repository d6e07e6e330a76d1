"""Progress of long phases: tqdm bars on a terminal, nothing on a pipe or when asked quiet.

A ``progress`` argument of calib's API is None (silent) or a callable with tqdm's signature,
``progress(iterable, desc=..., total=...)``, returning the iterable it wraps (``tqdm.tqdm``
itself fits; :func:`terminal` gives the command line's). Loops go through :func:`steps`;
phases that are one long computation go through :func:`phase`: a bar without a count whose
elapsed time is refreshed while the phase runs, shown once it has lasted ``PHASE_DELAY``.
"""

from __future__ import annotations

import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

__all__ = ["PHASE_DELAY", "Progress", "phase", "steps", "terminal"]

Progress = Callable[..., Any]
"""``progress(iterable, desc=str, total=int | None)``: the iterable, wrapped (tqdm's form)."""

PHASE_DELAY = 1.0
"""Seconds a phase or a loop runs before its bar appears (short ones print nothing)."""

REFRESH = 0.5
"""Seconds between two refreshes of a phase's elapsed time."""

_T = TypeVar("_T")


def terminal(quiet: bool = False, stream=None) -> Progress | None:
    """The command line's progress: tqdm bars on stderr if it is a terminal (else None).

    Args:
        quiet: No bars at all (``--quiet``).
        stream: Where the bars go (default: ``sys.stderr``).
    """
    out = sys.stderr if stream is None else stream
    if quiet or not out.isatty():
        return None
    from tqdm import tqdm

    def bar(iterable=None, desc: str | None = None, total: int | None = None):
        shape = "{desc}: {elapsed}" if iterable is None and total is None else None  # a phase
        return tqdm(
            iterable,
            desc=desc,
            total=total,
            file=out,
            leave=False,
            delay=PHASE_DELAY,
            dynamic_ncols=True,
            bar_format=shape,
        )

    return bar


def steps(
    progress: Progress | None, iterable: Iterable[_T], desc: str, total: int | None = None
) -> Iterable[_T]:
    """``iterable``, wrapped by ``progress`` (itself when there is none)."""
    return iterable if progress is None else progress(iterable, desc=desc, total=total)


@contextmanager
def phase(progress: Progress | None, desc: str) -> Iterator[None]:
    """A bar that says what runs and for how long, while the block runs.

    With a tqdm-like ``progress`` (its bar has ``refresh`` and ``close``), a thread refreshes
    the bar's elapsed time from ``PHASE_DELAY`` on; any other callable is only told the
    phase's name (``progress(None, desc=desc, total=None)``).
    """
    if progress is None:
        yield
        return
    bar = progress(None, desc=desc, total=None)
    done = threading.Event()
    live = hasattr(bar, "refresh") and hasattr(bar, "close")

    def tick() -> None:
        if done.wait(PHASE_DELAY):
            return
        while not done.is_set():
            bar.refresh()
            done.wait(REFRESH)

    thread = threading.Thread(target=tick, daemon=True) if live else None
    if thread is not None:
        thread.start()
    try:
        yield
    finally:
        done.set()
        if thread is not None:
            thread.join()
            bar.close()
