"""One array of a Zarr (format 2) store, as :mod:`snn_fg.results.store` writes
and reads it: its chunks encoded and decoded (zstd, or zlib in stores written
until 29 Nov 2026; text as numcodecs' vlen-utf8), read chunk by chunk
(:class:`ZarrArray`) and grown along its first axis (:class:`GrowingArray`).
"""

from __future__ import annotations

import json
import struct
import threading
import zlib
from pathlib import Path

import numpy as np
import zstandard

from .atomic import write_bytes

#: how every chunk of a new array is compressed (:mod:`snn_fg.results.store`'s docstring says why)
COMPRESSOR = {"id": "zstd", "level": 1}
#: the dtype of a text array (vlen-utf8 chunks)
TEXT = np.dtype(object)


def json_bytes(value) -> bytes:
    return json.dumps(value, sort_keys=True, allow_nan=True).encode()


def write_json(path: Path, value) -> None:
    write_bytes(path, json_bytes(value))


_local = threading.local()  # (each thread's zstd compressors: one is not to be shared between threads)


def _zstd(level: int) -> zstandard.ZstdCompressor:
    """A zstd compressor at ``level``, made once per thread: a new one allocates its
    context at its first chunk (0.06 ms, a third of a map's encoding); the frames it
    writes are the same bytes either way."""
    made = _local.__dict__.setdefault("zstd", {})
    if level not in made:
        made[level] = zstandard.ZstdCompressor(level=level)
    return made[level]


def _encode(block: np.ndarray, compressor: dict) -> bytes:
    """One chunk's bytes: C-order values (text as numcodecs' vlen-utf8), compressed by ``compressor``."""
    if block.dtype == TEXT:
        items = [str(v).encode() for v in block.ravel()]
        raw = struct.pack("<I", len(items)) + b"".join(struct.pack("<I", len(b)) + b for b in items)
    else:
        raw = np.ascontiguousarray(block)
    if compressor["id"] == "zstd":
        return _zstd(compressor["level"]).compress(raw)
    return zlib.compress(raw, compressor["level"])


def _decode(data: bytes, dtype: np.dtype, shape, compressor: dict) -> np.ndarray:
    raw = zstandard.ZstdDecompressor().decompress(data) if compressor["id"] == "zstd" else zlib.decompress(data)
    if dtype != TEXT:
        return np.frombuffer(raw, dtype=dtype).reshape(shape).copy()
    (n,) = struct.unpack_from("<I", raw)
    items, at = [], 4
    for _ in range(n):
        (k,) = struct.unpack_from("<I", raw, at)
        items.append(raw[at + 4 : at + 4 + k].decode())
        at += 4 + k
    return np.array(items, dtype=object).reshape(shape)


def _blank(shape, dtype) -> np.ndarray:
    """A chunk never written: the fill value (0, or empty text)."""
    if dtype == TEXT or dtype.kind in "US":
        return np.full(shape, "", dtype=dtype)
    return np.zeros(shape, dtype)  # (the same zeros, from pages the system hands out zeroed)


class ZarrArray:
    """One array of a store, read chunk by chunk on indexing (``a[i]``,
    ``a[i:j]``; ``np.asarray(a)`` reads it all)."""

    def __init__(self, path: Path, length: int | None = None):
        self.path = Path(path)
        self.meta = meta = json.loads((self.path / ".zarray").read_text())
        self.dtype = np.dtype(meta["dtype"]) if meta["dtype"] != "|O" else TEXT
        self.chunks = tuple(meta["chunks"])
        shape = tuple(meta["shape"])
        # (a length from the attributes' windows_complete may run ahead of a shape stored by an older run,
        # which wrote the two apart)
        self.shape = shape if length is None else (length,) + shape[1:]

    ndim = property(lambda self: len(self.shape))

    def __len__(self):
        return self.shape[0]

    def chunk_path(self, k: int) -> Path:
        """The file of chunk ``k`` along the first axis."""
        return self.path / ".".join([str(k)] + ["0"] * (len(self.chunks) - 1))

    def chunk(self, k: int) -> np.ndarray:
        """Chunk ``k`` along the first axis (fill values where it was never written)."""
        try:
            return _decode(self.chunk_path(k).read_bytes(), self.dtype, self.chunks, self.meta["compressor"])
        except FileNotFoundError:
            return _blank(self.chunks, self.dtype)

    def rows(self, a: int, b: int) -> np.ndarray:
        """Rows ``a .. b - 1``."""
        c = self.chunks[0]
        parts = [self.chunk(k)[max(a - k * c, 0) : b - k * c] for k in range(a // c, -(-b // c))]
        return np.concatenate(parts) if parts else np.zeros((0,) + self.shape[1:], self.dtype)

    def __getitem__(self, index):
        if isinstance(index, (int, np.integer)):
            i = int(index) + (self.shape[0] if index < 0 else 0)
            if not 0 <= i < self.shape[0]:
                raise IndexError(f"index {index} out of range for {self.shape[0]} rows")
            return self.rows(i, i + 1)[0]
        if isinstance(index, slice) and index.step in (None, 1):
            a, b, _ = index.indices(self.shape[0])
            return self.rows(a, max(a, b))
        return np.asarray(self)[index]

    def __array__(self, dtype=None, copy=None):
        out = self.rows(0, self.shape[0])
        return out if dtype is None else out.astype(dtype)


class GrowingArray(ZarrArray):
    """An array of a store that grows along its first axis, keeping the
    chunk being filled in memory. A chunk is written once it is full: in
    place (a new file) while no reader may look at it, atomically once one
    may (its file holds rows of complete windows: written by :meth:`flush`,
    or found on disk when a store is continued); :meth:`flush` writes the
    chunk being filled (atomically), then :meth:`write_shape` the shape.
    Atomic writes go through :attr:`replace` (``replace(path, data)``; the
    store hands them to its writing thread, in order)."""

    #: how a file that readers may look at is written (atomically)
    replace = staticmethod(write_bytes)

    @classmethod
    def create(cls, path: Path, dtype, tail: tuple, chunk: int) -> GrowingArray:
        path.mkdir(parents=True)
        text = np.dtype(dtype) == TEXT
        meta = {
            "zarr_format": 2,
            "shape": [0, *tail],
            "chunks": [chunk, *tail],
            "order": "C",
            "dtype": "|O" if text else np.dtype(dtype).str,
            "fill_value": None if text else "" if np.dtype(dtype).kind in "US" else 0,
            "filters": [{"id": "vlen-utf8"}] if text else None,
            "dimension_separator": ".",
            "compressor": dict(COMPRESSOR),
        }
        write_json(path / ".zarray", meta)
        return cls(path)

    def __init__(self, path: Path, length: int | None = None):
        super().__init__(path, length)
        self.n = self.shape[0]
        self._last: tuple[int, np.ndarray] | None = None  # (number, values) of the chunk being filled
        self._unwritten = False  # whether that chunk holds rows not yet on disk
        self._seen = False  # whether a reader may look at that chunk's file (it holds complete windows)
        # (a full chunk's values, written: the next chunk fills them again, where a fresh chunk's pages,
        # faulted in and zeroed one by one as its rows were copied in, cost 0.08 ms a map's row)
        self._spare: np.ndarray | None = None
        self.shape_written = True

    def append(self, values) -> None:
        """Add rows (``values``: ``(k,) + tail``, cast to this array's dtype);
        the new shape is written by :meth:`write_shape`."""
        values = np.asarray(values, dtype=self.dtype).reshape((-1,) + self.chunks[1:])
        c, at = self.chunks[0], 0
        while at < len(values):
            k, r = divmod(self.n, c)
            take = min(c - r, len(values) - at)
            rows, at = values[at : at + take], at + take
            if r == 0 and take == c:  # (a whole new chunk: written from the rows themselves, never kept)
                self.flush()
                self._last = None
                self.n += take
                self.chunk_path(k).write_bytes(_encode(rows, self.meta["compressor"]))
                continue
            if self._last is None or self._last[0] != k:
                self.flush()
                # (rows before r are complete windows on disk, which readers may look at)
                self._last, self._seen = (k, self.chunk(k) if r else self._fresh()), r > 0
            self._last[1][r : r + take] = rows
            self._unwritten = True
            self.n += take
            if r + take == c:  # full: written now, and no longer kept
                if self._seen:
                    self.flush()
                else:
                    self.chunk_path(k).write_bytes(self._last_encoded())
                self._spare, self._last, self._unwritten = self._last[1], None, False
        self.shape = (self.n,) + self.shape[1:]
        self.shape_written = False

    def _fresh(self) -> np.ndarray:
        """A chunk to fill from its first row: the spare one if there is one (rows from
        the last chunk's past the rows appended are made fill values when it is written)."""
        if self._spare is None or self.dtype == TEXT:
            return _blank(self.chunks, self.dtype)
        block, self._spare = self._spare, None
        return block

    def _last_encoded(self) -> bytes:
        k, block = self._last
        rows = self.n - k * self.chunks[0]
        if rows < len(block):  # (a partly filled chunk: its rows past the array's length as never written)
            block[rows:] = _blank((1,), self.dtype)
        return _encode(block, self.meta["compressor"])

    def flush(self) -> None:
        """Write the chunk being filled, if it holds rows not yet on disk (atomically)."""
        if self._unwritten:
            self.replace(self.chunk_path(self._last[0]), self._last_encoded())
            self._unwritten, self._seen = False, True

    def write_shape(self) -> None:
        """Write the shape, if it changed since it was last written."""
        if not self.shape_written:
            self.resize(self.n)

    def resize(self, n: int) -> None:
        """Declare ``n`` rows (rows past ``n`` are written again as the array grows)."""
        self.meta["shape"][0] = self.n = n
        self.shape = (n,) + self.shape[1:]
        self.replace(self.path / ".zarray", json_bytes(self.meta))
        self.shape_written = True
