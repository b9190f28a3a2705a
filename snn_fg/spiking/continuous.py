"""One network over a whole recording: :func:`run_spiking_windows`.

A neuromorphic chip runs one fixed network on the event stream as it comes.
So does this: the network is built (and, for backends that unroll it,
instantiated) once for the whole recording, every event becomes one input
spike at its own timestamp (no replay, no per-window rebuild), and each
window's maps are decoded from the spikes counted inside that window,
shifted by a read-out lag: the window ``[t_start, t_end)`` is read from the
spikes in ``[t_start + lag, t_end + lag)``, since the network needs a few
synaptic delays and membrane time constants to answer. The backend counts
spikes per window through :attr:`~snn_fg.backends.RunSettings.count_bins_ms`,
and each window is decoded as soon as the run has passed the end of its
read-out span. :func:`run_spiking_windows` lets the backend forget each bin
once it is read (:attr:`~snn_fg.backends.RunSettings.on_bin`), so that a long
recording does not need the memory of all its spikes.

The input gains are calibrated once, to the mean event rate of an active
pixel inside a window (events per active pixel per window length, averaged
over the windows that have events), the counterpart of a frame's rate.
"""
from __future__ import annotations

import dataclasses
import time
from types import SimpleNamespace

import numpy as np

from .. import validate as check
from ..backends import DEFAULT_BACKEND, RunSettings, as_backend
from ..backends.base import each_bin
from ..errors import InputError
from ..frames.pool import pool_events, pool_frame, pooled_shape, unpool_maps
from ..maps import Maps
from .api import default_instantiate, resolve_network, run_params, stderr_log
from .decode import decode
from .inputs import event_spikes
from .record import SpikingRecord

#: Default read-out lag (ms): see the module docstring and
#: ``experiments.validation.dvs_latency`` for how long the network takes to answer.
READOUT_LAG_MS = 20.0


def _window_rate(windows, dt_ms: float) -> float:
    """Mean rate (Hz) of an active pixel inside a window, over windows with events."""
    rates = []
    for w in windows:
        ev = w.events
        if not len(ev):
            continue
        active = int(np.count_nonzero(w.pos) + np.count_nonzero(w.neg))
        span_s = max((w.t_end_us - w.t_start_us) / 1e6, dt_ms / 1000.0)
        rates.append(len(ev) / max(active, 1) / span_s)
    return float(np.mean(rates)) if rates else 0.0


def _spike_rate(inp, windows, t0_us: float, dt_ms: float) -> float:
    """Mean rate (Hz) of an active spike source inside a window, over windows
    with spikes: what the input adapter (pooling, refractory period) passes
    on, counted as :func:`_window_rate` counts events."""
    rates = []
    for w in windows:
        a = int(np.floor((w.t_start_us - t0_us) / (dt_ms * 1000.0)))
        b = max(int(np.floor((w.t_end_us - t0_us) / (dt_ms * 1000.0))), a + 1)
        lo, hi = np.searchsorted(inp.steps, [a, b])
        idx = inp.indices[lo:hi]
        idx = idx[idx < inp.clock_index]          # (not the window clock)
        if idx.size:
            rates.append(idx.size / np.unique(idx).size / ((b - a) * dt_ms / 1000.0))
    return float(np.mean(rates)) if rates else 0.0


def _all_events(windows):
    """The events of every window once (overlapping windows share events)."""
    ev = np.concatenate([w.events for w in windows]) if windows else np.zeros(0)
    if len(windows) > 1 and any(b.t_start_us < a.t_end_us for a, b in zip(windows, windows[1:])):
        ev = np.unique(ev)
    return ev


def run_spiking_windows(windows, *, params=None, spiking=None, network=None, backend=DEFAULT_BACKEND,
                        backend_options: dict | None = None, dt_ms: float = 0.5,
                        readout_lag_ms: float = READOUT_LAG_MS, calibrate: bool = True, feedback: bool = True,
                        instantiate: str | None = None, record_spikes: bool = True, window_clock: bool = True,
                        progress: bool = True, log=None, source: str = "<recording>") -> list[Maps]:
    """Run the spiking network once over consecutive windows of a recording.

    Parameters
    ----------
    windows : sequence of EventWindow
        The recording cut into windows (:func:`snn_fg.events.iter_windows`),
        all from one sensor, in time order.
    params, spiking, network, backend, backend_options, dt_ms, calibrate, feedback, instantiate, record_spikes
        As for :func:`~snn_fg.spiking.run_spiking`.
    readout_lag_ms : float
        Each window is read from the spikes ``readout_lag_ms`` later than
        its own time span; the simulation runs that long past the last window.
    window_clock : bool
        Fire the network's window clock (if it has one) as every window
        starts: its inhibitory pulse holds the grouping cells silent until
        the previous window's feedback has faded, so each window's light and
        dark grouping cells compete afresh. ``False``: the clock stays silent
        and the network carries its state from window to window.
    progress, log
        Stage messages and a progress bar on stderr, or ``log`` receiving them.

    Returns
    -------
    list of Maps
        One per window, each with its own spiking record; ``params`` says
        ``simulation.mode = "continuous"``, ``simulated_ms`` and
        ``network_builds = 1``.

    Examples
    --------
    >>> from snn_fg.events import image_to_events, iter_windows
    >>> from snn_fg.params import ModelParams
    >>> from snn_fg.scenes import disc
    >>> rec = image_to_events(disc(radius=10).image)
    >>> wins = list(iter_windows(rec, window_ms=2))
    >>> maps = run_spiking_windows(wins, params=ModelParams(levels=2), progress=False)
    >>> len(maps) == len(wins), maps[0].params["simulation"]["network_builds"]
    (True, 1)
    """
    run = simulate_windows(windows, params=params, spiking=spiking, network=network, backend=backend,
                           backend_options=backend_options, dt_ms=dt_ms, readout_lag_ms=readout_lag_ms,
                           calibrate=calibrate, feedback=feedback, instantiate=instantiate,
                           record_spikes=record_spikes, window_clock=window_clock, progress=progress, log=log,
                           source=source, keep_run=False)
    return window_maps(run)


@dataclasses.dataclass
class ContinuousRun:
    """One simulation over a recording's windows (:func:`simulate_windows`):
    the network, the backend's result (spike counts per bin between
    ``edges`` and spike trains if recorded, unless the run was not kept),
    each window's read-out span ``spans[k]`` (ms from the first window's
    start, lag included) and each window's decoded maps and record
    (``decoded[k]``: ``fg_x, fg_y, grouping, SpikingRecord``) with the
    ``perf_counter()`` time it was decoded at (``decoded_at[k]``)."""

    windows: list
    network: object
    origin: dict
    backend: object
    result: object
    edges: list
    spans: list
    simulation: dict
    t_start: float
    decoded: list
    decoded_at: list


def simulate_windows(windows, *, params=None, spiking=None, network=None, backend=DEFAULT_BACKEND,
                     backend_options: dict | None = None, dt_ms: float = 0.5,
                     readout_lag_ms: float = READOUT_LAG_MS, calibrate: bool = True, feedback: bool = True,
                     instantiate: str | None = None, record_spikes: bool = True, window_clock: bool = True,
                     progress: bool = True, log=None, source: str = "<recording>",
                     keep_run: bool = True) -> ContinuousRun:
    """The simulation half of :func:`run_spiking_windows` (same parameters):
    one run over every window, each window decoded as the run passes the
    end of its read-out span; :func:`window_maps` makes their maps.

    ``keep_run=False`` lets the backend forget each counting bin once it is
    read (``RunSettings.on_bin``): the result then has no per-bin counts
    and no spike trains, and the memory need not grow with the recording.
    ``True`` keeps them in ``ContinuousRun.result`` (for analyses of the
    whole run's spikes)."""
    t_start = time.perf_counter()
    windows = list(windows)
    if not windows:
        raise InputError(source, "no window to process")
    lag = check.number("run_spiking_windows", "readout_lag_ms", readout_lag_ms, lo=0)
    h, w = windows[0].pos.shape
    t0 = windows[0].t_start_us
    events = _all_events(windows)
    if not len(events):
        raise InputError(source, "no window has an event: nothing to simulate")
    net, origin = resolve_network(network, params, spiking, (h, w), feedback)
    pool = net.params.input_pool
    inp = event_spikes(pool_events(events, pool), (*pooled_shape((h, w), pool)[::-1], 2), dt_ms, replay=False,
                       source=source, t0_us=t0, refractory_ms=net.input_refractory_ms)
    clock = bool(check.flag("run_spiking_windows", "window_clock", window_clock) and net.by_role("clock"))
    if clock:      # the window clock fires as every window starts
        inp = inp.with_clock([int(np.floor((x.t_start_us - t0) / (dt_ms * 1000.0))) for x in windows])
    adapted = pool > 1 or net.input_refractory_ms > 0
    rate = _spike_rate(inp, windows, t0, dt_ms) if adapted else _window_rate(windows, dt_ms)
    if calibrate and not np.isclose(net.input_rate_hz, rate, rtol=1e-12, atol=0):
        origin["calibrated"] = {"from_hz": net.input_rate_hz, "to_hz": rate, "rate": "per active pixel in a window"}
        net = net.calibrated(rate)
    spans = [_read_out_span(x, t0, lag, dt_ms) for x in windows]
    edges = sorted({t for span in spans for t in span})
    duration = edges[-1]
    say = log if log is not None else (stderr_log if progress else None)
    sim_backend = as_backend(backend, backend_options)
    instantiate = instantiate or default_instantiate(sim_backend, inp)
    reader = _WindowReader(windows, spans, edges, pool)
    settings = RunSettings(duration_ms=duration, dt_ms=dt_ms, count_from_ms=edges[0], record_spikes=record_spikes,
                           instantiate=instantiate, count_bins_ms=tuple(edges), log=say, progress=progress,
                           on_bin=None if keep_run else reader)
    result = sim_backend.simulate(net, inp, settings)
    if result.binned_counts is not None:        # (a backend that kept its bins)
        for k, bin_result in each_bin(result):
            reader(k, bin_result)
    simulation = {"mode": "continuous", "simulated_ms": duration, "network_builds": 1, "readout_lag_ms": lag,
                  "dt_ms": dt_ms, "input": "events", "rate_hz_used": rate, "merged_input_spikes": inp.merged,
                  "instantiate": instantiate, "record_spikes": bool(record_spikes),
                  "window_clock": clock}
    return ContinuousRun(windows, net, origin, sim_backend, result, edges, spans, simulation, t_start,
                         reader.decoded, reader.decoded_at)


def _read_out_span(window, t0_us: float, lag_ms: float, dt_ms: float) -> tuple[float, float]:
    """A window's read-out span (ms from the first window's start, lag
    included) on the step grid, at least one step long: a recording's last
    window can be shorter than a step (it ends 1 us after the last event),
    and a span of no steps would count no spikes."""
    a = round(((window.t_start_us - t0_us) / 1000.0 + lag_ms) / dt_ms)
    b = round(((window.t_end_us - t0_us) / 1000.0 + lag_ms) / dt_ms)
    return a * dt_ms, max(b, a + 1) * dt_ms


def _bins_of(span, edges) -> tuple[int, int]:
    """The counting bins ``k0 .. k1 - 1`` that make up a read-out span (spans
    are made of edges)."""
    return int(np.searchsorted(edges, span[0])), int(np.searchsorted(edges, span[1]))


class _WindowReader:
    """Receives a run's counting bins in order (``RunSettings.on_bin``) and
    decodes each window as soon as the last bin of its read-out span is in:
    ``decoded[k] = (fg_x, fg_y, grouping, SpikingRecord)``. Only the windows
    still being read hold their counts and spikes."""

    def __init__(self, windows, spans, edges, pool: int = 1):
        self.windows, self.edges, self.pool = windows, edges, pool
        self.bins = [_bins_of(span, edges) for span in spans]
        self.reading: dict = {}
        self.decoded: list = [None] * len(windows)
        self.decoded_at: list = [None] * len(windows)      # perf_counter() when each window was decoded

    def __call__(self, k: int, result):
        for i, (k0, k1) in enumerate(self.bins):
            if not k0 <= k < k1:
                continue
            counts, spikes = self.reading.setdefault(i, ({}, []))
            for name, c in result.counts.items():
                counts[name] = counts[name] + c if name in counts else c.astype(np.int64)
            if result.spikes is not None:
                spikes.append(result.spikes)
            if k == k1 - 1:
                del self.reading[i]
                self.decoded[i] = self._decode(i, result, counts, spikes)
                self.decoded_at[i] = time.perf_counter()

    def _decode(self, i, result, counts, spikes):
        k0, k1 = self.bins[i]
        trains = None
        if spikes:
            trains = {n: (np.concatenate([s[n][0] for s in spikes]), np.concatenate([s[n][1] for s in spikes]))
                      for n in spikes[0]}
        window_result = dataclasses.replace(result, counts=counts, count_window_ms=self.edges[k1] - self.edges[k0],
                                            spikes=trains)
        w = self.windows[i]
        fg_x, fg_y, grouping = unpool_maps(*decode(window_result)[:3], w.pos | w.neg, self.pool)
        on, off = pool_frame(w.pos, w.neg, self.pool)
        masks = SimpleNamespace(on=on != 0, off=off != 0)
        return fg_x, fg_y, grouping, SpikingRecord.from_result(window_result, masks, self.edges[k0])


def window_maps(run: ContinuousRun) -> list[Maps]:
    """Each window's maps, decoded from the spikes counted in its read-out
    span, with the whole run's parameters; ``timings_s["window"]`` is the
    wall time from the previous window's decoding (the first: from the
    run's start) to this one's, what the stream spent on the window."""
    out = []
    before = [run.t_start] + run.decoded_at[:-1]
    for span, (fg_x, fg_y, grouping, rec), t0, t1 in zip(run.spans, run.decoded, before, run.decoded_at):
        k0, k1 = _bins_of(span, run.edges)
        simulation = {**rec.timing(), **run.simulation, "count_from_ms": run.edges[k0],
                      "count_to_ms": run.edges[k1]}
        params = run_params(run.network, run.origin, run.backend, run.result, rec.populations, simulation,
                            run.t_start)
        params["timings_s"]["window"] = t1 - t0
        out.append(Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), params,
                        rec.arrays()))
    return out
