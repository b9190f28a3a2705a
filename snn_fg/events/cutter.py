"""Cutting a stream of events into time windows as it arrives (:class:`WindowCutter`, what
:func:`~snn_fg.events.window.iter_windows` and a live stream cut with), and the clock a live
stream's dropped events leave behind (:class:`TimePassed`).

A window's events and frames are made when first read (:class:`CutWindow`): a run that reads a
window's maps on a second thread makes them there, and a hop whose read-out is skipped for a newer
one (``snn-fg live --hop-ms``) never makes them. Joined at every window, the events of an 85 ms
window were copied again every 10 ms hop, and its frames built, on the thread that feeds the
network."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from snn_fg import validate
from snn_fg.errors import InputError, InputWarning, Remedy
from snn_fg.events.core import EVENT_DTYPE, check_monotonic
from snn_fg.events.frame import EmptyWindowWarning, EventWindow, events_to_frame
from snn_fg.events.io import no_span_problem

#: a window's length by default (ms): the iCub's microsaccade period, the paper's window
WINDOW_MS = 85.0


def _filter(events, denoise_us, refractory_us):
    if len(events) and denoise_us:
        from tonic.transforms import Denoise  # (tonic takes over a second to import: only when a filter is asked for)

        events = Denoise(filter_time=denoise_us)(events)
    if len(events) and refractory_us:
        from tonic.transforms import RefractoryPeriod

        events = RefractoryPeriod(delta=refractory_us)(events)
    return events


def _ms_to_us(name, value, positive=True) -> int:
    """A time in milliseconds given to :func:`iter_windows`, as whole microseconds."""
    ms = validate.number("iter_windows", name, value, lo=0, lo_open=positive)
    us = round(ms * 1000)
    if positive and us < 1:
        validate.fail("iter_windows", name, value, "must be at least 0.001 ms (1 us)")
    return int(us)


def _window_times(window_ms, start_ms, stride_ms) -> tuple[int, int, int]:
    """Window length, start and stride of :func:`iter_windows` in microseconds, checked."""
    win = _ms_to_us("window_ms", window_ms)
    start = _ms_to_us("start_ms", start_ms, positive=False)
    return win, start, win if stride_ms is None else _ms_to_us("stride_ms", stride_ms)


def _check_window_options(max_windows, denoise_us, refractory_us) -> None:
    if max_windows is not None:
        validate.integer("iter_windows", "max_windows", max_windows, lo=1)
    for name, v in (("denoise_us", denoise_us), ("refractory_us", refractory_us)):
        if v is not None:
            validate.number("iter_windows", name, v, lo=0)


@dataclass(frozen=True)
class TimePassed:
    """A live stream's clock has reached ``t_us`` though no event came (those
    of a dropped slot were thrown away): what :meth:`WindowCutter.add` takes
    instead of events, so that the windows before it complete."""

    t_us: int

    def __len__(self) -> int:
        return 0


class CutWindow(EventWindow):
    """An :class:`~snn_fg.events.frame.EventWindow` whose ``events`` (the ``parts``
    it was cut from, joined) and ``pos``/``neg`` frames are made when first read,
    on whichever thread reads them (made twice at worst by two at once: the same
    arrays)."""

    _LAZY = ("events", "pos", "neg")

    @classmethod
    def of_parts(cls, parts: list, size, *, index: int, t_start_us: int, t_end_us: int, t_first_event_us):
        w = object.__new__(cls)
        for name, v in (("index", index), ("t_start_us", t_start_us), ("t_end_us", t_end_us)):
            object.__setattr__(w, name, v)
        object.__setattr__(w, "t_first_event_us", t_first_event_us)
        object.__setattr__(w, "_parts", parts)
        object.__setattr__(w, "_size", size)
        return w

    def __getattr__(self, name):  # (only for an attribute not yet set: the lazy ones)
        if name not in CutWindow._LAZY or "_parts" not in self.__dict__:
            raise AttributeError(name)
        if name == "events":  # (joined alone: the feed of a filtered stream reads a window's events, not its frames)
            parts = self.__dict__["_parts"]
            events = parts[0] if len(parts) == 1 else np.concatenate(parts) if parts else np.zeros(0, EVENT_DTYPE)
            object.__setattr__(self, "events", events)
            return events
        pos, neg = events_to_frame(self.events, self.__dict__["_size"])
        object.__setattr__(self, "pos", pos)
        object.__setattr__(self, "neg", neg)
        return self.__dict__[name]


class WindowCutter:
    """:func:`iter_windows`' cut made one chunk at a time, as a live stream
    arrives: :meth:`add` takes the next events (in time order) and returns
    the windows they complete, :meth:`finish` the last window once the
    stream has ended. Windows are cut on the stream's own clock: window
    ``k`` is ``[origin + k * stride, ... + window)`` with ``origin`` the
    first event's time plus ``start_ms`` (:meth:`span`). The options are
    :func:`iter_windows`' (``name`` is the stream's, for errors)."""

    def __init__(
        self,
        sensor_size,
        name="<stream>",
        *,
        window_ms: float = WINDOW_MS,
        start_ms: float = 0,
        stride_ms: float | None = None,
        max_windows: int | None = None,
        denoise_us: int | None = None,
        refractory_us: int | None = None,
    ):
        self.win, self.start, self.stride = _window_times(window_ms, start_ms, stride_ms)
        _check_window_options(max_windows, denoise_us, refractory_us)
        self.max_windows, self.denoise_us, self.refractory_us = max_windows, denoise_us, refractory_us
        self.start_ms = start_ms
        self.size, self.name = sensor_size, name
        # the events from the current window's start on, as they came (views of the chunks): a window
        # takes those before its end, and they are joined only when it is read (CutWindow)
        self.parts: list = []
        self.t0 = self.w_start = self.w_end = self.prev_t = None
        self.k = self.seen = 0
        self.stopped = False  # (a live stream its caller ended: with no event, no window and no error)

    def begin_at(self, t_first: int, seen: int) -> None:
        """The stream is read from past its start: its first event was at ``t_first`` (us) and
        ``seen`` events before the first one to come are left out (all earlier than the first window)."""
        self.t0, self.seen = int(t_first), int(seen)
        self.w_start = self.t0 + self.start
        self.w_end = self.w_start + self.win

    @property
    def filtered(self) -> bool:
        """Whether a window's events are filtered (its own, not the stream's)."""
        return bool(self.denoise_us or self.refractory_us)

    @property
    def origin(self) -> int | None:
        """The first window's start (us, the stream's clock), once an event has come."""
        return None if self.t0 is None else self.t0 + self.start

    @property
    def done(self) -> bool:
        """Whether ``max_windows`` windows have been cut."""
        return self.max_windows is not None and self.k >= self.max_windows

    def span(self, k: int) -> tuple[int, int]:
        """Window ``k``'s whole span ``(start, end)`` in us (a stream's last window may end earlier)."""
        a = self.origin + k * self.stride
        return a, a + self.win

    def held_events(self, events: np.ndarray) -> np.ndarray:
        """The ``events`` some window holds (:meth:`held`): ``events`` itself where all are
        (a live stream's chunk after its first window's start: no copy)."""
        if self.stride <= self.win and self.max_windows is None and len(events) and events["t"][0] >= self.origin:
            return events
        return events[self.held(events["t"])]

    def held(self, t: np.ndarray) -> np.ndarray:
        """Which of the times ``t`` (in us) some window holds (none before the first
        window, in the gaps of a stride longer than the window, after ``max_windows``)."""
        d = np.asarray(t, dtype=np.int64) - self.origin
        inside = (d >= 0) & (d % self.stride < self.win) if self.stride > self.win else d >= 0
        if self.max_windows is not None:
            inside &= d < (self.max_windows - 1) * self.stride + self.win
        return inside

    def add(self, chunk) -> list[EventWindow]:
        """The windows that events ``chunk`` (later than every event before), or
        the stream's clock reaching a time (:class:`TimePassed`), complete."""
        if isinstance(chunk, TimePassed):
            if self.done or self.t0 is None or chunk.t_us <= self.prev_t:
                return []
            self.prev_t = int(chunk.t_us)
            return self._complete()
        if self.done or not len(chunk):
            return []
        check_monotonic(chunk, self.name, offset=self.seen, prev_t=self.prev_t)
        self.seen += len(chunk)
        self.prev_t = int(chunk["t"][-1])
        if self.t0 is None:
            self.t0 = int(chunk["t"][0])
            self.w_start = self.t0 + self.start
            self.w_end = self.w_start + self.win
        new = chunk if chunk["t"][0] >= self.w_start else chunk[chunk["t"] >= self.w_start]  # (no copy: all)
        if len(new):
            self.parts.append(new)
        return self._complete()

    def _before(self, t: int) -> list:
        """The parts of the events held before time ``t`` (views: nothing is copied)."""
        out = []
        for part in self.parts:
            if part["t"][-1] < t:
                out.append(part)
                continue
            cut = int(np.searchsorted(part["t"], t, side="left"))
            if cut:
                out.append(part[:cut])
            break
        return out

    def _complete(self) -> list[EventWindow]:
        """The windows that end at or before the newest time."""
        out = []
        while self.prev_t >= self.w_end:  # every window that ends at or before the newest timestamp is complete
            out.append(self._emit(self._before(self.w_end), self.w_start, self.w_end))
            if self.done:
                break
            self.w_start += self.stride
            self.w_end = self.w_start + self.win
            kept = []  # (the parts from the next window's start on)
            for part in self.parts:
                if part["t"][-1] < self.w_start:
                    continue
                cut = int(np.searchsorted(part["t"], self.w_start, side="left")) if part["t"][0] < self.w_start else 0
                kept.append(part[cut:])
            self.parts = kept
        return out

    def finish(self) -> list[EventWindow]:
        """The last window, ending with the stream (one microsecond after its last event)."""
        if self.done:
            return []
        if self.t0 is None:
            if self.stopped:
                return []
            raise InputError(self.name, "recording contains no events")
        if self.seen > 1 and self.prev_t == self.t0:
            raise InputError(
                self.name, f"{no_span_problem(self.seen, self.t0)} and has no window to cut; is the file cut short?"
            )
        if self.w_start > self.prev_t:
            if self.k == 0:
                last_ms = (self.prev_t - self.t0) / 1000
                raise InputError(
                    self.name,
                    f"the start, {_ms(self.start_ms)} ms, lies after the last event "
                    f"({_ms(last_ms)} ms after the first)",
                    remedy=Remedy(f"start_ms below {last_ms:g}", f"--start-ms below {last_ms:g}"),
                )
            return []
        span_us = self.prev_t - self.t0
        if self.k == 0 and self.seen >= SHORT_STREAM_EVENTS and span_us < SHORT_STREAM_US:
            warnings.warn(
                f"{self.name}: all {self.seen:,} events lie within {span_us} us, so its one window holds them all: "
                "are its times in milliseconds? They are read as microseconds (multiply by 1000)",
                InputWarning,
                stacklevel=4,
            )
        # the last window ends with the recording: its nominal end may lie far beyond
        return [self._emit(list(self.parts), self.w_start, min(self.w_end, self.prev_t + 1))]

    def _emit(self, parts: list, ws, we) -> EventWindow:
        """Window ``k`` of the events ``parts``: filtered now (a filter reads them all), else
        a :class:`CutWindow` that joins them and makes its frames when first read."""
        n = sum(len(p) for p in parts)
        if self.filtered and n:
            events = _filter(np.concatenate(parts), self.denoise_us, self.refractory_us)
            parts, n = [events], len(events)
        if not n:
            warnings.warn(
                f"{self.name}: window {self.k} [{ws} us, {we} us) has no events; its frames are all zero",
                EmptyWindowWarning,
                stacklevel=4,
            )
        out = CutWindow.of_parts(parts, self.size, index=self.k, t_start_us=ws, t_end_us=we, t_first_event_us=self.t0)
        self.k += 1
        return out


#: a stream of this many events or more that spans less than this many microseconds is warned of: its
#: times are likely milliseconds (a new user's 40,000 events in one window of 0.1 ms, 1 Dec)
SHORT_STREAM_EVENTS, SHORT_STREAM_US = 1000, 1000


def _ms(value: float) -> str:
    """A time in ms for a line: ``85``, ``2.5``, and ``99,999,999`` (not ``1e+08``)."""
    return f"{value:,.0f}" if abs(value) >= 1e5 else f"{value:g}"
