"""Events in the SpiNNaker interface board's (SPIF) UDP packets, as ``aestream`` sends them.

Each event is a little-endian 32-bit word: bit 31 says whether a timestamp
follows (0: a second word, the time in microseconds; 1: none), bits 30-16
hold ``x``, bit 15 the polarity (1: ON) and bits 14-0 ``y``. A packet is a
whole number of such events. Timestamps are 32 bits, so a stream's clock
wraps after 71.6 minutes; :class:`Unwrap` carries it on.
"""

from __future__ import annotations

import numpy as np

from snn_fg.events._core import EVENT_DTYPE

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
    if not words.size:
        return np.zeros(0, EVENT_DTYPE)
    stamped = (words & NO_TIME) == 0
    if not stamped.any():
        ev_words, times = words, np.full(words.size, now_us, np.int64)
    elif stamped.all():
        if words.size % 2:
            return None
        pairs = words.reshape(-1, 2)
        ev_words, times = pairs[:, 0], pairs[:, 1].astype(np.int64)
    else:  # (mixed: walk the words)
        ev_words, times, i = [], [], 0
        while i < words.size:
            if words[i] & NO_TIME:
                ev_words.append(words[i])
                times.append(now_us)
                i += 1
            elif i + 1 < words.size:
                ev_words.append(words[i])
                times.append(int(words[i + 1]))
                i += 2
            else:
                return None
        ev_words, times = np.array(ev_words, np.uint32), np.array(times, np.int64)
    ev = np.empty(ev_words.size, EVENT_DTYPE)
    ev["x"] = (ev_words >> 16) & MAX_COORD
    ev["y"] = ev_words & MAX_COORD
    ev["p"] = (ev_words >> 15) & 1
    ev["t"] = times
    return ev


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
        if self.last is not None:
            back = np.flatnonzero(np.diff(np.concatenate([[self.last], t])) < -self.SPAN // 2)
            for i in back:  # (once in 71 minutes)
                t[i:] += self.SPAN
                self.base += self.SPAN
        self.last = int(t[-1])
        return t
