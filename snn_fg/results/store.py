"""A recording's maps on disk as its windows complete: a Zarr group (format 2).

``DIR/maps.zarr`` is a folder that any Zarr reader opens (zarr-python,
xarray, zarr.js...), also while a run is still writing it. It holds one
array per kind of per-window result, all growing along their first axis:

- arrays of two or more dimensions per window (``fg_x``, ``fg_y``,
  ``grouping``, ``event_frame``) are stacked, ``(n_windows, H, W)``,
  :data:`WINDOW_CHUNK` windows a chunk (stores written until 30 Nov 2026:
  one; both read and continue);
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
before the attributes, so a reader never sees a window that is not whole.
A chunk that holds only the window being written (every map's, one chunk
a window; a scalar's first) is written at once, in place: no reader looks
at it before the attributes say the window is complete. A chunk that holds
complete windows as well (a per-window scalar's, 1024 windows a chunk) is
replaced atomically, and replacing a file is the costly write (ext4 makes
the new file's data reach the disk first: about 3 ms, against 0.3 ms for a
new file), so those chunks, the arrays' shapes (``.zarray``) and
``windows_complete`` are written together at the first window, then at most
once a second while the run writes (:meth:`MapsStore.flush`), and at its end
or when it stops: every reader sees the windows up to a second late, and a
run killed outright recomputes at most a second of windows on ``--resume``
(two, if it was killed while its writing thread was a flush behind).
Those replacements are made on a thread of their own (:class:`Writer`), in
the order they were asked for: the run does not wait for the disk once a
second (a flush replaced 18 files of a live run's store, 70 ms in which
the network stood still).
Chunks are zstd-compressed (level 1: the sparse maps in about a quarter of
zlib's time and a tenth smaller; zstd is a codec of zarr-python's numcodecs
and of TensorStore); a store written with zlib (until 29 Nov 2026) reads
and resumes in zlib.

Nothing here keeps more than one chunk per array in memory (and the buffer of the
last full one, which the next fills again).
"""

from __future__ import annotations

import json
import queue
import threading
import time
from pathlib import Path

import numpy as np

from .. import validate as check
from ..errors import InputError
from .atomic import write_bytes
from .zarr_array import TEXT, GrowingArray, ZarrArray, json_bytes, write_json

#: the store's name in a run's output folder
STORE_NAME = "maps.zarr"
#: ``attrs["snn_fg"]["format"]``: what wrote the group (a reader refuses another)
FORMAT = "snn-fg maps 1"
#: elements per chunk of a growing 1-D array (scalars per window, ragged spike counts)
FLAT_CHUNK = 1 << 14
#: windows per chunk of a per-window scalar (the chunk being filled is written again at every flush)
SCALAR_CHUNK = 1024
#: windows per chunk of a per-window map and of ``window_params``: a new file costs about 0.3 ms
#: (ext4), and a 10 ms hop wrote six (each map's and the parameters' text), a chunk of one
#: window each; eight windows a chunk write one of each in eight hops, the same bytes compressed
#: (a full chunk is written once; the one being filled is written again only at a flush)
WINDOW_CHUNK = 8
#: seconds between flushes while a run writes (module docstring)
FLUSH_EVERY_S = 1.0
#: writes that may wait for the store's writing thread (:class:`Writer`): a flush is about 20
WRITES_AHEAD = 64


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


def _said(value) -> str:
    """A run key's value in a line (cut short past 40 characters), or ``not given``."""
    text = "not given" if value is None else json.dumps(value) if isinstance(value, (dict, list)) else str(value)
    return text if len(text) <= 40 else text[:37] + "..."


def key_differences(stored: dict, run_key: dict, may_differ=()) -> str:
    """How the run key ``run_key`` differs from the ``stored`` one of an earlier run, in words (``"window_ms
    (60.0 before, 50.0 now)"``; empty: it does not): the keys ``may_differ`` left out, and an option not given
    left out on both sides (a run made before an option was added continues)."""
    stored = {k: v for k, v in stored.items() if v is not None and k not in may_differ}
    given = {k: v for k, v in json.loads(json.dumps(run_key)).items() if v is not None and k not in may_differ}
    differ = sorted(k for k in set(stored) | set(given) if stored.get(k) != given.get(k))
    return ", ".join(f"{k} ({_said(stored.get(k))} before, {_said(given.get(k))} now)" for k in differ)


def _same_run(path, run_key: dict, may_differ=()) -> dict:
    """The attributes of the store at ``path``; refused when made with another ``run_key`` (``may_differ`` left out)."""
    attrs = read_attrs(path)
    if differ := key_differences(attrs["snn_fg"].get("run_key") or {}, run_key, may_differ):
        raise InputError(
            path, f"--resume needs the same input and options as the run being continued; these differ: {differ}"
        )
    return attrs


def stored_run(path, run_key: dict, may_differ=()) -> dict | None:
    """The attributes of the store at ``path``, made with ``run_key`` (``may_differ``: see :meth:`MapsStore.reopen`;
    None: no store there; refused when made with another ``run_key``); reads only its attributes."""
    return _same_run(path, run_key, may_differ) if Path(path).is_dir() else None


def windows_complete(folder) -> int:
    """How many windows the store in a run's output ``folder`` holds whole (0: none, or no store)."""
    try:
        return int(read_attrs(Path(folder) / STORE_NAME)["snn_fg"]["windows_complete"])
    except (InputError, OSError, KeyError):
        return 0


def run_finished(folder) -> bool:
    """Whether the store in a run's output ``folder`` holds a run that has ended (:meth:`MapsStore.finish`)."""
    try:
        return bool(read_attrs(Path(folder) / STORE_NAME)["snn_fg"]["complete"])
    except (InputError, OSError, KeyError):
        return False


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


class Writer:
    """Atomic replacements of a store's files (``put(path, data)``), made one
    after another on a thread of its own, in the order they were put. At
    most :data:`WRITES_AHEAD` wait (``put`` then waits for room); an error
    raised there is raised again by the next ``put`` or :meth:`wait`. The
    thread ends when it has had nothing to do for a second (a store left
    open holds none), and the next ``put`` starts another."""

    def __init__(self):
        self.q: queue.Queue = queue.Queue(WRITES_AHEAD)
        self.error: BaseException | None = None
        self.lock = threading.Lock()
        self.thread: threading.Thread | None = None

    def _work(self):
        while True:
            try:
                path, data = self.q.get(timeout=1.0)
            except queue.Empty:
                with self.lock:
                    if self.q.empty():  # (a put that came meanwhile found this thread still running)
                        self.thread = None
                        return
                continue
            try:
                if self.error is None:  # (after an error, nothing more: the store stays as it was then)
                    write_bytes(path, data)
            except BaseException as exc:
                self.error = exc
            finally:
                self.q.task_done()

    def put(self, path, data: bytes) -> None:
        self._raise()
        self.q.put((path, data))
        with self.lock:
            if self.thread is None:
                self.thread = threading.Thread(target=self._work, name="snn-fg store writer", daemon=True)
                self.thread.start()

    def wait(self) -> None:
        """Every write put so far made (or its error raised)."""
        self.q.join()
        self._raise()

    def _raise(self):
        if self.error is not None:
            raise self.error


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
        self.writer = Writer()
        for a in self.arrays.values():
            a.replace = self.writer.put
        self.flushed_at = time.monotonic()  # when the store was last flushed

    @classmethod
    def create(cls, path, run_key: dict) -> MapsStore:
        path = Path(path)
        path.mkdir(parents=True)
        write_json(path / ".zgroup", {"zarr_format": 2})
        write_json(
            path / ".zattrs",
            {"snn_fg": {"format": FORMAT, "windows_complete": 0, "complete": False, "run_key": run_key}, "params": {}},
        )
        return cls(path, read_attrs(path))

    @classmethod
    def reopen(cls, path, run_key: dict, may_differ=()) -> MapsStore:
        """The store at ``path`` to continue; refused when it was made with another ``run_key``
        (but for the keys ``may_differ``, which it takes from ``run_key`` from then on)."""
        attrs = _same_run(path, run_key, may_differ)
        attrs["snn_fg"]["run_key"] = json.loads(json.dumps(run_key))
        for stray in Path(path).rglob("*.part"):  # (atomic writes cut short by a kill)
            stray.unlink()
        return cls(path, attrs)

    def go_on(self) -> None:
        """A finished run continued past its end (a longer run of the same recording): its
        store is not complete until :meth:`finish` again."""
        self._status(complete=False)

    @property
    def complete(self) -> bool:
        return bool(self.attrs["snn_fg"]["complete"])

    def prepare(self, maps, **more) -> None:
        """Make the arrays that a window like ``maps`` (with ``more``) writes, before the first
        window is appended: a live run makes them from its warm-up's last window, so that their
        folders and files (8-12 ms for a dozen arrays) are not the first window's time."""
        self._array("window_params", TEXT, (), WINDOW_CHUNK)
        self._window_arrays(maps, more)

    def append(self, maps, **more) -> None:
        """Add one window: ``maps`` (its arrays, ``extra`` and ``params``) and ``more`` arrays."""
        if self.n == 0:
            self.attrs["params"] = dict(maps.params)
        base = self.attrs["params"]
        differ = {k: v for k, v in maps.params.items() if base.get(k) != v}
        self._array("window_params", TEXT, (), WINDOW_CHUNK).append([json.dumps(differ, sort_keys=True)])
        for a, v in self._window_arrays(maps, more):
            a.append(v)
        for key, a in self.arrays.items():
            if key.endswith("_offsets"):
                a.append([self.arrays[key.removesuffix("_offsets")].n])
            elif a.n == self.n and f"{key}_offsets" not in self.arrays:
                a.append(np.zeros((1,) + a.chunks[1:], a.dtype))  # absent from this window: zeros
        self.n += 1
        if self.n == 1 or time.monotonic() - self.flushed_at >= FLUSH_EVERY_S:
            self.flush(wait=False)

    def _window_arrays(self, maps, more: dict) -> list:
        """The arrays a window's ``maps`` and ``more`` go to, made where new, with the rows to append:
        ``[(array, rows)]`` (a ragged one's offsets made too)."""
        out = []
        arrays = {"fg_x": maps.fg_x, "fg_y": maps.fg_y, "grouping": maps.grouping, **maps.extra, **more}
        for key, v in arrays.items():
            v = np.asarray(v)
            if v.ndim == 1:  # ragged: its length may vary from window to window
                self._array(f"{key}_offsets", np.int64, (), FLAT_CHUNK)
                out.append((self._array(key, v.dtype, (), FLAT_CHUNK), v))
                continue
            a = self._array(key, v.dtype, v.shape, WINDOW_CHUNK if v.ndim else SCALAR_CHUNK)
            if a.chunks[1:] != v.shape:
                check.fail(
                    "MapsStore",
                    None,
                    None,
                    f"array {key!r} changes its shape between windows "
                    f"({a.chunks[1:]} before, {v.shape} in window {self.n}); cannot store it",
                )
            out.append((a, v[None]))
        return out

    def flush(self, wait: bool = True) -> None:
        """Every window appended made visible to readers: the chunks that hold
        complete windows, the arrays' shapes, then ``windows_complete``
        (``wait``: on disk when this returns; else on the way, by the writing thread)."""
        for a in self.arrays.values():
            a.flush()
            a.write_shape()
        self._status(windows_complete=self.n)
        self.flushed_at = time.monotonic()
        if wait:
            self.writer.wait()

    def _array(self, key: str, dtype, tail: tuple, chunk: int) -> GrowingArray:
        """The array ``key``, made when first met (the windows before it: fill values, or no part)."""
        if key not in self.arrays:
            a = self.arrays[key] = GrowingArray.create(self.path / key, dtype, tuple(tail), chunk)
            a.replace = self.writer.put
            if key.endswith("_offsets"):
                a.append(np.zeros(self.n + 1, np.int64))
            else:
                a.resize(self.n)
        return self.arrays[key]

    def describe(self, params: dict) -> None:
        """The run's parameters (its ``params``) as far as it has gone, written by the next
        :meth:`flush`: a run cut short keeps them as a finished one does."""
        self.attrs["params"] = params

    def finish(self, params: dict) -> None:
        """The run's final parameters, and the store marked complete."""
        self.describe(params)
        self.attrs["snn_fg"]["complete"] = True  # (written by the flush, after the chunks and shapes)
        self.flush()

    def _status(self, **changes) -> None:
        self.attrs["snn_fg"].update(changes)
        self.writer.put(self.path / ".zattrs", json_bytes(self.attrs))


#: the arrays every window writes from the first on (the maps and the window's parameters): all
#: their chunks up to ``windows_complete`` exist in a store that is whole. (An array first met at
#: a later window has no chunks for the windows before it: they read as fill values.)
EVERY_WINDOW = ("fg_x", "fg_y", "grouping", "window_params")


def _check_whole(path: Path, arrays: dict, n: int) -> None:
    """One clear line when the store at ``path`` lacks one of :data:`EVERY_WINDOW` or a chunk of
    one for its ``n`` complete windows (a folder copied in part, a file deleted): read on, the
    missing windows would be fill values, zeros, and every number made from them wrong."""
    for key in EVERY_WINDOW:
        if key not in arrays:
            raise InputError(path, f"has no {key} array: the store is incomplete or damaged")
        a = arrays[key]
        c = a.chunks[0]
        for k in range(-(-n // c)):
            if not a.chunk_path(k).is_file():
                raise InputError(
                    a.chunk_path(k),
                    f"missing: windows {k * c}-{min(n, (k + 1) * c) - 1} of the {n} the store holds complete "
                    "are not there (the store is damaged: run the recording again)",
                )


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
    _check_whole(path, arrays, n)
    own = [json.loads(t) for t in np.asarray(arrays.pop("window_params"))]
    params = dict(attrs["params"])
    if any(own):
        params["windows"] = own
    if not lazy:
        arrays = {k: np.asarray(v) for k, v in arrays.items()}
    maps = [arrays.pop(k) for k in ("fg_x", "fg_y", "grouping")]
    return (*maps, params, arrays)
