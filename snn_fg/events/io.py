"""Open event-camera recordings: one entry point for every supported format.

=================  ============================  =========================  =========
extension          format                        decoder                    streams
=================  ============================  =========================  =========
``.es``            Event Stream 2.x (DVS)        ours (``_decoders``)       yes
``.raw``           Prophesee EVT 2.0             expelliarmus (+ our check) yes
``.raw``           Prophesee EVT 3.0             ours (expelliarmus 1.1     yes
                                                 drifts by 4096 us steps)
``.dat``           Prophesee DAT (CD events)     expelliarmus (+ our check) yes
``.aedat4``        iniVation AEDAT 4             ``aedat`` package          yes (per packet)
``.bin``           N-MNIST / N-Caltech101        tonic ``read_mnist_file``  no
``.log``           iCub YARP ``data.log`` (AE)   ours                       yes
``.npy``           structured array x, y, t, p   numpy (memory-mapped)      yes
``.npz``           structured array x, y, t, p   numpy                      no
(array)            structured array x, y, t, p   --                         yes
=================  ============================  =========================  =========

The extension picks the format; the file's leading bytes must agree (an
Event Stream file renamed ``.raw`` is refused with a clear message instead of
being decoded into garbage).  All timestamps are microseconds (int64); the
first timestamp is kept as the file gives it (not shifted to zero).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import numpy as np

from snn_fg.errors import InputError, SnnFgError
from snn_fg.events import _decoders as dec
from snn_fg.events._core import (EVENT_DTYPE, Recording, as_events, check_in_sensor, check_sensor_size,
                                 empty_events)

SUFFIX_FORMAT = {
    ".es": "es", ".raw": "raw", ".dat": "dat", ".aedat4": "aedat4", ".bin": "nmnist",
    ".log": "yarp", ".npy": "npy", ".npz": "npz",
}
#: Formats whose reader yields bounded chunks (see the module table).
STREAMING_FORMATS = frozenset({"es", "evt2", "evt3", "dat", "aedat4", "yarp", "npy", "array"})
NMNIST_SIZE = (34, 34)
DEFAULT_CHUNK = 1_000_000

_MAGICS = [
    (b"Event Stream", "an Event Stream (.es) file"),
    (b"#!AER-DAT4", "an AEDAT 4 (.aedat4) file"),
    (b"#!AER-DAT", "an AEDAT 1-3 file (not supported)"),
    (b"\x93NUMPY", "a numpy .npy file"),
    (b"PK\x03\x04", "a zip/.npz file"),
    (b"PK\x05\x06", "a zip/.npz file"),
    (b"\x89PNG", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
]


def _sniff(head: bytes):
    for magic, name in _MAGICS:
        if head.startswith(magic):
            return name
    if head.startswith(b"%"):
        return "a Prophesee RAW/DAT file"
    if head and all(32 <= c < 127 or c in (9, 10, 13) for c in head[:4096]):
        first = head.split(b"\n", 1)[0]
        if dec._YARP_LINE.match(first):
            return "a YARP data.log text file"
        return "a text file"
    return None


_EXPECTED = {
    "es": ("an Event Stream (.es) file",),
    "aedat4": ("an AEDAT 4 (.aedat4) file",),
    "npy": ("a numpy .npy file",),
    "npz": ("a zip/.npz file",),
    "raw": ("a Prophesee RAW/DAT file", None),
    "dat": ("a Prophesee RAW/DAT file", None),
    "nmnist": (None,),
    "yarp": ("a YARP data.log text file",),
}


def detect_format(path) -> str:
    """Format name from the extension, checked against the file's first bytes."""
    path = Path(path)
    fmt = SUFFIX_FORMAT.get(path.suffix.lower())
    if fmt is None:
        raise InputError(path, f"unknown event file extension '{path.suffix or '(none)'}' "
                               f"(supported: {', '.join(sorted(SUFFIX_FORMAT))})")
    if not path.exists():
        raise InputError(path, "no such file")
    if not path.is_file():
        raise InputError(path, "not a regular file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError as exc:
        raise InputError(path, f"cannot read file ({exc.strerror or exc})")
    if not head:
        raise InputError(path, "file is empty", "byte offset 0")
    seen = _sniff(head)
    if seen not in _EXPECTED[fmt]:
        want = {"es": "an Event Stream file", "aedat4": "an AEDAT 4 file", "npy": "a .npy file",
                "npz": "an .npz archive", "raw": "a Prophesee RAW file", "dat": "a Prophesee DAT file",
                "nmnist": "an N-MNIST binary file", "yarp": "a YARP data.log text file"}[fmt]
        what = seen or "unrecognised binary data"
        raise InputError(path, f"extension says {want} but the content looks like {what}; "
                               "is the file mislabelled?", "byte offset 0")
    return fmt


# --------------------------------------------------------------------------
# per-format sources
# --------------------------------------------------------------------------
@dataclass
class _Source:
    path: Path | None
    format: str
    sensor_size: tuple
    _chunks: object = field(repr=False)  # callable(chunk_events) -> iterator of raw chunks

    @property
    def streams(self) -> bool:
        return self.format in STREAMING_FORMATS


def _open_es(path, sensor_size, chunk_events, **_):
    w, h, off = dec.read_es_header(path)
    size = check_sensor_size(sensor_size or (w, h), path)
    return _Source(path, "es", size, lambda n: dec.iter_es(path, off))


def _open_raw(path, sensor_size, chunk_events, encoding=None, **_):
    info, off = dec.read_raw_header(path)
    enc = (encoding or dec.raw_encoding(info) or "evt2").lower()
    if enc not in ("evt2", "evt3"):
        raise InputError(path, f"RAW encoding '{enc}' is not supported (only EVT 2.0 and EVT 3.0)")
    geom = dec.raw_geometry(info)
    if sensor_size is None and geom is None:
        raise InputError(path, f"{enc.upper()} file has no geometry in its header; pass the sensor size "
                               "explicitly (sensor_size=(W, H), CLI --sensor-size WxH; a Prophesee Gen3 "
                               "VGA sensor is 640x480)")
    size = check_sensor_size(sensor_size or geom, path)
    if enc == "evt3":
        return _Source(path, "evt3", size, lambda n: dec.iter_evt3(path, off))

    def chunks(n):
        dec.check_evt2(path, off, size)  # clear errors (with byte offsets) before the C decoder runs
        yield from _expelliarmus_chunks(path, "evt2", n)
    return _Source(path, "evt2", size, chunks)


def _expelliarmus_chunks(path, encoding, n):
    from expelliarmus import Wizard

    wiz = Wizard(encoding=encoding, fpath=str(path), chunk_size=int(n))
    for arr in wiz.read_chunk():
        if arr is None:
            return
        yield arr


def _open_dat(path, sensor_size, chunk_events, **_):
    info, off = dec.read_raw_header(path)
    with open(path, "rb") as fh:
        fh.seek(off)
        td = fh.read(2)
    if len(td) < 2:
        raise InputError(path, "DAT file ends before its event type/size bytes", f"byte offset {off + len(td)}")
    if td[1] != 8:
        raise InputError(path, f"DAT events are {td[1]} bytes, expected 8 (CD events)", f"byte offset {off + 1}")
    geom = dec.raw_geometry(info)
    if sensor_size is None and geom is None:
        raise InputError(path, "DAT file has no Width/Height in its header; pass sensor_size=(W, H)")
    size = check_sensor_size(sensor_size or geom, path)

    def chunks(n):
        w, h = size[0], size[1]
        for pos, words in dec._iter_words(path, off + 2, 8):
            data = (words >> np.uint64(32)).astype(np.uint32)
            x = data & 0x3FFF
            y = (data >> 14) & 0x3FFF
            bad = (x >= w) | (y >= h)
            if bad.any():
                i = int(np.argmax(bad))
                raise InputError(path, f"event at (x={int(x[i])}, y={int(y[i])}) lies outside the "
                                       f"{w} x {h} sensor", f"byte offset {pos + 8 * i}")
        yield from _expelliarmus_chunks(path, "dat", n)
    return _Source(path, "dat", size, chunks)


def _panic_safe(path, what, fn, *args):
    try:
        return fn(*args)
    except SnnFgError:
        raise
    except (KeyboardInterrupt, SystemExit, GeneratorExit, MemoryError):
        raise
    except BaseException as exc:  # the Rust decoder can raise a pyo3 PanicException (a BaseException)
        raise InputError(path, f"{what}: {exc}".strip().rstrip(":")) from None


def _check_aedat4_header(path):
    """Light check of the AEDAT4 file header before the Rust decoder sees it.

    The header is ``#!AER-DAT4.0\r\n``, a 4-byte size and a flatbuffer
    holding an XML description; corrupt non-ASCII bytes in that XML make
    the decoder panic, so they are reported here with their offset.
    """
    with open(path, "rb") as fh:
        head = fh.read(14 + 4)
        if len(head) < 18:
            raise InputError(path, "AEDAT4 header is truncated", f"byte offset {len(head)}")
        n = int.from_bytes(head[14:18], "little")
        body = fh.read(min(n, 1 << 24))
    if len(body) < n:
        raise InputError(path, f"AEDAT4 header announces {n} bytes but the file ends first",
                         f"byte offset {18 + len(body)}")
    start = body.find(b"<")
    end = body.rfind(b">")
    if start < 0 or end < start:
        raise InputError(path, "AEDAT4 header holds no XML description", "byte offset 18")
    xml = np.frombuffer(body[start:end + 1], dtype=np.uint8)
    bad = xml >= 128
    if bad.any():
        raise InputError(path, "AEDAT4 header description is corrupt (non-ASCII byte)",
                         f"byte offset {18 + start + int(np.argmax(bad))}")


def _open_aedat4(path, sensor_size, chunk_events, **_):
    import aedat

    _check_aedat4_header(path)
    decoder = _panic_safe(path, "AEDAT4 decoder rejected the file", aedat.Decoder, str(path))
    streams = _panic_safe(path, "AEDAT4 decoder rejected the file", decoder.id_to_stream)
    ids = [sid for sid, s in streams.items() if s.get("type") == "events"]
    if not ids:
        raise InputError(path, "AEDAT4 file has no event stream")
    target = min(ids)
    geom = (streams[target].get("width"), streams[target].get("height"))
    if sensor_size is None and None in geom:
        raise InputError(path, "AEDAT4 event stream has no width/height; pass sensor_size=(W, H)")
    size = check_sensor_size(sensor_size or geom, path)

    def chunks(n):
        d = _panic_safe(path, "AEDAT4 decoder rejected the file", aedat.Decoder, str(path))
        it = iter(d)
        k = 0
        while True:
            packet = _panic_safe(path, f"AEDAT4 packet {k} could not be decoded", next, it, None)
            if packet is None:
                return
            k += 1
            if packet.get("stream_id") != target or "events" not in packet:
                continue
            e = packet["events"]
            out = np.empty(len(e), dtype=EVENT_DTYPE)
            out["x"] = e["x"]
            out["y"] = e["y"]
            out["t"] = e["t"].astype(np.int64)
            out["p"] = e["on"]
            yield out
    return _Source(path, "aedat4", size, chunks)


def _open_nmnist(path, sensor_size, chunk_events, **_):
    from tonic.io import read_mnist_file

    nbytes = path.stat().st_size
    if nbytes % 5:
        raise InputError(path, f"N-MNIST files hold 5-byte events; {nbytes} bytes leaves "
                               f"{nbytes % 5} trailing", f"byte offset {nbytes - nbytes % 5}")
    size = check_sensor_size(sensor_size or NMNIST_SIZE, path)

    def chunks(n):
        raw = np.fromfile(path, dtype=np.uint8).reshape(-1, 5)
        td = raw[:, 1] != 240  # y == 240 marks timer-overflow records
        bad = td & ((raw[:, 0] >= size[0]) | (raw[:, 1] >= size[1]))
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError(path, f"event at (x={int(raw[i, 0])}, y={int(raw[i, 1])}) lies outside the "
                                   f"{size[0]} x {size[1]} sensor", f"byte offset {5 * i}")
        yield read_mnist_file(str(path), dtype=EVENT_DTYPE)
    return _Source(path, "nmnist", size, chunks)


def _open_yarp(path, sensor_size, chunk_events, codec="auto", channel=0, timer_bits=dec.YARP_TIMER_BITS, **_):
    size = check_sensor_size(sensor_size or dec.YARP_SENSOR, path)
    return _Source(path, "yarp", size,
                   lambda n: dec.iter_yarp(path, codec=codec, channel=channel, timer_bits=timer_bits))


def _load_npy(path, mmap=True):
    try:
        arr = np.load(path, mmap_mode="r" if mmap else None, allow_pickle=False)
    except Exception as exc:  # numpy's header parser can raise ValueError, SyntaxError, TokenError...
        raise InputError(path, f"not a readable .npy array ({type(exc).__name__}: {exc})") from None
    return arr


def _infer_size(path, arrays):
    """Sensor size = (max x + 1, max y + 1) over chunks; used when none is given."""
    mx = my = -1
    for a in arrays:
        if len(a):
            mx = max(mx, int(a["x"].max()))
            my = max(my, int(a["y"].max()))
    if mx < 0 or my < 0:
        raise InputError(path, "cannot infer the sensor size (no events, or negative coordinates); "
                               "pass sensor_size=(W, H)")
    return check_sensor_size((mx + 1, my + 1), path)


def _open_npy(path, sensor_size, chunk_events, **_):
    arr = _load_npy(path)
    if arr.dtype.names is None or arr.ndim != 1:
        raise InputError(path, f".npy must hold a 1-D structured array with fields x, y, t, p "
                               f"(found dtype {arr.dtype}, shape {arr.shape})")
    as_events(arr[:0], path)  # field check

    total, dtype, base = len(arr), arr.dtype, int(getattr(arr, "offset", 0))
    if not isinstance(arr, np.memmap) or not (arr.flags.c_contiguous or arr.flags.f_contiguous):
        def slices(n):
            for i in range(0, total, n):
                yield as_events(np.asarray(arr[i:i + n]), path, offset=i)
    else:
        def slices(n):
            # one short-lived mapping per chunk, copied and unmapped, so resident
            # memory stays at one chunk however large the file is
            for i in range(0, total, n):
                m = min(n, total - i)
                view = np.memmap(path, dtype=dtype, mode="r", offset=base + i * dtype.itemsize, shape=(m,))
                chunk = np.array(view)
                del view
                yield as_events(chunk, path, offset=i)
    size = check_sensor_size(sensor_size, path) if sensor_size is not None else \
        _infer_size(path, slices(chunk_events))
    return _Source(path, "npy", size, slices)


def _open_npz(path, sensor_size, chunk_events, **_):
    try:
        with np.load(path, allow_pickle=False) as z:
            keys = list(z.files)
            if "events" in keys:
                arr = z["events"]
            elif all(k in keys for k in "xytp"):
                cols = {k: z[k] for k in "xytp"}
                n = len(cols["t"])
                if any(c.ndim != 1 or len(c) != n for c in cols.values()):
                    raise InputError(path, "arrays x, y, t, p in the .npz must be 1-D and of equal length")
                arr = np.empty(n, dtype=[(k, cols[k].dtype) for k in "xytp"])
                for k in "xytp":
                    arr[k] = cols[k]
            else:
                structured = [k for k in keys if z[k].dtype.names]
                if len(structured) != 1:
                    raise InputError(path, f".npz needs an 'events' structured array or x, y, t, p arrays "
                                           f"(found keys {', '.join(keys) or 'none'})")
                arr = z[structured[0]]
            file_size = tuple(int(v) for v in z["sensor_size"]) if "sensor_size" in keys else None
    except SnnFgError:
        raise
    except Exception as exc:  # zip, zlib and numpy header errors of every kind
        raise InputError(path, f"not a readable .npz archive ({type(exc).__name__}: {exc})") from None
    ev = as_events(arr, path)
    size = sensor_size if sensor_size is not None else file_size
    size = check_sensor_size(size, path) if size is not None else _infer_size(path, [ev])
    return _Source(path, "npz", size, lambda n: iter([ev]))


_OPENERS = {"es": _open_es, "raw": _open_raw, "dat": _open_dat, "aedat4": _open_aedat4,
            "nmnist": _open_nmnist, "yarp": _open_yarp, "npy": _open_npy, "npz": _open_npz}


def _open_source(source, sensor_size=None, chunk_events=DEFAULT_CHUNK, **options) -> _Source:
    if isinstance(source, Recording):
        size = check_sensor_size(sensor_size or source.sensor_size)
        ev = source.events
        return _Source(source.path, source.format, size,
                       lambda n: (ev[i:i + n] for i in range(0, max(len(ev), 1), n)))
    if isinstance(source, RecordingStream):
        return source._source
    if isinstance(source, np.ndarray):
        ev = as_events(source, "<array>")
        size = check_sensor_size(sensor_size, "<array>") if sensor_size is not None else \
            _infer_size("<array>", [ev])
        return _Source(None, "array", size, lambda n: (ev[i:i + n] for i in range(0, max(len(ev), 1), n)))
    if not isinstance(source, (str, Path)):
        raise InputError(repr(source)[:60], "expected a file path, a Recording or a structured event array")
    path = Path(source)
    fmt = detect_format(path)
    try:
        return _OPENERS[fmt](path, sensor_size, chunk_events, **options)
    except TypeError as exc:
        if "unexpected keyword" in str(exc):
            raise InputError(path, f"option not understood for {fmt} files: {exc}") from None
        raise


class RecordingStream:
    """A recording read chunk by chunk: iterate it to get event arrays.

    Header information (``format``, ``sensor_size``, ``path``) is available
    before reading; each iteration re-reads the file from the start.  Chunks
    hold at most ``chunk_events`` events (fewer at the end), are validated
    (coordinates inside the sensor; errors name the global event index) and
    have dtype :data:`EVENT_DTYPE`.  ``streams`` tells whether the underlying
    reader works with bounded memory (see the module table).
    """

    def __init__(self, source, chunk_events=DEFAULT_CHUNK, sensor_size=None, progress=False, **options):
        if int(chunk_events) < 1:
            raise InputError("<options>", f"chunk_events must be at least 1, got {chunk_events}")
        self.chunk_events = int(chunk_events)
        self._source = _open_source(source, sensor_size, self.chunk_events, **options)
        self.progress = progress

    path = property(lambda self: self._source.path)
    format = property(lambda self: self._source.format)
    sensor_size = property(lambda self: self._source.sensor_size)
    streams = property(lambda self: self._source.streams)

    def __iter__(self) -> Iterator[np.ndarray]:
        src = self._source
        name = src.path if src.path is not None else "<array>"
        n = self.chunk_events
        done = 0
        bar = None
        if self.progress:
            from tqdm import tqdm
            bar = tqdm(unit="ev", unit_scale=True, desc=f"reading {Path(str(name)).name}", leave=False,
                       disable=None)
        pending = []
        pending_n = 0
        try:
            for raw in src._chunks(n):
                ev = as_events(raw, name, offset=done + pending_n)
                check_in_sensor(ev, src.sensor_size, name, offset=done + pending_n)
                if not len(ev):
                    continue
                pending.append(ev)
                pending_n += len(ev)
                while pending_n >= n:
                    buf = np.concatenate(pending) if len(pending) > 1 else pending[0]
                    out, rest = buf[:n], buf[n:]
                    pending, pending_n = ([rest] if len(rest) else []), len(rest)
                    done += len(out)
                    if bar is not None:
                        bar.update(len(out))
                    yield out
            if pending_n:
                out = np.concatenate(pending) if len(pending) > 1 else pending[0]
                done += len(out)
                if bar is not None:
                    bar.update(len(out))
                yield out
        finally:
            if bar is not None:
                bar.close()


def iter_recording(source, chunk_events: int = DEFAULT_CHUNK, sensor_size=None, progress: bool = False,
                   **options) -> RecordingStream:
    """Stream a recording in chunks of at most ``chunk_events`` events.

    ``source`` is a path, a :class:`Recording` or a structured array.  The
    returned :class:`RecordingStream` is iterable and knows ``format`` and
    ``sensor_size`` up front.  Memory stays bounded for the formats in
    :data:`STREAMING_FORMATS`; ``.npz`` and N-MNIST ``.bin`` are read whole.
    Format options: ``encoding`` ("evt2"/"evt3", for headerless ``.raw``);
    YARP ``codec`` ("auto", "24", "20"), ``channel`` (0, 1 or None) and
    ``timer_bits`` (30).
    """
    return RecordingStream(source, chunk_events=chunk_events, sensor_size=sensor_size, progress=progress,
                           **options)


def open_recording(path, sensor_size=None, progress: bool = False, **options) -> Recording:
    """Read a whole recording (any supported format, or a structured array).

    ``sensor_size`` ``(W, H)`` overrides the file's geometry and is required
    for headerless EVT2/EVT3 files; for arrays and ``.npy`` without it the
    size is inferred as (max x + 1, max y + 1).  Bad input raises
    :class:`~snn_fg.errors.InputError` naming file, problem and place.
    """
    stream = RecordingStream(path, chunk_events=DEFAULT_CHUNK, sensor_size=sensor_size, progress=progress,
                             **options)
    parts = list(stream)
    events = np.concatenate(parts) if len(parts) > 1 else (parts[0] if parts else empty_events())
    return Recording(events=events, sensor_size=stream.sensor_size, format=stream.format, path=stream.path)
