"""Writers for event arrays: ``.npy``, ``.npz``, Prophesee EVT2/EVT3 ``.raw`` and
Event Stream ``.es`` (DVS; :func:`encode_es_atis` makes ATIS streams).  Every file
is written atomically (complete or absent)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from snn_fg import validate
from snn_fg.errors import InputError
from snn_fg.events.core import as_events, check_in_sensor, check_monotonic, sensor_size_parameter
from snn_fg.results.atomic import atomic_path
from snn_fg.results.marks import MARK

#: Largest sensor side EVT2/EVT3 can address (11-bit coordinates).
PROPHESEE_MAX_SIZE = 2048
#: Stream type bytes of the Event Stream specification.
ES_DVS, ES_ATIS = 1, 2


def _prepare(owner, events, sensor_size, need_sorted=False, need_nonneg_t=False):
    ev = as_events(events)
    size = sensor_size_parameter(owner, sensor_size)
    check_in_sensor(ev, size)
    if need_sorted:
        check_monotonic(ev)
    if need_nonneg_t and len(ev) and ev["t"][0] < 0:
        raise InputError("<array>", "this format cannot store negative timestamps", "event 0")
    return ev, size


def _prophesee_start(events, sensor_size, version: int):
    """Checked events and the text header of an EVT ``version``.0 file."""
    ev, (w, h, _) = _prepare(f"encode_evt{version}", events, sensor_size, need_sorted=True, need_nonneg_t=True)
    if w > PROPHESEE_MAX_SIZE or h > PROPHESEE_MAX_SIZE:
        raise InputError("<array>", f"EVT{version} stores at most {PROPHESEE_MAX_SIZE} pixels a side")
    header = f"% evt {version}.0\n% format EVT{version};height={h};width={w}\n% geometry {w}x{h}\n% end\n"
    return ev, header.encode()


def encode_evt2(events, sensor_size) -> bytes:
    """EVT 2.0 bytes (header with geometry + 32-bit words); events sorted by time."""
    ev, hdr = _prophesee_start(events, sensor_size, 2)
    t = ev["t"].astype(np.int64)
    th = t >> 6
    if len(t) and th[-1] >= (1 << 28):
        raise InputError("<array>", "timestamps beyond 2**34 us do not fit EVT2's counter")
    new_th = np.ones(len(t), dtype=bool)
    new_th[1:] = th[1:] != th[:-1]
    cd = (
        ((ev["p"].astype(np.uint32) & 1) << 28)
        | ((t & 63).astype(np.uint32) << 22)
        | (ev["x"].astype(np.uint32) << 11)
        | ev["y"].astype(np.uint32)
    )
    thw = (np.uint32(0x8) << np.uint32(28)) | th.astype(np.uint32)
    slots = np.stack([thw, cd], axis=1)
    keep = np.stack([new_th, np.ones(len(t), dtype=bool)], axis=1)
    return hdr + slots[keep].astype("<u4").tobytes()


def encode_evt3(events, sensor_size) -> bytes:
    """EVT 3.0 bytes using single-event words (no vectors); events sorted by time."""
    ev, hdr = _prophesee_start(events, sensor_size, 3)
    t = ev["t"].astype(np.int64)
    hi = (t >> 12) & 0xFFF
    lo = t & 0xFFF
    blk = t >> 12
    n = len(t)
    new_hi = np.ones(n, dtype=bool)
    new_hi[1:] = blk[1:] != blk[:-1]
    new_lo = new_hi.copy()
    new_lo[1:] |= lo[1:] != lo[:-1]
    y = ev["y"].astype(np.int64)
    new_y = np.ones(n, dtype=bool)
    new_y[1:] = y[1:] != y[:-1]
    slots = np.stack(
        [0x8000 | hi, 0x6000 | lo, y, 0x2000 | (ev["p"].astype(np.int64) << 11) | ev["x"].astype(np.int64)], axis=1
    )
    keep = np.stack([new_hi, new_lo, new_y, np.ones(n, dtype=bool)], axis=1)
    # a block of 2**24 us skipped entirely would look like no wrap: add TIME_HIGH words in between
    if n > 1 and (np.diff(blk) >= 4096).any():
        raise InputError("<array>", "gaps of 2**24 us or more cannot be stored in EVT3")
    return hdr + slots[keep].astype("<u2").tobytes()


def encode_es(events, sensor_size) -> bytes:
    """Event Stream 2.0.0 DVS bytes; events sorted by time, first timestamp >= 0."""
    ev, size = _prepare("encode_es", events, sensor_size, need_sorted=True, need_nonneg_t=True)
    return _es_header(ES_DVS, size) + _es_body(ev["t"], ev["p"] & 1, ev["x"], ev["y"], flag_bits=1)


def encode_es_atis(events, sensor_size, exposures=None) -> bytes:
    """Event Stream 2.0.0 ATIS bytes holding change detections and exposure measurements.

    ``events`` are the change detections (polarity events, ``p`` = 1 for ON);
    ``exposures`` (optional) are threshold crossings, a structured array with
    fields x, y, t, p where ``p`` is the specification's ``is_second`` flag.
    Both must be sorted by time; at equal timestamps change detections are
    written first.  The file uses overflow bytes but no reset bytes.
    """
    ev, size = _prepare("encode_es_atis", events, sensor_size, need_sorted=True, need_nonneg_t=True)
    exp = _prepare(
        "encode_es_atis", exposures if exposures is not None else ev[:0], size, need_sorted=True, need_nonneg_t=True
    )[0]
    both = np.concatenate([ev, exp])
    is_tc = np.concatenate([np.zeros(len(ev), np.uint8), np.ones(len(exp), np.uint8)])
    order = np.argsort(both["t"], kind="stable")
    both, is_tc = both[order], is_tc[order]
    flags = ((both["p"].astype(np.uint8) & 1) << 1) | is_tc
    return _es_header(ES_ATIS, size) + _es_body(both["t"], flags, both["x"], both["y"], flag_bits=2)


def _es_header(stream_type: int, size) -> bytes:
    w, h = size[0], size[1]
    if w > 65535 or h > 65535:
        raise InputError("<array>", "Event Stream stores at most 65535 x 65535 pixels")
    return b"Event Stream" + bytes([2, 0, 0, stream_type]) + np.array([w, h], dtype="<u2").tobytes()


def _es_body(t, flags, x, y, flag_bits: int) -> bytes:
    """5-byte events, each preceded by the overflow bytes its time gap needs.

    Byte 0 holds the time since the previous event above ``flag_bits`` flag
    bits; a gap the time field cannot hold takes overflow bytes, each worth
    1 (DVS) or up to 3 (ATIS) units of ``2**(8 - flag_bits) - 1`` us
    (see :mod:`snn_fg.events.eventstream`).
    """
    unit = (256 >> flag_bits) - 1
    per_byte = (1 << flag_bits) - 1  # units one overflow byte can hold
    first_special = 256 - (1 << flag_bits)  # its value with 0 units: the reset byte
    t = np.asarray(t, dtype=np.int64)
    delta = np.diff(np.concatenate([[0], t]))
    units, rem = delta // unit, delta % unit
    full, part = units // per_byte, units % per_byte
    n_over = full + (part > 0)
    rec = np.empty((len(t), 5), dtype=np.uint8)
    rec[:, 0] = (rem << flag_bits) | flags
    x = np.asarray(x).astype(np.uint16)
    y = np.asarray(y).astype(np.uint16)
    rec[:, 1], rec[:, 2] = x & 0xFF, x >> 8
    rec[:, 3], rec[:, 4] = y & 0xFF, y >> 8
    out = np.full(int(n_over.sum()) + 5 * len(t), 0xFF, dtype=np.uint8)  # full overflow bytes
    starts = np.cumsum(n_over + 5) - 5  # start of each event's 5 bytes
    out[(starts[:, None] + np.arange(5)[None, :]).ravel()] = rec.ravel()
    out[starts[part > 0] - 1] = first_special + part[part > 0]  # the partly filled overflow byte
    return out.tobytes()


def save_events(path, events, sensor_size, encoding: str | None = None) -> Path:
    """Write ``events`` to ``path``; the format follows the extension.

    ``.npy``: the structured array (dtype :data:`EVENT_DTYPE`); ``.npz``:
    ``events`` plus ``sensor_size``; ``.raw``: Prophesee EVT2 (default) or
    ``encoding="evt3"``; ``.es``: Event Stream 2.0 DVS.  Binary formats need
    time-sorted events.  The write is atomic.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    ev, size = _prepare("save_events", events, sensor_size)
    if suffix == ".npy":
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.save(fh, ev, allow_pickle=False)
    elif suffix == ".npz":
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, events=ev, sensor_size=np.array(size, dtype=np.int64), written_by=np.array(MARK))
    elif suffix == ".raw":
        enc = encoding.lower() if isinstance(encoding, str) else (encoding or "evt2")
        validate.choice("save_events", "encoding", enc, ("evt2", "evt3"))
        data = encode_evt2(ev, size) if enc == "evt2" else encode_evt3(ev, size)
        with atomic_path(path) as tmp:
            tmp.write_bytes(data)
    elif suffix == ".es":
        data = encode_es(ev, size)
        with atomic_path(path) as tmp:
            tmp.write_bytes(data)
    else:
        raise InputError(path, f"cannot write events as '{suffix or '(no extension)'}' (use .npy, .npz, .raw or .es)")
    return path
