"""A model on a live stream, in this process: what ``snn-fg live`` runs, and
:func:`run_live`, the same from Python with each window handed to your own code
(``from snn_fg.models import get_model, run_live``).

A live run warms its model up on synthetic events (:func:`warm_up`), so that
the first window's latency is the model's work and not its start-up, cuts
the stream into windows on its own clock
(:class:`~snn_fg.events.live.LiveStream`, which drops whole windows when the
model falls behind), runs the model on it as ``snn-fg run`` runs on a
recording, and publishes each window as its maps are made
(:class:`~snn_fg.results.publish.LiveRecord`: the window's span, latency and
grouping peaks, and ``live.json``'s summary at the end). ``snn-fg live``
(:mod:`snn_fg.cli.live`) adds its output folder, the live page and figures.
"""

from __future__ import annotations

import time
import warnings
from collections import namedtuple
from contextlib import ExitStack, closing

import numpy as np

from .. import validate as check
from ..backends.cores import usable_cores
from ..errors import InputError
from ..events import EVENT_DTYPE, EmptyWindowWarning, Recording, iter_windows
from ..events.cutter import WINDOW_MS
from ..events.live import MAX_BEHIND, SKIP_BEHIND, LiveStream
from ..events.live_dv import CAMERA, WAIT_S, camera_found
from ..events.live_screen import prepare_screen
from ..events.live_sources import IDLE_S, open_source, parse_address
from ..frames.pool import pooled_shape
from ..frames.pyramid import check_levels
from ..results.peaks import grouping_peaks
from ..results.publish import PEAKS, LiveModel, LiveRecord, Publisher, ended_by

#: what a warm-up gives (:func:`warm_up`): its seconds, and its last window with its maps
WarmUp = namedtuple("WarmUp", "seconds window maps")

#: simulated time the spiking network is handed at a time on a live stream (ms): it follows the events this closely
LIVE_SEGMENT_MS = 5.0


def run_live(
    model,
    source,
    on_window=None,
    *,
    sensor_size=None,
    window_ms: float = WINDOW_MS,
    hop_ms: float | None = None,
    start_ms: float = 0.0,
    max_behind: int = MAX_BEHIND,
    skip_behind: int = SKIP_BEHIND,
    peaks: int = PEAKS,
    publish: str | None = None,
    wait_s: float = WAIT_S,
    idle_s: float = IDLE_S,
    on_ready=None,
    stop=None,
) -> dict:
    """Run ``model`` (:func:`~snn_fg.models.get_model`) on a live stream until it ends, as
    ``snn-fg live`` does without its folder, and return ``live.json``'s summary.

    ``source``: ``udp://HOST:PORT``, ``dv://HOST:PORT`` or ``camera://[SERIAL]`` (as ``snn-fg live``), or your own
    stream: any iterable of event arrays (fields ``x``, ``y``, ``t`` in microseconds, ``p``),
    read on a thread of its own as it gives them, a chunk counting as arrived when it is given
    (:class:`~snn_fg.events.live_sources.ChunkSource`; ``sensor_size`` ``(W, H)`` needed).
    ``on_window(window, maps, line)`` is called with each window kept, in order, as soon as its
    maps are made and published: ``line`` holds what ``--publish`` sends (the window's span,
    ``latency_ms`` and grouping ``peaks``). It runs on the thread that makes the maps, so what
    it takes adds to the next windows' latency: hand heavy work to a thread of your own.
    Windows the model cannot keep up with are dropped whole (the policy of ``live.json``,
    ``max_behind`` as ``--max-behind``); ``window_ms``, ``hop_ms``, ``skip_behind``, ``start_ms``,
    ``peaks``, ``publish``, ``wait_s`` and ``idle_s`` are ``snn-fg live``'s ``--window-ms``,
    ``--hop-ms``, ``--skip-behind``, ``--start-ms``, ``--peaks``, ``--publish``, ``--wait-s`` and
    ``--idle-s``.
    ``on_ready()`` is called once the model is warmed up and waits for the stream (where
    ``snn-fg live`` says "ready": start a ``udp://`` sender then). ``stop``, a
    ``threading.Event`` another thread may set, ends the run there as the sender's end would
    (the windows before it are made; ``ended``: ``stopped``). The summary also gives
    ``on_window_s``, the seconds ``on_window`` took, and says so in ``why_behind`` where they
    made the model fall behind."""
    window_ms = check.number("run_live", "window_ms", window_ms, lo=0, lo_open=True)  # (before a warm-up uses it)
    start_ms = check.number("run_live", "start_ms", start_ms, lo=0)
    with ExitStack() as opened:
        publisher = opened.enter_context(closing(Publisher(publish))) if publish else None
        source, warm = open_warmed(model, source, sensor_size, window_ms, peaks, wait_s=wait_s, idle_s=idle_s)
        opened.enter_context(closing(source))
        stream, record = live_stream(
            model, source, window_ms=window_ms, hop_ms=hop_ms, start_ms=start_ms, max_behind=max_behind,
            skip_behind=skip_behind, publisher=publisher, peaks=peaks, warm_s=warm.seconds, on_ready=on_ready,
        )  # fmt: skip
        stream.stop = stop
        opened.enter_context(closing(stream))
        record.on_window_s = 0.0

        def each(w, maps):
            if on_window is not None:
                t = time.perf_counter()
                on_window(w, maps, record.last)
                record.on_window_s += time.perf_counter() - t

        with warnings.catch_warnings():  # (a dropped window's events never came: it is no empty window)
            warnings.simplefilter("ignore", EmptyWindowWarning)  # (one that is, is handed over with line["events"] 0)
            try:
                LiveModel(model, stream, record).run_windows_into(stream, each)
            except InputError:  # (stopped by the caller before any event came: no window, and no error)
                if not (stream.cutting is not None and stream.cutting.stopped and stream.cutting.t0 is None):
                    raise
    # (after the stream and source are closed: a UDP socket's lost packets are read as it closes)
    ended = "stopped" if stop is not None and stop.is_set() else ended_by(source)
    return record.summary(ended)


def open_warmed(model, source, sensor_size, window_ms: float, peaks: int = PEAKS, **opening):
    """The live source ``source`` opened (:func:`~snn_fg.events.live_sources.open_source`; ``opening``:
    its ``wait_s``, ``idle_s``) and ``model`` warmed up for it: ``(source, WarmUp)``.
    A ``dv://`` stream is connected to (a ``camera://`` opened) after the warm-up when its size
    is given (a DV server sends from the moment a reader connects, a camera once it is opened),
    else before it, since the stream tells the size; a UDP port is bound before it (packets
    sent meanwhile wait in the kernel's buffer)."""
    name = source if isinstance(source, str) else "<events>"
    camera = isinstance(source, str) and source.startswith(CAMERA)
    sends_at_once = camera or (isinstance(source, str) and parse_address(source)[0] == "dv")
    warm = None
    if sends_at_once and sensor_size is not None:
        if camera:  # (no camera is said before the warm-up's seconds, not after them)
            camera_found(source)
        warm = warmed_up(model, sensor_size, window_ms, name, peaks)
    opened = open_source(source, sensor_size, found=camera and warm is not None, **opening)
    if warm is None:
        try:
            warm = warmed_up(model, opened.sensor_size, window_ms, name, peaks)
        except BaseException:
            opened.close()
            raise
    return opened, warm


def live_stream(
    model, source, *, window_ms: float, hop_ms, start_ms: float, max_behind: int, skip_behind: int = SKIP_BEHIND,
    publisher=None, view=None,
    peaks: int = PEAKS, warm_s=None, on_ready=None,
):  # fmt: skip
    """The stream cut from ``source`` for ``model`` (:class:`~snn_fg.events.live.LiveStream`; ``on_ready``
    called once the model first asks for events) and the record of its windows
    (:class:`~snn_fg.results.publish.LiveRecord`)."""
    _said_in_warm_up(model)
    spiking = hasattr(model, "run_options")
    lag_ms = model.run_options.recording.readout_lag_ms if spiking else 0.0
    stream = LiveStream(
        source,
        window_ms=window_ms,
        stride_ms=hop_ms,
        start_ms=start_ms or 0.0,
        max_behind=max_behind,
        lag_ms=lag_ms,
        skip_behind=skip_behind,
    )
    if spiking:  # (the rate model takes whole windows)
        stream.segment_ms = LIVE_SEGMENT_MS
    stream.on_ready = on_ready
    record = LiveRecord(stream, publisher, peaks, view)
    record.warm_up_s, record.cores = warm_s, usable_cores()
    record.windows_alone = not spiking  # (a spiking model's timings are the whole run's, not a window's own)
    return stream, record


def warmed_up(model, sensor_size, window_ms: float, name: str, peaks: int = PEAKS) -> WarmUp:
    """``model`` checked against the sensor (its pyramid's levels fit the frame; an InputError naming
    ``name`` if not) and warmed up (:func:`warm_up`)."""
    w, h = sensor_size[:2]
    check_levels(
        pooled_shape((h, w), model.params.input_pool), model.params.levels, name, model.params.levels_per_octave
    )
    return warm_up(model, sensor_size, window_ms, peaks)


def _said_in_warm_up(model) -> None:
    """The live run on the warmed-up model says no stage message: each was said in the warm-up, on the same
    network and backend object (the fast engine's "prepared" line came a second time, after "ready")."""
    if isinstance(getattr(model, "run_keywords", None), dict):  # (the spiking models: their backend's messages)
        model.run_keywords["log"] = _unsaid


def _unsaid(message: str) -> None:
    """Where a message already said goes."""


def warm_up(model, sensor_size, window_ms: float, peaks: int = PEAKS, windows: int = 3) -> WarmUp:
    """Run ``model`` on ``windows`` windows of synthetic events of the sensor's
    size (:func:`warm_up_events`), so that a live run finds its code compiled
    and loaded (the packet screen's too:
    :func:`~snn_fg.events.live_screen.prepare_screen`), its network's tables
    built and its arrays allocated (the spiking model keeps them on its backend
    object) before the first packet. Returns the seconds it took and the last
    window with its maps, which the run's store makes its arrays from
    (:func:`~snn_fg.cli.runner.run_recording`'s ``template``)."""
    t0 = time.perf_counter()
    prepare_screen()  # (the receiving thread's, for each packet)
    w, h = sensor_size[:2]
    rec = Recording(warm_up_events(w, h, window_ms * 1000.0, windows), (w, h, 2), "synthetic")
    made = []

    def each(window, maps):
        grouping_peaks(maps, peaks)
        made[:] = [window, maps]

    model.run_windows_into(list(iter_windows(rec, window_ms=window_ms)), each)
    return WarmUp(round(time.perf_counter() - t0, 3), *made)


def warm_up_events(w: int, h: int, window_us: float, windows: int, per_window: int = 20_000) -> np.ndarray:
    """Synthetic events for a warm-up: a ring (a third of the sensor's height
    across) moving right, ON on its leading half and OFF on its trailing one,
    ``per_window`` events in each of ``windows`` windows (deterministic)."""
    n = per_window * windows
    rng = np.random.default_rng(0)
    t = np.sort(rng.uniform(0, window_us * windows, n)).astype(np.int64)
    angle = rng.uniform(0, 2 * np.pi, n)
    r = h / 6 * (1 + 0.05 * rng.standard_normal(n))
    cx = w / 3 + (w / 3) * t / (window_us * windows)
    ev = np.zeros(n, EVENT_DTYPE)
    ev["t"] = t
    ev["x"] = np.clip(cx + r * np.cos(angle), 0, w - 1).astype(ev["x"].dtype)
    ev["y"] = np.clip(h / 2 + r * np.sin(angle), 0, h - 1).astype(ev["y"].dtype)
    ev["p"] = np.cos(angle) > 0
    return ev
