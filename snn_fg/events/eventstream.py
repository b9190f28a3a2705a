"""Event Stream 2.x (``.es``) files: header and streaming DVS and ATIS decoders.

Specification: https://github.com/neuromorphic-paris/event_stream.  A file
starts with ``Event Stream``, three version bytes and a stream type byte
(0 generic, 1 DVS, 2 ATIS, 3 asynchronous display, 4 colour); DVS and ATIS
streams add the sensor width and height (little-endian uint16) and then share
one byte layout.  Between events a reader is *idle*, and a byte read there is
either a one-byte *special* (overflow: time passes; reset: nothing happens,
so a reader can resynchronise) or byte 0 of a 5-byte event whose bytes 1-4
are x and y (little-endian uint16).  Byte 0 holds the time since the previous
event above ``F`` flag bits:

======  =====  ======================  =========================  ==================================
stream  ``F``  special bytes           an overflow byte adds      flag bits of byte 0
======  =====  ======================  =========================  ==================================
DVS     1      0xFE reset, 0xFF        127 us                     ``is_increase``
ATIS    2      0xFC reset, 0xFD-0xFF   63 us x (byte & 3)         ``polarity << 1 | is_tc``
======  =====  ======================  =========================  ==================================

so a byte is special when its time field is all ones, and an overflow adds
``(byte - first special byte) x (2**(8 - F) - 1)`` us.  An ATIS event with
``is_tc = 0`` is a change detection, a polarity event like a DVS one
(``polarity`` = ``is_increase``); ``is_tc = 1`` is a threshold crossing, half
of an exposure measurement (``polarity`` = ``is_second``).  Exposure events
carry grey levels, not polarities, so they are counted, not returned.

Decoders read :data:`~snn_fg.events.source.READ_BYTES` at a time and keep
their state across reads, so memory does not grow with the file; every
problem is an :class:`~snn_fg.errors.InputError` with a byte offset.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from snn_fg.errors import InputError
from snn_fg.events.core import check_sensor_size, file_sensor_size, pack_events
from snn_fg.events.source import READ_BYTES, DecodeTally, Source

MAGIC = b"Event Stream"
#: Stream type byte -> name, as the specification lists them.
STREAM_TYPES = {0: "generic", 1: "DVS", 2: "ATIS", 3: "asynchronous display", 4: "colour"}
#: Flag bits in byte 0 of an event, per supported stream type.
FLAG_BITS = {"DVS": 1, "ATIS": 2}
_VERSION_OFFSET = len(MAGIC)  # major, minor, patch
_TYPE_OFFSET = _VERSION_OFFSET + 3
_SIZE_OFFSET = _TYPE_OFFSET + 1  # width, height: little-endian uint16
_BODY_OFFSET = _SIZE_OFFSET + 4
_EVENT_BYTES = 5


@dataclass(frozen=True)
class Header:
    """What the 20-byte header of a DVS or ATIS Event Stream says."""

    stream: str  # "DVS" or "ATIS"
    width: int
    height: int
    body_offset: int = _BODY_OFFSET


def read_header(path) -> Header:
    """Parse and check the header; other stream types are refused by name."""
    with open(path, "rb") as fh:
        head = fh.read(_BODY_OFFSET)
    if len(head) < _BODY_OFFSET and MAGIC.startswith(head[: len(MAGIC)]):  # (a file cut inside its header)
        raise InputError(
            path, f"file ends inside its header ({len(head)} of {_BODY_OFFSET} bytes)", f"byte offset {len(head)}"
        )
    if not head.startswith(MAGIC):
        raise InputError(path, "not an Event Stream file (missing 'Event Stream' signature)", "byte offset 0")
    major, minor, patch = head[_VERSION_OFFSET:_TYPE_OFFSET]
    if major != 2:
        raise InputError(
            path,
            f"Event Stream version {major}.{minor}.{patch} is not supported (only 2.x)",
            f"byte offset {_VERSION_OFFSET}",
        )
    kind = head[_TYPE_OFFSET]
    name = STREAM_TYPES.get(kind, "unknown")
    if name not in FLAG_BITS:
        raise InputError(
            path,
            f"Event Stream holds {name} events (stream type {kind}); only DVS and ATIS event streams are supported",
            f"byte offset {_TYPE_OFFSET}",
        )
    if len(head) < _BODY_OFFSET:
        raise InputError(path, "Event Stream header is truncated (no sensor size)", f"byte offset {len(head)}")
    w = int.from_bytes(head[_SIZE_OFFSET : _SIZE_OFFSET + 2], "little")
    h = int.from_bytes(head[_SIZE_OFFSET + 2 : _BODY_OFFSET], "little")
    if w == 0 or h == 0:
        raise InputError(path, f"Event Stream header gives an empty sensor ({w} x {h})", f"byte offset {_SIZE_OFFSET}")
    check_sensor_size((w, h), path)  # coordinates must fit EVENT_DTYPE whatever size the caller asks for
    return Header(name, w, h)


def open_es(path, sensor_size, chunk_events) -> Source:
    """Open a DVS (decoder ``"es"``) or ATIS (``"es-atis"``) Event Stream file.

    ``sensor_size``, if given, must be the header's (:func:`~snn_fg.events.core.file_sensor_size`).
    """
    header = read_header(path)
    size = file_sensor_size(path, sensor_size, (header.width, header.height))
    if header.stream == "DVS":
        return Source(path, "es", size, lambda n, tally: iter_dvs(path, header))
    return Source(path, "es-atis", size, lambda n, tally: iter_atis(path, header, tally))


def iter_dvs(path, header: Header, read_bytes: int = READ_BYTES):
    """Decode the events of a DVS stream chunk by chunk (``p`` = ``is_increase``)."""
    for flags, x, y, t in iter_records(path, header, read_bytes):
        yield pack_events(x, y, t, flags)


def iter_atis(path, header: Header, tally: DecodeTally, read_bytes: int = READ_BYTES):
    """Decode the change-detection events of an ATIS stream chunk by chunk.

    Exposure-measurement events are added to ``tally.exposure_events`` and
    left out; they still advance time, as every event's time is relative to
    the previous event of either kind.
    """
    for flags, x, y, t in iter_records(path, header, read_bytes):
        change = (flags & 1) == 0
        tally.exposure_events += int(len(flags) - np.count_nonzero(change))
        yield pack_events(x[change], y[change], t[change], flags[change] >> 1)


def iter_records(path, header: Header, read_bytes: int = READ_BYTES):
    """Yield ``(flags, x, y, t)`` arrays for the 5-byte events of each read.

    :func:`_scan` finds where events and special bytes start; each overflow's
    time then goes to the event that follows it (across reads if need be).
    """
    flag_bits = FLAG_BITS[header.stream]
    special = 256 - (1 << flag_bits)
    overflow_unit = (256 >> flag_bits) - 1
    t_prev = 0
    pending_us = 0  # overflow time read but not yet given to an event
    carry = b""  # bytes of an event cut by the end of a read
    base = header.body_offset  # file offset of the first byte of ``buf``
    with open(path, "rb") as fh:
        fh.seek(base)
        while True:
            raw = fh.read(read_bytes)
            eof = len(raw) < read_bytes
            buf = np.frombuffer(carry + raw, dtype=np.uint8)
            starts, specials, used = _scan(buf, special)
            if len(starts):
                over = (buf[specials].astype(np.int64) - special) * overflow_unit
                # the overflow before event i is in the slots up to i; the last slot carries over
                per_event = np.bincount(
                    np.searchsorted(starts, specials), weights=over, minlength=len(starts) + 1
                ).astype(np.int64)
                head = buf[starts]
                delta = (head >> flag_bits).astype(np.int64) + per_event[:-1]
                delta[0] += pending_us
                pending_us = int(per_event[-1])
                t = t_prev + np.cumsum(delta)
                t_prev = int(t[-1])
                x = buf[starts + 1] | (buf[starts + 2].astype(np.uint16) << 8)
                y = buf[starts + 3] | (buf[starts + 4].astype(np.uint16) << 8)
                n = _first_outside(header, x, y)  # (the events before one outside: their windows are cut)
                yield head[:n] & ((1 << flag_bits) - 1), x[:n], y[:n], t[:n]
                if n < len(starts):
                    raise _outside(path, header, x[n], y[n], base + int(starts[n]))
            else:
                pending_us += int(((buf[specials].astype(np.int64) - special) * overflow_unit).sum())
            carry = bytes(buf[used:])
            base += used
            if eof:
                break
    if carry:
        raise InputError(
            path, f"file ends inside an event ({len(carry)} of {_EVENT_BYTES} bytes)", f"byte offset {base}"
        )


@njit(cache=True, nogil=True)
def _scan(buf: np.ndarray, special: int):
    """Walk the byte state machine over ``buf`` from idle.

    Returns the start offsets of the whole events, the offsets of the special
    bytes, and how many bytes were used (the rest is an incomplete event).
    A byte at an event boundary is either special (``>= special``: a time
    overflow, one byte) or the first of a 5-byte event. Compiled: the walk is
    one test per event, which in Python took about a fifth of a second per
    second of a busy DVS recording.
    """
    n = buf.size
    starts = np.empty(n // _EVENT_BYTES + 1, dtype=np.int64)
    specials = np.empty(n, dtype=np.int64)
    n_starts = n_specials = 0
    pos = 0
    while pos < n:
        if buf[pos] >= special:
            specials[n_specials] = pos
            n_specials += 1
            pos += 1
        elif pos + _EVENT_BYTES <= n:
            starts[n_starts] = pos
            n_starts += 1
            pos += _EVENT_BYTES
        else:
            break  # an event cut by the end of the buffer
    return starts[:n_starts].copy(), specials[:n_specials].copy(), pos


def _first_outside(header: Header, x, y) -> int:
    """The index of the first event outside the header's sensor (``len(x)``: none)."""
    bad = (x >= header.width) | (y >= header.height)
    return int(np.argmax(bad)) if bad.any() else len(x)


def _outside(path, header: Header, x, y, offset: int) -> InputError:
    return InputError(
        path,
        f"event at (x={int(x)}, y={int(y)}) lies outside the {header.width} x {header.height} sensor of the header",
        f"byte offset {offset}",
    )
