"""Cooperative cancellation: an interrupted run stops at its next check.

Python runs a signal handler wherever the main thread happens to be. When that
is a finalizer run by the garbage collector, or an import, the
KeyboardInterrupt it raises is swallowed there and the run goes on: a long
simulation would then run to its end. The command line catches SIGINT and SIGTERM
with :class:`Signals`, which records each
(:func:`request`), and the long loops (the windows of a recording, the
chunks and segments of a simulation, the iterations of the rate model) call
:func:`check` between steps.

Examples
--------
>>> from snn_fg.backends import cancel
>>> cancel.check()                      # nothing requested: returns
>>> cancel.request("SIGTERM")
>>> try:
...     cancel.check()
... except KeyboardInterrupt as stop:       # (doctest itself lets KeyboardInterrupt through)
...     print("stopped by", stop)
stopped by SIGTERM
>>> cancel.clear()
"""

from __future__ import annotations

import signal
import sys

_requested: list[str] = []


def request(reason: str) -> None:
    """Ask the running work to stop at its next :func:`check`."""
    _requested.append(reason)


def clear() -> None:
    """Forget the requests (the command that received them has ended)."""
    _requested.clear()


def check() -> None:
    """Raise KeyboardInterrupt if a stop was requested (even one whose own
    KeyboardInterrupt was swallowed since)."""
    if _requested:
        raise KeyboardInterrupt(_requested[-1])


class Signals:
    """Ctrl-C (SIGINT) and SIGTERM while a command runs: each is remembered
    (:func:`request`, so a run whose KeyboardInterrupt a library
    swallowed still stops at its next check and never commits its output)
    and raised as KeyboardInterrupt. A swallowed one is not printed ("Exception
    ignored..."): the one-line message follows."""

    def __init__(self):
        self.received: list[str] = []
        self.previous = {}
        self.previous_hook = None

    def __call__(self, signum, frame):  # noqa: ARG002 - signal handler signature
        self.received.append(signal.Signals(signum).name)
        request(self.received[-1])
        raise KeyboardInterrupt(self.received[-1])

    def _unraisable(self, info):
        if not (issubclass(info.exc_type, KeyboardInterrupt) and self.received):
            self.previous_hook(info)

    def __enter__(self):
        clear()
        for sig in (signal.SIGINT, signal.SIGTERM):
            self.previous[sig] = signal.signal(sig, self)
        self.previous_hook, sys.unraisablehook = sys.unraisablehook, self._unraisable
        return self

    def __exit__(self, *exc):
        for sig, handler in self.previous.items():
            signal.signal(sig, handler)
        sys.unraisablehook = self.previous_hook
        clear()
