"""The step loop called without the interpreter lock: :func:`run_steps`.

:func:`.core.run_steps` holds Python's interpreter lock for as long as it
runs (the whole of a segment's simulation), so a second Python thread of
the process (a recording's windows decoded and written while the run goes
on, :class:`~snn_fg.models.spiking.window_reader.WindowReader`; a live
stream's receiver) waits for it, and the engine then waits for that thread
at every return: two cores ran slower than one. Called through here, the
loop lets those threads run beside it.
"""

from __future__ import annotations

import sys

from numba import njit

from . import compiled, core

#: the stamp of the sources this module's cached code was compiled from (it compiles core's in)
STAMP = "snn_fg_fast_engine_unlocked.sources"


@njit(cache=True, nogil=True)
def run_steps(n0, n1, run, th, numbering, tables):
    """:func:`.core.run_steps` (same arguments and result), the interpreter lock released."""
    return core.run_steps(n0, n1, run, th, numbering, tables)


compiled.drop_stale_caches(run_steps, (sys.modules[__name__],), STAMP)
