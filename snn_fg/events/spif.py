"""Events in the SpiNNaker interface board's (SPIF) UDP packets, as ``aestream`` sends them.

Each event is a little-endian 32-bit word: bit 31 says whether a timestamp
follows (0: a second word, the time in microseconds; 1: none), bits 30-16
hold ``x``, bit 15 the polarity (1: ON) and bits 14-0 ``y``. A packet is a
whole number of such events. Timestamps are 32 bits, so a stream's clock
wraps after 71.6 minutes; :class:`Unwrap` carries it on.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from snn_fg.events.core import EVENT_DTYPE

#: bit 31 set: the event has no timestamp word after it
NO_TIME = np.uint32(1 << 31)
#: the largest coordinate a SPIF word holds
MAX_COORD = (1 << 15) - 1
#: events in one datagram our sender writes (8 KB with timestamps)
PACKET_EVENTS = 1024


def encode(events: np.ndarray, timestamps: bool = True) -> bytes:
    """``events`` (:data:`EVENT_DTYPE`) as one packet's bytes; ``timestamps``:
    each with its time (``t``, microseconds, taken modulo 2**32)."""
    word = (
        (events["x"].astype(np.uint32) << 16)
        | (events["p"].astype(np.uint32) > 0).astype(np.uint32) << 15
        | events["y"].astype(np.uint32)
    )
    if not timestamps:
        return (word | NO_TIME).astype("<u4").tobytes()
    out = np.empty((len(events), 2), "<u4")
    out[:, 0] = word
    out[:, 1] = (events["t"].astype(np.int64) & 0xFFFFFFFF).astype(np.uint32)
    return out.tobytes()


def decode(data: bytes, now_us: int) -> np.ndarray | None:
    """One packet's events (:data:`EVENT_DTYPE`; those without a timestamp
    stamped ``now_us``, the arrival), or None where the packet is malformed (a
    length that is not a whole number of words, or a timestamped event whose
    time word is missing). Timestamps are the packet's 32-bit ones."""
    if len(data) % 4:
        return None
    words = np.frombuffer(data, "<u4")
    ev = np.empty(words.size, EVENT_DTYPE)  # (room for a packet of events without timestamps)
    n = _walk(words, now_us, ev)
    return None if n < 0 else ev[:n]


@njit(cache=True, nogil=True)
def _walk(words, now_us, ev):
    """The events of a packet's ``words`` into ``ev``; their number, or -1 where a
    timestamped event's time word is missing. (Compiled: it runs a packet at a
    time on the receiving thread, 3.6 us a packet of 1024 events against 32 us
    for numpy's branches for packets with, without and with some timestamps.)"""
    n, i = 0, 0
    while i < words.size:
        w = words[i]
        if w & NO_TIME:
            ev[n].t = now_us
            i += 1
        elif i + 1 < words.size:
            ev[n].t = words[i + 1]
            i += 2
        else:
            return -1
        ev[n].x = (w >> 16) & MAX_COORD
        ev[n].y = w & MAX_COORD
        ev[n].p = (w >> 15) & 1
        n += 1
    return n


class Unwrap:
    """A stream's 32-bit timestamps carried on past 2**32 us: a time more than
    half the range before the last one is taken to have wrapped."""

    SPAN = 1 << 32

    def __init__(self):
        self.base, self.last = 0, None

    def __call__(self, t: np.ndarray) -> np.ndarray:
        if not t.size:
            return t
        t = t + self.base
        self.base = _unwrap(t, self.base, -1 if self.last is None else self.last, self.last is not None, self.SPAN)
        self.last = int(t[-1])
        return t


@njit(cache=True, nogil=True)
def _unwrap(t, base, last, has_last, span):
    """``t`` carried on in place past each wrap (a time more than half the range before
    the one before it; the first compared with ``last``); returns the new base."""
    before = last
    for i in range(t.size):
        if (i > 0 or has_last) and t[i] - before < -(span // 2):  # (once in 71 minutes)
            t[i:] += span
            base += span
        before = t[i]
    return base


def prepare() -> None:
    """:func:`decode` and :class:`Unwrap` compiled (or loaded from numba's cache) as a UDP stream's
    packets call them: a packet's words, then its events' times, a strided field (numba's layout 'A').
    On a first run each took seconds on a busy machine, and a live run's receiver compiled them at the
    first packet, on the stream's time (22 of 24 windows of the demo dropped): a UDP source calls this
    as it binds its port, before the model's warm-up."""
    ev = np.zeros(2, EVENT_DTYPE)
    ev["t"] = (1, 2)
    for packet in (encode(ev), encode(ev, timestamps=False)):
        got = decode(packet, 0)
        got["t"] = Unwrap()(got["t"])
