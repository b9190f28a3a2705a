"""Open event-camera recordings: one entry point for every supported format
(:func:`iter_recording` chunk by chunk, :func:`open_recording` whole), for a
file (its format told by :mod:`.formats`), a :class:`~snn_fg.events.Recording`
or a structured event array.

All timestamps are microseconds (int64); the first timestamp is kept as the
file gives it (not shifted to zero). An ATIS Event Stream holds two kinds of
events: change detections, which are polarity events and are returned, and
exposure measurements, which carry grey levels; these are counted
(``Recording.exposure_events``, ``RecordingStream.exposure_events``) and left
out.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from snn_fg import validate
from snn_fg.errors import InputError, InputWarning
from snn_fg.events.core import (
    Recording,
    as_events,
    check_in_sensor,
    check_sensor_size,
    empty_events,
    infer_sensor_size,
    sensor_size_parameter,
)
from snn_fg.events.formats import FORMATS, check_format_options, detect_format, refuse_options
from snn_fg.events.source import DecodeTally, Source
from snn_fg.results.progress import bar

DEFAULT_CHUNK = 1_000_000


def _chunks_of(events: np.ndarray, exposure_events: int = 0):
    def chunks(n, tally):
        tally.exposure_events = exposure_events
        for i in range(0, max(len(events), 1), n):
            yield events[i : i + n]

    return chunks


def _open_source(source, sensor_size, chunk_events, options: dict) -> Source:
    if isinstance(source, (Recording, RecordingStream, np.ndarray)):
        refuse_options(options, "<array>", "an in-memory recording")
    if isinstance(source, Recording):
        size = check_sensor_size(sensor_size or source.sensor_size)
        return Source(source.path, source.format, size, _chunks_of(source.events, source.exposure_events))
    if isinstance(source, RecordingStream):
        return source._source
    if isinstance(source, np.ndarray):
        ev = as_events(source, "<array>")
        size = sensor_size if sensor_size is not None else infer_sensor_size("<array>", [ev])
        return Source(None, "array", size, _chunks_of(ev))
    if not isinstance(source, (str, Path)):
        raise InputError(repr(source)[:60], "expected a file path, a Recording or a structured event array")
    path = Path(source)
    fmt = FORMATS[detect_format(path)]
    foreign = {k: v for k, v in options.items() if k not in fmt.options}
    refuse_options(foreign, str(path), fmt.label)
    return fmt.opener(path, sensor_size, chunk_events, **options)


class RecordingStream:
    """A recording read chunk by chunk: iterate it to get event arrays.

    Header information (``format``, ``sensor_size``, ``path``) is available
    before reading; each iteration re-reads the file from the start.  Chunks
    hold at most ``chunk_events`` events (fewer at the end), are validated
    (coordinates inside the sensor; errors name the global event index) and
    have dtype :data:`EVENT_DTYPE`.  ``streams`` tells whether the underlying
    reader works with bounded memory (see the module table).
    ``exposure_events`` counts the ATIS exposure events skipped so far in the
    latest iteration (the file's total once an iteration has finished);
    ``skipped`` names everything left out (exposure events, AEDAT4 frames,
    IMU samples and triggers, the other camera of a YARP log...) with counts.
    The format options are described in :mod:`snn_fg.events.formats`.
    An iteration that ends with more than one event, all at one timestamp,
    warns (:class:`~snn_fg.errors.InputWarning`): such a stream is most
    likely a file cut short (``warn_no_span = False`` turns this off, for a
    reader that refuses such a stream itself).
    """

    warn_no_span = True

    def __init__(
        self,
        source,
        *,
        chunk_events: int = DEFAULT_CHUNK,
        sensor_size=None,
        progress: bool = False,
        encoding: str | None = None,
        codec: str | None = None,
        channel: int | str | None = None,
        timer_bits: int | None = None,
        chip: str | None = None,
    ):
        options = check_format_options(
            "RecordingStream", encoding=encoding, codec=codec, channel=channel, timer_bits=timer_bits, chip=chip
        )
        if sensor_size is not None:
            sensor_size = sensor_size_parameter("RecordingStream", sensor_size)
        self.chunk_events = validate.integer("RecordingStream", "chunk_events", chunk_events, lo=1)
        self._source = _open_source(source, sensor_size, self.chunk_events, options)
        self.progress = progress
        self._tally = DecodeTally()
        self._skip = None

    path = property(lambda self: self._source.path)
    format = property(lambda self: self._source.format)
    sensor_size = property(lambda self: self._source.sensor_size)
    streams = property(lambda self: self._source.streams)
    exposure_events = property(lambda self: self._tally.exposure_events)
    #: what the latest iteration read and left out, by kind, with counts (see DecodeTally.skipped)
    skipped = property(lambda self: self._tally.skipped)

    def skip_to(self, after_us: int) -> tuple[int, int] | None:
        """Begin every later iteration at the events from ``after_us`` after the first one, where the
        file's own index of its times says where they lie (DSEC's ``ms_to_idx``): ``(the first
        event's time, the events left unread)``; None where it cannot say (the stream reads from the
        start). Errors name events by their index in the whole file still."""
        skip = self._source.skip(int(after_us)) if self._source.skip is not None else None
        self._skip = skip
        return None if skip is None else (skip.t_first, skip.index)

    def __iter__(self) -> Iterator[np.ndarray]:
        src = self._source
        name = src.path if src.path is not None else "<array>"
        self._tally = tally = DecodeTally()
        bar = self._progress_bar(name)
        n, t_first, t_last = 0, None, None
        chunks, first = (src.chunks, 0) if self._skip is None else (self._skip.chunks, self._skip.index)
        try:
            for out in _rechunk(chunks(self.chunk_events, tally), self.chunk_events, name, src.sensor_size, first):
                if bar is not None:
                    bar.update(len(out))
                n += len(out)
                t_first = int(out["t"][0]) if t_first is None else t_first
                t_last = int(out["t"][-1])
                yield out
        finally:
            if bar is not None:
                bar.close()
        if self.warn_no_span and n > 1 and t_first == t_last:
            warnings.warn(f"{name}: {no_span_problem(n, t_first)}; is the file cut short?", InputWarning, stacklevel=2)

    def _progress_bar(self, name):
        if not self.progress:
            return None

        return bar(f"reading {Path(str(name)).name}", "events", unit_scale=True)


def no_span_problem(n: int, t: int) -> str:
    """What is wrong with a stream of ``n`` events all at time ``t``."""
    return f"all {n:,} events have the same timestamp ({t} us), so the recording spans no time"


def _rechunk(raw_chunks, n: int, name, sensor_size, first: int = 0) -> Iterator[np.ndarray]:
    """Validated :data:`EVENT_DTYPE` chunks of exactly ``n`` events (the last may be shorter);
    ``first``: the file's events before the first of ``raw_chunks`` (for the indices errors give).

    A decoder that meets damage (a file cut inside an event, bytes that are no event) has
    yielded the events before it: they are yielded too, so that the windows they complete
    are cut, and then its error is raised with the index of the event at fault
    (:func:`at_event`)."""
    done = first
    pending = []
    pending_n = 0
    raw_chunks, damage = iter(raw_chunks), None
    while True:
        try:
            raw = next(raw_chunks)
        except StopIteration:
            break
        except InputError as exc:
            damage = exc
            break
        ev = as_events(raw, name, offset=done + pending_n)
        check_in_sensor(ev, sensor_size, name, offset=done + pending_n)
        if not len(ev):
            continue
        pending.append(ev)
        pending_n += len(ev)
        while pending_n >= n:
            buf = np.concatenate(pending) if len(pending) > 1 else pending[0]
            out, rest = buf[:n], buf[n:]
            pending, pending_n = ([rest] if len(rest) else []), len(rest)
            done += len(out)
            yield out
    if pending_n:
        yield np.concatenate(pending) if len(pending) > 1 else pending[0]
    if damage is not None:
        raise at_event(damage, done + pending_n) from None


def at_event(error: InputError, index: int) -> InputError:
    """``error``, a decoder's (which knows the byte offset), with the index of the event at
    fault added to its place: ``index`` events came before it (an error that names an
    event already is returned as it is)."""
    where = error.where or ""
    if "event" in where:
        return error
    where = f"{where}, event {index}" if where else f"event {index}"
    return error.but(where=where)


def iter_recording(
    source,
    *,
    chunk_events: int = DEFAULT_CHUNK,
    sensor_size=None,
    progress: bool = False,
    encoding: str | None = None,
    codec: str | None = None,
    channel: int | str | None = None,
    timer_bits: int | None = None,
    chip: str | None = None,
) -> RecordingStream:
    """Stream a recording in chunks of at most ``chunk_events`` events.

    ``source`` is a path, a :class:`Recording` or a structured array.  The
    returned :class:`RecordingStream` is iterable and knows ``format`` and
    ``sensor_size`` up front.  Memory stays bounded for the formats in
    :data:`STREAMING_FORMATS`; ``.npz`` and N-MNIST ``.bin`` are read whole.
    ``encoding``, ``codec``, ``channel``, ``timer_bits`` and ``chip`` are the
    format options of :mod:`snn_fg.events.formats`.

    Examples
    --------
    >>> import numpy as np
    >>> from snn_fg.events import EVENT_DTYPE
    >>> ev = np.zeros(250, EVENT_DTYPE)
    >>> ev["t"] = np.arange(250) * 100
    >>> stream = iter_recording(ev, chunk_events=100, sensor_size=(8, 8))
    >>> stream.format, [len(chunk) for chunk in stream]
    ('array', [100, 100, 50])
    """
    options = check_format_options(
        "iter_recording", encoding=encoding, codec=codec, channel=channel, timer_bits=timer_bits, chip=chip
    )
    if sensor_size is not None:
        sensor_size_parameter("iter_recording", sensor_size)
    return RecordingStream(source, chunk_events=chunk_events, sensor_size=sensor_size, progress=progress, **options)


def open_recording(
    path,
    *,
    sensor_size=None,
    progress: bool = False,
    encoding: str | None = None,
    codec: str | None = None,
    channel: int | str | None = None,
    timer_bits: int | None = None,
    chip: str | None = None,
) -> Recording:
    """Read a whole recording (any supported format, or a structured array).

    Parameters
    ----------
    path : str, Path, Recording or structured array
        The recording; the extension picks the format (see the module table)
        and the file's first bytes must agree with it.
    sensor_size : (int, int), optional
        ``(W, H)``: overrides the file's geometry; required for headerless
        EVT2/EVT3 files. Arrays and ``.npy`` files without it get
        ``(max x + 1, max y + 1)``.
    progress : bool
        Show a progress bar while reading.
    encoding, codec, channel, timer_bits, chip
        Format options: ``encoding`` ("evt2", "evt3") for RAW files without a
        header, ``codec`` ("auto", "24", "20"), ``channel`` (0, 1, "both") and
        ``timer_bits`` for iCub YARP logs (``channel`` 0 or 1 for MVSEC's HDF5), ``chip`` ("dvs128", "davis240", ...)
        for AEDAT 2.0 files whose header names no camera. An option for another
        format is refused.

    Returns
    -------
    Recording
        ``events`` (x, y, t in microseconds, p), ``sensor_size`` (W, H, 2),
        ``format``, ``path`` and, for ATIS Event Streams, the number of
        exposure events left out (``exposure_events``).

    Raises
    ------
    InputError
        A bad file, naming it, the problem and the byte offset or event.
    ParameterError
        A bad or inapplicable option.

    Examples
    --------
    >>> import numpy as np
    >>> from snn_fg.events import EVENT_DTYPE
    >>> rec = open_recording(np.array([(1, 0, 10, 1), (2, 1, 20, 0), (3, 2, 30, 1)], EVENT_DTYPE),
    ...                      sensor_size=(4, 3))
    >>> rec.format, len(rec), rec.sensor_size, rec.duration_us
    ('array', 3, (4, 3, 2), 20)
    """
    options = check_format_options(
        "open_recording", encoding=encoding, codec=codec, channel=channel, timer_bits=timer_bits, chip=chip
    )
    if sensor_size is not None:
        sensor_size_parameter("open_recording", sensor_size)
    stream = RecordingStream(path, chunk_events=DEFAULT_CHUNK, sensor_size=sensor_size, progress=progress, **options)
    parts = list(stream)
    events = np.concatenate(parts) if len(parts) > 1 else (parts[0] if parts else empty_events())
    return Recording(
        events=events,
        sensor_size=stream.sensor_size,
        format=stream.format,
        path=stream.path,
        exposure_events=stream.exposure_events,
    )
