"""What a run of the fast engine hands back: its spike trains
(:class:`SpikeTrains`), each counting bin as the run passes it
(:class:`BinStream`, for ``RunSettings.on_bin``) and the
:class:`~snn_fg.backends.base.SimulationResult` (:func:`simulation_result`). The engine
itself is :mod:`.backend`; the numbering of cells and the spike log it keeps are
described in :mod:`~snn_fg.backends.fast.core`."""

from __future__ import annotations

import time
from collections.abc import Mapping

import numpy as np

from ...network.graph import Network
from ..base import RunSettings, SimulationResult, bin_result, lif_populations, segments
from . import tables as ft
from .neurons import MS
from .stencils import MV


def first_step_at(t_ms: float, dt_ms: float) -> int:
    """The first step whose time ``n * dt`` (seconds, as Brian2's clock
    computes it) is at or after ``t_ms``: where Brian2's ``t >= t_count`` starts."""
    dt_s, t_s = dt_ms * MS, t_ms * MS
    n = max(0, int(np.floor(t_s / dt_s)) - 2)
    while np.int64(n) * dt_s < t_s:
        n += 1
    return n


class SpikeTrains(Mapping):
    """Every spike of a run's LIF populations, ``name -> (cell, t_ms)`` as
    :class:`~snn_fg.backends.base.SimulationResult` documents it, ``cell`` int32.

    The log is regrouped by population once, into two int32 arrays (8 bytes
    a spike), and the times are made on access. A BSDS frame's run has
    about 1e8 spikes: an argsort with int64 keys and float64 times took
    about 70 bytes a spike, more than the simulation itself."""

    def __init__(self, network: Network, ids, step_start, starts, dt_ms: float, first_step: int = 0):
        """``first_step``: the step of ``step_start[0]`` (a part of a run)."""
        from .counting import group_by_population, population_totals

        per_pop = np.zeros(starts.size, dtype=np.int64)
        population_totals(ids, starts, per_pop)
        keep = np.array([not p.is_source for p in network.populations], dtype=np.uint8)
        kept = np.where(keep == 1, per_pop, 0)
        self._cuts = np.concatenate([[0], np.cumsum(kept)]).astype(np.int64)
        self._local = np.empty(int(self._cuts[-1]), dtype=np.int32)
        self._step = np.empty(int(self._cuts[-1]), dtype=np.int32)
        group_by_population(ids, step_start, starts, keep, self._cuts, self._local, self._step)
        if first_step:
            self._step += np.int32(first_step)
        self._index = {p.name: q for q, p in enumerate(network.populations) if not p.is_source}
        self._dt_s = dt_ms * MS

    def __getitem__(self, name):
        q = self._index[name]
        a, b = self._cuts[q], self._cuts[q + 1]
        return self._local[a:b], (self._step[a:b] * self._dt_s) / MS  # Brian2's t = n * dt, in ms

    def between(self, a_ms: float, b_ms: float) -> dict:
        """``name -> (cell, t_ms)`` of the spikes with ``a_ms <= t < b_ms``
        (what masking every population's times gives), found by bisection:
        each population's spikes are in time order. A recording's windows
        each take their own spikes this way; masking made every window pay
        for every spike of the run, and made its times in float64."""
        s_a, s_b = self._first_step(a_ms), self._first_step(b_ms)
        out = {}
        for name, q in self._index.items():
            steps = self._step[self._cuts[q] : self._cuts[q + 1]]
            lo = self._cuts[q] + np.searchsorted(steps, s_a)
            hi = self._cuts[q] + np.searchsorted(steps, s_b)
            out[name] = self._local[lo:hi], (self._step[lo:hi] * self._dt_s) / MS
        return out

    def _first_step(self, t_ms: float) -> int:
        """The first step whose time, as :meth:`__getitem__` computes it, is
        at or after ``t_ms``."""
        n = max(0, int(np.floor(t_ms * MS / self._dt_s)) - 2)
        while (np.float64(n) * self._dt_s) / MS < t_ms:
            n += 1
        return n

    def __iter__(self):
        return iter(self._index)

    def __len__(self):
        return len(self._index)


class BinStream:
    """Hands each counting bin to ``RunSettings.on_bin`` as the run passes
    its end (:meth:`.fast._Run.simulate` stops there), then drops the spikes no
    delay reaches any more, counting those in the counting window first:
    the log then holds a bin and the longest delay, not the whole run."""

    def __init__(self, name: str, tab: ft.EngineTables, chosen: dict, run, settings: RunSettings):
        self.run, self.settings, self.on_bin, self.tab = run, settings, settings.on_bin, tab
        self.started = (time.perf_counter(), time.process_time())  # (the run's start: FastBackend.simulate sets it)
        self.edges = [end for end, snapshot in segments(settings) if snapshot]
        self.edges_ms = settings.count_bins_ms
        self.reach = run.reach
        pops = lif_populations(tab.network)
        self.cells = {p.name: slice(run.first[p.name], run.first[p.name] + chosen[p.name].size) for p in pops}
        self.template = SimulationResult(
            network=tab.network,
            backend=name,
            sites=chosen,
            counts={},
            count_window_ms=0.0,
            simulated_ms=settings.duration_ms,
            dt_ms=settings.dt_ms,
        )
        self.starts = np.ascontiguousarray(run.cells[:, 0])
        # (the tables' kept kernel mass, rounded once: run_stats rounds 174 projections' for
        # every bin's stats otherwise, half of its 0.14 ms)
        self.kept_kernel_mass = {k: round(v, 4) for k, v in tab.kept_mass.items()}
        self.counts = np.zeros(run.state.size, dtype=np.int64)  # the whole counting window's
        self.counted_to = first_step_at(settings.count_from_ms, settings.dt_ms)
        self.dropped = 0
        self.j = 0  # the next edge to reach
        self.seconds = self.cpu_seconds = 0.0  # spent by on_bin (reading the bins), not simulating

    def next_stop(self, n: int) -> int:
        return self.edges[self.j] if self.j < len(self.edges) else self.run.n_steps

    def reached(self, n: int):
        from .counting import count_cells

        while self.j < len(self.edges) and self.edges[self.j] <= n:
            if self.j:
                self._hand_over(self.j - 1, n)
            self.j += 1
            keep = max(0, n - self.reach)  # (the next bin starts at n: its spikes are all still to come)
            if keep > self.counted_to:
                ids, step_start = self.run.spikes()
                count_cells(ids, step_start[self.counted_to], step_start[keep], self.counts)
                self.counted_to = keep
            self.dropped += self.run.forget_before(keep, n)

    def skipping(self, n: int) -> int:
        """The run skips from step ``n`` on (:meth:`.run.Run.skip`), forgetting its log:
        the log's spikes are counted first; returns the first step of the bin
        being filled, whose log position is still read."""
        from .counting import count_cells

        ids, step_start = self.run.spikes()
        count_cells(ids, step_start[self.counted_to], step_start[n], self.counts)
        self.counted_to = n
        self.dropped += ids.size
        return self.edges[self.j - 1] if self.j else 0

    def _hand_over(self, k: int, n: int):
        from .counting import BinCounts

        ids, step_start = self.run.spikes()
        a, b = self.edges[k], self.edges[k + 1]
        lo, hi = int(step_start[a]), int(step_start[b])
        counts = BinCounts(ids[lo:hi].copy(), self.cells, self.counts.size, b - a)
        spikes = None
        if self.settings.record_spikes:
            spikes = SpikeTrains(
                self.template.network,
                ids[lo:hi],
                step_start[a : b + 1] - lo,
                self.starts,
                self.settings.dt_ms,
                first_step=a,
            )
        t, cpu = time.perf_counter(), time.process_time()
        # (the run so far: its record if the caller stops it here, as a stream that ends does)
        self.template.stats = run_stats(self.tab, self.run, self, n)
        result = bin_result(self.template, counts, self.edges_ms[k], self.edges_ms[k + 1], spikes)
        result.timings_s = {
            "run": t - self.started[0] - self.seconds,
            "run_cpu": cpu - self.started[1] - self.cpu_seconds,
        }
        self.on_bin(k, result)
        self.seconds += time.perf_counter() - t
        self.cpu_seconds += time.process_time() - cpu

    def final_counts(self) -> np.ndarray:
        """Each cell's spikes in the counting window, once the run is over."""
        from .counting import count_cells

        ids, step_start = self.run.spikes()
        count_cells(ids, step_start[self.counted_to], ids.size, self.counts)
        return self.counts


def simulation_result(
    name: str, tab: ft.EngineTables, chosen: dict, run, settings: RunSettings, stream: BinStream | None = None
) -> SimulationResult:
    from .counting import bin_counts, count_cells

    ids, step_start = run.spikes()
    n = run.state.size
    pops = lif_populations(tab.network)
    cells = {p.name: slice(run.first[p.name], run.first[p.name] + chosen[p.name].size) for p in pops}
    if stream is not None:
        all_counts = stream.final_counts()
    else:
        all_counts = np.zeros(n, dtype=np.int64)
        count_cells(ids, step_start[first_step_at(settings.count_from_ms, settings.dt_ms)], ids.size, all_counts)
    counts = {p.name: all_counts[cells[p.name]] for p in pops}
    binned = None
    if settings.count_bins_ms is not None and stream is None:
        ends = [end for end, snapshot in segments(settings) if snapshot]
        cuts = step_start[ends]
        # a cell fires at most once a step, so a bin of at most 65535 steps
        # (32 s at 0.5 ms) fits uint16: the array holds every cell in every
        # bin (the whole network over a recording is ~1e7 cells a bin), and
        # half the bytes are half the memory that grows with a recording
        fits = len(ends) < 2 or int(np.diff(ends).max()) <= np.iinfo(np.uint16).max
        per_bin = np.zeros((max(cuts.size - 1, 0), n), dtype=np.uint16 if fits else np.int32)
        bin_counts(ids, cuts.astype(np.int64), per_bin)
        binned = {p.name: per_bin[:, cells[p.name]] for p in pops}
    spikes = (
        SpikeTrains(tab.network, ids, step_start, np.ascontiguousarray(run.cells[:, 0]), settings.dt_ms)
        if settings.record_spikes and stream is None
        else None
    )
    state = {}
    if settings.record_state:
        values = run.final_state()
        for p in pops:
            state[p.name] = {
                var: values[cells[p.name], k] / MV
                for k, var in enumerate(("v", "I_exc", "I_inh"))
                if var in settings.record_state
            }
    stats = run_stats(tab, run, stream)
    return SimulationResult.of_run(
        settings,
        network=tab.network,
        backend=name,
        sites={p.name: chosen[p.name] for p in pops},
        counts=counts,
        spikes=spikes,
        state=state,
        binned_counts=binned,
        stats=stats,
    )


def run_stats(tab: ft.EngineTables, run, stream: BinStream | None = None, n: int | None = None) -> dict:
    """The engine's counters of ``run`` (its synaptic events in all and per
    projection, closed-form advances, active cell-steps, cells handed input,
    input spikes and spikes; with :data:`.lif.PHASES`, the cycles of each
    phase as ``cycles_<phase>`` and the synaptic events by kind of
    projection) before step ``n`` (default: the whole run),
    with the tables' kept kernel mass and taps: a result's ``stats``."""
    from .deliver import N_ACTIVE_STEPS, N_ADVANCES, N_EVENTS, N_FLUSHED, PH_ACTIVE, PHASE_NAMES
    from .lif import PHASES

    totals, n_input = run.totals, run.input_spikes(n)
    phases = {}
    if PHASES:
        phases = {f"cycles_{name}": int(totals[PH_ACTIVE + k]) for k, name in enumerate(PHASE_NAMES)}
        conv = tab.prj[:, ft.J_KIND] == ft.CONV
        phases.update(
            synaptic_events_conv=int(run.events[conv].sum()), synaptic_events_resize=int(run.events[~conv].sum())
        )
    kept = stream.kept_kernel_mass if stream is not None else {k: round(v, 4) for k, v in tab.kept_mass.items()}
    return {
        "kept_kernel_mass": dict(kept),
        "taps": dict(tab.taps),
        # (the counts as Python ints in one call: a bin's stats are made twice a 10 ms hop)
        "synaptic_events": dict(zip([pr.name for pr in tab.network.projections], run.events.tolist(), strict=True)),
        "synaptic_events_total": int(totals[N_EVENTS]),
        "closed_form_advances": int(totals[N_ADVANCES]),
        "active_cell_steps": int(totals[N_ACTIVE_STEPS]),
        "cells_handed_input": int(totals[N_FLUSHED]),
        "cells": run.n_present,
        "input_spikes": n_input,
        "spikes": int(run.log_length + (stream.dropped if stream else 0) - n_input),
        "steps_skipped": run.skipped,
        **phases,
    }
