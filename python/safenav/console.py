"""What safenav prints besides its results.

One rule for every command: standard output carries the results (tables,
summaries); standard error carries status lines, details and progress.
``--quiet`` silences status and progress (errors are still printed);
``--verbose`` adds details.  Progress is a tqdm bar when standard error is a
terminal and plain lines (no carriage returns) otherwise."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager

__all__ = ["QUIET", "NORMAL", "VERBOSE", "configure", "level", "info", "detail", "progress", "task"]

QUIET, NORMAL, VERBOSE = 0, 1, 2
_level = NORMAL


def configure(new_level: int) -> None:
    """Set the verbosity: :data:`QUIET`, :data:`NORMAL` or :data:`VERBOSE`."""
    global _level
    if new_level not in (QUIET, NORMAL, VERBOSE):
        raise ValueError(f"verbosity level = {new_level!r}: must be QUIET, NORMAL or VERBOSE")
    _level = new_level


def level() -> int:
    """The current verbosity."""
    return _level


def info(message: str) -> None:
    """A status line (standard error), unless quiet."""
    if _level >= NORMAL:
        print(message, file=sys.stderr, flush=True)


def detail(message: str) -> None:
    """A detail line (standard error), only when verbose."""
    if _level >= VERBOSE:
        print(message, file=sys.stderr, flush=True)


class progress:
    """Progress over ``total`` units: ``with progress(n, "trials") as bar: ... bar.update()``.

    Nothing when quiet or ``enabled`` is false; a tqdm bar on a terminal;
    otherwise one plain line per tenth of the work."""

    def __init__(self, total: int, desc: str, *, unit: str = "it", enabled: bool = True):
        self.total, self.desc, self.unit = int(total), desc, unit
        self.on = enabled and _level >= NORMAL and self.total > 0
        self.n, self._tenths, self._t0 = 0, 0, time.perf_counter()
        self._bar = None
        if self.on and sys.stderr.isatty():
            from tqdm import tqdm

            self._bar = tqdm(total=self.total, desc=desc, unit=unit, leave=False, file=sys.stderr)

    def update(self, n: int = 1) -> None:
        self.n += n
        if self._bar is not None:
            self._bar.update(n)
        elif self.on and self.n * 10 // self.total > self._tenths:
            self._tenths = self.n * 10 // self.total
            print(f"{self.desc}: {self.n}/{self.total} {self.unit} ({time.perf_counter() - self._t0:.1f} s)",
                  file=sys.stderr, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> "progress":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


@contextmanager
def task(desc: str, *, enabled: bool = True):
    """A step without a count: a status line when it starts and one with its wall time when it ends."""
    t0 = time.perf_counter()
    if enabled:
        info(f"{desc} ...")
    yield
    if enabled:
        info(f"{desc}: done in {time.perf_counter() - t0:.1f} s")
