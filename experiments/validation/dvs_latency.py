"""Latency of the continuous spiking run on dvs.es (issue 11, item 3), from its spike trains.

Used by ``experiments.validation.dvs_biplane --model spiking``. Two measures, both on
maps decoded from spike counts accumulated in steps of ``step_ms``:

* **window latency**: from a window's start, how long until the map of the
  spikes counted since that start has a grouping map within Pearson r >= 0.9
  of the window's final grouping map (the one read out over the window's
  span plus the read-out lag). Reported as the first such time; "never"
  when r stays below within the window's span plus the lag;
* **plane latency**: from the run's first events (the first window's start),
  how long until the grouping peak of the map of every spike so far sits on
  the plane (inside the filled outline of the events of the window holding
  that time).
"""

from __future__ import annotations

import numpy as np

from snn_fg.models.spiking.decode import decode_rates
from snn_fg.scoring.metrics import grouping_peak

#: r a window's running grouping map must reach against its final one
R_WITHIN = 0.9


class _Counter:
    """Spike counts per cell of every population since a chosen time, moved
    forward in time step by step (spikes sorted by time once)."""

    def __init__(self, run):
        self.run = run
        self.trains = {}
        for name, (cells, t) in run.result.spikes.items():
            order = np.argsort(t, kind="stable")
            self.trains[name] = (cells[order], t[order])

    def reset(self, t_from: float):
        self.t_from = self.t_now = t_from
        self.counts = {n: np.zeros(self.run.result.sites[n].size, dtype=np.int64) for n in self.trains}

    def advance(self, t_to: float):
        for name, (cells, t) in self.trains.items():
            a, b = np.searchsorted(t, [self.t_now, t_to])
            if b > a:
                self.counts[name] += np.bincount(cells[a:b], minlength=self.counts[name].size)
        self.t_now = t_to

    def grouping(self) -> np.ndarray:
        span_s = max(self.t_now - self.t_from, 1e-9) / 1000.0
        rates = {n: c / span_s for n, c in self.counts.items()}
        return decode_rates(self.run.network, self.run.result.sites, rates)[2]


def _pearson(a, b) -> float:
    a, b = a.ravel() - a.mean(), b.ravel() - b.mean()
    d = np.sqrt((a * a).sum() * (b * b).sum())
    return float((a * b).sum() / d) if d > 0 else float("nan")


def window_latencies(run, maps, step_ms: float) -> list[dict]:
    """Per window: r of the running map against the final one at each step,
    and the first time (ms from the window's start) it reaches :data:`R_WITHIN`."""
    counter, out = _Counter(run), []
    lag = run.simulation["readout_lag_ms"]
    for (a, b), m in zip(run.spans, maps):
        start = a - lag
        counter.reset(start)
        times, rs = [], []
        t = start
        while t < b - 1e-9:
            t = min(t + step_ms, b)
            counter.advance(t)
            times.append(round(t - start, 6))
            rs.append(_pearson(counter.grouping(), m.grouping))
        hit = next((tt for tt, r in zip(times, rs) if r >= R_WITHIN), None)
        out.append({"t_ms": times, "r": rs, "latency_ms": hit})
    return out


def plane_latency(run, regions, step_ms: float, until_ms: float) -> dict:
    """The grouping peak of all spikes since the run's start, step by step,
    and the first time it lies on the plane (``regions[k]``: the plane of window k)."""
    counter = _Counter(run)
    lag = run.simulation["readout_lag_ms"]
    starts = [a - lag for a, _ in run.spans]
    start = starts[0]
    counter.reset(start)
    times, on = [], []
    t = start
    while t < min(until_ms, run.spans[-1][1]) - 1e-9:
        t += step_ms
        counter.advance(t)
        g = counter.grouping()
        k = max(0, int(np.searchsorted(starts, t, side="right")) - 1)
        r, c = grouping_peak(g)
        times.append(round(t - start, 6))
        on.append(bool(g.max() > 0 and regions[k][r, c]))
    hit = next((tt for tt, o in zip(times, on) if o), None)
    return {"t_ms": times, "peak_on_plane": on, "latency_ms": hit}
