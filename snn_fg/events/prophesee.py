"""Prophesee recordings: the ``%`` text header of RAW/DAT files, EVT 2.0 and
EVT 3.0 ``.raw`` and DAT ``.dat`` CD events.

EVT3 is decoded here (expelliarmus 1.1 drifts by 4096 us steps); EVT2 and
DAT are decoded by expelliarmus after every word has been checked here, so
corrupt files give an :class:`~snn_fg.errors.InputError` with a byte offset
instead of reaching the C decoder.
"""

from __future__ import annotations

import re

import numpy as np

from snn_fg.errors import InputError
from snn_fg.events.core import SENSOR_SIZE, file_sensor_size, pack_events
from snn_fg.events.source import READ_BYTES, Source

ENCODINGS = ("evt2", "evt3")
#: A DAT body starts with two bytes (event type, event size), then events of this many bytes.
DAT_EVENT_BYTES = 8


def open_raw(path, sensor_size, chunk_events, *, encoding: str | None = None) -> Source:
    """Open an EVT2 or EVT3 ``.raw`` file; ``encoding`` is needed only when the header does not say."""
    info, off = read_header(path)
    enc = encoding or header_encoding(info) or "evt2"
    if enc not in ENCODINGS:
        raise InputError(path, f"RAW encoding '{enc}' is not supported (only EVT 2.0 and EVT 3.0)")
    geom = header_geometry(info)
    if sensor_size is None and geom is None:
        raise InputError(
            path,
            f"{enc.upper()} file whose header gives no sensor size (no geometry, width or height line)",
            remedy=SENSOR_SIZE,
            note=" (a Prophesee Gen3 VGA sensor is 640 x 480)",
        )
    size = file_sensor_size(path, sensor_size, geom)
    if enc == "evt3":
        return Source(path, "evt3", size, lambda n, tally: iter_evt3(path, off, tally=tally))

    def chunks(n, tally):
        try:
            check_evt2(path, off, size, tally)  # clear errors (with byte offsets) before the C decoder runs
        except InputError as damage:  # (read up to it, as every other format is: then the error)
            yield from evt2_before(path, off, _offset_of(damage))
            raise damage from None
        yield from _expelliarmus_chunks(path, "evt2", n)

    return Source(path, "evt2", size, chunks)


def open_dat(path, sensor_size, chunk_events) -> Source:
    """Open a DAT file of 8-byte CD events."""
    info, off = read_header(path)
    with open(path, "rb") as fh:
        fh.seek(off)
        td = fh.read(2)  # event type, event size
    if len(td) < 2:
        raise InputError(path, "DAT file ends before its event type/size bytes", f"byte offset {off + len(td)}")
    if td[1] != DAT_EVENT_BYTES:
        raise InputError(
            path, f"DAT events are {td[1]} bytes, expected {DAT_EVENT_BYTES} (CD events)", f"byte offset {off + 1}"
        )
    geom = header_geometry(info)
    if sensor_size is None and geom is None:
        raise InputError(
            path, "DAT file whose header gives no sensor size (no '% Width'/'% Height' line)", remedy=SENSOR_SIZE
        )
    size = file_sensor_size(path, sensor_size, geom)

    def chunks(n, tally):
        check_dat(path, off + 2, size)
        yield from _expelliarmus_chunks(path, "dat", n)

    return Source(path, "dat", size, chunks)


def read_header(path, max_header: int = 1 << 20):
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
                if len(line) <= 4096:  # (the file ended before the line did)
                    raise InputError(path, "file ends inside its header", f"byte offset {offset + len(line)}")
                raise InputError(path, "header line is longer than 4 KiB", f"byte offset {offset}")
            try:
                text = line[1:].decode("ascii").strip()
            except UnicodeDecodeError:
                raise InputError(path, "header line is not ASCII text", f"byte offset {offset}") from None
            offset += len(line)
            if offset > max_header:
                raise InputError(path, "header is longer than 1 MiB", f"byte offset {offset}")
            if text == "end":
                break
            parts = text.split(None, 1)
            if parts:
                info[parts[0].lower()] = parts[1] if len(parts) > 1 else ""
    return info, offset


def header_geometry(info: dict):
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


def header_encoding(info: dict):
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
            yield pos, np.frombuffer(raw[:usable], dtype=dtype)  # (the whole words before a cut, then the cut)
            if usable != len(raw):
                raise InputError(
                    path,
                    f"file ends inside a {8 * word_bytes}-bit word ({len(raw) - usable} trailing bytes)",
                    f"byte offset {pos + usable}",
                )
            pos += len(raw)


EVT2_TYPES = (0x0, 0x1, 0x8, 0xA, 0xE, 0xF)


#: word type of an external trigger event, in EVT 2.0 and EVT 3.0 alike
EXT_TRIGGER = 0xA


def check_evt2(path, offset, sensor_size, tally=None):
    """Check every EVT2 word: known type, CD events inside the sensor; count
    the trigger events (which the decoder leaves out) in ``tally``."""
    w, h = sensor_size[0], sensor_size[1]
    for pos, words in _iter_words(path, offset, 4):
        typ = words >> 28
        bad = ~np.isin(typ, EVT2_TYPES)
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(
                path,
                f"unknown EVT2 word type 0x{int(typ[i]):X} (file is corrupt or not EVT2)",
                f"byte offset {pos + 4 * i}",
            )
        if tally is not None:
            tally.skip("trigger events", np.count_nonzero(typ == EXT_TRIGGER))
        cd = typ <= 1  # CD_OFF, CD_ON; other word types carry no coordinates
        x = np.where(cd, (words >> 11) & 0x7FF, 0)
        y = np.where(cd, words & 0x7FF, 0)
        _refuse_outside(path, x, y, w, h, pos, 4)


def _offset_of(error: InputError) -> int:
    """The byte offset this module's errors give in their place (``byte offset N``)."""
    return int(re.search(r"byte offset (\d+)", error.where or "").group(1))


def evt2_before(path, offset, end):
    """The CD events of the EVT2 words from byte ``offset`` up to byte ``end`` (where damage
    begins), decoded here: the C decoder reads a whole file. As it decodes them: a CD word's time
    is the last time-high word's 28 bits above its own 6 (0 before the first)."""
    high = 0
    for pos, words in _iter_words(path, offset, 4):
        words = words[: max(0, (end - pos) // 4)]
        typ = words >> 28
        is_high = typ == 8
        last = np.maximum.accumulate(np.where(is_high, np.arange(len(words)), -1))
        t_high = np.where(last >= 0, (words[np.maximum(last, 0)] & 0x0FFFFFFF).astype(np.int64), high)
        if is_high.any():
            high = int(words[np.flatnonzero(is_high)[-1]] & 0x0FFFFFFF)
        cd = typ <= 1
        w = words[cd]
        yield pack_events((w >> 11) & 0x7FF, w & 0x7FF, (t_high[cd] << 6) | ((w >> 22) & 0x3F), typ[cd])
        if pos + 4 * len(words) >= end:
            return


EVT3_KNOWN = np.zeros(16, dtype=bool)
EVT3_KNOWN[[0x0, 0x2, 0x3, 0x4, 0x5, 0x6, 0x7, 0x8, 0xA, 0xE, 0xF]] = True
_BITS12 = np.arange(12, dtype=np.uint16)


def iter_evt3(path, offset, read_bytes=READ_BYTES, tally=None):
    """Decode Prophesee EVT 3.0 (16-bit words) chunk by chunk.

    Timestamp = (TIME_HIGH << 12) | TIME_LOW on a 24-bit counter; a TIME_HIGH
    that goes backwards is a counter wrap and adds 2**24 us.  TIME_LOW words
    never carry into TIME_HIGH (counting TIME_LOW wrap-arounds on top of
    TIME_HIGH is the "4096 us drift" bug some decoders have).  Events before
    the first TIME_HIGH or the first EVT_ADDR_Y have no defined time/row and
    are dropped, as Prophesee's reference decoder does. External trigger
    events are counted in ``tally`` and left out.
    """
    # state carried across chunks
    th_raw = -1  # last TIME_HIGH payload (raw 12 bits), -1 = none yet
    th_abs = -1  # unwrapped TIME_HIGH counter (in units of 4096 us)
    tl = 0  # TIME_LOW payload valid after the last TIME_HIGH (0 if none)
    y_cur = -1
    bx_cur = -1  # base x for vectors
    pol_cur = 0
    for pos, w in _iter_words(path, offset, 2, read_bytes):
        n = len(w)
        typ = (w >> 12).astype(np.int8)
        pay = (w & 0xFFF).astype(np.int64)
        bad = ~EVT3_KNOWN[typ]
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(
                path,
                f"unknown EVT3 word type 0x{int(typ[i]):X} (file is corrupt or not EVT3)",
                f"byte offset {pos + 2 * i}",
            )
        idx = np.arange(n)
        if tally is not None:
            tally.skip("trigger events", np.count_nonzero(typ == EXT_TRIGGER))

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
        tl_at = np.where(last_tl > last_th, pay[np.maximum(last_tl, 0)], np.where(last_th >= 0, 0, tl))
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
            yield pack_events(ax, ay, at, ap)

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


def check_dat(path, offset, sensor_size):
    """Check that every DAT CD event lies inside the sensor."""
    w, h = sensor_size[0], sensor_size[1]
    for pos, words in _iter_words(path, offset, DAT_EVENT_BYTES):
        data = (words >> np.uint64(32)).astype(np.uint32)
        x = data & 0x3FFF
        y = (data >> 14) & 0x3FFF
        _refuse_outside(path, x, y, w, h, pos, DAT_EVENT_BYTES)


def _refuse_outside(path, x, y, w, h, pos, word_bytes):
    bad = (x >= w) | (y >= h)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            path,
            f"event at (x={int(x[i])}, y={int(y[i])}) lies outside the {w} x {h} sensor",
            f"byte offset {pos + word_bytes * i}",
        )


def _expelliarmus_chunks(path, encoding, n):
    from expelliarmus import Wizard  # (0.1 s to import: only for the files it decodes)

    wiz = Wizard(encoding=encoding, fpath=str(path), chunk_size=int(n))
    for arr in wiz.read_chunk():
        if arr is None:
            return
        yield arr
