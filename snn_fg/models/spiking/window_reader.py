"""Reading a continuous run's windows as it goes: :class:`WindowReader`
receives the backend's counting bins (``RunSettings.on_bin``) and decodes
each window of a recording as soon as its read-out span is complete
(:mod:`snn_fg.models.spiking.continuous` runs the network)."""

from __future__ import annotations

import dataclasses
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from types import SimpleNamespace

import numpy as np

from ...backends.base import SparseCounts
from ...frames.pool import pool_frame
from ...results.maps import CONFIDENCE, Maps
from .decode import decode_maps
from .record import SpikingRecord, run_provenance
from .stream_input import StreamEnded, StreamFeed


def bins_of(span, edges) -> tuple[int, int]:
    """The counting bins ``k0 .. k1 - 1`` that make up a read-out span (spans
    are made of edges; ``edges`` sorted, best an array)."""
    return int(np.searchsorted(edges, span[0])), int(np.searchsorted(edges, span[1]))


class RunningCounts:
    """The spike counts of a run's bins summed cell by cell, every population
    in one flat int32 array, so that a window's counts are one subtraction
    (:meth:`since`) and the total at a window's start one copy (:meth:`mark`).

    The sum wraps around at 2**32 (numpy's integer addition), and so does the
    subtraction: a window's counts are exact however long the total has run,
    as long as no cell fires 2**31 times within one window."""

    def __init__(self):
        self.flat = None  # (int32, every population's cells one after the other)
        self.parts: dict = {}  # population -> its slice of ``flat``
        self.fresh = True  # (no bin added since the restart)

    def restart(self, counts: dict):
        """The total from zero, laid out for ``counts`` (a bin's: population -> cells)."""
        if not self.parts:
            n = 0
            for name, c in counts.items():
                self.parts[name] = slice(n, n + c.size)
                n += c.size
        self.flat, self.fresh = None, True

    def add(self, counts: dict):
        """Add a bin's counts (the same populations, in any order, as every bin)."""
        if counts.keys() != self.parts.keys():
            raise RuntimeError(f"a bin counts the populations {sorted(counts)}, not those before {sorted(self.parts)}")
        if self.fresh:  # (the first bin since the restart is copied, not added to zeros: no pass over zeroed pages)
            self.flat = np.empty(max((s.stop for s in self.parts.values()), default=0), np.int32)
        for name, c in counts.items():
            part = self.flat[self.parts[name]]
            if self.fresh:
                np.copyto(part, c, casting="unsafe")
            else:
                np.add(part, c, out=part, casting="unsafe")
        self.fresh = False

    def mark(self) -> np.ndarray | None:
        """The total now (a copy; None while it is zero since the restart), for :meth:`since`."""
        return None if self.fresh else self.flat.copy()

    def since(self, mark: np.ndarray | None, hand_over: bool = False) -> dict:
        """The counts added since ``mark`` (None: since :meth:`restart`; written over), population by
        population (:class:`WindowCounts`); ``hand_over``: the total itself is handed over
        (and restarted before it is added to again) in place of a copy."""
        if mark is not None:  # (the mark is the window's own: its counts take its place)
            flat = np.subtract(self.flat, mark, out=mark)
        elif hand_over:
            flat, self.flat = self.flat, None
        else:
            flat = self.flat.copy()
        return WindowCounts({name: flat[s] for name, s in self.parts.items()}, flat=flat, parts=self.parts)


class WindowCounts(dict):
    """Population -> a window's spike counts: slices ``parts[population]`` of one array ``flat``."""

    def __init__(self, counts: dict, *, flat: np.ndarray, parts: dict):
        super().__init__(counts)
        self.flat, self.parts = flat, parts


def window_counts(bins: list) -> WindowCounts:
    """The sum of a window's :class:`~snn_fg.backends.base.SparseCounts`, spike by spike,
    in the narrowest unsigned integers that hold a cell firing every step (an 85 ms window
    at 1 ms fits a byte: the passes over every cell after, its summary and rates, read a
    quarter of int32's bytes)."""
    steps = sum(b.steps for b in bins)
    kind = np.uint8 if steps <= 0xFF else np.uint16 if steps <= 0xFFFF else np.int32
    flat = np.zeros(bins[0].cells, kind)
    for b in bins:
        b.into(flat)
    parts = bins[0].parts
    return WindowCounts({name: flat[s] for name, s in parts.items()}, flat=flat, parts=parts)


class WindowReader:
    """Receives a run's counting bins in order (``RunSettings.on_bin``) and
    decodes each window as soon as the last bin of its read-out span is in:
    into ``run.decoded[k] = (fg_x, fg_y, grouping, SpikingRecord)``, or as
    its maps to ``on_window(window, maps)``. Only the windows still being
    read hold their counts and spikes; the windows themselves come from
    ``feed`` (:class:`~snn_fg.models.spiking.stream_input.StreamFeed`); once the
    stream has ended and its last window is read, :class:`StreamEnded` stops
    a run laid out for more windows.

    ``threaded`` (where the process may use more than one core): a window
    is decoded and handed to ``on_window`` on a second thread while the
    simulation goes on (the fast engine's loop runs without the interpreter
    lock): windows still leave in order, at most :attr:`AHEAD` wait, and
    an error raised there is raised again here. Used as a context manager,
    which waits for the last window (or, on an error, for the one being
    written)."""

    #: windows handed to the decoding thread and not yet finished
    AHEAD = 2

    def __init__(
        self,
        feed: StreamFeed,
        spans,
        edges,
        pool: int,
        run,
        on_window=None,
        threaded: bool = False,
        cells: bool = True,
        unpool: bool = True,
    ):
        self.feed, self.edges, self.pool, self.run, self.on_window = feed, edges, pool, run, on_window
        self.unpool = unpool  # (False: the maps stay on the network's blocks)
        ends = np.searchsorted(np.asarray(edges), np.asarray(spans, dtype=np.float64).reshape(-1, 2))
        self.bins = list(zip(ends[:, 0].tolist(), ends[:, 1].tolist()))
        self.first = 0  # the first window not decoded yet (spans start and end in order)
        # the counts of the bins so far, summed; a window being read holds their value at its
        # start (None: the total began with it) and its spikes (a window's counts are the difference:
        # one pass over the cells a bin, however many windows overlap, as with --stride-ms shorter
        # than the window)
        self.total = RunningCounts()
        self.reading: dict = {}
        self.last_at = run.t_start  # perf_counter() when the last window was decoded
        self.threaded, self.cells = threaded, cells
        self.worker = None
        self.pending: deque = deque()
        self.failed = False
        self.last_result = None  # the last bin's result (the whole run's, if it is stopped early)

    def __enter__(self):
        if self.threaded:
            self.worker = ThreadPoolExecutor(1, thread_name_prefix="snn-fg-decode")
        return self

    def __exit__(self, kind, exc, tb):
        if self.worker is None:
            return
        try:
            if kind is None:
                self._wait(0)
        finally:
            self.worker.shutdown(wait=True, cancel_futures=True)
            self.worker = None

    def _wait(self, most: int):
        """Wait until at most ``most`` windows are pending, raising their errors."""
        while len(self.pending) > most:
            self.pending.popleft().result()

    def __call__(self, k: int, result):
        self.last_result = result
        i, ending = self.first, []
        # (bins kept as their spikes: a window adds its own, see SparseCounts)
        sparse = isinstance(result.counts, SparseCounts)
        while i < len(self.bins) and self.bins[i][0] <= k:
            k0, k1 = self.bins[i]
            if k < k1:
                if k == k0 and sparse:  # (its bins themselves, added up at its end)
                    self.reading[i] = ([], [])
                elif k == k0 and not self.reading:  # (none open: the window's counts are the total from here)
                    self.total.restart(result.counts)
                    self.reading[i] = (None, [])
                elif k == k0:  # (the counts so far, before this bin: what the window's end subtracts)
                    self.reading[i] = (self.total.mark(), [])
                before, spikes = self.reading[i]
                if self.feed.dropped(i):  # (a live stream dropped it: nothing of it is kept, nor is it decoded)
                    self.reading[i] = (None, [])
                else:
                    if sparse:
                        before.append(result.counts)
                    if result.spikes is not None:
                        spikes.append(result.spikes)
                if k == k1 - 1:
                    ending.append(i)
            i += 1
        if self.reading and not sparse:  # (no window open: the total need not follow, its differences are what count)
            self.total.add(result.counts)
        for i in ending:
            self._read(i, result)
        while self.first < len(self.bins) and self.bins[self.first][1] <= k + 1:
            self.first += 1
        if self.feed.ended and self.feed.n <= self.first < len(self.bins):
            raise StreamEnded(f"{self.feed.n} windows")

    def _read(self, i: int, result):
        """Window ``i``'s last bin is in: its counts (the total now less that at its
        start) are decoded here or on the decoding thread."""
        before, spikes = self.reading.pop(i)
        w = self.feed.window(i)
        # (skipped: a live stream dropped it, or a newer hop's read-out is due as soon: not decoded)
        skip = self.feed.dropped(i) or self.feed.stale(w)
        counts = {}
        if skip:
            pass
        elif isinstance(before, list):  # (the window's own bins, kept as their spikes)
            counts = window_counts(before)
        else:  # (the total is this window's alone where no other reads on from it)
            counts = self.total.since(before, hand_over=before is None and not self.reading)
        if self.worker is None:
            self._finish(i, w, result, counts, spikes, skip)
        else:
            self._wait(self.AHEAD - 1)
            self.pending.append(self.worker.submit(self._finish, i, w, result, counts, spikes, skip))

    def _finish(self, i, w, result, counts, spikes, skip=False):
        if self.failed:  # (an earlier window failed on the thread: none after it)
            return
        try:
            self._hand(i, w, result, counts, spikes, skip)
        except BaseException:
            self.failed = True
            raise

    def _hand(self, i, w, result, counts, spikes, skip=False):
        if skip:  # (passed on in order, behind the windows still being decoded)
            self.feed.passed(w)
            return
        decoded, before = self._decode(i, w, result, counts, spikes), self.last_at
        self.last_at = time.perf_counter()
        if self.on_window is None:
            self.run.decoded[i], self.run.decoded_at[i] = decoded, self.last_at
        else:
            self.on_window(w, maps_of(self.run, i, decoded, result, self.last_at - before, self.bins[i]))

    def _decode(self, i, w, result, counts, spikes):
        k0, k1 = self.bins[i]
        trains = None
        if spikes:
            trains = {n: tuple(np.concatenate([s[n][j] for s in spikes]) for j in range(2)) for n in spikes[0]}
        window_result = dataclasses.replace(
            result, counts=counts, count_window_ms=self.edges[k1] - self.edges[k0], spikes=trains
        )
        if self.unpool and self.pool > 1:
            fg_x, fg_y, grouping, conf = decode_maps(window_result, w.pos | w.neg, self.pool)
        else:  # (on the network's own grid)
            fg_x, fg_y, grouping, conf = decode_maps(window_result)
        on, off = pool_frame(w.pos, w.neg, self.pool)
        masks = SimpleNamespace(on=on != 0, off=off != 0)
        rec = SpikingRecord.from_result(window_result, masks, self.edges[k0], self.cells)
        return fg_x, fg_y, grouping, conf, rec


def maps_of(run, k: int, decoded, result, window_s: float, bins=None) -> Maps:
    """Window ``k``'s maps from its ``decoded`` tuple, with the parameters
    of ``result`` (the whole run's, or the bin's while it runs); ``bins``:
    its counting bins (:func:`bins_of`) where the caller knows them (a
    search of the run's edges, a list, cost 3 ms a window)."""
    fg_x, fg_y, grouping, conf, rec = decoded
    k0, k1 = bins_of(run.spans[k], run.edges) if bins is None else bins
    so_far = {
        "duration_ms": run.edges[k1],
        "simulated_ms": run.edges[k1],
    }  # (when it was read: a stream's end is not known)
    simulation = {
        **rec.timing(),
        **run.simulation,
        **so_far,
        "count_from_ms": run.edges[k0],
        "count_to_ms": run.edges[k1],
    }
    params = run_provenance(run.network, run.origin, run.backend, result, rec.populations, simulation, run.t_start)
    params["timings_s"]["window"] = window_s
    extra = {**rec.arrays(), CONFIDENCE: conf.astype(np.float32)}
    return Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), params, extra)
