"""One simulation of the Loihi 2 backend: its state, the loop called a
stretch of steps at a time, each counting bin as the run passes its end,
and the :class:`~snn_fg.backends.base.SimulationResult` handed back."""

from __future__ import annotations

import time

import numpy as np

from .. import cancel
from ..base import RunSettings, SimulationResult, bin_result, lif_populations, segments
from . import kernel as k
from . import rest
from .tables import InputFeed, Loihi2Tables

#: initial room of the spike log (spikes); it grows when a step may not fit
LOG_START = 1 << 16


def step_of(t_ms: float, dt_ms: float) -> int:
    """The step at time ``t_ms``, as the export's ``run.py`` counts it (and
    :func:`~snn_fg.backends.base.segments` the bins' edges)."""
    return int(round(t_ms / dt_ms))


class Run:
    """The state of one simulation: every cell's current ``u``, voltage
    ``v``, last spike step and spike total (counts are differences of the
    totals), the slots of input ahead (``pending``) and, if spikes are
    recorded, the spike log (since the last bin handed over)."""

    def __init__(self, tab: Loihi2Tables, chosen: dict, inputs, settings: RunSettings):
        self.tab, self.chosen, self.settings = tab, chosen, settings
        self.net = k.Net(*(getattr(tab, name) for name in k.Net._fields))
        self.n_steps = step_of(settings.duration_ms, settings.dt_ms)
        n = tab.n_cells
        self.pops = lif_populations(tab.network)
        self.flag = np.full(n, k.F_ABSENT, np.uint16)
        for p in self.pops:
            self.flag[tab.first[p.name] + chosen[p.name]] = k.F_ACTIVE
        self.act = np.flatnonzero(self.flag == k.F_ACTIVE).astype(np.int32)
        self.n_present = int(self.act.size)
        self.act.resize(n, refcheck=False)
        self.state = np.zeros((n, rest.N_STATE_COLUMNS), np.int32)
        self.state[:, rest.S_LAST] = -(10**9)
        self.wake, self.wake_n = np.zeros((tab.depth, n), np.int32), np.zeros(tab.depth, np.int64)
        self.total = np.zeros(n, np.int64)
        self.merged = np.zeros(n, np.int32)
        self.pending = np.zeros((tab.depth, n), np.int64)
        self.buf, self.acc = np.zeros(n, np.int32), np.zeros(n, np.int64)
        self.mark, self.touched = np.zeros(n, np.uint8), np.zeros(n, np.int32)
        self.cnt = np.zeros(len(tab.pops), np.int64)
        self.log = np.zeros(LOG_START if settings.record_spikes else 1, np.int32)
        self.step_start = np.zeros(self.n_steps + 1, np.int64)
        self.scalars = np.array([0, int(settings.record_spikes), self.n_present], np.int64)
        self.counters = np.zeros(k.N_COUNTERS, np.int64)
        self.feed = InputFeed(tab, inputs, self.n_steps)
        self.count_from = step_of(settings.count_from_ms, settings.dt_ms)
        self.edges = [end for end, snapshot in segments(settings) if snapshot]
        self.streamed = settings.on_bin is not None
        self.at_count_from = self.at_edge = None  # the totals when the window opened, at the last edge
        self.bins = []  # each bin's counts (every cell), unless handed over
        self.read_s = self.read_cpu_s = 0.0  # spent by on_bin

    def simulate(self, chunk: int, bar=None):
        """Every step, stopping at chunk ends (progress, Ctrl-C), the input's
        block ends, the counting window's start and the bins' edges."""
        stops = sorted({self.count_from, *self.edges, self.n_steps})
        n = 0
        while True:
            self._at(n)
            if n >= self.n_steps:
                return
            a, b, in_ptr, in_ids = self.feed.block(n)
            end = min(n + chunk, b, next(s for s in stops if s > n))
            self.in_ptr, self.in_ids = in_ptr, in_ids
            cells = k.Cells(*(getattr(self, name) for name in k.Cells._fields))  # (the log may have grown)
            reached = k.run_steps(n, end, a, self.net, cells)
            if reached < end:  # the next step may not fit in the log
                self.log = np.concatenate([self.log, np.zeros(max(self.log.size, self.n_present), np.int32)])
            if bar is not None:
                bar(reached - n)
            cancel.check()
            n = reached
            self.step_start[n] = self.scalars[0]

    def _at(self, n: int):
        """The run is at step ``n`` (not yet run): open the counting window, close a bin."""
        if n == self.count_from:
            self.at_count_from = self.total.copy()
        if n not in self.edges:
            return
        j = self.edges.index(n)
        if j:
            self._bin(j - 1, self.total - self.at_edge)
        self.at_edge = self.total.copy()

    def _bin(self, j: int, counts: np.ndarray):
        """Bin ``j``'s counts (every cell) to ``on_bin`` with its spikes, or kept for the result."""
        if not self.streamed:
            fits = self.edges[j + 1] - self.edges[j] <= np.iinfo(np.uint16).max  # (a cell fires once a step at most)
            self.bins.append(counts.astype(np.uint16 if fits else np.int32))
            return
        spikes = self.spikes_between(self.edges[j], self.edges[j + 1]) if self.settings.record_spikes else None
        ms = self.settings.count_bins_ms
        t, cpu = time.perf_counter(), time.process_time()
        self.settings.on_bin(j, bin_result(self.template(), self.per_population(counts), ms[j], ms[j + 1], spikes))
        self.read_s += time.perf_counter() - t
        self.read_cpu_s += time.process_time() - cpu
        self.scalars[0] = 0  # (the bin's spikes are handed over: the log starts again)
        self.step_start[self.edges[j + 1]] = 0

    def per_population(self, values: np.ndarray) -> dict:
        """Values indexed (last) by cell number as population name -> those of its present cells."""
        return {p.name: values[..., self.tab.first[p.name] + self.chosen[p.name]] for p in self.pops}

    def spikes_between(self, a: int, b: int) -> dict:
        """The logged spikes of steps ``a`` to ``b - 1`` as population name
        -> ``(cell, t_ms)``, ``cell`` indexing the population's sites."""
        lo, hi = int(self.step_start[a]), int(self.step_start[b])
        ids = self.log[lo:hi].astype(np.int64)
        steps = np.repeat(np.arange(a, b), np.diff(self.step_start[a : b + 1]))
        out = {}
        for p in self.pops:
            f, sites = self.tab.first[p.name], self.chosen[p.name]
            sel = (ids >= f) & (ids < f + p.size)
            local = ids[sel] - f
            cell = local if sites.size == p.size else np.searchsorted(sites, local)
            out[p.name] = (cell.astype(np.int32), steps[sel] * self.settings.dt_ms)
        return out

    def template(self) -> SimulationResult:
        """A result with this run's network, cells and backend (a bin's, or the whole run's)."""
        return SimulationResult.of_run(
            self.settings,
            network=self.tab.network,
            backend="loihi2",
            sites={p.name: self.chosen[p.name] for p in self.pops},
            counts={},
        )

    def result(self) -> SimulationResult:
        """The whole run's result (after :meth:`simulate`)."""
        s, res = self.settings, self.template()
        res.counts = self.per_population(self.total - self.at_count_from)
        if self.bins:
            res.binned_counts = self.per_population(np.stack(self.bins))
        if s.record_spikes and not self.streamed:
            res.spikes = self.spikes_between(0, self.n_steps)
        if "v" in s.record_state:
            t = self.tab
            k.catch_up_all(self.n_steps - 1, t.pops, t.pop_of, self.flag, self.state)
            v = self.per_population(self.state[:, rest.S_V])
            for p in self.pops:
                res.state[p.name] = {"v": v[p.name] / self.tab.unit_per_mv[p.name] + p.neuron.v_reset_mv}
        synapses_in = {p.name: 0 for p in self.pops}
        for pr in self.tab.network.projections:
            synapses_in[pr.target] += self.tab.synapses.get(pr.name, 0)
        res.stats = {
            "cells": self.n_present,
            "synapses_in": synapses_in,
            "synaptic_events_total": int(self.counters[k.K_EVENTS]),
            "input_spikes": self.feed.spikes,
            "spikes": int(sum(int(c.sum()) for c in self.per_population(self.total).values())),
            "max_a_in": int(self.counters[k.K_MAX_A_IN]),
            "u_wraps": int(self.counters[k.K_U_WRAPS]),
            "v_saturated": int(self.counters[k.K_V_SATURATED]),
            "active_cell_steps": int(self.counters[k.K_UPDATES]),
            "wakes": int(self.counters[k.K_WAKES]),
        }
        return res
