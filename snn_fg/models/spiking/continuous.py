"""One network over a whole recording: :func:`run_spiking_windows`.

A neuromorphic chip runs one fixed network on the event stream as it comes.
So does this: the network is built (and, for backends that unroll it,
instantiated) once for the whole recording and fed the events as they come
(no replay, no per-window rebuild), and each
window's maps are decoded from the spikes counted inside that window,
shifted by a read-out lag: the window ``[t_start, t_end)`` is read from the
spikes in ``[t_start + lag, t_end + lag)``, since the network needs a few
synaptic delays and membrane time constants to answer. The backend counts
spikes per window through :attr:`~snn_fg.backends.RunSettings.count_bins_ms`,
and each window is decoded as soon as the run has passed the end of its
read-out span. :func:`run_spiking_windows` lets the backend forget each bin
once it is read (:attr:`~snn_fg.backends.RunSettings.on_bin`), so that a long
recording does not need the memory of all its spikes.

How events become input spikes is the network's input coding
(:func:`~.stream_input.input_stream`): with ``events``, each event is a spike
of its (pooled) source at its own time step, unless that source fired in
that step already or within the input adapter's refractory period (the
compact network's 60 ms); with ``window`` and ``sliding``, an event sets its
source's hold, and held sources fire at the input rate, not once per event.

The recording is read once, as a live stream is (:mod:`.stream_input`):
its events are handed to a backend that streams its input (the fast engine)
a segment of steps at a time as they are read, and nothing the run needs
is taken from events not read yet. The input gains are calibrated before
the run (the compact network to its input adapter's ceiling, a network
without one to the rate of window 0), and every window is read out over a
whole window's span, a recording's last one too (``docs/live.md``). A
recording cut by ``max_windows`` is read on through its last window's
read-out lag (:func:`read_past_the_cut`): that window's maps are those of a
longer run.
"""

from __future__ import annotations

import dataclasses
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ...backends import RunSettings
from ...backends.base import each_bin
from ...backends.cores import usable_cores
from ...results.maps import Maps
from .options import SpikingOptions
from .record import run_provenance
from .stream_input import (
    HORIZON_MS,
    SEGMENT_MS,
    StreamEnded,
    StreamFeed,
    StreamLayout,
    arrivals,
    read_out_spans,
    stream_rate_hz,
    window_arrivals,
    window_steps,
)
from .window_reader import WindowReader, maps_of


def run_spiking_windows(windows, *, source: str = "<recording>", **keywords) -> list[Maps]:
    """Run the spiking network once over consecutive windows of a recording.

    Parameters
    ----------
    windows : iterable of EventWindow
        The recording cut into windows (:func:`snn_fg.events.iter_windows`),
        all from one sensor, in time order, read once (a list, any iterable,
        or :class:`~snn_fg.events.RecordingWindows`, whose events the network
        takes as they are read: memory does not grow with the recording).
        A list ends with its last window: that window's read-out lag runs
        without input; what ``iter_windows`` returns, or a
        :class:`~snn_fg.events.RecordingWindows`, cut by ``max_windows``
        reads on through it (:func:`read_past_the_cut`).
    params, spiking, network, backend, backend_options, dt_ms, calibrate, feedback, instantiate, record_spikes
        As for :func:`~snn_fg.models.spiking.run_spiking`.
    readout_lag_ms : float
        Each window is read from the spikes ``readout_lag_ms`` later than
        its own time span; the simulation runs that long past the last window.
    readout_ms : float or None
        Count each window's spikes over the last ``readout_ms`` of that span
        only (once the network has settled on the window; ``None``: all of it).
    window_clock : bool
        Fire the network's window clock (if it has one) as each window
        starts, or where windows overlap once every window length
        (:class:`~.stream_input.StreamLayout` says when): its inhibitory
        pulse holds the grouping cells silent until the previous window's
        feedback has faded, so each window's light and dark grouping cells
        compete afresh. ``False``: the clock stays silent and the network
        carries its state from window to window.
    progress, log
        Stage messages and a progress bar on stderr, or ``log`` receiving them.
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
    >>> from snn_fg.frames.scenes import disc
    >>> rec = image_to_events(disc(radius=10).image)
    >>> wins = list(iter_windows(rec, window_ms=2))
    >>> maps = run_spiking_windows(wins, params=ModelParams(levels=2), progress=False)
    >>> len(maps) == len(wins), maps[0].params["simulation"]["network_builds"]
    (True, 1)
    """
    opts = SpikingOptions.from_keywords("run_spiking_windows", keywords, frame=False)
    return window_maps(_simulate(windows, opts, source=source, keep_run=False))


def stream_spiking_windows(
    windows,
    on_window,
    *,
    source: str = "<recording>",
    cells: bool = True,
    **keywords,
) -> dict:
    """:func:`run_spiking_windows` handing each window's maps to
    ``on_window(window, maps)`` as soon as the run has passed the end of its
    read-out span, instead of returning them all at the end: nothing of a
    window is kept once handed over. Each window's ``params`` are those
    known then (a backend that streams its bins, such as the fast engine,
    has no statistics or timings of the whole run yet); returns the whole
    run's, to update the run's parameters with (``counts``,
    ``backend_stats``, ``kept_kernel_mass``, ``timings_s``). ``cells=False``:
    the maps' ``extra`` holds no per-cell spike counts (nor is time spent
    gathering them)."""
    opts = SpikingOptions.from_keywords("stream_spiking_windows", keywords, frame=False)
    run = _simulate(windows, opts, source=source, keep_run=False, on_window=on_window, cells=cells)
    result = run.result if run.result is not None else run.last_bin  # (a run stopped as its stream ended)
    whole = run_provenance(run.network, run.origin, run.backend, result, {}, run.simulation, run.t_start)
    return {
        **{k: whole[k] for k in ("counts", "backend_stats", "kept_kernel_mass", "timings_s")},
        "windows": run.n_windows,
        "merged_input_spikes": run.merged,
        "simulated_ms": run.simulation["simulated_ms"],  # (a window's own is what had been simulated when it was read)
        "readout_without_input_ms": run.without_input_ms,
    }


@dataclasses.dataclass
class ContinuousRun:
    """One simulation over a recording's windows (:func:`simulate_windows`):
    the network, the backend's result (spike counts per bin between
    ``edges`` and spike trains if recorded, unless the run was not kept),
    each window's read-out span ``spans[k]`` (ms from the first window's
    start, lag included) and each window's decoded maps and record
    (``decoded[k]``: ``fg_x, fg_y, grouping, SpikingRecord``) with the
    ``perf_counter()`` time it was decoded at (``decoded_at[k]``)."""

    n_windows: int
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
    merged: int = 0
    last_bin: object = None
    #: ms of the last window's read-out lag that ran past the stream's end, without input
    #: (0: events came until the read-out ended, :func:`read_past_the_cut`)
    without_input_ms: float = 0.0


def simulate_windows(
    windows,
    *,
    source: str = "<recording>",
    keep_run: bool = True,
    on_window=None,
    cells: bool = True,
    segment_ms: float = SEGMENT_MS,
    **keywords,
) -> ContinuousRun:
    """The simulation half of :func:`run_spiking_windows` (same parameters):
    one run over every window, each window decoded as the run passes the
    end of its read-out span; :func:`window_maps` makes their maps.

    ``windows``: a list of windows, or a stream cut as it is read (an
    object with a ``cut()`` method giving its event chunks and a
    :class:`~snn_fg.events.cutter.WindowCutter`, as
    :class:`~snn_fg.events.RecordingWindows` and a live source do), read once
    (:mod:`.stream_input`); ``segment_ms``: the input handed to the backend
    at a time.

    ``keep_run=False`` lets the backend forget each counting bin once it is
    read (``RunSettings.on_bin``): the result then has no per-bin counts
    and no spike trains, and the memory need not grow with the recording.
    ``True`` keeps them in ``ContinuousRun.result`` (for analyses of the
    whole run's spikes; the stream is read whole first). ``on_window(window, maps)``: each window's maps as it
    is decoded (:func:`stream_spiking_windows`), none kept in the result;
    ``cells=False``: the windows' records leave out the per-cell counts."""
    opts = SpikingOptions.from_keywords("simulate_windows", keywords, frame=False)
    return _simulate(
        windows, opts, source=source, keep_run=keep_run, on_window=on_window, cells=cells, segment_ms=segment_ms
    )


def _simulate(
    windows, opts: SpikingOptions, *, source, keep_run, on_window=None, cells=True, segment_ms: float = SEGMENT_MS
) -> ContinuousRun:
    """:func:`simulate_windows` with its options made (checked once, passed whole)."""
    t_start = time.perf_counter()
    sim, backend = opts.simulator, opts.simulator.backend_object()
    threaded = usable_cores() > 1
    cut = windows.cut() if hasattr(windows, "cut") else None
    read_out = None if cut is None else read_past_the_cut(cut[1], opts.recording.readout_lag_ms)
    segment_ms = getattr(windows, "segment_ms", segment_ms)  # (a live stream: handed over in shorter segments)
    if cut is None:
        stream = window_arrivals(windows)
    else:
        stream = arrivals(*cut)
    live = hasattr(windows, "dropped_window")  # (a live stream: its receiver's queue holds what has come)
    feed = StreamFeed(
        read_ahead(stream) if threaded and not live else stream,
        lambda f: lay_out(f, opts, None if cut is None else cut[1], read_out),
        name=source,
        drain=keep_run or cut is None or not backend.streams_input,
        keep=keep_run,
        segment_ms=segment_ms,
        drops=windows if live else None,
    )
    lay = feed.layout
    net = lay.network
    edges = np.unique(np.asarray(lay.spans, dtype=np.float64)).tolist()
    inp = feed.input if backend.streams_input else feed.input.whole()
    instantiate = sim.cells_for(backend, inp)
    simulation = {
        "mode": "continuous",
        "simulated_ms": edges[-1],
        "network_builds": 1,
        "readout_lag_ms": opts.recording.readout_lag_ms,
        **({"readout_ms": opts.recording.readout_ms} if opts.recording.readout_ms is not None else {}),
        "dt_ms": lay.dt_ms,
        "input": "events",
        "input_coding": net.input_coding,
        **({"seed": lay.seed} if lay.held else {}),
        "rate_hz_used": lay.rate_hz,
        "instantiate": instantiate,
        "record_spikes": bool(sim.record_spikes),
        "window_clock": lay.clock,
    }
    n = len(lay.spans)
    run = ContinuousRun(
        n, net, lay.origin, backend, None, edges, lay.spans, simulation, t_start, [None] * n, [None] * n
    )
    unpool = opts.network.maps_grid == "sensor"
    reader = WindowReader(feed, lay.spans, edges, net.params.input_pool, run, on_window, threaded, cells, unpool)
    simulation["decode_thread"] = reader.threaded
    settings = RunSettings(
        duration_ms=edges[-1],
        dt_ms=lay.dt_ms,
        count_from_ms=edges[0],
        record_spikes=sim.record_spikes,
        instantiate=instantiate,
        count_bins_ms=tuple(edges),
        log=sim.say,
        progress=sim.progress and feed.ended,  # (a run laid out ahead of its stream: the windows show the progress)
        on_bin=None if keep_run else reader,
    )
    with reader:
        try:
            run.result = backend.simulate(net, inp, settings)
        except StreamEnded:  # (the stream ended before the run laid out for it: its last window is read)
            run.n_windows = feed.n
            simulation["simulated_ms"] = lay.spans[feed.n - 1][1]
        if run.result is not None and run.result.binned_counts is not None:  # (a backend that kept its bins)
            for k, bin_result in each_bin(run.result):
                reader(k, bin_result)
    run.merged = feed.merged
    if feed.ended and feed.n <= run.n_windows:  # (no window cut past the last read out: the stream ended in it)
        run.without_input_ms = opts.recording.readout_lag_ms
    run.last_bin = reader.last_result
    return run


def read_past_the_cut(cut, lag_ms: float) -> int | None:
    """For a stream ``cut`` (a :class:`~snn_fg.events.cutter.WindowCutter`) by ``max_windows``:
    that number, the windows read out, after letting ``cut`` cut the windows that a longer
    run begins before the last one's read-out ends (``lag_ms`` past its end). So the network
    is fed the events a longer run feeds it until then, and its window clock fires and its
    held inputs reset as there: the last window's maps are those of a longer run, not of a
    read-out lag spent without input. None without ``max_windows``."""
    n = cut.max_windows
    if n is None:
        return None
    reach = cut.win + round(lag_ms * 1000)  # (window n - 1's read-out ends this long after it starts)
    cut.max_windows = n + max(0, -(-reach // cut.stride) - 1)
    return n


def lay_out(feed: StreamFeed, opts: SpikingOptions, cut, read_out: int | None = None) -> StreamLayout:
    """The run over ``feed``'s stream, laid out before it starts (:class:`StreamLayout`):
    the network for the sensor's frame, calibrated for a stream
    (:func:`~.stream_input.stream_rate_hz`), and every window's read-out span,
    for the windows known (a stream read whole, or a list of windows) or
    for those the stream can hold within :data:`~.stream_input.HORIZON_MS`
    (``cut``: the stream's :class:`~snn_fg.events.cutter.WindowCutter`; None for a list);
    ``read_out``: only the first so many windows are read out (:func:`read_past_the_cut`)."""
    first = feed.held.get(0)
    shape = first.pos.shape if cut is None else (int(cut.size[1]), int(cut.size[0]))
    net, origin = opts.network.resolve(shape)
    rate = stream_rate_hz(net, feed.first_window)
    if opts.network.calibrate and not np.isclose(net.input_rate_hz, rate, rtol=1e-12, atol=0):
        origin["calibrated"] = {
            "from_hz": net.input_rate_hz,
            "to_hz": rate,
            "rate": "per active source, for a stream (stream_rate_hz)",
        }
        net = net.calibrated(rate)
    dt_ms, lag = opts.simulator.step_for(net), opts.recording.readout_lag_ms
    if cut is None:  # (times from the first window's start)
        length = max(w.t_end_us - w.t_start_us for w in feed.held.values())
        starts = np.array([w.t_start_us - feed.origin for _, w in sorted(feed.held.items())], dtype=np.int64)
    else:
        n = feed.n if feed.ended else int(HORIZON_MS * 1000 // cut.stride)
        n = n if cut.max_windows is None else min(n, cut.max_windows)
        length, starts = cut.win, cut.stride * np.arange(n, dtype=np.int64)
    steps = window_steps(starts, starts + length, 0, dt_ms)
    counted = length if opts.recording.readout_ms is None else min(length, opts.recording.readout_ms * 1000.0)
    read = starts[:read_out]  # (the windows read out; those after them only feed the run, read_past_the_cut)
    return StreamLayout(
        network=net,
        origin=origin,
        shape=shape,
        dt_ms=dt_ms,
        rate_hz=net.input_rate_hz,
        spans=read_out_spans(read + length - counted, read + length, 0, lag, dt_ms),
        steps=steps,
        clock=bool(opts.recording.window_clock and net.by_role("clock")),
        seed=opts.recording.seed,
        lag_ms=lag,
        window_length=max(1, int(round(length / (dt_ms * 1000.0)))),
        period_us=int(length) if starts.size > 1 and np.diff(starts).min() < length else 0,
    )


def read_ahead(windows):
    """Iterate ``windows`` with the next one read on a second thread
    meanwhile (decoding a recording's file releases the interpreter lock in
    its compiled byte walk and in numpy).

    Closed before its end (a run stopped by bad input further on, say), it
    does not wait for the reading thread, which ends once its read is done:
    a generator left unfinished is closed by the garbage collector whenever
    it runs, inside ``threading``'s own locks too, where waiting for a
    thread to end deadlocked (a test run hung in ``Thread.start``, 29 Nov)."""
    it, end = iter(windows), object()
    ahead = ThreadPoolExecutor(1, thread_name_prefix="snn-fg-read")
    try:
        coming = ahead.submit(next, it, end)
        while True:
            w = coming.result()
            if w is end:
                return
            coming = ahead.submit(next, it, end)
            yield w
    finally:
        ahead.shutdown(wait=False, cancel_futures=True)


def window_maps(run: ContinuousRun) -> list[Maps]:
    """Each window's maps, decoded from the spikes counted in its read-out
    span, with the whole run's parameters; ``timings_s["window"]`` is the
    wall time from the previous window's decoding (the first: from the
    run's start) to this one's, what the stream spent on the window."""
    before = [run.t_start] + run.decoded_at[:-1]
    return [
        maps_of(run, k, decoded, run.result, t1 - t0)
        for k, (decoded, t0, t1) in enumerate(zip(run.decoded, before, run.decoded_at))
    ]
