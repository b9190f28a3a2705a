"""One simulation of the fast engine: its cells, active set and spike log
(:class:`Run`), fed by the compiled loop of :mod:`~snn_fg.backends.fast.core`, and the cell
arrays kept from one run to the next (:class:`Pool`)."""

from __future__ import annotations

import numpy as np

from .. import cancel
from ..base import RunSettings, lif_populations
from . import tables as ft
from .feed import InputFeed
from .results import BinStream  # noqa: F401 - (named in an annotation)
from .share import Sharing

#: cells handed their input in one batch (handover.flush_rows)
FOUND = 4096
#: initial room of the spike log (spikes); it doubles when a step needs more
LOG_START = 1 << 16
#: int64 values between two threads' counters (two 64-byte cache lines; they
#: hold :data:`.deliver.PH_GATHER` too)
APART = 16


class Run:
    """The mutable state of one simulation: cells, active set and spike log.

    Only the chosen cells exist, numbered population after population
    (:mod:`~snn_fg.backends.fast.core` describes the numbering and the maps between grid and
    number)."""

    def __init__(self, tab: ft.EngineTables, chosen: dict, inputs, n_steps: int, pool: Pool, threads: int = 1):
        from .deliver import PH_GATHER
        from .lif import STATE

        self.tab, self.n_steps, self.pool, self.threads = tab, n_steps, pool, threads
        off = self._number(chosen)
        self.ctype = np.repeat(tab.pops[:, ft.P_TYPE], self.cells[:, 1]).astype(np.uint8)
        self.feed = InputFeed(tab, self.first, inputs, n_steps)
        self.reach = int(tab.prj[:, ft.J_DELAY].max()) if len(tab.prj) else 0  # (the longest delay, steps)
        self.skipped = 0  # steps not simulated (skip)
        lif = lif_populations(tab.network)
        self.n_present = int(sum(chosen[p.name].size for p in lif))
        self.state = pool.zeros("state", off, STATE)  # all at rest: never touched
        self.scalars = np.zeros(2 * threads + 1, dtype=np.int64)
        self.log = np.empty(LOG_START, dtype=np.int32)
        self.step_start = np.zeros(n_steps + 1, dtype=np.int64)
        self.spike_tmp = pool.zeros("spike_tmp", off + 1, np.int32)
        # each thread's own arrays: its summed input and its marks, and (as long
        # as its share of the cells) its active cells and scratch
        size = max([p.size for p in lif] + [1])
        self.acc = pool.zeros("acc", threads * size, np.float64).reshape(threads, size)  # (at rest: all 0)
        rows = max([p.channels * p.grid[0] for p in lif] + [1])
        words = max([p.channels * p.grid[0] * ((p.grid[1] + 63) // 64) for p in lif] + [1])
        self.bits = np.zeros((threads, words + 1), np.uint64)  # (a spare word: deliver.mark_taps)
        self.listed = np.zeros((threads, rows), np.uint8)
        self.sharing = Sharing(tab.network.populations, chosen, threads)
        self.owner, self.work = self.sharing.owner, self.sharing.work
        cap = int(self.sharing.owned_cells().max()) + 1  # (a spare slot: flush_rows appends without a branch)
        self.act, self.new, self.tmp, self.fresh = (
            pool.zeros(name, threads * cap, np.int32).reshape(threads, cap) for name in ("act", "new", "tmp", "fresh")
        )
        self.radix = np.zeros((threads, 2048), dtype=np.int64)
        # (each thread's counters in a cache line of their own: written by the thread as it delivers)
        self.counters = np.zeros((threads, max(PH_GATHER + 1, APART)), dtype=np.int64)
        self.prj_events = np.zeros((threads, len(tab.network.projections)), dtype=np.int64)
        self.dirty = np.zeros((threads, rows + 1), np.int64)  # (a spare slot: deliver.mark_row writes without a branch)
        self.n_dirty = np.zeros((threads, APART), np.int64)  # (column 0; apart, as the counters)
        found = max([FOUND] + [p.grid[1] for p in lif])
        self.found, self.found_g = np.zeros((threads, found), np.int64), np.zeros((threads, found), np.int64)

    def _number(self, chosen: dict) -> int:
        """Number the chosen cells (see :mod:`~snn_fg.backends.fast.core`); returns how many."""
        from .deliver import C_FLAT, C_PRES, C_WHOLE

        pops = self.tab.network.populations
        self.cells = np.full((len(pops), 5), -1, dtype=np.int64)
        flats, pres, rank, off, n_flat, n_words = [], [], [], 0, 0, 0
        for q, p in enumerate(pops):
            sites = chosen[p.name]
            self.cells[q, :2] = off, sites.size
            self.cells[q, C_WHOLE] = int(sites.size == p.size)
            if sites.size != p.size:
                flats.append(sites.astype(np.int32))
                self.cells[q, C_FLAT] = n_flat
                n_flat += sites.size
            if not p.is_source:
                words = presence_words(p, sites)
                pres.append(words)
                counts = np.bitwise_count(words) if hasattr(np, "bitwise_count") else _ones(words)
                rank.append(np.concatenate([[0], np.cumsum(counts[:-1], dtype=np.int64)]))
                self.cells[q, C_PRES] = n_words
                n_words += words.size
            off += sites.size
        self.first = {p.name: int(self.cells[q, 0]) for q, p in enumerate(pops)}
        self.flat_of = np.concatenate(flats) if flats else np.zeros(1, dtype=np.int32)
        self.pres = np.concatenate(pres + [np.zeros(1, np.uint64)])  # (a spare word: deliver.mark_taps)
        self.rank = np.concatenate(rank) if rank else np.zeros(1, dtype=np.int64)
        return off

    def simulate(self, settings: RunSettings, chunk: int, stream: BinStream | None = None, compiled=None):
        """Run every step; with ``stream``, stop at each counting-bin edge
        for it to hand the bin over and drop the spikes no delay reaches.
        ``compiled`` (a :class:`threading.Event`) is set once the first call
        of the compiled loop returns: its code is compiled by then."""
        from .core import CellNumbering, KernelTables, RunArrays, ThreadArrays, run_steps

        tables = KernelTables(*(getattr(self.tab, name) for name in KernelTables._fields))
        numbering = CellNumbering(*(getattr(self, name) for name in CellNumbering._fields))
        with _progress(settings) as bar:
            n = 0
            self.feed.reached(0)
            if stream is not None:
                stream.reached(0)
            while n < self.n_steps:
                end = min(n + chunk, self.n_steps)
                end = min(end, self.feed.stop_after(n))
                if stream is not None:
                    end = min(end, stream.next_stop(n))
                run = RunArrays(*(getattr(self, name) for name in RunArrays._fields))  # (the log may have grown)
                threads = ThreadArrays(*(getattr(self, name) for name in ThreadArrays._fields))  # (and the lists)
                reached = run_steps(n, end, run, threads, numbering, tables)
                if compiled is not None:
                    compiled.set()
                self.sharing.chunk_done(self)
                if reached < end:  # the next step may not fit in the spike log
                    self.log = np.concatenate([self.log, np.empty(self.log.size, dtype=np.int32)])
                bar(reached - n)
                cancel.check()
                n = reached
                if stream is not None:  # (the bins that end here are handed over before the next input is awaited)
                    stream.reached(n)
                while stream is not None and (resume := self.feed.resume_at(n)) > n:  # (a run keeping its log: none)
                    self.skip(n, resume, stream)
                    n = resume
                    stream.reached(n)
                self.feed.reached(n)

    def skip(self, n: int, to: int, stream: BinStream):
        """Steps ``n .. to - 1`` are not simulated (a live stream dropped
        them, :meth:`.feed.InputFeed.resume_at`): every cell is put at rest and
        the spikes of the log forgotten (``stream``, which hands the bins
        over, counts them first), so that step ``to`` begins as a run with
        no input before it would. Counted in :attr:`skipped`."""
        from .core import reset
        from .deliver import N_FRESH

        first = stream.skipping(n)  # (the earliest step whose log position is still read)
        reset(self.state, self.fresh, self.counters[:, N_FRESH])
        self.counters[:, N_FRESH] = 0
        self.scalars[:] = 0  # (no active cell, an empty log)
        self.step_start[max(0, min(first, n - self.reach)) : to + 1] = 0
        self.skipped += to - n

    def release(self):
        """Hand the cell arrays back to the pool, at rest again."""
        from .core import reset
        from .deliver import N_FRESH

        reset(self.state, self.fresh, self.counters[:, N_FRESH])

    def spikes(self):
        """Every spike of the run: the cell numbers (int32, a view of the log)
        and where each step's spikes start in them (``step_start[s]``, with
        ``step_start[n_steps]`` the total)."""
        return self.log[: self.log_length], self.step_start

    def forget_before(self, step: int, now: int) -> int:
        """Drop the spikes of the steps before ``step`` from the log (no
        projection reaches that far back any more), the run being at step
        ``now``; ``step_start`` of steps ``step .. now`` moves with them,
        that of earlier steps is no longer valid. Returns how many spikes
        were dropped."""
        k = int(self.step_start[step])
        if k:
            log_n = self.log_length
            self.log[: log_n - k] = self.log[k:log_n]
            self.scalars[self.threads] = log_n - k
            self.step_start[step : now + 1] -= k
        return k

    @property
    def log_length(self) -> int:
        """How many spikes the log holds."""
        return int(self.scalars[self.threads])

    @property
    def totals(self) -> np.ndarray:
        """The counters (:data:`.deliver.N_EVENTS` ...) summed over threads."""
        return self.counters.sum(axis=0)

    @property
    def events(self) -> np.ndarray:
        """The synaptic events of each projection, summed over threads."""
        return self.prj_events.sum(axis=0)

    def input_spikes(self, n: int | None = None) -> int:
        """How many input spikes the run fed (before step ``n``)."""
        return self.feed.spikes_fed(n)

    in_ptr = property(lambda self: self.feed.ptr)
    in_ids = property(lambda self: self.feed.ids)

    def final_state(self) -> np.ndarray:
        """Every cell's ``(v, I_exc, I_inh)`` at the end of the run (volts, one row per cell)."""
        from .core import final_state

        out = np.zeros((self.state.size, 3))
        final_state(self.state, self.ctype, self.tab.nrn, self.tab.adv, self.n_steps, out)
        return out


def presence_words(p, sites: np.ndarray) -> np.ndarray:
    """The presence bits of population ``p`` whose cells ``sites`` (flat
    indices) exist: per row of each channel, ``ceil(cols / 64)`` words, bit
    ``j % 64`` of word ``j // 64`` for column ``j``."""
    c, r, cols = p.shape
    words = (cols + 63) // 64
    mask = np.zeros((c * r, words * 64), bool)
    flat = np.zeros(p.size, bool)
    flat[sites] = True
    mask[:, :cols] = flat.reshape(c * r, cols)
    return np.packbits(mask, axis=1, bitorder="little").view(np.uint64).reshape(-1).copy()


def _ones(words: np.ndarray) -> np.ndarray:
    """Set bits of each word (numpy before 2.0 has no bitwise_count)."""
    return np.unpackbits(words.view(np.uint8).reshape(-1, 8), axis=1).sum(axis=1)


class Pool:
    """Cell arrays kept from one run to the next (a run over a recording,
    window after window, or the next frame): allocating them anew would
    fault in hundreds of megabytes of fresh memory per run. Arrays handed
    out by :meth:`zeros` come back at rest (:meth:`Run.release`).

    Large arrays are mapped in 2 MB pages where the system offers them
    (:func:`zeroed`): a run touches cells all over its state array, and
    faulting that in 4 kB at a time cost about 0.5 s of the first
    ``dvs.es`` window a process simulated (2.1 s in all)."""

    def __init__(self):
        self.arrays: dict = {}

    def zeros(self, name, n, dtype):
        """The pool's array ``name``, at least ``n`` long (zeros when new)."""
        a = self.arrays.get(name)
        if a is None or a.size < n or a.dtype != np.dtype(dtype):
            a = self.arrays[name] = zeroed(max(n, 1), dtype)
        return a[:n]

    def clear(self):
        self.arrays.clear()


#: arrays at least this large (bytes) are mapped with the huge-page hint
HUGE_FROM = 4 << 20


def zeroed(n: int, dtype) -> np.ndarray:
    """``np.zeros(n, dtype)``, for a large array as an anonymous memory map
    with the kernel's transparent-huge-page hint (``MADV_HUGEPAGE``), so
    that touching it faults in 2 MB at a time. Where the hint does not
    exist (not Linux) or the map fails, plain ``np.zeros``."""
    import mmap

    dtype = np.dtype(dtype)
    size = n * dtype.itemsize
    advice = getattr(mmap, "MADV_HUGEPAGE", None)
    if size < HUGE_FROM or advice is None:
        return np.zeros(n, dtype)
    try:
        m = mmap.mmap(-1, size, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
        m.madvise(advice)
    except (OSError, ValueError, AttributeError):
        return np.zeros(n, dtype)
    return np.frombuffer(m, dtype=dtype, count=n)  # (writable; the array keeps the map alive)


class _progress:
    """A callable advancing a progress bar (:mod:`snn_fg.results.progress`) by simulated steps (or doing nothing).
    The bar appears when the first steps are done, so it never sits at 0
    while the engine's code compiles."""

    def __init__(self, settings: RunSettings):
        self.settings, self.bar = settings, None

    def __enter__(self):
        return self

    def __call__(self, steps: int):
        if self.bar is None and self.settings.progress:
            from ...results.progress import bar

            self.bar = bar("simulating", "ms", round(self.settings.duration_ms))
        if self.bar is not None:
            self.bar.update(steps * self.settings.dt_ms)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
