"""Cooperative cancellation: an interrupted run stops at its next check.

Python runs a signal handler wherever the main thread happens to be. When that
is a finalizer run by the garbage collector, or an import, the
KeyboardInterrupt it raises is swallowed there and the run goes on: a long
simulation would then run to its end. The command line records every signal
here (:func:`request`), and the long loops (the windows of a recording, the
chunks and segments of a simulation, the iterations of the rate model) call
:func:`check` between steps.

Examples
--------
>>> from snn_fg import cancel
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
