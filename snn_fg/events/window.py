"""Stage 1 of the model: event frames (:func:`events_to_frame`, :class:`EventWindow`), and a
recording cut into time windows (:func:`iter_windows`, with :mod:`snn_fg.events.cutter`'s cutter)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from snn_fg.errors import InputError
from snn_fg.events._core import as_events, check_in_sensor, sensor_size_parameter
from snn_fg.events.formats import check_read_options
from snn_fg.events.io import iter_recording


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
        from snn_fg.events.cutter import WindowCutter  # (the cutter builds on this module's windows)

        return stream, WindowCutter(stream.sensor_size, stream.path if stream.path is not None else "<array>", **window)


#: the options of :func:`iter_windows` that say how a stream is cut (the others say how it is read)
WINDOW_KEYS = ("window_ms", "start_ms", "stride_ms", "max_windows", "denoise_us", "refractory_us")


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
