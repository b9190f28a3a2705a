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

from ..backends import RunSettings
from ..backends.base import each_bin
from ..errors import InputError
from ..pyramid.pool import pool_events, pool_frame, pooled_shape, unpool_maps
from ..lowering.input_spikes import event_spikes
from ..maps import Maps
from .decode import decode
from .options import SpikingOptions
from .record import SpikingRecord, run_provenance


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


def run_spiking_windows(windows, *, source: str = "<recording>", options: SpikingOptions | None = None,
                        **keywords) -> list[Maps]:
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
    options : SpikingOptions, optional
        All of the above made once, instead of keywords (its frame part is
        not used).
    source : str
        What the windows come from, for error messages.

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
    run = simulate_windows(windows, source=source, keep_run=False,
                           options=SpikingOptions.of("run_spiking_windows", options, keywords, frame=False))
    return window_maps(run)


def stream_spiking_windows(windows, on_window, *, source: str = "<recording>",
                           options: SpikingOptions | None = None, **keywords) -> dict:
    """:func:`run_spiking_windows` handing each window's maps to
    ``on_window(k, maps)`` as soon as the run has passed the end of its
    read-out span, instead of returning them all at the end: nothing of a
    window is kept once handed over. Each window's ``params`` are those
    known then (a backend that streams its bins, such as the fast engine,
    has no statistics or timings of the whole run yet); returns the whole
    run's, to update the run's parameters with (``counts``,
    ``backend_stats``, ``kept_kernel_mass``, ``timings_s``)."""
    opts = SpikingOptions.of("stream_spiking_windows", options, keywords, frame=False)
    run = simulate_windows(windows, source=source, keep_run=False, options=opts, on_window=on_window)
    whole = run_provenance(run.network, run.origin, run.backend, run.result, {}, run.simulation, run.t_start)
    return {k: whole[k] for k in ("counts", "backend_stats", "kept_kernel_mass", "timings_s")}


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


def simulate_windows(windows, *, source: str = "<recording>", keep_run: bool = True,
                     options: SpikingOptions | None = None, on_window=None, **keywords) -> ContinuousRun:
    """The simulation half of :func:`run_spiking_windows` (same parameters):
    one run over every window, each window decoded as the run passes the
    end of its read-out span; :func:`window_maps` makes their maps.

    ``keep_run=False`` lets the backend forget each counting bin once it is
    read (``RunSettings.on_bin``): the result then has no per-bin counts
    and no spike trains, and the memory need not grow with the recording.
    ``True`` keeps them in ``ContinuousRun.result`` (for analyses of the
    whole run's spikes). ``on_window(k, maps)``: each window's maps as it
    is decoded (:func:`stream_spiking_windows`), none kept in the result."""
    t_start = time.perf_counter()
    opts = SpikingOptions.of("simulate_windows", options, keywords, frame=False)
    sim, lag = opts.simulator, opts.recording.readout_lag_ms
    windows = list(windows)
    if not windows:
        raise InputError(source, "no window to process")
    events = _all_events(windows)
    if not len(events):
        raise InputError(source, "no window has an event: nothing to simulate")
    net, origin = opts.network.resolve(windows[0].pos.shape)
    inp, clock = _window_input(windows, events, net, sim.dt_ms, opts.recording.window_clock, source)
    t0 = windows[0].t_start_us
    adapted = net.params.input_pool > 1 or net.input_refractory_ms > 0
    rate = _spike_rate(inp, windows, t0, sim.dt_ms) if adapted else _window_rate(windows, sim.dt_ms)
    if opts.network.calibrate and not np.isclose(net.input_rate_hz, rate, rtol=1e-12, atol=0):
        origin["calibrated"] = {"from_hz": net.input_rate_hz, "to_hz": rate, "rate": "per active pixel in a window"}
        net = net.calibrated(rate)
    spans = [_read_out_span(x, t0, lag, sim.dt_ms) for x in windows]
    edges = sorted({t for span in spans for t in span})
    backend = sim.backend_object()
    instantiate = sim.cells_for(backend, inp)
    simulation = {"mode": "continuous", "simulated_ms": edges[-1], "network_builds": 1, "readout_lag_ms": lag,
                  "dt_ms": sim.dt_ms, "input": "events", "rate_hz_used": rate, "merged_input_spikes": inp.merged,
                  "instantiate": instantiate, "record_spikes": bool(sim.record_spikes),
                  "window_clock": clock}
    run = ContinuousRun(windows, net, origin, backend, None, edges, spans, simulation, t_start,
                        [None] * len(windows), [None] * len(windows))
    reader = _WindowReader(windows, spans, edges, net.params.input_pool, run, on_window)
    settings = RunSettings(duration_ms=edges[-1], dt_ms=sim.dt_ms, count_from_ms=edges[0],
                           record_spikes=sim.record_spikes, instantiate=instantiate, count_bins_ms=tuple(edges),
                           log=sim.say, progress=sim.progress, on_bin=None if keep_run else reader)
    run.result = backend.simulate(net, inp, settings)
    if run.result.binned_counts is not None:        # (a backend that kept its bins)
        for k, bin_result in each_bin(run.result):
            reader(k, bin_result)
    return run


def _window_input(windows, events, net, dt_ms: float, window_clock: bool, source: str):
    """The input spikes of the windows' ``events`` on the network's (pooled)
    grid, with the window clock firing as each window starts when
    ``window_clock`` is on and the network has one; and whether it does."""
    pool, t0 = net.params.input_pool, windows[0].t_start_us
    inp = event_spikes(pool_events(events, pool), (*pooled_shape(windows[0].pos.shape, pool)[::-1], 2), dt_ms,
                       replay=False, source=source, t0_us=t0, refractory_ms=net.input_refractory_ms)
    clock = bool(window_clock and net.by_role("clock"))
    if clock:
        inp = inp.with_clock([int(np.floor((x.t_start_us - t0) / (dt_ms * 1000.0))) for x in windows])
    return inp, clock


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
    into ``run.decoded[k] = (fg_x, fg_y, grouping, SpikingRecord)``, or as
    its maps to ``on_window(k, maps)``. Only the windows still being read
    hold their counts and spikes."""

    def __init__(self, windows, spans, edges, pool: int, run: ContinuousRun, on_window=None):
        self.windows, self.edges, self.pool, self.run, self.on_window = windows, edges, pool, run, on_window
        self.bins = [_bins_of(span, edges) for span in spans]
        self.reading: dict = {}
        self.last_at = run.t_start          # perf_counter() when the last window was decoded

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
                decoded, before, self.last_at = self._decode(i, result, counts, spikes), self.last_at, \
                    time.perf_counter()
                if self.on_window is None:
                    self.run.decoded[i], self.run.decoded_at[i] = decoded, self.last_at
                else:
                    self.on_window(i, _maps_of(self.run, i, decoded, result, self.last_at - before))

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
    before = [run.t_start] + run.decoded_at[:-1]
    return [_maps_of(run, k, decoded, run.result, t1 - t0)
            for k, (decoded, t0, t1) in enumerate(zip(run.decoded, before, run.decoded_at))]


def _maps_of(run: ContinuousRun, k: int, decoded, result, window_s: float) -> Maps:
    """Window ``k``'s maps from its ``decoded`` tuple, with the parameters
    of ``result`` (the whole run's, or the bin's while it runs)."""
    fg_x, fg_y, grouping, rec = decoded
    k0, k1 = _bins_of(run.spans[k], run.edges)
    simulation = {**rec.timing(), **run.simulation, "count_from_ms": run.edges[k0], "count_to_ms": run.edges[k1]}
    params = run_provenance(run.network, run.origin, run.backend, result, rec.populations, simulation, run.t_start)
    params["timings_s"]["window"] = window_s
    return Maps(fg_x.astype(np.float32), fg_y.astype(np.float32), grouping.astype(np.float32), params, rec.arrays())
