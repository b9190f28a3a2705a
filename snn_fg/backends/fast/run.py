"""One simulation of the fast engine: its cells, active set and spike log
(:class:`Run`), fed by the compiled loop of :mod:`.core`, and the cell
arrays kept from one run to the next (:class:`Pool`)."""

from __future__ import annotations

import numpy as np

from ... import cancel
from ..base import RunSettings, lif_populations, source_offsets
from . import tables as ft
from .results import BinStream  # noqa: F401 - (named in an annotation)

#: initial room of the spike log (spikes); it doubles when a step needs more
LOG_START = 1 << 16
#: a Conv into a population with fewer than this fraction of its cells
#: instantiated, whose kernel has at least this many taps per row it covers,
#: finds its synapses from the targets' side (deliver._conv_gather): visiting
#: a row costs about as much as following that many taps. 0.05: with the
#: level-1 simple cells masked to the event pixels, a dvs.es window has 9.9 %
#: of them, and gathering their DoG input made windows 0 and 5 (from 100 ms)
#: take 2.67-2.74 and 2.59-2.61 s against 2.32-2.40 and 2.09-2.11 s at 0.05
#: (side by side, load 0.9-1.1); a BSDS frame, with 1 % of them, was the same
GATHER_BELOW = 0.05
GATHER_TAPS_PER_ROW = 8


def _input_events(tab: ft.EngineTables, first_cell: dict, idx, steps, length: int, first_step: int = 0):
    """Input spikes ``(idx, steps)`` as cell numbers (``first_cell``:
    population -> its first number) grouped by step, ``(ptr, ids)``: the
    spikes of step ``first_step + s`` are ``ids[ptr[s]:ptr[s + 1]]``, for
    ``s`` below ``length``."""
    idx, steps = np.asarray(idx, dtype=np.int64), np.asarray(steps, dtype=np.int64) - first_step
    keep = (steps >= 0) & (steps < length)
    idx, steps = idx[keep], steps[keep]
    first = source_offsets(tab.network)
    ids = np.empty(idx.size, dtype=np.int64)
    known = np.zeros(idx.size, dtype=bool)
    for name, start in first.items():
        sel = (idx >= start) & (idx < start + tab.network.population(name).size)
        ids[sel] = first_cell[name] + idx[sel] - start
        known |= sel
    ids, steps = ids[known], steps[known]  # (clock spikes for a network without a clock)
    order = np.lexsort((ids, steps))
    ids, steps = ids[order], steps[order]
    return np.searchsorted(steps, np.arange(length + 1)).astype(np.int64), ids.astype(np.int32)


class _InputFeed:
    """The input of a run as the compiled loop reads it: ``ptr``/``ids``
    (:func:`_input_events`) of one period of steps, the loop taking step
    ``n``'s spikes from ``n % period``. A repeating input (or a whole
    run's) is one period loaded once; a
    :class:`~snn_fg.lowering.input_stream.SegmentedInput` is loaded a
    segment at a time, each a period the run must stop at the end of
    (:meth:`stop_after`) for the next to be loaded (:meth:`reached`)."""

    def __init__(self, tab: ft.EngineTables, first_cell: dict, inputs, n_steps: int):
        self.tab, self.first_cell, self.inputs, self.n_steps = tab, first_cell, inputs, n_steps
        self.segmented = hasattr(inputs, "segment")
        self.total = 0  # input spikes of the segments loaded before the current one
        if self.segmented:
            self.period, self.loaded = int(inputs.segment_steps), -1
            self.reached(0)
        else:
            periodic = inputs.period_steps is not None and inputs.period_steps < n_steps
            self.period = int(inputs.period_steps) if periodic else max(n_steps, 1)
            self.ptr, self.ids = _input_events(tab, first_cell, inputs.indices, inputs.steps, self.period)

    def stop_after(self, n: int) -> int:
        """The last step (exclusive) a call of the loop from step ``n`` may reach."""
        return (n // self.period + 1) * self.period if self.segmented else self.n_steps

    def reached(self, n: int) -> None:
        """The run is at step ``n``: load its segment if it is a new one."""
        j = n // self.period
        if self.segmented and j != self.loaded and n < self.n_steps:
            if self.loaded >= 0:
                self.total += int(self.ptr[-1])
            idx, steps = self.inputs.segment(j)
            keep = steps < self.n_steps  # (the last segment may reach past the run's end)
            self.ptr, self.ids = _input_events(
                self.tab, self.first_cell, idx[keep], steps[keep], self.period, j * self.period
            )
            self.loaded = j

    def spikes_fed(self) -> int:
        """How many input spikes the run fed, without a pass over the spike log."""
        if self.segmented:
            return self.total + int(self.ptr[-1])
        periods, rest = divmod(self.n_steps, self.ptr.size - 1)
        return int(periods * self.ptr[-1] + self.ptr[rest])


class Run:
    """The mutable state of one simulation: cells, active set and spike log.

    Only the chosen cells exist, numbered population after population
    (:mod:`.core` describes the numbering and the maps between grid and
    number)."""

    def __init__(self, tab: ft.EngineTables, chosen: dict, inputs, n_steps: int, pool: "Pool"):
        from .core import N_FRESH, STATE

        self.tab, self.n_steps, self.pool = tab, n_steps, pool
        off = self._number(chosen)
        sparse = self.cells[tab.prj[:, ft.J_TGT], 1] < GATHER_BELOW * tab.pops[tab.prj[:, ft.J_TGT], ft.P_SIZE]
        self.gather = (sparse & (tab.taps_per_row >= GATHER_TAPS_PER_ROW)).astype(np.uint8)
        self.ctype = np.repeat(tab.pops[:, ft.P_TYPE], self.cells[:, 1]).astype(np.uint8)
        self.feed = _InputFeed(tab, self.first, inputs, n_steps)
        self.n_present = int(sum(chosen[p.name].size for p in lif_populations(tab.network)))
        self.state = pool.zeros("state", off, STATE)  # all at rest: never touched
        self.inact = pool.zeros("inact", off, np.uint8)
        self.act, self.new, self.tmp, self.fresh = (
            pool.zeros(name, off, np.int32) for name in ("act", "new", "tmp", "fresh")
        )
        self.radix = np.zeros(2048, dtype=np.int64)
        self.scalars = np.zeros(2, dtype=np.int64)
        self.log = np.empty(LOG_START, dtype=np.int32)
        self.step_start = np.zeros(n_steps + 1, dtype=np.int64)
        largest = int(max(chosen[p.name].size for p in lif_populations(tab.network)))
        self.acc = pool.zeros("acc", max(largest, 1), np.float64)
        self.touched = pool.zeros("touched", largest + tab.max_fanout, np.int64)
        self.counters = np.zeros(N_FRESH + 1, dtype=np.int64)
        self.prj_events = np.zeros(len(tab.network.projections), dtype=np.int64)

    def _number(self, chosen: dict) -> int:
        """Number the chosen cells (see :mod:`.core`); returns how many."""
        from .core import C_BITS, C_FLAT, C_MAP, C_ROW

        pops = self.tab.network.populations
        self.cells = np.full((len(pops), 6), -1, dtype=np.int64)
        maps, flats, columns, rows, bits, off, n_map, n_flat, n_row, n_bits = [], [], [], [], [], 0, 0, 0, 0, 0
        for q, p in enumerate(pops):
            sites = chosen[p.name]
            self.cells[q, :2] = off, sites.size
            if sites.size != p.size:
                local = np.full(p.size, -1, dtype=np.int32)
                local[sites] = np.arange(sites.size, dtype=np.int32)
                maps.append(local)
                flats.append(sites.astype(np.int32))
                columns.append((sites % p.grid[1]).astype(np.int32))
                rows.append(np.searchsorted(sites, np.arange(p.channels * p.grid[0] + 1) * p.grid[1]))
                bits.append(np.packbits(local >= 0, bitorder="little"))
                self.cells[q, C_MAP], self.cells[q, C_FLAT], self.cells[q, C_ROW] = n_map, n_flat, n_row
                self.cells[q, C_BITS] = n_bits
                n_map, n_flat, n_row = n_map + p.size, n_flat + sites.size, n_row + rows[-1].size
                n_bits += bits[-1].size
            off += sites.size
        self.first = {p.name: int(self.cells[q, 0]) for q, p in enumerate(pops)}
        self.cmap = np.concatenate(maps) if maps else np.zeros(1, dtype=np.int32)
        self.flat_of = np.concatenate(flats) if flats else np.zeros(1, dtype=np.int32)
        self.column_of = np.concatenate(columns) if columns else np.zeros(1, dtype=np.int32)
        self.row_ptr = np.concatenate(rows).astype(np.int64) if rows else np.zeros(1, dtype=np.int64)
        self.bits = np.concatenate(bits) if bits else np.zeros(1, dtype=np.uint8)
        return off

    def simulate(self, settings: RunSettings, chunk: int, stream: "BinStream | None" = None):
        """Run every step; with ``stream``, stop at each counting-bin edge
        for it to hand the bin over and drop the spikes no delay reaches."""
        from .core import CellNumbering, KernelTables, RunArrays, run_steps

        tables = KernelTables(*(getattr(self.tab, name) for name in KernelTables._fields))
        numbering = CellNumbering(*(getattr(self, name) for name in CellNumbering._fields))
        with _progress(settings) as bar:
            n = 0
            if stream is not None:
                stream.reached(0)
            while n < self.n_steps:
                end = min(n + chunk, self.n_steps)
                end = min(end, self.feed.stop_after(n))
                if stream is not None:
                    end = min(end, stream.next_stop(n))
                run = RunArrays(*(getattr(self, name) for name in RunArrays._fields))  # (the log may have grown)
                reached = run_steps(n, end, run, numbering, tables)
                if reached < end:  # the next step may not fit in the spike log
                    self.log = np.concatenate([self.log, np.empty(self.log.size, dtype=np.int32)])
                bar(reached - n)
                cancel.check()
                n = reached
                self.feed.reached(n)
                if stream is not None:
                    stream.reached(n)

    def release(self):
        """Hand the cell arrays back to the pool, at rest again."""
        from .core import N_FRESH, reset

        reset(self.state, self.inact, self.act, int(self.scalars[0]), self.fresh, int(self.counters[N_FRESH]))

    def spikes(self):
        """Every spike of the run: the cell numbers (int32, a view of the log)
        and where each step's spikes start in them (``step_start[s]``, with
        ``step_start[n_steps]`` the total)."""
        return self.log[: int(self.scalars[1])], self.step_start

    def forget_before(self, step: int, now: int) -> int:
        """Drop the spikes of the steps before ``step`` from the log (no
        projection reaches that far back any more), the run being at step
        ``now``; ``step_start`` of steps ``step .. now`` moves with them,
        that of earlier steps is no longer valid. Returns how many spikes
        were dropped."""
        k = int(self.step_start[step])
        if k:
            log_n = int(self.scalars[1])
            self.log[: log_n - k] = self.log[k:log_n]
            self.scalars[1] = log_n - k
            self.step_start[step : now + 1] -= k
        return k

    def input_spikes(self) -> int:
        """How many input spikes the run fed."""
        return self.feed.spikes_fed()

    in_ptr = property(lambda self: self.feed.ptr)
    in_ids = property(lambda self: self.feed.ids)

    def final_state(self) -> np.ndarray:
        """Every cell's ``(v, I_exc, I_inh)`` at the end of the run (volts, one row per cell)."""
        from .core import final_state

        out = np.zeros((self.state.size, 3))
        final_state(self.state, self.ctype, self.tab.nrn, self.tab.adv, self.n_steps, out)
        return out


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
    """A callable advancing a tqdm bar by simulated steps (or doing nothing).
    The bar appears when the first steps are done, so it never sits at 0
    while the engine's code compiles."""

    def __init__(self, settings: RunSettings):
        self.settings, self.bar = settings, None

    def __enter__(self):
        return self

    def __call__(self, steps: int):
        if self.bar is None and self.settings.progress:
            from tqdm import tqdm

            self.bar = tqdm(total=round(self.settings.duration_ms), unit="ms", desc="simulating", leave=False)
        if self.bar is not None:
            self.bar.update(steps * self.settings.dt_ms)

    def __exit__(self, *exc):
        if self.bar is not None:
            self.bar.close()
