"""iCub ``yarpdatadumper`` logs (``data.log``): address-event bottles of the
event-driven library, one text line each: ``[n t] AE (ts addr ts addr ...)``.

Decoded line by line with bounded memory; problems are
:class:`~snn_fg.errors.InputError` naming the line.
"""

from __future__ import annotations

import re

import numpy as np

from snn_fg import validate
from snn_fg.errors import InputError
from snn_fg.events.core import check_sensor_size, empty_events, pack_events
from snn_fg.events.source import DecodeTally, Source

#: Address codecs of event-driven ("auto": guessed from the first AE words).
CODECS = ("auto", "24", "20")
#: Cameras of the iCub: 0 left, 1 right.
CHANNELS = (0, 1, "both")
SENSOR_SIZE = (304, 240)
#: ATIS timestamp tick (event-driven's default VLIB_CLOCK_PERIOD_NS).
TICK_NS = 80
#: Bits of the event-driven timestamp counter (default VLIB_TIMER_BITS).
TIMER_BITS = 30
LINE_PATTERN = re.compile(rb"^\s*(?:(\d+)\s+(-?[0-9.eE+-]+)\s+)?([A-Za-z_]+)\s*\((.*)\)\s*$")


def open_yarp(
    path, sensor_size, chunk_events, *, codec: str = "auto", channel: int | str = 0, timer_bits: int = TIMER_BITS
) -> Source:
    """Open a ``data.log``; ``channel`` is 0 (left camera), 1 (right) or ``"both"``."""
    size = check_sensor_size(sensor_size or SENSOR_SIZE, path)
    keep = None if channel == "both" else channel
    return Source(
        path,
        "yarp",
        size,
        lambda n, tally: iter_yarp(path, codec=codec, channel=keep, timer_bits=timer_bits, tally=tally),
    )


def is_yarp_line(line: bytes) -> bool:
    """Whether ``line`` looks like one line of a ``data.log`` (used to recognise the format)."""
    return LINE_PATTERN.match(line) is not None


def decode_addresses(addr: np.ndarray, codec: str):
    """Split 32-bit AE words into ``(x, y, p, channel, is_dvs)``.

    ``codec="24"`` (event-driven's default CODEC_304x240_24): p bit 0,
    x bits 1-10, y bits 12-20, channel bit 22, and bits 23-31 flag
    non-vision samples (APS/IMU/skin/audio).  ``codec="20"``
    (CODEC_304x240_20): p bit 0, x bits 1-9, y bits 10-17, type bits
    18-19, channel bit 20, skin bit 21.
    """
    a = addr.astype(np.uint32)
    p = a & 1
    if codec == "24":
        x = (a >> 1) & 0x3FF
        y = (a >> 12) & 0x1FF
        ch = (a >> 22) & 1
        is_dvs = (a & 0xFF800000) == 0
    elif codec == "20":
        x = (a >> 1) & 0x1FF
        y = (a >> 10) & 0xFF
        ch = (a >> 20) & 1
        is_dvs = (a & 0xFFEC0000) == 0  # type == 0, skin == 0, no higher bits
    else:
        raise ValueError(codec)
    return x, y, p, ch, is_dvs


def guess_codec(addr: np.ndarray) -> str:
    """Pick the address codec from a sample of AE words.

    In the 24-bit codec bits 10-11 are always 0 for a 304-pixel-wide sensor
    (x < 512, and bit 11 is filler); in the 20-bit codec they hold y's low
    bits, which real data sets somewhere in any sizeable sample.
    """
    a = addr.astype(np.uint32)
    a = a[(a & 0xFF800000) == 0]
    if len(a) and ((a >> 10) & 0x3).any():
        return "20"
    return "24"


def iter_yarp(
    path,
    codec: str = "auto",
    channel: int | None = 0,
    timer_bits: int = TIMER_BITS,
    lines_per_chunk: int = 20000,
    tally=None,
):
    """Decode AE bottles of a ``yarpdatadumper`` log: ``[n t] AE (ts addr ts addr ...)``.

    Timestamps are the ATIS counter masked to ``timer_bits`` bits (bit 31,
    a flag in older logs, is dropped) in 80 ns ticks; counter wraps (a drop
    of more than half the counter range) are unwrapped.  Only DVS events of
    ``channel`` (0 = left, 1 = right, ``None`` = both) are returned; other
    bottle types, non-vision samples and the other camera's events are
    skipped, and counted in ``tally`` (a :class:`~snn_fg.events.source.DecodeTally`).
    """
    tally = tally if tally is not None else DecodeTally()
    period = 1 << timer_bits
    mask = period - 1
    validate.choice("iter_yarp", "codec", codec, CODECS)
    state = {"codec": None if codec == "auto" else codec, "last": None, "wraps": 0}
    pending_ts, pending_addr, pending_line = [], [], []

    def flush(final=False):
        if not pending_ts:
            return None
        ts = np.concatenate(pending_ts)
        addr = np.concatenate(pending_addr)
        lines = np.concatenate(pending_line)
        pending_ts.clear()
        pending_addr.clear()
        pending_line.clear()
        if state["codec"] is None:
            if len(addr) < 1000 and not final:
                # not enough evidence yet: keep for the next batch
                pending_ts.append(ts)
                pending_addr.append(addr)
                pending_line.append(lines)
                return None
            state["codec"] = guess_codec(addr)
        x, y, p, ch, is_dvs = decode_addresses(addr, state["codec"])
        keep = is_dvs if channel is None else is_dvs & (ch == channel)
        tally.skip("non-vision samples (IMU or skin)", np.count_nonzero(~is_dvs))
        if channel is not None:
            tally.skip(f"events of the other camera (channel {1 - channel})", np.count_nonzero(is_dvs & ~keep))
        ts, x, y, p, lines = ts[keep], x[keep], y[keep], p[keep], lines[keep]
        if not len(ts):
            return empty_events()
        raw = (ts & 0x7FFFFFFF) & mask
        prev = np.concatenate([[raw[0] if state["last"] is None else state["last"]], raw[:-1]])
        wrap = (prev - raw) > (period >> 1)
        wraps = state["wraps"] + np.cumsum(wrap)
        state["wraps"] = int(wraps[-1])
        state["last"] = int(raw[-1])
        ticks = raw + wraps * period
        t_us = (ticks * TICK_NS) // 1000
        bad = (x >= SENSOR_SIZE[0]) | (y >= SENSOR_SIZE[1])
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(
                path,
                f"event at (x={int(x[i])}, y={int(y[i])}) lies outside the ATIS "
                f"{SENSOR_SIZE[0]} x {SENSOR_SIZE[1]} sensor (wrong codec? "
                f"decoded with the {state['codec']}-bit codec)",
                f"line {int(lines[i])}",
            )
        return pack_events(x, y, t_us, p)

    n_lines = 0
    n_ae = 0
    with open(path, "rb") as fh:
        for lineno, line in enumerate(fh, start=1):
            n_lines += 1
            if not line.strip():
                continue
            m = LINE_PATTERN.match(line)
            if m is None:
                raise InputError(path, "not a YARP data.log line (expected '[n t] TAG (values ...)')", f"line {lineno}")
            tag = m.group(3)
            if tag not in (b"AE", b"LAE"):
                tally.skip(f"{tag.decode(errors='replace')} bottles")
                continue
            try:
                vals = np.array(m.group(4).split(), dtype=np.int64)
            except ValueError:
                raise InputError(path, "AE bottle holds a non-integer value", f"line {lineno}") from None
            step = 3 if tag == b"LAE" else 2
            if len(vals) % step:
                raise InputError(
                    path, f"{tag.decode()} bottle has {len(vals)} values, not a multiple of {step}", f"line {lineno}"
                )
            if len(vals) and ((vals < -(1 << 31)) | (vals >= (1 << 32))).any():
                raise InputError(path, "AE bottle value does not fit in 32 bits", f"line {lineno}")
            vals = vals & 0xFFFFFFFF
            v = vals.reshape(-1, step)
            n_ae += len(v)
            pending_ts.append(v[:, 0])
            pending_addr.append(v[:, 1])
            pending_line.append(np.full(len(v), lineno))
            if len(pending_line) >= lines_per_chunk:
                out = flush()
                if out is not None and len(out):
                    yield out
    out = flush(final=True)
    if out is not None and len(out):
        yield out
    if n_ae == 0 and n_lines == 0:
        raise InputError(path, "YARP log is empty")
