"""An end to a library call that may never return and holds Python's interpreter lock while it
waits: dv-processing's ``NetworkReader`` waits in its constructor for a DV stream's header, and a
server that accepts the connection and sends none (a web server, another program's port) holds it
there for good, where neither Ctrl-C nor a thread of ours can run.

:func:`ends_process_after` watches such a call from a thread running compiled code without the
lock: past its deadline it writes one line to standard error and ends the process with exit
status 2 (before a run's output exists, so nothing is left half-written). Where the C library's
``write``, ``usleep`` and ``_exit`` cannot be had (not a POSIX system) it does nothing.
"""

from __future__ import annotations

import contextlib
import ctypes
import threading
import time

import numpy as np
from numba import njit

#: how often the watchdog looks whether the call returned (s)
TICK_S = 0.05


def _libc():
    try:
        libc = ctypes.CDLL(None)
        fns = libc.write, libc.usleep, libc._exit
    except (OSError, AttributeError, TypeError):
        return None
    write, usleep, exit_ = fns
    # (the buffer's address as an integer: the same register as a pointer in the C calling convention)
    write.argtypes, write.restype = [ctypes.c_int, ctypes.c_size_t, ctypes.c_size_t], ctypes.c_ssize_t
    usleep.argtypes, usleep.restype = [ctypes.c_uint], ctypes.c_int
    exit_.argtypes, exit_.restype = [ctypes.c_int], None
    return write, usleep, exit_


_FNS = _libc()
_watch = None
if _FNS is not None:
    _write, _usleep, _exit = _FNS

    @njit(nogil=True)  # (not cached: it calls the C library through addresses of this process)
    def _watch(state, ticks, tick_us, message, code):
        """``state[1] = 1`` once running; then, unless ``state[0]`` is set within ``ticks``
        ticks, ``message`` to standard error and the process ended with ``code``."""
        state[1] = 1
        for _ in range(ticks):
            if state[0]:
                return 0
            _usleep(tick_us)
        if state[0]:
            return 0
        _write(2, message.ctypes.data, message.size)
        _exit(code)
        return 1


@contextlib.contextmanager
def ends_process_after(seconds: float, message: str, code: int = 2):
    """Within the block: if it has not ended ``seconds`` from now, ``snn-fg: error: {message}``
    goes to standard error and the process ends with ``code``."""
    if _watch is None:
        yield
        return
    state = np.zeros(2, np.int64)
    line = np.frombuffer(f"snn-fg: error: {message}\n".encode(), np.uint8).copy()
    ticks = max(1, int(np.ceil(seconds / TICK_S)))
    watcher = threading.Thread(
        target=_watch, args=(state, ticks, int(TICK_S * 1e6), line, code), name="snn-fg watchdog", daemon=True
    )
    watcher.start()
    while not state[1]:  # (compiled and running without the interpreter lock before the block begins)
        time.sleep(0.001)
    try:
        yield
    finally:
        state[0] = 1
