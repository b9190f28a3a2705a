"""What a live run gives out as each window's maps are made: one JSON line per
window to ``--publish udp://HOST:PORT`` or ``tcp://HOST:PORT`` (its time span
and strongest proto-objects, for a gaze controller), the live page's latest
window (``--view``, :mod:`snn_fg.results.live_view`), and the run's record,
``live.json`` (every window's latency, and their median, 95th percentile and
worst).

A window's latency is the time from the arrival of its last event to its
maps being published (its JSON line sent, the page given them); they are
written to ``maps.zarr`` right after. A window that no later event completes
(the last) waits for the end of the stream: ``live.json`` marks it
(``completed_by``) and gives the latency also without it.
"""

from __future__ import annotations

import json
import socket
import time
import warnings

import numpy as np

from snn_fg.errors import InputError, InputWarning
from snn_fg.results.atomic import save_text
from snn_fg.results.peaks import grouping_peaks
from snn_fg.validate import address

#: the drop policy, as live.json states it
DROP_POLICY = (
    "whole windows: a stride's slot of events is dropped when it begins while more than max_behind windows whose "
    "read-out (the read-out lag past their end) was over before it began wait for their maps; a window holding a "
    "dropped slot is neither computed, written nor published, and the spiking network does not simulate the "
    "dropped time that no kept window reads out: it goes on at the next kept slot with every cell at rest "
    "(simulated_ms_dropped); with --hop-ms, max_behind counts windows' worth of hops, and a hop whose read-out is "
    "due when the events that complete the read-out of the hop skip_behind hops later have all come already is not "
    "decoded (windows_skipped): the network takes its events all the same, and a newer hop's maps are made in its "
    "place"
)
#: live.json's ``ended`` when the stream ended by itself (a UDP source says it went silent: :func:`ended_by`)
SENDER_CLOSED = "the sender closed the stream"
#: a window's ``completed_by`` when no event past its read-out came: the end of the stream completed it
END_OF_STREAM = "the end of the stream"
#: seconds a TCP subscriber is given to take a line before publishing stops
TCP_TIMEOUT_S = 1.0
#: the grouping peaks a live window's line gives (``--peaks``)
PEAKS = 3
#: decimals of a latency in milliseconds (0.01 ms: the clocks' jitter is larger)
LATENCY_DECIMALS = 2
#: the share of the time a live run's stream came which, used by the run on all its cores or by the model's
#: thread alone, says that the model (not other programs) is what fell behind
BUSY_SHARE = 0.8
#: the share of the stream's time that ``run_live``'s callback took for it to be named as why the model fell behind
CALLBACK_SHARE = 0.2
#: seconds of a warm-up after the stream's first event arrived from which the warm-up is named as why the model
#: fell behind (a little more than a window of the default 85 ms)
LATE_WARM_UP_S = 0.1


def ended_by(source) -> str:
    """live.json's ``ended`` for a stream that ended by itself: what ``source`` says of it (a UDP
    source's ``ended_by``: it went silent), else :data:`SENDER_CLOSED`."""
    return getattr(source, "ended_by", SENDER_CLOSED)


class Publisher:
    """One JSON line per window: in a UDP datagram to ``udp://HOST:PORT``, or on
    a TCP connection made to ``tcp://HOST:PORT`` (a listening gaze controller).
    A TCP subscriber that goes away (or takes no line for :data:`TCP_TIMEOUT_S`)
    is said once, and the run goes on without publishing."""

    def __init__(self, url: str):
        scheme, host, port = address(url, ("udp", "tcp"), "--publish")
        self.url, self.address, self.tcp = url, (host, port), scheme == "tcp"
        if not self.tcp:
            self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            return
        try:
            self.sock = socket.create_connection(self.address, timeout=TCP_TIMEOUT_S)
        except OSError as exc:
            raise InputError(url, f"--publish: cannot connect: {exc.strerror or exc}") from None

    def send(self, message: dict) -> None:
        line = (json.dumps(message) + "\n").encode()
        if not self.tcp:
            self.sock.sendto(line, self.address)
            return
        if self.sock is None:
            return
        try:
            self.sock.sendall(line)
        except OSError as exc:
            warnings.warn(
                f"{self.url}: the subscriber went away ({exc.strerror or exc}); the run goes on without publishing",
                InputWarning,
                stacklevel=2,
            )
            self.close()

    def close(self):
        if self.sock is not None:
            self.sock.close()
            self.sock = None


class LiveRecord:
    """The windows of a live run as they are published, and ``live.json`` at its end."""

    def __init__(self, stream, publisher: Publisher | None = None, peaks: int = PEAKS, view=None):
        self.stream, self.publisher, self.k, self.view = stream, publisher, peaks, view
        self.rows: list = []
        self.t_start = time.perf_counter()
        self.warm_up_s = None  # (the warm-up before the stream: snn_fg.models.live.warm_up)
        self.last = None  # (the latest window's published line)
        self.on_window_s = None  # (run_live: the seconds its caller's callback took, said in the summary)
        self.cores = None  # (the cores the run may use: snn_fg.cli.live gives backends.cores.usable_cores())
        self.window_run_s: list = []  # (a window-by-window model's own time for each window: its maps' timings)
        self.windows_alone = False  # (whether the model makes each window on its own: live_stream says)

    def window(self, w, maps) -> None:
        """Window ``w``'s maps are made: publish them, note the latency (and, for a model that makes each
        window on its own, the rate and frame-based models, its time for the window: their maps say it)."""
        arrived = self.stream.arrival(w)
        run_s = (getattr(maps, "params", None) or {}).get("timings_s", {}).get("run")
        if self.windows_alone and run_s is not None:
            self.window_run_s.append(float(run_s))
        origin = self.stream.origin - self.stream.start
        message = {
            "window": int(w.index),  # (its number in the stream, as in maps.zarr and windows.csv)
            "t_start_us": int(w.t_start_us - origin),
            "t_end_us": int(w.t_end_us - origin),
            "stream_t_start_us": int(w.t_start_us),  # (the span on the stream's own clock: its events' times)
            "stream_t_end_us": int(w.t_end_us),
            "events": int(len(w.events)),
            "peaks": [  # (float32 values to the digits they hold, not float64's tail of noise)
                {k: round(v, 3) if isinstance(v, float) else v for k, v in peak.items()}
                for peak in grouping_peaks(maps, self.k)
            ],
        }
        now = time.perf_counter()
        message["latency_ms"] = None if arrived is None else round((now - arrived) * 1000, LATENCY_DECIMALS)
        message["published_unix_s"] = round(time.time(), 6)
        self.last = message  # (what run_live hands its caller with the maps)
        if self.publisher is not None:
            self.publisher.send(message)
        if self.view is not None:  # (with the run's counts so far, which the page shows)
            counts = {"windows": len(self.rows) + 1, "windows_dropped": self.stream.windows_dropped}
            self.view.show(w, maps, {**message, **counts, "windows_skipped": self.stream.windows_skipped})
        row = {k: message[k] for k in ("window", "t_start_us", "t_end_us", "events", "latency_ms")}
        row["drop_before"] = self.stream.dropped_before_read_out(w)
        row["completed_by"] = END_OF_STREAM if self.stream.completed_by_end(w) else "the stream's events"
        self.rows.append(row)

    def summary(self, ended: str) -> dict:
        """``live.json``: ``latency_ms`` over every window, and ``latency_ms_streaming`` over those the
        stream's own events completed, without the last one(s), which waited for the end of the stream."""
        out = {
            "windows": len(self.rows),
            **self.stream.stats(),
            "latency_ms": _latency(self.rows),
            "latency_ms_streaming": _latency([r for r in self.rows if r["completed_by"] != END_OF_STREAM]),
            "windows_completed_by_end": sum(r["completed_by"] == END_OF_STREAM for r in self.rows),
            "ended": ended,
            "warm_up_s": self.warm_up_s,
            "warm_up_on_stream_s": self._warm_up_on_stream(),
            "seconds": round(time.perf_counter() - self.t_start, 3),
            **self._cpu(),
            "stride_ms": self.stream.stride / 1000,
        }
        if self.window_run_s:  # (the median: a window's time, not the warm-up of the first)
            out["model_ms_a_window"] = round(1000 * float(np.median(self.window_run_s)), 1)
        if self.on_window_s is not None:
            out["on_window_s"] = round(self.on_window_s, 3)
        out["why_behind"] = why_behind(out)
        return {
            **out,
            "drop_policy": DROP_POLICY,
            "max_behind": self.stream.max_behind,
            "skip_behind": self.stream.skip_behind,
            "per_window": self.rows,
        }

    def _warm_up_on_stream(self) -> float | None:
        """Seconds of the warm-up that ran after the stream's first event arrived (a ``dv://`` or ``camera://``
        stream without its size given is connected to before the warm-up, to learn it), which the first
        windows waited for; 0.0 when the warm-up came first, None when no event came. The record is made
        as the warm-up ends (:attr:`t_start`)."""
        first = self.stream.first_arrival
        return None if first is None else round(max(0.0, self.t_start - first), 3)

    def _cpu(self) -> dict:
        """``streamed_s``: wall seconds from the first event's arrival to the last's (the silence that ends a
        UDP stream left out); ``cpu_s``, ``model_cpu_s``: the CPU seconds of the whole process (every thread)
        and of the model's thread over those same seconds (sampled as packets arrive,
        :meth:`~snn_fg.events.live.LiveStream.cpu_span`), so that their share of ``streamed_s`` cannot pass
        100 % a core; ``cores``: the cores it may run on. A model behind its stream whose run used nearly all
        of ``streamed_s`` on its cores is slower than the stream on this machine; one that used much less
        waited for a core."""
        span = self.stream.cpu_span()
        wall, cpu, model = (None, None, None) if span is None else (round(v, 3) for v in span)
        return {"streamed_s": wall, "cpu_s": cpu, "model_cpu_s": model, "cores": self.cores}

    def keep_only(self, windows) -> None:
        """Keep the rows of ``windows`` (their numbers) only: a run cut short may have published a
        window its store did not take whole, and live.json says what the folder holds."""
        held = {int(w) for w in windows}
        self.rows = [r for r in self.rows if r["window"] in held]

    def save(self, path, ended: str) -> dict:
        """Write ``live.json`` (:meth:`summary`, marked by the version that wrote it: a later run's
        ``--force`` replaces only such a record) and return the summary."""
        from snn_fg import __version__

        out = self.summary(ended)
        save_text(path, json.dumps({"snn_fg_version": __version__, **out}, indent=1) + "\n")
        return out


def _latency(rows) -> dict | None:
    """Median, p95 and max of the latencies of ``rows`` (None without one)."""
    lat = np.array([r["latency_ms"] for r in rows if r["latency_ms"] is not None], dtype=np.float64)
    if not lat.size:
        return None
    stats = {"median": np.median(lat), "p95": np.percentile(lat, 95), "max": lat.max()}
    return {k: round(float(v), LATENCY_DECIMALS) for k, v in stats.items()}


def why_behind(summary: dict) -> str | None:
    """Why a live run fell behind (windows dropped or hops skipped), from its CPU while the stream came
    (``live.json``: ``streamed_s``, ``cpu_s``, ``model_cpu_s``, ``cores``): the model is slower than the stream
    here, or other programs had the cores. None when nothing fell behind or no event came. ``live.json`` keeps
    it (``why_behind``) and the line ``snn-fg live`` ends with says it. Named instead: a warm-up that ran
    :data:`LATE_WARM_UP_S` or more after the stream's first event came (``warm_up_on_stream_s``: the model
    was built on the stream's time, and its CPU says nothing of the windows that waited for it), or a
    ``run_live`` caller's callback that took :data:`CALLBACK_SHARE` of the stream's time or more
    (``on_window_s``): the model waited for it."""
    behind = (summary.get("windows_dropped") or 0) + (summary.get("windows_skipped") or 0)
    late = summary.get("warm_up_on_stream_s")
    if behind and late is not None and late >= LATE_WARM_UP_S:  # (before streamed_s: all may have come meanwhile)
        return (
            f"the model was built and warmed up after the stream's first event came, for {late:.1f} s of the "
            "stream's time, which its first windows waited for (give the stream's size, --sensor-size WxH or "
            "sensor_size=(W, H), and the warm-up comes before the stream)"
        )
    wall, cores = summary.get("streamed_s"), summary.get("cores")
    if not (behind and wall and cores):
        return None
    callback = summary.get("on_window_s")
    if callback is not None and callback >= CALLBACK_SHARE * wall:
        return (
            f"on_window took {callback:.1f} s of the {wall:.1f} s the stream came, and the model waited for it "
            "(hand its work to a thread of your own)"
        )
    run, model = summary["cpu_s"] / (wall * cores), summary["model_cpu_s"] / wall
    said = f"the run used {run:.0%} of its {cores} core{'s' if cores != 1 else ''} while the stream came"
    own, stride = summary.get("model_ms_a_window"), summary.get("stride_ms")
    if own is not None and stride and own >= BUSY_SHARE * stride:
        # (a model that makes each window on its own says its time for one: its thread's CPU leaves out the
        # threads it works on, and the windows dropped leave the cores idle, so neither share tells it)
        return (
            f"the model took {own:g} ms a window (the median) against the stream's {stride:g} ms: it is slower "
            "than the stream on this machine (--network compact needs less)"
        )
    start = _at_the_start(summary)
    if start is not None and start[1] - start[0] + 1 == behind:  # (all of them: the stream's start, then caught up)
        return (
            f"only the stream's first windows fell behind ({start[0]}-{start[1]}), and the model kept up after them "
            f"({said}): a recording's start-up burst, events on most of the sensor, does this (--start-ms past it)"
        )
    if run >= BUSY_SHARE or model >= BUSY_SHARE:
        verdict = f"{said}: the model is slower than the stream on this machine"
    else:
        verdict = f"{said}: other programs had the rest, and the model waited for them"
    if start is not None:  # (a share over the whole stream does not tell a burst at its start apart: said too)
        verdict += f"; {start[1] - start[0] + 1} of them at the stream's start (windows {start[0]}-{start[1]})"
    return verdict


def _at_the_start(summary: dict) -> tuple[int, int] | None:
    """The windows skipped or dropped in one unbroken run from the stream's start (``[first, last]``, with
    ``first`` its first or second window), or None."""
    ranges = sorted([*(summary.get("skipped_windows") or ()), *(summary.get("dropped_windows") or ())])
    if not ranges or ranges[0][0] > 1:
        return None
    first, last = ranges[0]
    for a, b in ranges[1:]:  # (a hop skipped and the windows dropped after it: one run)
        if a > last + 1:
            break
        last = max(last, b)
    return int(first), int(last)


class LiveModel:
    """``model`` as :func:`~snn_fg.cli.runner.run_recording` runs it, with each
    window's maps published (``record``) once written (the windows that hold
    a dropped slot are not handed over: :class:`~snn_fg.events.live.LiveStream`)."""

    def __init__(self, model, stream, record: LiveRecord):
        self.model, self.stream, self.record = model, stream, record

    def __getattr__(self, name):
        return getattr(self.model, name)

    def run_windows_into(self, windows, emit, start: int = 0) -> dict:
        def each(w, maps):  # (a dropped window comes not: the stream passes it over)
            self.record.window(w, maps)  # (published first: the write adds nothing to the latency)
            emit(w, maps)
            self.stream.done(w)

        return self.model.run_windows_into(windows, each, start)
