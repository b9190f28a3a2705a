"""Running a model on an input into an output folder, as ``snn-fg run`` does
(the folder is an :class:`~snn_fg.atomic.OutputFolder`: all or nothing).
"""
from __future__ import annotations

import sys
import warnings
from pathlib import Path

import numpy as np

from . import cancel
from .errors import InputError
from .inputs import Frame
from .maps import Maps, MapsSeriesWriter
from .models import Model


def run_frame(model: Model, frame: Frame, out: Path, source: dict, crop=None, figures: bool = True) -> Maps:
    """One frame through ``model``; ``maps.npz`` and (with ``figures``) its
    figures into ``out`` (``crop``: see :meth:`Model.write_figures`)."""
    maps = model.run_frame(frame)
    maps.params = {**maps.params, "source": source}
    maps.save(out / "maps.npz")
    if figures:
        model.write_figures(out, maps, model.figure_input(frame), crop=crop)
    return maps


class _LazyFrames:
    """Event frames (+1 ON, -1 OFF) shown as RGB only when a figure row needs them."""

    def __init__(self, frames):
        self.frames = frames

    def __len__(self):
        return len(self.frames)

    def __getitem__(self, i):
        f = self.frames[i]
        return model_input_rgb(f)


def model_input_rgb(frame):
    from .figures import event_frame_rgb

    return event_frame_rgb(frame > 0, frame < 0)


def run_recording(model: Model, windows, out: Path, source: dict, name: str, crop=None, figures: bool = True) -> int:
    """Every window of a recording through ``model``; one ``maps.npz`` (one
    map per window, streamed to disk) and (with ``figures``) its figures into
    ``out``. Returns the number of windows (``crop``: see
    :meth:`Model.write_figures`).

    The windows' times (``t_start_us``, ``t_end_us``, figure titles) count
    from the recording's first event; ``params["source"]["first_event_us"]``
    keeps that event's time in the file's own clock. Each window's share of
    pixels with an event is recorded (``pixel_share``), and a window above
    :data:`~snn_fg.events.activity.SATURATED_SHARE` is warned about and
    listed (``saturated_windows``)."""
    from .events import EmptyWindowWarning
    from .events.activity import Activity, pixel_share, saturated_lines

    t0, t1, n_events, shares = [], [], [], []
    origin = None           # the recording's first event: times a user sees count from it
    n_empty = n_blank = 0
    with MapsSeriesWriter(out / "maps.npz") as sink, warnings.catch_warnings():
        warnings.simplefilter("ignore", EmptyWindowWarning)     # counted and reported once below
        for w, maps in model.run_windows(windows):
            cancel.check()          # (an interrupt swallowed inside the window stops the run here)
            has_events = bool(w.pos.any() or w.neg.any())
            n_empty += not has_events
            n_blank += has_events and not (maps.fg_x.any() or maps.fg_y.any())
            # the window's event frame (+1 ON, -1 OFF) is kept with its maps
            sink.append(maps, event_frame=w.pos.astype(np.int8) - w.neg.astype(np.int8))
            if origin is None:
                origin = w.t_start_us if w.t_first_event_us is None else w.t_first_event_us
            t0.append(w.t_start_us - origin)
            t1.append(w.t_end_us - origin)
            n_events.append(len(w.events))
            shares.append(pixel_share(w))
        if sink.n == 0:
            raise InputError(name, "no window to process: the recording has no events after --start-ms")
        if n_empty:
            print(f"snn-fg: warning: {n_empty} of {sink.n} windows had no events; their maps are zero",
                  file=sys.stderr)
        if n_blank:
            hint = f" ({model.blank_window_hint})" if model.blank_window_hint else ""
            print(f"snn-fg: warning: {n_blank} of {sink.n - n_empty} windows with events have no figure-ground "
                  f"vector{hint}", file=sys.stderr)
        act = Activity(t_start_ms=np.array(t0) / 1000, t_end_ms=np.array(t1) / 1000, events=np.array(n_events),
                       share=np.array(shares), window_ms=source.get("window_ms", 0))
        for line in saturated_lines(act):
            print(f"snn-fg: warning: {line}", file=sys.stderr)
        source = {**source, "first_event_us": origin,     # the file's clock: the one absolute time kept
                  "pixel_share": [round(v, 4) for v in shares], "saturated_windows": act.saturated.tolist()}
        st = sink.stacked()
        maps = Maps(st["fg_x"], st["fg_y"], st["grouping"], {**sink.params, "source": source},
                    {k: v for k, v in st.items() if k not in ("fg_x", "fg_y", "grouping")})
        titles = [f"{a / 1000:.0f}-{b / 1000:.0f} ms" for a, b in zip(t0, t1)]
        sink.finish(maps.params, t_start_us=np.array(t0, dtype=np.int64), t_end_us=np.array(t1, dtype=np.int64))
        if figures:
            model.write_figures(out, maps, _LazyFrames(st["event_frame"]), titles, crop)
        return sink.n
