"""Our own streaming decoders: Event Stream (.es) DVS, Prophesee EVT3 and EVT2
word checks, and the iCub YARP ``data.log`` text format.

Each decoder is a generator of :data:`EVENT_DTYPE` chunks that keeps its state
across chunks, so files of any size decode with bounded memory.  Every problem
is raised as :class:`~snn_fg.errors.InputError` with a byte offset (binary
formats) or line number (text).
"""
from __future__ import annotations

import re

import numpy as np

from snn_fg.errors import InputError
from snn_fg.events._core import EVENT_DTYPE

READ_BYTES = 1 << 22  # 4 MiB per read


def _pack(x, y, t, p) -> np.ndarray:
    out = np.empty(len(t), dtype=EVENT_DTYPE)
    out["x"] = x
    out["y"] = y
    out["t"] = t
    out["p"] = p
    return out


def _concat(parts) -> np.ndarray:
    parts = [p for p in parts if len(p)]
    if not parts:
        return np.zeros(0, dtype=EVENT_DTYPE)
    return parts[0] if len(parts) == 1 else np.concatenate(parts)


# --------------------------------------------------------------------------
# Event Stream
# --------------------------------------------------------------------------
ES_MAGIC = b"Event Stream"
ES_TYPES = {0: "generic", 1: "dvs", 2: "atis", 3: "asynchronous display", 4: "color"}


def read_es_header(path) -> tuple[int, int, int]:
    """Return ``(width, height, body_offset)`` of an Event Stream 2.x DVS file."""
    with open(path, "rb") as fh:
        head = fh.read(20)
    if not head.startswith(ES_MAGIC):
        raise InputError(path, "not an Event Stream file (missing 'Event Stream' signature)", "byte offset 0")
    if len(head) < 16:
        raise InputError(path, "Event Stream header is truncated", f"byte offset {len(head)}")
    major = head[12]
    if major != 2:
        raise InputError(path, f"Event Stream version {major}.{head[13]}.{head[14]} is not supported (only 2.x)",
                         "byte offset 12")
    kind = head[15]
    if kind != 1:
        name = ES_TYPES.get(kind, f"unknown type {kind}")
        raise InputError(path, f"Event Stream holds {name} events; only DVS event streams are supported",
                         "byte offset 15")
    if len(head) < 20:
        raise InputError(path, "Event Stream header is truncated (no sensor size)", f"byte offset {len(head)}")
    w = int(head[16]) | (int(head[17]) << 8)
    h = int(head[18]) | (int(head[19]) << 8)
    if w == 0 or h == 0:
        raise InputError(path, f"Event Stream header gives an empty sensor ({w} x {h})", "byte offset 16")
    return w, h, 20


def iter_es(path, body_offset: int = 20, read_bytes: int = READ_BYTES):
    """Decode the DVS events of an Event Stream 2.x file chunk by chunk.

    The byte state machine (idle: 0xFF = overflow of 127 us, 0xFE = reset,
    anything else starts a 5-byte event) is decoded with numpy between
    special bytes, which are rare in busy recordings.
    """
    t_prev = 0
    overflow = 0
    carry = np.zeros(0, dtype=np.uint8)
    base = body_offset  # file offset of carry[0]
    with open(path, "rb") as fh:
        fh.seek(body_offset)
        while True:
            raw = fh.read(read_bytes)
            eof = len(raw) < read_bytes
            b = np.concatenate([carry, np.frombuffer(raw, dtype=np.uint8)]) if len(carry) else \
                np.frombuffer(raw, dtype=np.uint8)
            n = len(b)
            pos = 0
            parts = []
            win = 256
            while pos < n:
                # records assumed contiguous from pos; find the first special byte in idle position
                nrec_avail = (n - pos) // 5
                if nrec_avail == 0:
                    # only a partial record (or specials) left
                    if b[pos] >= 0xFE:
                        overflow += 127 if b[pos] == 0xFF else 0
                        pos += 1
                        continue
                    break
                m = min(nrec_avail, win)
                heads = b[pos:pos + 5 * m:5]
                special = heads >= 0xFE
                k = int(np.argmax(special)) if special.any() else m
                if k:
                    rec = b[pos:pos + 5 * k].reshape(k, 5)
                    delta = (rec[:, 0] >> 1).astype(np.int64)
                    delta[0] += overflow
                    overflow = 0
                    t = t_prev + np.cumsum(delta)
                    t_prev = int(t[-1])
                    x = rec[:, 1].astype(np.int64) | (rec[:, 2].astype(np.int64) << 8)
                    y = rec[:, 3].astype(np.int64) | (rec[:, 4].astype(np.int64) << 8)
                    parts.append((x, y, t, rec[:, 0] & 1, base + pos))
                    pos += 5 * k
                if k < m:
                    win = 256
                    while pos < n and b[pos] >= 0xFE:
                        if b[pos] == 0xFF:
                            overflow += 127
                        pos += 1
                else:
                    win = min(win * 4, 1 << 20)
            if parts:
                xs = np.concatenate([q[0] for q in parts])
                ys = np.concatenate([q[1] for q in parts])
                big = (xs > 32767) | (ys > 32767)
                if big.any():
                    i = int(np.argmax(big))
                    # locate the byte offset of that record
                    sizes = np.cumsum([len(q[0]) for q in parts])
                    j = int(np.searchsorted(sizes, i, side="right"))
                    within = i - (int(sizes[j - 1]) if j else 0)
                    raise InputError(path, f"event coordinate ({int(xs[i])}, {int(ys[i])}) is out of range",
                                     f"byte offset {parts[j][4] + 5 * within}")
                yield _pack(xs, ys, np.concatenate([q[2] for q in parts]), np.concatenate([q[3] for q in parts]))
            carry = b[pos:].copy()
            base += pos
            if eof:
                break
    if len(carry):
        raise InputError(path, f"file ends inside an event ({len(carry)} of 5 bytes)", f"byte offset {base}")


# --------------------------------------------------------------------------
# Prophesee RAW header
# --------------------------------------------------------------------------
def read_raw_header(path, max_header: int = 1 << 20):
    """Parse the ``%`` text header of a Prophesee RAW/DAT file.

    Returns ``(header_dict, body_offset)``; keys are lower-case first words
    (``evt``, ``format``, ``geometry``, ``width``, ``height``...).
    """
    info: dict[str, str] = {}
    offset = 0
    with open(path, "rb") as fh:
        while True:
            peek = fh.read(1)
            if peek != b"%":
                break
            line = peek + fh.readline(4096)
            if not line.endswith(b"\n"):
                raise InputError(path, "header line is unterminated or longer than 4 KiB",
                                 f"byte offset {offset}")
            try:
                text = line[1:].decode("ascii").strip()
            except UnicodeDecodeError:
                raise InputError(path, "header line is not ASCII text", f"byte offset {offset}")
            offset += len(line)
            if offset > max_header:
                raise InputError(path, "header is longer than 1 MiB", f"byte offset {offset}")
            if text == "end":
                break
            parts = text.split(None, 1)
            if parts:
                info[parts[0].lower()] = parts[1] if len(parts) > 1 else ""
    return info, offset


def raw_geometry(info: dict):
    """Sensor ``(W, H)`` from a RAW/DAT header, or ``None`` when it gives none."""
    g = info.get("geometry")
    if g:
        m = re.fullmatch(r"\s*(\d+)\s*x\s*(\d+)\s*", g)
        if m:
            return int(m.group(1)), int(m.group(2))
    f = info.get("format")
    if f:
        kv = dict(item.split("=", 1) for item in f.split(";")[1:] if "=" in item)
        if kv.get("width", "").isdigit() and kv.get("height", "").isdigit():
            return int(kv["width"]), int(kv["height"])
    if info.get("width", "").strip().isdigit() and info.get("height", "").strip().isdigit():
        return int(info["width"]), int(info["height"])
    return None


def raw_encoding(info: dict):
    """``"evt2"``, ``"evt3"``, another name, or ``None`` if the header does not say."""
    f = info.get("format", "")
    if f:
        name = f.split(";")[0].strip().lower()
        return {"evt2": "evt2", "evt3": "evt3", "evt21": "evt21", "evt2.1": "evt21"}.get(name, name)
    e = info.get("evt", "").strip()
    if e:
        return {"2.0": "evt2", "3.0": "evt3", "2.1": "evt21"}.get(e, "evt" + e)
    return None


def _iter_words(path, offset, word_bytes, read_bytes=READ_BYTES):
    """Yield ``(byte_offset, words)`` of little-endian words from ``offset``."""
    dtype = np.dtype(f"<u{word_bytes}")
    read_bytes -= read_bytes % word_bytes
    with open(path, "rb") as fh:
        fh.seek(offset)
        pos = offset
        while True:
            raw = fh.read(read_bytes)
            if not raw:
                return
            usable = len(raw) - len(raw) % word_bytes
            if usable != len(raw):
                raise InputError(path, f"file ends inside a {8 * word_bytes}-bit word "
                                       f"({len(raw) - usable} trailing bytes)", f"byte offset {pos + usable}")
            yield pos, np.frombuffer(raw, dtype=dtype)
            pos += len(raw)


EVT2_TYPES = (0x0, 0x1, 0x8, 0xA, 0xE, 0xF)


def check_evt2(path, offset, sensor_size):
    """Check every EVT2 word: known type, CD events inside the sensor."""
    w, h = sensor_size[0], sensor_size[1]
    for pos, words in _iter_words(path, offset, 4):
        typ = words >> 28
        bad = ~np.isin(typ, EVT2_TYPES)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(path, f"unknown EVT2 word type 0x{int(typ[i]):X} (file is corrupt or not EVT2)",
                             f"byte offset {pos + 4 * i}")
        cd = typ <= 1
        x = (words >> 11) & 0x7FF
        y = words & 0x7FF
        bad = cd & ((x >= w) | (y >= h))
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(path, f"event at (x={int(x[i])}, y={int(y[i])}) lies outside the {w} x {h} sensor",
                             f"byte offset {pos + 4 * i}")


EVT3_KNOWN = np.zeros(16, dtype=bool)
EVT3_KNOWN[[0x0, 0x2, 0x3, 0x4, 0x5, 0x6, 0x7, 0x8, 0xA, 0xE, 0xF]] = True
_BITS12 = np.arange(12, dtype=np.uint16)


def iter_evt3(path, offset, read_bytes=READ_BYTES):
    """Decode Prophesee EVT 3.0 (16-bit words) chunk by chunk.

    Timestamp = (TIME_HIGH << 12) | TIME_LOW on a 24-bit counter; a TIME_HIGH
    that goes backwards is a counter wrap and adds 2**24 us.  TIME_LOW words
    never carry into TIME_HIGH (counting TIME_LOW wrap-arounds on top of
    TIME_HIGH is the "4096 us drift" bug some decoders have).  Events before
    the first TIME_HIGH or the first EVT_ADDR_Y have no defined time/row and
    are dropped, as Prophesee's reference decoder does.
    """
    # state carried across chunks
    th_raw = -1      # last TIME_HIGH payload (raw 12 bits), -1 = none yet
    th_abs = -1      # unwrapped TIME_HIGH counter (in units of 4096 us)
    tl = 0           # TIME_LOW payload valid after the last TIME_HIGH (0 if none)
    y_cur = -1
    bx_cur = -1      # base x for vectors
    pol_cur = 0
    for pos, w in _iter_words(path, offset, 2, read_bytes):
        n = len(w)
        typ = (w >> 12).astype(np.int8)
        pay = (w & 0xFFF).astype(np.int64)
        bad = ~EVT3_KNOWN[typ]
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(path, f"unknown EVT3 word type 0x{int(typ[i]):X} (file is corrupt or not EVT3)",
                             f"byte offset {pos + 2 * i}")
        idx = np.arange(n)

        # --- time high, unwrapped
        is_th = typ == 0x8
        th_pay = pay[is_th]
        prev = np.concatenate([[th_raw], th_pay[:-1]]) if len(th_pay) else th_pay
        wraps = np.cumsum((th_pay < prev) & (prev >= 0))
        # absolute counter (units of 4096 us) = payload + 4096 * wraps so far
        if th_abs < 0:
            th_vals = th_pay + 4096 * wraps
        else:
            th_vals = th_abs + (th_pay - th_raw) + 4096 * wraps
        last_th = np.maximum.accumulate(np.where(is_th, idx, -1))
        th_rank = np.cumsum(is_th) - 1  # index into th_vals of last TIME_HIGH
        th_at = np.where(last_th >= 0, th_vals[np.maximum(th_rank, 0)] if len(th_vals) else 0, th_abs)

        # --- time low: valid only after the last TIME_HIGH
        is_tl = typ == 0x6
        last_tl = np.maximum.accumulate(np.where(is_tl, idx, -1))
        tl_at = np.where(last_tl > last_th, pay[np.maximum(last_tl, 0)],
                         np.where(last_th >= 0, 0, tl))
        t_at = th_at * 4096 + tl_at
        t_ok = th_at >= 0

        # --- y
        is_y = typ == 0x0
        last_y = np.maximum.accumulate(np.where(is_y, idx, -1))
        y_at = np.where(last_y >= 0, pay[np.maximum(last_y, 0)] & 0x7FF, y_cur)

        # --- single events
        is_x = (typ == 0x2) & t_ok & (y_at >= 0)
        ev_x = pay[is_x] & 0x7FF
        ev_p = (pay[is_x] >> 11) & 1
        sx, sy, st, sp, si = ev_x, y_at[is_x], t_at[is_x], ev_p, idx[is_x]

        # --- vectors
        is_bx = typ == 0x3
        is_v12 = typ == 0x4
        is_v8 = typ == 0x5
        inc = np.where(is_v12, 12, np.where(is_v8, 8, 0))
        cum = np.cumsum(inc)
        cum_excl = cum - inc
        last_bx = np.maximum.accumulate(np.where(is_bx, idx, -1))
        has_bx = last_bx >= 0
        bx_pay = pay[np.maximum(last_bx, 0)]
        # base x at each word: from this chunk's VECT_BASE_X, or carried state
        start_x = np.where(has_bx, bx_pay & 0x7FF, bx_cur)
        since = np.where(has_bx, cum_excl - cum[np.maximum(last_bx, 0)], cum_excl)
        vx0 = start_x + since
        vpol = np.where(has_bx, (bx_pay >> 11) & 1, pol_cur)
        is_vec = (is_v12 | is_v8) & t_ok & (y_at >= 0) & (start_x >= 0)
        vparts = []
        if is_vec.any():
            vi = idx[is_vec]
            mask = pay[is_vec].astype(np.uint16)
            nb = np.where(is_v12[is_vec], 12, 8)
            bits = ((mask[:, None] >> _BITS12[None, :]) & 1).astype(bool) & (_BITS12[None, :] < nb[:, None])
            rows, cols = np.nonzero(bits)
            vparts = (vx0[vi][rows] + cols, y_at[vi][rows], t_at[vi][rows], vpol[vi][rows], vi[rows])
        if vparts:
            ax = np.concatenate([sx, vparts[0]])
            ay = np.concatenate([sy, vparts[1]])
            at = np.concatenate([st, vparts[2]])
            ap = np.concatenate([sp, vparts[3]])
            ai = np.concatenate([si, vparts[4]])
            order = np.argsort(ai, kind="stable")
            ax, ay, at, ap, ai = ax[order], ay[order], at[order], ap[order], ai[order]
        else:
            ax, ay, at, ap, ai = sx, sy, st, sp, si
        big = ax > 32767
        if big.any():
            i = int(np.argmax(big))
            raise InputError(path, "vector event runs past x = 32767", f"byte offset {pos + 2 * int(ai[i])}")
        if len(ax):
            yield _pack(ax, ay, at, ap)

        # --- update state for the next chunk
        if len(th_pay):
            th_raw = int(th_pay[-1])
            th_abs = int(th_vals[-1])
            tl = 0
        if last_tl[-1] > last_th[-1]:
            tl = int(pay[last_tl[-1]])
        if last_y[-1] >= 0:
            y_cur = int(pay[last_y[-1]] & 0x7FF)
        if has_bx[-1] or bx_cur >= 0:
            bx_cur = int(vx0[-1] + inc[-1])
            pol_cur = int(vpol[-1])


# --------------------------------------------------------------------------
# iCub YARP data.log
# --------------------------------------------------------------------------
YARP_SENSOR = (304, 240)
#: ATIS timestamp tick (event-driven's default VLIB_CLOCK_PERIOD_NS).
YARP_TICK_NS = 80
#: Bits of the event-driven timestamp counter (default VLIB_TIMER_BITS).
YARP_TIMER_BITS = 30
_YARP_LINE = re.compile(rb"^\s*(?:(\d+)\s+(-?[0-9.eE+-]+)\s+)?([A-Za-z_]+)\s*\((.*)\)\s*$")


def yarp_decode_addresses(addr: np.ndarray, codec: str):
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


def guess_yarp_codec(addr: np.ndarray) -> str:
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


def iter_yarp(path, codec: str = "auto", channel: int | None = 0, timer_bits: int = YARP_TIMER_BITS,
              lines_per_chunk: int = 20000):
    """Decode AE bottles of a ``yarpdatadumper`` log: ``[n t] AE (ts addr ts addr ...)``.

    Timestamps are the ATIS counter masked to ``timer_bits`` bits (bit 31,
    a flag in older logs, is dropped) in 80 ns ticks; counter wraps (a drop
    of more than half the counter range) are unwrapped.  Only DVS events of
    ``channel`` (0 = left, 1 = right, ``None`` = both) are returned; other
    bottle types and non-vision samples are skipped.
    """
    period = 1 << timer_bits
    mask = period - 1
    state = {"codec": None if codec == "auto" else codec, "last": None, "wraps": 0}
    if state["codec"] not in (None, "24", "20"):
        raise InputError(path, f"unknown YARP codec {codec!r} (use '24', '20' or 'auto')")
    pending_ts, pending_addr, pending_line = [], [], []

    def flush(final=False):
        if not pending_ts:
            return None
        ts = np.concatenate(pending_ts)
        addr = np.concatenate(pending_addr)
        lines = np.concatenate(pending_line)
        pending_ts.clear(); pending_addr.clear(); pending_line.clear()
        if state["codec"] is None:
            if len(addr) < 1000 and not final:
                # not enough evidence yet: keep for the next batch
                pending_ts.append(ts); pending_addr.append(addr); pending_line.append(lines)
                return None
            state["codec"] = guess_yarp_codec(addr)
        x, y, p, ch, is_dvs = yarp_decode_addresses(addr, state["codec"])
        keep = is_dvs if channel is None else is_dvs & (ch == channel)
        ts, x, y, p, lines = ts[keep], x[keep], y[keep], p[keep], lines[keep]
        if not len(ts):
            return np.zeros(0, dtype=EVENT_DTYPE)
        raw = (ts & 0x7FFFFFFF) & mask
        prev = np.concatenate([[raw[0] if state["last"] is None else state["last"]], raw[:-1]])
        wrap = (prev - raw) > (period >> 1)
        wraps = state["wraps"] + np.cumsum(wrap)
        state["wraps"] = int(wraps[-1])
        state["last"] = int(raw[-1])
        ticks = raw + wraps * period
        t_us = (ticks * YARP_TICK_NS) // 1000
        bad = (x >= YARP_SENSOR[0]) | (y >= YARP_SENSOR[1])
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(path, f"event at (x={int(x[i])}, y={int(y[i])}) lies outside the ATIS "
                                   f"{YARP_SENSOR[0]} x {YARP_SENSOR[1]} sensor (wrong codec? "
                                   f"decoded with the {state['codec']}-bit codec)", f"line {int(lines[i])}")
        return _pack(x, y, t_us, p)

    n_lines = 0
    n_ae = 0
    with open(path, "rb") as fh:
        for lineno, line in enumerate(fh, start=1):
            n_lines += 1
            if not line.strip():
                continue
            m = _YARP_LINE.match(line)
            if m is None:
                raise InputError(path, "not a YARP data.log line (expected '[n t] TAG (values ...)')",
                                 f"line {lineno}")
            tag = m.group(3)
            if tag not in (b"AE", b"LAE"):
                continue
            try:
                vals = np.array(m.group(4).split(), dtype=np.int64)
            except ValueError:
                raise InputError(path, "AE bottle holds a non-integer value", f"line {lineno}")
            step = 3 if tag == b"LAE" else 2
            if len(vals) % step:
                raise InputError(path, f"{tag.decode()} bottle has {len(vals)} values, not a multiple of {step}",
                                 f"line {lineno}")
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
