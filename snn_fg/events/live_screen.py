"""The screen each packet of a live stream passes on the receiving thread
(:class:`~snn_fg.events.live.LiveStream`): events inside the sensor and in
time order are kept, the others counted; a source takes up to :data:`BATCH`
packets at a time for it."""

from __future__ import annotations

import numpy as np
from numba import njit

from .core import EVENT_DTYPE

#: packets taken off a UDP socket's buffer (batches off a DV reader) at a time, at most, once one has
#: arrived: the events of those already waiting are screened and queued for the model together (per
#: packet, that took a sixth of a core beside the compact network, 29 Nov); none is waited for
BATCH = 64


@njit(cache=True, nogil=True)
def screen_events(x, y, t, w, h, last_t):
    """Which events to keep: inside the ``w`` x ``h`` sensor and no earlier than
    every event before them (``last_t``: the latest so far). Returns the mask and
    ``(outside, first outside, backwards, first backwards, its time, the latest
    before it)``, the firsts -1 where none (one pass, a packet at a time on the
    receiving thread: in numpy it took a sixth of a core beside the compact network)."""
    keep = np.ones(x.size, np.bool_)
    outside, first_out, backwards, first_back, back_t, back_before = 0, -1, 0, -1, 0, 0
    latest = last_t
    for i in range(x.size):
        if x[i] < 0 or x[i] >= w or y[i] < 0 or y[i] >= h:
            keep[i] = False
            outside += 1
            if first_out < 0:
                first_out = i
        elif t[i] < latest:
            keep[i] = False
            backwards += 1
            if first_back < 0:
                first_back, back_t, back_before = i, t[i], latest
        else:
            latest = t[i]
    return keep, (outside, first_out, backwards, first_back, back_t, back_before)


def prepare_screen() -> None:
    """:func:`screen_events` compiled (or loaded from numba's cache) for every packet it will see: the
    fields of an event array are strided views (numba's layout 'A'), those of an empty or one-event
    array contiguous ('C'), and each layout is compiled apart, on a first run for a second or more.
    Called once, in a live run's warm-up (:func:`~snn_fg.models.live.warm_up`), before a ``dv://``
    stream is connected to (a DV server sends from then on); a :class:`~snn_fg.events.live.LiveStream`
    made without one compiles it at its first packet."""
    for n in (0, 2):
        ev = np.zeros(n, EVENT_DTYPE)
        screen_events(ev["x"], ev["y"], ev["t"], 1, 1, 0)
