"""A recording cut into time windows (:func:`iter_windows`, :class:`RecordingWindows`), read once
or again, with :mod:`snn_fg.events.cutter`'s cutter; the windows are :mod:`snn_fg.events.frame`'s."""

from __future__ import annotations

from snn_fg.errors import InputError
from snn_fg.events.cutter import WINDOW_MS, WindowCutter
from snn_fg.events.formats import check_read_options
from snn_fg.events.frame import EventWindow
from snn_fg.events.io import iter_recording


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
        cutter = WindowCutter(stream.sensor_size, stream.path if stream.path is not None else "<array>", **window)
        if cutter.start > 0:  # (a file that indexes its times is read from the first window's start)
            skipped = stream.skip_to(cutter.start)
            if skipped is not None:
                cutter.begin_at(*skipped)
        return stream, cutter


#: the options of :func:`iter_windows` that say how a stream is cut (the others say how it is read)
WINDOW_KEYS = ("window_ms", "start_ms", "stride_ms", "max_windows", "denoise_us", "refractory_us")


def iter_windows(
    recording_or_path,
    *,
    window_ms: float = WINDOW_MS,
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
      (never past the end of the recording): how the models read such a short
      window out and how it is scored, ``docs/usage.md`` ("A recording's last window").
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
      ``codec``, ``channel``, ``timer_bits``, ``chip``); an option that does not apply
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
        yield from handed_out(cut.add(chunk))
        if cut.done:
            return
    yield from handed_out(cut.finish())


def handed_out(windows: list):
    """The windows of the list one by one, each let go of as it is handed out: a chunk can
    complete thousands of short windows at once, and a window read keeps its frames (a
    0.1 ms window over a 1 s recording held 1.5 GB of frames until its chunk was done)."""
    windows.reverse()
    while windows:
        yield windows.pop()


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
