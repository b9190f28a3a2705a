"""A DAVIS camera's grey-level (APS) frames, on the clock of its events.

A DAVIS sensor's pixels give both events and, every few tens of
milliseconds, an intensity frame; an AEDAT 4 file stores the frames as a
stream of their own beside the events (:func:`snn_fg.events.aedat4.iter_frames`).
The frames come from the same pixels as the events, so the frame-based
model can read the very scene the event models read: this module gives
them to it.

* :func:`open_frames` says whether a recording has frames and how large
  they are; :func:`require_frames` turns "it has none" or "they are another
  size than the event sensor" into one clear line.
* :func:`iter_frames` reads them one at a time as :class:`ApsFrame` s,
  refusing frames out of time order or of another size.
* :func:`frame_summary` counts them and says how often they come
  (``snn-fg events``).
* :func:`with_frames` hands each event window the frame it is run on: the
  **last frame whose timestamp lies before the window's end** (``t_us <
  t_end_us``), which may lie before the window's start when frames are
  rarer than windows. A window before the first frame has none.

A frame's time is the middle of its exposure, from the start and end of
exposure every AEDAT 4 frame carries, in the same microseconds as the
events (the frame's own timestamp is the middle of the exposure by the
format's schema but its start by dv-processing's writer, so it is used only
when a file gives no exposure).
Formats other than AEDAT 4 carry no frames here (an ATIS Event Stream's
exposure measurements are per-pixel grey levels, not frames).

Examples
--------
>>> from snn_fg.events.aps import open_frames
>>> import numpy as np
>>> open_frames(np.zeros(0, [("x", "<u2"), ("y", "<u2"), ("t", "<i8"), ("p", "i1")])) is None
True
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snn_fg.errors import InputError, Remedy
from snn_fg.events import aedat4
from snn_fg.events.formats import detect_format
from snn_fg.events.frame import EventWindow


@dataclass(frozen=True)
class ApsFrame:
    """One grey-level frame: its place in the file (``index``), its time
    (``t_us``, the middle of its exposure, on the events' clock), the
    exposure's start and end (``exposure_us``) and the ``image``: uint8,
    ``(H, W)`` grey or ``(H, W, 3)`` RGB."""

    index: int
    t_us: int
    image: np.ndarray
    exposure_us: tuple[int, int]


@dataclass(frozen=True)
class FrameSource:
    """A recording's frame stream: its file and the frames' ``(width, height)``."""

    path: Path
    size: tuple[int, int]


@dataclass(frozen=True)
class FrameSummary:
    """How many frames a recording holds (``count``), their size ``(W, H)``,
    the first and last frame's times and the median time between two
    frames (us; ``None`` with fewer than two frames)."""

    count: int
    size: tuple[int, int]
    t_first_us: int | None
    t_last_us: int | None
    interval_us: float | None

    def text(self, origin_us: int | None = None) -> str:
        """One line: count, size, how often, and (with ``origin_us``, the
        recording's first event) when the first and last frame come."""
        if not self.count:
            return f"none (the frame stream, {self.size[0]} x {self.size[1]}, is empty)"
        line = f"{self.count:,} frames of {self.size[0]} x {self.size[1]}"
        if self.interval_us:
            line += f", one every {self.interval_us / 1000:.1f} ms ({1e6 / self.interval_us:.1f} per second)"
        if origin_us is not None:
            first, last = ((t - origin_us) / 1000 for t in (self.t_first_us, self.t_last_us))
            line += f", {first:g} to {last:g} ms after the first event"
        return line


@dataclass(frozen=True)
class ApsWindow(EventWindow):
    """An event window with the APS frame the frame-based model runs on
    (:func:`with_frames`); ``aps`` is ``None`` before the recording's first frame."""

    aps: ApsFrame | None = None


def open_frames(source) -> FrameSource | None:
    """The frame stream of ``source`` (a recording's path), or ``None`` when
    it has none: an AEDAT 4 file without a frame stream, any other format,
    or a recording in memory."""
    if not isinstance(source, (str, Path)):
        return None
    path = Path(source)
    if detect_format(path) != "aedat4":
        return None
    size = aedat4.frame_stream(path)
    if size is None:
        return None
    if None in size:
        raise InputError(path, "the AEDAT4 frame stream declares no width/height")
    return FrameSource(path, (int(size[0]), int(size[1])))


def require_frames(source, sensor_size) -> FrameSource:
    """:func:`open_frames`, refusing in one line a recording without frames
    and frames of another size than the event sensor ``(W, H, ...)``."""
    frames = open_frames(source)
    if frames is None:
        what = Path(str(source)).suffix or "an in-memory recording"
        has = "holds events only" if what == ".aedat4" else f"is {what}, a format that carries no frames"
        raise InputError(
            source if isinstance(source, (str, Path)) else "<array>",
            f"has no APS frames (it {has}): the fbfg model reads the grey-level frames of a DAVIS "
            "camera's AEDAT4 recording, and an event model reads its events",
            remedy=Remedy("name='rate' or 'spiking' to get_model", "--model rate or spiking"),
        )
    _check_size(frames.path, frames.size, (0, 0), sensor_size, "the frame stream")
    return frames


def _check_size(path, size, offset, sensor_size, what: str, where=None) -> None:
    w, h = int(sensor_size[0]), int(sensor_size[1])
    if tuple(size) != (w, h) or tuple(offset) != (0, 0):
        at = f" at offset ({offset[0]}, {offset[1]})" if tuple(offset) != (0, 0) else ""
        raise InputError(
            path,
            f"{what} is {size[0]} x {size[1]} pixels{at} but the event sensor is {w} x {h}: the frame "
            "model's maps must lie on the event pixels to be compared with the event models'",
            where,
        )


def _middle_of_exposure(raw: dict) -> int:
    """A decoded frame's time: the middle of its exposure (its timestamp when it gives no exposure)."""
    begin, end = int(raw["exposure_begin_t"]), int(raw["exposure_end_t"])
    return (begin + end) // 2 if end > begin > 0 else int(raw["t"])


def _image(raw: dict) -> np.ndarray:
    """The frame's pixels as uint8 grey ``(H, W)`` or RGB ``(H, W, 3)`` (alpha dropped)."""
    pixels = np.asarray(raw["pixels"], dtype=np.uint8)
    return pixels[..., :3] if pixels.ndim == 3 else pixels


def iter_frames(frames: FrameSource, sensor_size=None):
    """The :class:`ApsFrame` s of ``frames`` in file order, one at a time.

    A frame earlier than the one before it is an :class:`InputError` naming
    both (we do not sort: that would hold every frame); with ``sensor_size``
    a frame of another size than the sensor, or placed at an offset (a
    region of interest), is one too.
    """
    prev = None
    for k, raw in enumerate(aedat4.iter_frames(frames.path)):
        t = _middle_of_exposure(raw)
        where = f"APS frame {k}"
        if prev is not None and t < prev:
            raise InputError(
                frames.path,
                f"APS frames out of time order: frame {k} ({t} us) comes before frame {k - 1} ({prev} us)",
                where,
            )
        if sensor_size is not None:
            size, offset = (raw["width"], raw["height"]), (raw["offset_x"], raw["offset_y"])
            _check_size(frames.path, size, offset, sensor_size, f"APS frame {k}", where)
        prev = t
        yield ApsFrame(k, t, _image(raw), (int(raw["exposure_begin_t"]), int(raw["exposure_end_t"])))


def frame_summary(frames: FrameSource) -> FrameSummary:
    """Count the frames of ``frames`` and how often they come (one pass, no image kept)."""
    times = [f.t_us for f in iter_frames(frames)]
    steps = np.diff(times)
    return FrameSummary(
        count=len(times),
        size=frames.size,
        t_first_us=times[0] if times else None,
        t_last_us=times[-1] if times else None,
        interval_us=float(np.median(steps)) if len(steps) else None,
    )


def with_frames(windows, frames):
    """Each window of ``windows`` (in time order) as an :class:`ApsWindow`
    holding the last frame of ``frames`` (:class:`ApsFrame` s in time order)
    whose time lies before the window's end; frames are read as the windows
    need them."""
    it = iter(frames)
    pending, current = next(it, None), None
    for w in windows:
        while pending is not None and pending.t_us < w.t_end_us:
            current, pending = pending, next(it, None)
        yield ApsWindow(**{f.name: getattr(w, f.name) for f in dataclasses.fields(w)}, aps=current)


class FramedWindows:
    """A recording's windows (re-iterable, e.g. :class:`~snn_fg.events.RecordingWindows`)
    each paired with its frame (:func:`with_frames`) on every iteration, the
    frames read again with the windows and checked against ``sensor_size``."""

    def __init__(self, windows, frames: FrameSource, sensor_size):
        self.windows, self.frames, self.sensor_size = windows, frames, sensor_size

    def __iter__(self):
        return with_frames(self.windows, iter_frames(self.frames, self.sensor_size))


def pairing_note(t_end_us, aps_index, aps_t_us=None) -> str:
    """One line on which frame each window ran on: the windows' ends and, per
    window, the frame's index (-1: none yet) and time (one clock; ``None``
    when no window had a frame)."""
    t_end_us, aps_index = np.asarray(t_end_us), np.asarray(aps_index)
    has = aps_index >= 0
    line = f"each window ran on the last APS frame before its end: {int(has.sum())} of {len(has)} windows"
    if has.any():
        lag = (t_end_us[has] - np.asarray(aps_t_us)[has]) / 1000
        used = np.unique(aps_index[has])
        line += (
            f", {len(used)} distinct frame{'s' if len(used) > 1 else ''} "
            f"({lag.min():.1f}-{lag.max():.1f} ms before the window's end)"
        )
    if not has.all():
        line += f"; {int((~has).sum())} window{'s' if (~has).sum() > 1 else ''} before the first frame: maps empty"
    return line
