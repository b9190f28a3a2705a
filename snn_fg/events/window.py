"""Stage 1 of the model: event frames, and cutting a recording into time windows."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numba import njit

from snn_fg import validate
from snn_fg.errors import InputError, Remedy
from snn_fg.events._core import EVENT_DTYPE, as_events, check_in_sensor, check_monotonic, sensor_size_parameter
from snn_fg.events.formats import check_read_options
from snn_fg.events.io import iter_recording, no_span_problem


def events_to_frame(events, sensor_size, source="<array>", offset: int = 0):
    """Return ``(pos, neg)``, uint8 ``H x W`` event frames (model.md stage 1).

    Each pixel keeps the polarity of its last event: ``pos`` is 1 where that
    event was ON, ``neg`` where it was OFF; pixels without events are 0 in
    both (``edges = pos | neg``).  "Last" means latest timestamp; among equal
    timestamps the later one in the array wins.  Events outside the sensor
    raise :class:`~snn_fg.errors.InputError` naming the event index.
    """
    w, h, _ = sensor_size_parameter("events_to_frame", sensor_size)
    ev = as_events(events, source, offset)
    check_in_sensor(ev, (w, h), source, offset)
    pos = np.zeros(h * w, dtype=np.uint8)
    neg = np.zeros(h * w, dtype=np.uint8)
    if len(ev):
        t = ev["t"]
        if len(t) > 1 and (np.diff(t) < 0).any():
            ev = ev[np.argsort(t, kind="stable")]
        _last_polarity(ev["x"], ev["y"], ev["p"], w, pos, neg)
    return pos.reshape(h, w), neg.reshape(h, w)


@njit(cache=True, nogil=True)
def _last_polarity(x, y, p, w, pos, neg):
    """Each pixel's last event in array order sets it in ``pos`` (ON) or ``neg`` (OFF)."""
    for k in range(x.size):
        i = np.int64(y[k]) * w + np.int64(x[k])
        on = p[k] > 0
        pos[i] = on
        neg[i] = not on


class EmptyWindowWarning(UserWarning):
    """A time window contained no events; its frames are all zero."""


@dataclass(frozen=True)
class EventWindow:
    """One time window ``[t_start_us, t_end_us)`` and its event frame.

    ``events`` are the window's events (after the optional denoise and
    refractory filters); ``pos``/``neg`` come from :func:`events_to_frame`.
    Times are in the recording's own clock (some formats stamp Unix time);
    ``t_first_event_us``, the recording's first event, is the origin of every
    time shown to a user (:attr:`span_ms`).
    """

    index: int
    t_start_us: int
    t_end_us: int
    events: np.ndarray
    pos: np.ndarray
    neg: np.ndarray
    t_first_event_us: int | None = None

    @property
    def span_ms(self) -> tuple[float, float]:
        """Start and end, ms after the recording's first event (after the
        window's own start when that is unknown)."""
        origin = self.t_start_us if self.t_first_event_us is None else self.t_first_event_us
        return (self.t_start_us - origin) / 1000.0, (self.t_end_us - origin) / 1000.0

    @property
    def edges(self) -> np.ndarray:
        """1 where any event fired (model.md stage 1)."""
        return self.pos | self.neg


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


class RecordingWindows:
    """A recording's windows that can be read more than once: each
    iteration is a fresh :func:`iter_windows` over ``recording_or_path``
    with ``options`` (a file is read again from its start), holding one
    window at a time, not the recording; :meth:`cut` gives its events as
    they are read and the cutter that makes the windows (the spiking model
    reads a recording so, once, as it reads a live stream)."""

    def __init__(self, recording_or_path, **options):
        self.recording, self.options = recording_or_path, options

    def __iter__(self):
        return _cut_windows(self)

    def cut(self, owner: str = "RecordingWindows"):
        """The recording's event chunks (a :class:`~snn_fg.events.io.RecordingStream`, read
        once) and a :class:`WindowCutter` to cut them with, for a reader that takes the
        events as they come (the spiking network) rather than window by window."""
        window = {k: v for k, v in self.options.items() if k in WINDOW_KEYS}
        read = check_read_options(owner, {k: v for k, v in self.options.items() if k not in WINDOW_KEYS})
        stream = iter_recording(self.recording, **read)
        stream.warn_no_span = False  # (refused by the cut)
        return stream, WindowCutter(stream.sensor_size, stream.path if stream.path is not None else "<array>", **window)


#: the options of :func:`iter_windows` that say how a stream is cut (the others say how it is read)
WINDOW_KEYS = ("window_ms", "start_ms", "stride_ms", "max_windows", "denoise_us", "refractory_us")


def _check_window_options(max_windows, denoise_us, refractory_us) -> None:
    if max_windows is not None:
        validate.integer("iter_windows", "max_windows", max_windows, lo=1)
    for name, v in (("denoise_us", denoise_us), ("refractory_us", refractory_us)):
        if v is not None:
            validate.number("iter_windows", name, v, lo=0)


def iter_windows(
    recording_or_path,
    *,
    window_ms: float = 85,
    start_ms: float = 0,
    stride_ms: float | None = None,
    max_windows: int | None = None,
    denoise_us: int | None = None,
    refractory_us: int | None = None,
    **read_options,
):
    """Cut a recording into time windows and yield :class:`EventWindow` s.

    Window ``k`` covers ``[t0 + start + k * stride, ... + window)`` where ``t0``
    is the recording's first timestamp, ``stride`` defaults to the window
    length (no overlap; a stride longer than the window skips time).  The
    recording is read chunk by chunk (:func:`iter_recording`), so memory is
    bounded by one window plus one chunk, not by the file.

    * Windows continue until one contains the last event; a window longer
      than the recording yields one window holding everything after the start.
      The last window's ``t_end_us`` is one microsecond after the last event
      (never past the end of the recording).
    * An empty window (a pause in the recording) is yielded with all-zero
      frames and an :class:`EmptyWindowWarning`.
    * Timestamps must not go backwards: that is an InputError naming the
      event index (we do not sort, since sorting needs the whole file).
    * Events outside the sensor are an InputError naming the event index.
    * ``denoise_us`` / ``refractory_us`` apply tonic's ``Denoise`` /
      ``RefractoryPeriod`` to each window's events separately (no state is
      carried across windows).  Their semantics are tonic's: Denoise keeps an
      event if a 4-neighbour fired within ``denoise_us`` *before* it (and keeps
      every event with ``t < denoise_us``); RefractoryPeriod drops an event
      closer than ``refractory_us`` to the pixel's previous event, dropped or
      not (and drops an event at ``t == 0``).  Both loop in Python (~1 us per
      event).
    * A recording without events, one whose events all have the same
      timestamp (a file cut short, most likely), or a start after its last
      event, is an InputError.
    * ``read_options`` say how the recording is read, as for
      :func:`~snn_fg.events.iter_recording`: ``sensor_size``, ``chunk_events``
      and the format options of :mod:`snn_fg.events.formats` (``encoding``,
      ``codec``, ``channel``, ``timer_bits``); an option that does not apply
      to the recording's format is a ParameterError.
    * It returns an iterator, read once like a generator, that can also hand
      the spiking model its events as read (:class:`WindowIterator`): given to
      ``model.run_windows`` whole, a run cut by ``max_windows`` reads on through
      the last window's read-out lag, as ``snn-fg run --max-windows`` does (a
      ``list`` of the windows ends with the last one: its lag runs without input).
    """
    return WindowIterator(
        RecordingWindows(
            recording_or_path,
            window_ms=window_ms,
            start_ms=start_ms,
            stride_ms=stride_ms,
            max_windows=max_windows,
            denoise_us=denoise_us,
            refractory_us=refractory_us,
            **read_options,
        )
    )


def _cut_windows(windows: RecordingWindows):
    """The windows of ``windows``, cut as they are read (the generator :func:`iter_windows` returned)."""
    stream, cut = windows.cut("iter_windows")
    for chunk in stream:
        yield from cut.add(chunk)
        if cut.done:
            return
    yield from cut.finish()


class WindowIterator:
    """What :func:`iter_windows` returns: its windows read once (``for``, ``next``),
    or (:meth:`cut`, before any is read) its events as read, for the spiking model,
    which reads the last window out from the events after it as a longer run does."""

    def __init__(self, windows: RecordingWindows):
        self._windows, self._it = windows, None

    def __iter__(self):
        return self

    def __next__(self) -> EventWindow:
        if self._it is None:
            self._it = _cut_windows(self._windows)
        return next(self._it)

    def cut(self, owner: str = "iter_windows"):
        """As :meth:`RecordingWindows.cut`; the iterator is used up by it."""
        if self._it is not None:
            raise InputError("<windows>", "windows of iter_windows already read: they are read once; call it again")
        self._it = iter(())
        return self._windows.cut(owner)


@dataclass(frozen=True)
class TimePassed:
    """A live stream's clock has reached ``t_us`` though no event came (those
    of a dropped slot were thrown away): what :meth:`WindowCutter.add` takes
    instead of events, so that the windows before it complete."""

    t_us: int

    def __len__(self) -> int:
        return 0


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
        window_ms: float = 85,
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
        # the events of the windows not yet complete, as they came: joined once a window completes
        # (joined at every chunk, a live stream's 5 ms chunks copied the whole window 17 times)
        self.parts: list = []
        self.t0 = self.w_start = self.w_end = self.prev_t = None
        self.k = self.seen = 0

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
        new = chunk[chunk["t"] >= self.w_start]
        if len(new):
            self.parts.append(new)
        return self._complete()

    def _events(self) -> np.ndarray:
        """The events held, in one array."""
        if len(self.parts) != 1:
            self.parts = [np.concatenate(self.parts) if self.parts else np.zeros(0, dtype=EVENT_DTYPE)]
        return self.parts[0]

    def _complete(self) -> list[EventWindow]:
        """The windows that end at or before the newest time."""
        out = []
        while self.prev_t >= self.w_end:  # every window that ends at or before the newest timestamp is complete
            buf = self._events()
            cut = int(np.searchsorted(buf["t"], self.w_end, side="left"))
            out.append(self._emit(buf[:cut], self.w_start, self.w_end))
            if self.done:
                break
            self.w_start += self.stride
            self.w_end = self.w_start + self.win
            self.parts = [buf[int(np.searchsorted(buf["t"], self.w_start, side="left")) :]]
        return out

    def finish(self) -> list[EventWindow]:
        """The last window, ending with the stream (one microsecond after its last event)."""
        if self.done:
            return []
        if self.t0 is None:
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
                    f"the start, {self.start_ms:g} ms, lies after the last event ({last_ms:g} ms after the first)",
                    remedy=Remedy(f"start_ms below {last_ms:g}", f"--start-ms below {last_ms:g}"),
                )
            return []
        # the last window ends with the recording: its nominal end may lie far beyond
        return [self._emit(self._events(), self.w_start, min(self.w_end, self.prev_t + 1))]

    def _emit(self, events, ws, we) -> EventWindow:
        ev = _filter(events, self.denoise_us, self.refractory_us)
        if not len(ev):
            warnings.warn(
                f"{self.name}: window {self.k} [{ws} us, {we} us) has no events; its frames are all zero",
                EmptyWindowWarning,
                stacklevel=4,
            )
        pos, neg = events_to_frame(ev, self.size)
        out = EventWindow(
            index=self.k, t_start_us=ws, t_end_us=we, events=ev, pos=pos, neg=neg, t_first_event_us=self.t0
        )
        self.k += 1
        return out
