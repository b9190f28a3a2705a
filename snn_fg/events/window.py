"""Stage 1 of the model: event frames, and cutting a recording into time windows."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numba import njit

from snn_fg import validate
from snn_fg.errors import InputError
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
    with ``options`` (a file is read again from its start), so that a
    reader that needs two passes (the spiking model calibrates its input
    on the whole recording first) holds one window at a time, not the
    recording."""

    def __init__(self, recording_or_path, **options):
        self.recording, self.options = recording_or_path, options

    def __iter__(self):
        return iter_windows(self.recording, **self.options)


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
    """
    read_options = check_read_options("iter_windows", read_options)
    win, start, stride = _window_times(window_ms, start_ms, stride_ms)
    _check_window_options(max_windows, denoise_us, refractory_us)
    stream = iter_recording(recording_or_path, **read_options)
    stream.warn_no_span = False  # (refused below)
    size = stream.sensor_size
    name = stream.path if stream.path is not None else "<array>"

    buf = np.zeros(0, dtype=EVENT_DTYPE)
    t0 = None
    w_start = w_end = None
    k = 0
    seen = 0
    prev_t = None

    def emit(events, ws, we):
        nonlocal k
        ev = _filter(events, denoise_us, refractory_us)
        if not len(ev):
            warnings.warn(
                f"{name}: window {k} [{ws} us, {we} us) has no events; its frames are all zero",
                EmptyWindowWarning,
                stacklevel=3,
            )
        pos, neg = events_to_frame(ev, size)
        out = EventWindow(index=k, t_start_us=ws, t_end_us=we, events=ev, pos=pos, neg=neg, t_first_event_us=t0)
        k += 1
        return out

    for chunk in stream:
        check_monotonic(chunk, name, offset=seen, prev_t=prev_t)
        seen += len(chunk)
        prev_t = int(chunk["t"][-1])
        if t0 is None:
            t0 = int(chunk["t"][0])
            w_start = t0 + start
            w_end = w_start + win
        buf = np.concatenate([buf, chunk[chunk["t"] >= w_start]]) if len(buf) else chunk[chunk["t"] >= w_start]
        # every window that ends at or before the newest timestamp is complete
        while prev_t >= w_end:
            cut = int(np.searchsorted(buf["t"], w_end, side="left"))
            yield emit(buf[:cut], w_start, w_end)
            if max_windows is not None and k >= max_windows:
                return
            w_start += stride
            w_end = w_start + win
            keep_from = int(np.searchsorted(buf["t"], w_start, side="left"))
            buf = buf[keep_from:]
    if t0 is None:
        raise InputError(name, "recording contains no events")
    if seen > 1 and prev_t == t0:
        raise InputError(name, f"{no_span_problem(seen, t0)} and has no window to cut; is the file cut short?")
    if w_start > prev_t:
        if k == 0:
            raise InputError(
                name, f"start_ms={start_ms} lies after the last event ({(prev_t - t0) / 1000:g} ms after the first)"
            )
        return
    # the last window ends with the recording: its nominal end may lie far beyond
    yield emit(buf, w_start, min(w_end, prev_t + 1))
