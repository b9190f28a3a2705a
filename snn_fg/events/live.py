"""A live event stream as a model reads it: received on a thread of its own,
cut into windows on the stream's clock, with bounded memory.

:class:`LiveStream` takes a source's packets (:mod:`snn_fg.events.live_sources`) on a receiving
thread and hands their events to the model in the order they came, either as event chunks with the
:class:`~snn_fg.events.cutter.WindowCutter` that cuts them (:meth:`cut`: the spiking network, which
takes the events as they arrive) or window by window (iterating it: the rate model). Events outside
the sensor and events earlier than the stream's latest are dropped and counted, each said once.

Drop policy: the stream is cut into slots of one stride (the window, or
``--hop-ms``); a window is made of ``window / stride`` slots. When a slot
begins while more than ``max_behind`` windows wait for their maps that
could have them (their read-out, ``lag_ms`` past their end, was over
before the slot began; :meth:`done` says which window was published
last), the whole slot is dropped: its events are counted and thrown away,
and every window that holds it is dropped (:meth:`dropped_window`: not
written, not published, and not computed). The windows in between are
kept whole. So at most ``max_behind + 2`` windows of events wait (docs/live.md,
"When the model falls behind"; live.json: ``DROP_POLICY``); the
model learns that the stream's clock has passed the dropped
events (:class:`~snn_fg.events.cutter.TimePassed`), so that the windows
before them complete. A dropped slot costs no simulated time: where no kept window is read
out (:meth:`resume_at`), the spiking network skips the rest of the slot and
goes on at the next one put at rest, as if no event had come before it.

With ``--hop-ms``, ``max_behind`` counts windows' worth of hops (a slot is dropped once the network lags a
window behind, as without hops), and a hop falls behind first by its read-out: a hop whose read-out is due
when the events that complete the read-out of the hop ``skip_behind`` hops later have come already (the
model is that many hops behind) is not decoded (:meth:`LiveStream.stale`, ``windows_skipped``): the network
takes its events all the same, and a newer hop's maps are made in its place.
"""

from __future__ import annotations

import queue
import threading
import time
import warnings

import numpy as np

from snn_fg.errors import InputError, InputWarning
from snn_fg.events.cutter import WINDOW_MS, TimePassed, WindowCutter, _window_times
from snn_fg.events.live_screen import screen_events
from snn_fg.events.window import handed_out

#: the end of the stream, on the queue
_END = object()
#: seconds of arrivals between two samples of the CPU used (two clock reads: nothing beside a packet's 117 us)
CPU_SAMPLE_S = 0.01
#: with --hop-ms, how many hops behind the stream the model may be when a hop's read-out is due before it is skipped
#: (--skip-behind): with 1, the compact network on its blocks on one core made 517-530 of the 533 hops of dvs.es
#: looped 6 times; with 2, 530-533 (p95 9-12 ms, worst 19-23 ms), and 533 with the store made in the warm-up (30 Nov,
#: docs/live.md "Measured")
SKIP_BEHIND = 2
#: read-out windows that may wait for their maps before whole ones are dropped (--max-behind; 0: least latency)
MAX_BEHIND = 0


class LiveStream:
    """The events of ``source`` as they arrive; the window options are
    :class:`~snn_fg.events.cutter.WindowCutter`'s (``stride_ms``: the hop)."""

    def __init__(
        self, source, *, window_ms=WINDOW_MS, stride_ms=None, start_ms=0.0, max_behind: int = MAX_BEHIND, lag_ms=0.0,
        skip_behind: int = SKIP_BEHIND,
    ):  # fmt: skip
        self.source, self.name = source, source.name
        self.sensor_size = source.sensor_size
        self.options = {"window_ms": window_ms, "stride_ms": stride_ms, "start_ms": start_ms}
        self.win, self.start, self.stride = _window_times(window_ms, start_ms, stride_ms)
        self.slots_per_window = max(1, -(-self.win // self.stride))
        self.lag_us = int(round(lag_ms * 1000))  # (how much later than its span a window is read out)
        self.max_behind, self.skip_behind = max_behind, skip_behind
        self.q: queue.Queue = queue.Queue()
        self.published = -1  # the last window whose maps are out
        self.origin = None  # the first window's start (us, the stream's clock)
        self.slot = -1  # the slot of the newest event
        self.dropped_slots: set = set()
        self.slot_arrival: dict = {}  # slot -> time its last event arrived (perf_counter)
        self.first_arrival = None  # (when the stream's first event arrived: before the warm-up's end, or after)
        self.events_received = self.events_dropped = self.outside = self.backwards = 0
        self.outside_reach = (0, 0)  # (the largest x and y of the events outside the sensor: the sensor they fit)
        # the CPU used while the stream comes, sampled on arrivals (cpu_span): the run's, and the model's thread's,
        # the thread that makes the stream (snn_fg.cli.live), since its clock is read from the receiving thread
        self.model_clock = time.pthread_getcpuclockid(threading.get_ident())
        self.cpu_first = self.cpu_last = None  # ((wall, process CPU, model thread CPU) at the first and latest sample)
        self.windows_dropped, self.windows_skipped = 0, 0  # (skipped: hops whose read-out gave way to a newer one)
        # (the numbers of the skipped and the dropped, as ranges [first, last] of consecutive ones: a long --hop-ms
        # run skips hops by the thousand; the timeline tells the two apart)
        self.skipped_windows: list = []
        self.dropped_ranges: list = []
        self.dropped_us = 0  # the dropped stream time the model did not simulate (resume_at)
        self.first_dropped = None  # the first slot dropped
        self.dropped_windows: set = set()  # (those not yet passed by the published ones)
        self.on_ready = None  # called once the model first asks for events
        self.stop = None  # (a threading.Event: once set, the stream ends where the model has read it)
        self.lock = threading.Lock()  # (the drop bookkeeping, shared by both threads)
        self.last_t = self.cutting = None  # (the last event's time; the cutter the model reads with)
        self.end_seen = self.warned = False  # (the model's thread took the end of the stream; a warning was given)
        self.thread = threading.Thread(target=self._receive, name="snn-fg live receiver", daemon=True)
        self.thread.start()

    # -- the receiving thread ----------------------------------------------------------------------
    def _receive(self):
        try:
            for ev, arrived in self.source.packets():
                self._take(ev, arrived)
        except BaseException as exc:  # (handed to the model's thread, raised there)
            self.q.put(exc)
        self.q.put(_END)

    def _take(self, ev, arrived):
        self.events_received += len(ev)
        if not len(ev):
            return
        if self.first_arrival is None:
            self.first_arrival = arrived
        w, h = self.sensor_size[:2]
        last = np.iinfo(np.int64).min if self.last_t is None else self.last_t
        keep, (outside, first_out, backwards, first_back, back_t, back_before) = screen_events(
            ev["x"], ev["y"], ev["t"], w, h, last
        )
        if self.cpu_last is None or arrived - self.cpu_last[0] >= CPU_SAMPLE_S:
            self._sample_cpu()
        if outside:
            self.outside += outside
            self.outside_reach = (
                max(self.outside_reach[0], int(ev["x"].max())),
                max(self.outside_reach[1], int(ev["y"].max())),
            )
            if self.outside == outside:
                warnings.warn(
                    f"{self.name}: event at (x={int(ev['x'][first_out])}, y={int(ev['y'][first_out])}) lies outside "
                    f"the {w} x {h} sensor; such events are dropped and counted "
                    "(events_outside: live.json, run_live's summary)",
                    InputWarning,
                    stacklevel=2,
                )
        if backwards:
            self.backwards += backwards
            if self.backwards == backwards:
                warnings.warn(
                    f"{self.name}: time runs backwards ({back_t} us after {back_before} us); events "
                    "earlier than the stream's latest are dropped and counted "
                    "(events_backwards: live.json, run_live's summary)",
                    InputWarning,
                    stacklevel=2,
                )
        if outside or backwards:
            ev = ev[keep]
            if not len(ev):
                return
        self.last_t = int(ev["t"][-1])
        if self.origin is None:
            self.origin = int(ev["t"][0]) + self.start
        slots = (ev["t"] - self.origin) // self.stride  # (in order: the times are)
        lo, hi = int(slots[0]), int(slots[-1])
        present = [lo] if lo == hi else np.unique(slots).tolist()
        with self.lock:
            for s in present:
                if s > self.slot:
                    self._begin(s)
        self.slot = max(self.slot, hi)
        gone = [s for s in present if s in self.dropped_slots]
        if gone:
            drop = np.isin(slots, gone)
            self.events_dropped += int(drop.sum())
            ev = ev[~drop]
            present = [s for s in present if s not in gone]
        for s in present:
            self.slot_arrival[s] = arrived
        if len(ev):
            self.q.put(ev)
        if gone:  # (the clock has passed them: the windows before them are complete)
            self.q.put(TimePassed(self.last_t))

    def _sample_cpu(self):
        """The CPU used so far, on the receiving thread as a packet comes: the whole process's, and the
        model's thread's (by its clock), with the wall time."""
        try:
            model = time.clock_gettime(self.model_clock)
        except OSError:  # (the model's thread has ended: the stream is over for it)
            return
        self.cpu_last = (time.perf_counter(), time.process_time(), model)
        if self.cpu_first is None:
            self.cpu_first = self.cpu_last

    def cpu_span(self) -> tuple[float, float, float] | None:
        """Wall seconds from the first sampled arrival to the latest (the first packet's and, to within
        :data:`CPU_SAMPLE_S`, the last's), and the CPU seconds of the process and of the model's thread over
        those same seconds; None before a packet came. Measured over the stream alone, the CPU share is
        honest: a run's CPU from the warm-up's end to its summary (the last windows and the idle wait after
        the stream included) read 119 % of its one core against the stream's wall time."""
        if self.cpu_first is None:
            return None
        (w0, p0, m0), (w1, p1, m1) = self.cpu_first, self.cpu_last
        return w1 - w0, p1 - p0, m1 - m0

    def _begin(self, s: int):
        """Slot ``s`` begins: dropped whole where too many windows wait for their maps that could have them."""
        # the last window whose read-out was over before slot s began: the one that slot s's own first event
        # completes (its read-out ending where the slot begins) is not counted, since no model can have made
        # its maps before that event came (counted, a model with no read-out lag, the rate model, lost every
        # other window however fast it was)
        complete = s - (self.win + self.lag_us) // self.stride - 1
        waiting = complete - self.published - sum(self.published < k <= complete for k in self.dropped_windows)
        # (with --hop-ms, a window's worth of hops: the network may lag as far as without hops, its
        # read-outs thinned meanwhile, stale, before any event is lost)
        waiting //= self.slots_per_window
        if waiting > self.max_behind:
            self.dropped_slots.add(s)
            self.first_dropped = s if self.first_dropped is None else self.first_dropped
            held = set(range(max(s - self.slots_per_window + 1, 0), s + 1)) - self.dropped_windows
            self.dropped_windows |= held  # (the windows that hold slot s)
            self.windows_dropped += len(held)
            for k in sorted(held):  # (above those dropped before: the slots begin in order)
                _note(self.dropped_ranges, k)
            if not self.warned:
                self.warned = True
                warnings.warn(
                    f"{self.name}: the model fell {waiting} window{'s' if waiting != 1 else ''} behind the stream; "
                    f"whole windows are dropped while more than {self.max_behind} wait "
                    "(counted: live.json, run_live's summary)",
                    InputWarning,
                    stacklevel=3,
                )

    # -- the model's thread ------------------------------------------------------------------------
    def chunks(self):
        """The events in arrival order, as much as has come at a time (and where events
        were dropped, the time they reached: a :class:`~snn_fg.events.cutter.TimePassed`), until the stream ends."""
        if self.on_ready is not None:
            self.on_ready()
        while True:
            if self.stop is not None and self.stop.is_set():  # (run_live's caller: the stream ends here)
                self.end_seen = True
                if self.cutting is not None:
                    self.cutting.stopped = True
                return
            try:
                items = [self.q.get(timeout=0.2)]
            except queue.Empty:
                continue
            while True:
                try:
                    items.append(self.q.get_nowait())
                except queue.Empty:
                    break
            events = [x for x in items if isinstance(x, np.ndarray)]
            passed = [x for x in items if isinstance(x, TimePassed)]
            ended = any(x is _END for x in items)
            failed = [x for x in items if isinstance(x, BaseException)]
            if events:
                yield np.concatenate(events)
            if passed:
                yield passed[-1]  # (the latest: none of the events after it is earlier)
            if failed:
                raise failed[0]
            if ended:
                self.end_seen = True
                return

    def cutter(self) -> WindowCutter:
        self.cutting = WindowCutter(self.sensor_size, self.name, **self.options)  # (told if stop ends the stream)
        return self.cutting

    def cut(self):
        """The event chunks and their cutter (a reader that takes the events as they come)."""
        return self.chunks(), self.cutter()

    def __iter__(self):
        """The windows kept, one by one (a dropped one is passed over, :meth:`done`)."""
        cut = self.cutter()
        for chunk in self.chunks():
            yield from self._kept(handed_out(cut.add(chunk)))
        if cut.t0 is None and not cut.stopped:  # (stopped by the caller before anything came: no window)
            raise InputError(self.name, "the stream ended before any event")
        yield from self._kept(handed_out(cut.finish()))

    def _kept(self, windows):
        for w in windows:
            if self.dropped_window(w.index) or self.stale(w):
                self.done(w)
            else:
                yield w

    def resume_at(self, t: float) -> float:
        """Where a model at time ``t`` (us from the first window's start) may go on:
        ``t``, or, inside a dropped slot that no kept window reads out at ``t``
        (window ``k`` is read over ``[k * stride + lag_us, ... + window)``), the
        slot's end or the next kept window's read-out start, whichever is first.
        The time skipped is counted (``live.json``: ``simulated_ms_dropped``)."""
        lag_us = self.lag_us
        with self.lock:
            s = int(t // self.stride)
            if s not in self.dropped_slots:
                return t
            to = (s + 1) * self.stride
            first = max(0, int((t - lag_us - self.win) // self.stride) + 1)
            for k in range(first, int((to - lag_us) // self.stride) + 1):
                start = k * self.stride + lag_us
                if k in self.dropped_windows or k <= self.published or start + self.win <= t:
                    continue
                if start <= t:
                    return t  # (a kept window is being read out)
                to = min(to, start)
            self.dropped_us += to - t
            return to

    def stale(self, w) -> bool:
        """Whether window ``w``'s read-out is skipped for a newer one's: with ``--hop-ms``, when the
        events that complete the read-out of the hop :attr:`skip_behind` hops later have come already
        (the model is that many hops behind) and the next hop is kept, so that a newer hop's maps can
        be made in the time ``w``'s would take. The
        network takes every event all the same: the hops made are those of a run, bit for bit.
        Counted (``windows_skipped``); asked once a window, before its maps are made."""
        if self.slots_per_window == 1 or self.last_t is None or self.dropped_window(w.index + 1):
            return False
        if self.last_t < w.t_end_us + self.skip_behind * self.stride + self.lag_us:
            return False
        self.windows_skipped += 1
        _note(self.skipped_windows, int(w.index))  # (asked in order)
        return True

    def slots_of(self, w) -> range:
        first = (w.t_start_us - self.origin) // self.stride
        return range(first, first + self.slots_per_window)

    def dropped_window(self, k: int) -> bool:
        """Whether window ``k`` holds a dropped slot (asked before it is :meth:`done`)."""
        return k in self.dropped_windows

    def dropped_before_read_out(self, w) -> bool:
        """Whether a slot that begins before window ``w``'s read-out ends (``lag_us``
        past its span, on the stream's clock) was dropped."""
        end = w.t_end_us + self.lag_us
        return self.first_dropped is not None and self.origin + self.first_dropped * self.stride < end

    def arrival(self, w) -> float | None:
        """When the last event of window ``w`` arrived (perf_counter), None without events."""
        times = [self.slot_arrival[s] for s in self.slots_of(w) if s in self.slot_arrival]
        return max(times) if times else None

    def completed_by_end(self, w) -> bool:
        """Whether window ``w`` was completed by the end of the stream rather than by its events: none came
        past its read-out (``lag_us`` past its span) and the segment the model reads it in
        (``segment_ms``, where set). Its latency then holds the wait for that end (``udp://``: ``--idle-s``
        without a packet; ``dv://``: the server closing), which a camera that goes on sending never has.
        Only once the end has come: a window read out while the stream goes on was completed by its events
        (with ``--hop-ms`` on a slow stream, early hops were marked completed by an end 0.7 s away)."""
        segment_us = int(round(getattr(self, "segment_ms", 0.0) * 1000))  # (set by a spiking run's caller)
        return self.end_seen and (self.last_t is None or self.last_t < w.t_end_us + self.lag_us + segment_us)

    def done(self, w) -> None:
        """Window ``w``'s maps are out (or it was dropped): its slots are forgotten."""
        with self.lock:
            self._done(w)

    def _done(self, w) -> None:
        self.published = max(self.published, w.index)
        first = self.slots_of(w).start  # (the next window starts a slot later: the slots before are done with)
        for s in [s for s in self.slot_arrival if s <= first]:
            del self.slot_arrival[s]
        self.dropped_slots = {s for s in self.dropped_slots if s > first}
        self.dropped_windows = {k for k in self.dropped_windows if k > self.published}

    def close(self):
        self.source.close()
        self.thread.join(timeout=2)

    def stats(self) -> dict:
        return {
            "windows_dropped": self.windows_dropped,
            "windows_skipped": self.windows_skipped,
            "skipped_windows": self.skipped_windows,
            "dropped_windows": self.dropped_ranges,
            "simulated_ms_dropped": self.dropped_us / 1000.0,
            "events_received": self.events_received,
            "events_dropped": self.events_dropped,
            "events_outside": self.outside,
            **(
                {"events_outside_reach": {"x": self.outside_reach[0], "y": self.outside_reach[1]}}
                if self.outside
                else {}
            ),
            "events_backwards": self.backwards,
            "packets_malformed": self.source.malformed,
            # (UDP: packets the kernel dropped, its buffer full, before the receiver read them; None: unknown)
            "packets_lost": getattr(self.source, "packets_lost", None),
        }


def _note(ranges: list, k: int) -> None:
    """Window ``k``, above every window in ``ranges`` (``[first, last]`` of consecutive numbers), added to them."""
    if ranges and ranges[-1][1] == k - 1:
        ranges[-1][1] = k
    else:
        ranges.append([k, k])
