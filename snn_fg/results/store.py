"""A recording's maps on disk as its windows complete: a Zarr group (format 2).

``DIR/maps.zarr`` is a folder that any Zarr reader opens (zarr-python,
xarray, zarr.js...), also while a run is still writing it. It holds one
array per kind of per-window result, all growing along their first axis:

- arrays of two or more dimensions per window (``fg_x``, ``fg_y``,
  ``grouping``, ``event_frame``) are stacked, ``(n_windows, H, W)``, one
  chunk per window;
- per-window scalars (``t_start_us``, ``pixel_share``) are ``(n_windows,)``;
- per-window arrays of one dimension, whose length may vary (the spike
  counts of the cells that fired, :class:`~snn_fg.models.spiking.SpikingRecord`),
  are stored *ragged*: ``key`` concatenates the windows' arrays and
  ``key_offsets`` (``n_windows + 1``) says where each window's part starts
  (:func:`~snn_fg.results.maps.window_part`);
- ``window_params`` holds each window's parameters that differ from the
  run's, as JSON text.

The group's attributes hold the run's ``params`` and ``snn_fg``:
``windows_complete`` (the windows a reader may use: every array holds at
least that many) and ``complete`` (the run has ended). Chunks are written
before the attributes, so a reader never sees a window that is not whole:
a chunk that holds complete windows is replaced atomically, and a chunk
that holds only the window being written (a map's, a new one) is written
in place, as no reader looks at it before the attributes say the window is
complete. The arrays' shapes (``.zarray``) are written again at most once a
second while the run writes (each is a file to replace, and a window has
about ten arrays): a Zarr reader opening the store during a run sees the
windows up to a second late, snn-fg's reader (from ``windows_complete``)
at once; at the end of the run they are exact. Chunks are zlib-compressed
(a codec every Zarr reader has); a map that is mostly zero compresses well.

Nothing here keeps more than one chunk per array in memory.
"""

from __future__ import annotations

import json
import struct
import time
import zlib
from pathlib import Path

import numpy as np

from .. import validate as check
from ..errors import InputError
from .atomic import write_bytes

#: the store's name in a run's output folder
STORE_NAME = "maps.zarr"
#: ``attrs["snn_fg"]["format"]``: what wrote the group (a reader refuses another)
FORMAT = "snn-fg maps 1"
#: zlib level of every chunk: 1 compresses the sparse maps nearly as well as 9, several times faster
ZLIB_LEVEL = 1
#: elements per chunk of a growing 1-D array (scalars per window, ragged spike counts)
FLAT_CHUNK = 1 << 14
#: windows per chunk of a per-window scalar (the chunk being filled is written again every window)
SCALAR_CHUNK = 1024
#: windows per chunk of ``window_params`` (each window's text written once, not again with the next)
PARAMS_CHUNK = 1
#: seconds between writes of the arrays' shapes while a run writes (module docstring)
SHAPES_EVERY_S = 1.0
_TEXT = np.dtype(object)


def _write_json(path: Path, value) -> None:
    write_bytes(path, json.dumps(value, sort_keys=True, allow_nan=True).encode())


def _encode(block: np.ndarray) -> bytes:
    """One chunk's bytes: C-order values (text as numcodecs' vlen-utf8), zlib-compressed."""
    if block.dtype == _TEXT:
        items = [str(v).encode() for v in block.ravel()]
        raw = struct.pack("<I", len(items)) + b"".join(struct.pack("<I", len(b)) + b for b in items)
    else:
        raw = np.ascontiguousarray(block).tobytes()
    return zlib.compress(raw, ZLIB_LEVEL)


def _decode(data: bytes, dtype: np.dtype, shape) -> np.ndarray:
    raw = zlib.decompress(data)
    if dtype != _TEXT:
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
    return np.full(shape, "" if dtype == _TEXT or dtype.kind in "US" else 0, dtype=dtype)


class ZarrArray:
    """One array of a store, read chunk by chunk on indexing (``a[i]``,
    ``a[i:j]``; ``np.asarray(a)`` reads it all)."""

    def __init__(self, path: Path, length: int | None = None):
        self.path = Path(path)
        self.meta = meta = json.loads((self.path / ".zarray").read_text())
        self.dtype = np.dtype(meta["dtype"]) if meta["dtype"] != "|O" else _TEXT
        self.chunks = tuple(meta["chunks"])
        shape = tuple(meta["shape"])
        # (a length from the attributes' windows_complete may run ahead of the
        # stored shape, written at most once a second while a run writes)
        self.shape = shape if length is None else (length,) + shape[1:]

    ndim = property(lambda self: len(self.shape))

    def __len__(self):
        return self.shape[0]

    def chunk(self, k: int) -> np.ndarray:
        """Chunk ``k`` along the first axis (fill values where it was never written)."""
        key = ".".join([str(k)] + ["0"] * (len(self.shape) - 1))
        try:
            return _decode((self.path / key).read_bytes(), self.dtype, self.chunks)
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
    """An array of a store that grows along its first axis: :meth:`append`
    writes the chunks it fills (the last one again as it fills), then the
    new shape. It keeps the last, partly filled chunk in memory."""

    @classmethod
    def create(cls, path: Path, dtype, tail: tuple, chunk: int) -> GrowingArray:
        path.mkdir(parents=True)
        text = np.dtype(dtype) == _TEXT
        meta = {
            "zarr_format": 2,
            "shape": [0, *tail],
            "chunks": [chunk, *tail],
            "order": "C",
            "dtype": "|O" if text else np.dtype(dtype).str,
            "fill_value": None if text else "" if np.dtype(dtype).kind in "US" else 0,
            "filters": [{"id": "vlen-utf8"}] if text else None,
            "dimension_separator": ".",
            "compressor": {"id": "zlib", "level": ZLIB_LEVEL},
        }
        _write_json(path / ".zarray", meta)
        return cls(path)

    def __init__(self, path: Path, length: int | None = None):
        super().__init__(path, length)
        self.n = self.shape[0]
        self._last: tuple[int, np.ndarray] | None = None  # (number, values) of the chunk being filled
        self.shape_written = True

    def append(self, values) -> None:
        """Add rows (``values``: ``(k,) + tail``, cast to this array's dtype);
        the new shape is written by :meth:`write_shape`."""
        values = np.asarray(values, dtype=self.dtype).reshape((-1,) + self.chunks[1:])
        c, at = self.chunks[0], 0
        while at < len(values):
            k, r = divmod(self.n, c)
            if self._last is None or self._last[0] != k:
                self._last = (k, self.chunk(k) if r else _blank(self.chunks, self.dtype))
            take = min(c - r, len(values) - at)
            self._last[1][r : r + take] = values[at : at + take]
            key = ".".join([str(k)] + ["0"] * (len(self.chunks) - 1))
            if r:  # (holds rows of complete windows)
                write_bytes(self.path / key, _encode(self._last[1]))
            else:  # (holds none: no reader looks at it yet)
                (self.path / key).write_bytes(_encode(self._last[1]))
            self.n, at = self.n + take, at + take
        self.shape = (self.n,) + self.shape[1:]
        self.shape_written = False

    def write_shape(self) -> None:
        """Write the shape, if it changed since it was last written."""
        if not self.shape_written:
            self.resize(self.n)

    def resize(self, n: int) -> None:
        """Declare ``n`` rows (rows past ``n`` are written again as the array grows)."""
        self.meta["shape"][0] = self.n = n
        self.shape = (n,) + self.shape[1:]
        _write_json(self.path / ".zarray", self.meta)
        self.shape_written = True


def read_attrs(path) -> dict:
    """A store's attributes; one clear line when ``path`` is not a store of ours."""
    path = Path(path)
    try:
        attrs = json.loads((path / ".zattrs").read_text())
    except FileNotFoundError:
        raise InputError(path, f"not a maps store: no .zattrs (a run's {STORE_NAME} folder is one)") from None
    except ValueError as exc:
        raise InputError(path / ".zattrs", f"not valid JSON ({exc})") from None
    if attrs.get("snn_fg", {}).get("format") != FORMAT:
        raise InputError(path, f"not a maps store written by snn-fg (expected format {FORMAT!r})")
    return attrs


def _same_run(path, run_key: dict) -> dict:
    """The attributes of the store at ``path``; refused when it was made with another ``run_key``."""
    attrs = read_attrs(path)
    # (an option not given is left out on both sides: a run made before an option was added continues)
    stored = {k: v for k, v in (attrs["snn_fg"].get("run_key") or {}).items() if v is not None}
    given = {k: v for k, v in json.loads(json.dumps(run_key)).items() if v is not None}
    if given != stored:
        differ = sorted(k for k in set(stored) | set(given) if stored.get(k) != given.get(k))
        raise InputError(
            path,
            f"--resume needs the same input and options as the run being continued; these differ: {', '.join(differ)}",
        )
    return attrs


def finished_run(path, run_key: dict) -> int | None:
    """The windows of the finished run in the store at ``path``, made with
    ``run_key`` (None: no store there, or its run has not ended; refused
    when made with another ``run_key``); reads only its attributes."""
    if not Path(path).is_dir():
        return None
    attrs = _same_run(path, run_key)["snn_fg"]
    return int(attrs["windows_complete"]) if attrs.get("complete") else None


def windows_complete(folder) -> int:
    """How many windows the store in a run's output ``folder`` holds whole (0: none, or no store)."""
    try:
        return int(read_attrs(Path(folder) / STORE_NAME)["snn_fg"]["windows_complete"])
    except (InputError, OSError, KeyError):
        return 0


def _lengths(path: Path, n: int) -> dict:
    """Each array of the store at ``path`` and its length at ``n`` windows
    (a ragged array's from its offsets)."""
    names = sorted(p.name for p in path.iterdir() if (p / ".zarray").is_file())
    out = {name: n + 1 for name in names if name.endswith("_offsets")}
    for name in names:
        if name not in out:
            out[name] = int(ZarrArray(path / f"{name}_offsets", n + 1)[n]) if f"{name}_offsets" in out else n
    return out


def store_arrays(path, n: int) -> dict:
    """Every array of the store at ``path`` as a lazily read :class:`ZarrArray`,
    the per-window ones cut to ``n`` windows (the ragged ones by their offsets)."""
    path = Path(path)
    return {name: ZarrArray(path / name, length) for name, length in sorted(_lengths(path, n).items())}


class MapsStore:
    """Writes a recording's maps into a store, window by window.

    :meth:`create` starts a new store, :meth:`reopen` continues one from its
    last complete window (parts of a window that was being written when the
    run stopped are written again). :meth:`append` adds one window's
    :class:`~snn_fg.results.maps.Maps` and any further per-window arrays;
    :meth:`finish` writes the run's final ``params`` and marks it complete.
    ``run_key`` is what must match for a run to continue this one (the
    input, the model and every option that changes the maps).
    """

    def __init__(self, path, attrs: dict):
        self.path = Path(path)
        self.attrs = attrs
        self.n = int(attrs["snn_fg"]["windows_complete"])
        self.arrays: dict[str, GrowingArray] = {}
        for name, length in _lengths(self.path, self.n).items():  # back to the last complete window
            self.arrays[name] = GrowingArray(self.path / name)
            self.arrays[name].resize(length)
        self.shapes_at = time.monotonic()  # when the arrays' shapes were last written

    @classmethod
    def create(cls, path, run_key: dict) -> MapsStore:
        path = Path(path)
        path.mkdir(parents=True)
        _write_json(path / ".zgroup", {"zarr_format": 2})
        _write_json(
            path / ".zattrs",
            {"snn_fg": {"format": FORMAT, "windows_complete": 0, "complete": False, "run_key": run_key}, "params": {}},
        )
        return cls(path, read_attrs(path))

    @classmethod
    def reopen(cls, path, run_key: dict) -> MapsStore:
        """The store at ``path`` to continue; refused when it was made with another ``run_key``."""
        attrs = _same_run(path, run_key)
        for stray in Path(path).rglob("*.part"):  # (atomic writes cut short by a kill)
            stray.unlink()
        return cls(path, attrs)

    @property
    def complete(self) -> bool:
        return bool(self.attrs["snn_fg"]["complete"])

    def append(self, maps, **more) -> None:
        """Add one window: ``maps`` (its arrays, ``extra`` and ``params``) and ``more`` arrays."""
        if self.n == 0:
            self.attrs["params"] = dict(maps.params)
        base = self.attrs["params"]
        differ = {k: v for k, v in maps.params.items() if base.get(k) != v}
        self._array("window_params", _TEXT, (), PARAMS_CHUNK).append([json.dumps(differ, sort_keys=True)])
        arrays = {"fg_x": maps.fg_x, "fg_y": maps.fg_y, "grouping": maps.grouping, **maps.extra, **more}
        for key, v in arrays.items():
            v = np.asarray(v)
            if v.ndim == 1:  # ragged: its length may vary from window to window
                self._array(f"{key}_offsets", np.int64, (), FLAT_CHUNK)
                self._array(key, v.dtype, (), FLAT_CHUNK).append(v)
            else:
                a = self._array(key, v.dtype, v.shape, 1 if v.ndim else SCALAR_CHUNK)
                if a.chunks[1:] != v.shape:
                    check.fail(
                        "MapsStore",
                        None,
                        None,
                        f"array {key!r} changes its shape between windows "
                        f"({a.chunks[1:]} before, {v.shape} in window {self.n}); cannot store it",
                    )
                a.append(v[None])
        for key, a in self.arrays.items():
            if key.endswith("_offsets"):
                a.append([self.arrays[key.removesuffix("_offsets")].n])
            elif a.n == self.n and f"{key}_offsets" not in self.arrays:
                a.append(np.zeros((1,) + a.chunks[1:], a.dtype))  # absent from this window: zeros
        self.n += 1
        if self.n == 1 or time.monotonic() - self.shapes_at >= SHAPES_EVERY_S:
            self._write_shapes()
        self._status(windows_complete=self.n)

    def _write_shapes(self) -> None:
        for a in self.arrays.values():
            a.write_shape()
        self.shapes_at = time.monotonic()

    def _array(self, key: str, dtype, tail: tuple, chunk: int) -> GrowingArray:
        """The array ``key``, made when first met (the windows before it: fill values, or no part)."""
        if key not in self.arrays:
            a = self.arrays[key] = GrowingArray.create(self.path / key, dtype, tuple(tail), chunk)
            if key.endswith("_offsets"):
                a.append(np.zeros(self.n + 1, np.int64))
            else:
                a.resize(self.n)
        return self.arrays[key]

    def finish(self, params: dict) -> None:
        """The run's final parameters, and the store marked complete."""
        self.attrs["params"] = params
        self._write_shapes()
        self._status(complete=True)

    def _status(self, **changes) -> None:
        self.attrs["snn_fg"].update(changes)
        _write_json(self.path / ".zattrs", self.attrs)


def read_maps(path, lazy: bool = False) -> tuple:
    """The fields of the :class:`~snn_fg.results.maps.Maps` of a store (``fg_x``,
    ``fg_y``, ``grouping``, ``params``, the other arrays): its complete windows (all
    of them once the run has ended). ``lazy``: arrays are
    :class:`ZarrArray` read on indexing (a long recording's figures draw
    a few windows), else numpy arrays. ``params["windows"]`` lists each
    window's own parameters when any window has some, as in ``maps.npz``."""
    path = Path(path)
    attrs = read_attrs(path)
    n = int(attrs["snn_fg"]["windows_complete"])
    if n == 0:
        raise InputError(path, "holds no complete window yet")
    arrays = store_arrays(path, n)
    own = [json.loads(t) for t in np.asarray(arrays.pop("window_params"))]
    params = dict(attrs["params"])
    if any(own):
        params["windows"] = own
    if not lazy:
        arrays = {k: np.asarray(v) for k, v in arrays.items()}
    maps = [arrays.pop(k) for k in ("fg_x", "fg_y", "grouping")]
    return (*maps, params, arrays)
