"""Progress of long work: a bar on a terminal, a plain line now and then elsewhere.

``tqdm`` turns itself off when stderr is not a terminal (a job's log file, a pipe, a
notebook, CI), so a run of many minutes said nothing until it ended. Where stderr is not a
terminal, :func:`bar` gives a :class:`Lines` instead: one line ``snn-fg: windows done 12
of 200 (1.5 min)`` at most every :data:`EVERY_S` seconds, none for a run that ends sooner.
Every progress bar of the package is made here (windows, recordings, a file's events read, downloads,
simulated ms in each backend), except a still's model iterations (seconds: a terminal's bar only).
"""

from __future__ import annotations

import sys
import time

from tqdm import tqdm

#: Seconds between two progress lines where stderr is not a terminal.
EVERY_S = 30.0
#: Units of things counted, which the description names ("windows done"); any other unit is a
#: measure ("ms" simulated) and follows the count.
COUNTED = ("win", "rec")


def bar(
    desc: str, unit: str, total: int | None = None, *, disable: bool = False, clock=time.monotonic, file=None, **shown
):
    """A progress counter of ``desc`` (``"windows done"``) on stderr: a tqdm bar on a terminal
    (``shown``: more of tqdm's options, e.g. ``unit_scale``), :class:`Lines` elsewhere, a silent
    tqdm with ``disable``. It has ``update``, ``close`` and ``with``."""
    file = sys.stderr if file is None else file
    if disable:
        return tqdm(disable=True)
    if _is_terminal(file):
        return tqdm(desc=desc, unit=unit, total=total, file=file, leave=False, **shown)
    return Lines(desc, unit, total, clock=clock, file=file)


def _is_terminal(file) -> bool:
    try:
        return file.isatty()
    except (AttributeError, ValueError):  # (a closed or a file-like object without isatty)
        return False


class Lines:
    """A count that prints ``snn-fg: DESC N of TOTAL (elapsed)`` at most every :data:`EVERY_S`
    seconds of ``clock``, on the update that passes the interval."""

    def __init__(self, desc: str, unit: str, total: int | None, *, clock=time.monotonic, file=None):
        self.desc, self.unit, self.total, self.clock = desc, unit, total, clock
        self.file = sys.stderr if file is None else file
        self.n = 0
        self.start = self.last = clock()

    def update(self, n: int = 1) -> None:
        self.n += n
        now = self.clock()
        if now - self.last >= EVERY_S:
            self.last = now
            of = f" of {self.total}" if self.total else ""
            if self.unit == "B":
                done = f"{self.n / 1e6:.1f}" + (f" of {self.total / 1e6:.1f}" if self.total else "") + " MB"
            else:
                unit = "" if self.unit in COUNTED else f" {self.unit}"
                done = f"{self.n:.0f}{of}{unit}"  # (simulated ms advance by a step's fraction)
            print(f"snn-fg: {self.desc} {done} ({_elapsed(now - self.start)})", file=self.file, flush=True)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _elapsed(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.1f} min"
