"""What a recording's run writes beside its maps, and what ``snn-fg plot`` draws from them.

A recording's output folder gets ``windows.csv`` (:mod:`.timeline`: a row per window) and, with
figures, ``maps.png`` (:data:`OVERVIEW_ROWS` windows evenly spaced, one grouping scale for the
whole recording) and ``timeline.png`` (the run over time). ``snn-fg plot`` draws any window as
a figure of its own, on the same grouping scale (:func:`save_window_figures`), and the maps over
the recording as an animation (:mod:`.animation`). Everything here reads a store's windows one at
a time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .activity import SATURATED_SHARE
from .atomic import save_figure
from .figures import APS_INPUT, EVENTS_INPUT, maps_figure, on_sensor, rows_shown, signed_frame_rgb
from .maps import input_name, made_by, made_from
from .outputs import WINDOW_FIGURE
from .store import STORE_NAME, read_attrs
from .timeline import (
    TABLE_NAME,
    TIMELINE_NAME,
    number_ranges,
    save_table,
    timeline_figure,
    window_numbers,
    window_rows,
)

#: windows the overview ``maps.png`` of a recording draws at most (evenly spaced)
OVERVIEW_ROWS = 6


class EventFrames:
    """A recording's event frames (+1 ON, -1 OFF), each shown as RGB only when a figure needs it."""

    def __init__(self, frames):
        self.frames = frames

    def __len__(self):
        return len(self.frames)

    def __getitem__(self, i):
        return signed_frame_rgb(self.frames[i])


def input_images(maps):
    """What a recording's figures show as each window's input: the APS frame the frame-based model
    ran on where the run stored one, else the window's event frame (:class:`EventFrames`)."""
    return maps.extra["aps_frame"] if "aps_frame" in maps.extra else EventFrames(maps.extra["event_frame"])


def input_note(maps) -> str:
    """What a figure's key says the input column of :func:`input_images` shows."""
    return APS_INPUT if "aps_frame" in maps.extra else EVENTS_INPUT


def _ms(us, decimals: int = 1) -> str:
    """A time in ms as a title gives it: whole ms, or to ``decimals`` places where the windows are not whole ms."""
    return f"{round(float(us) / 1000, decimals):g}"


def _decimals(times_us) -> int:
    """The places of ms that tell a recording's window times apart: tenths, more for windows shorter
    than 0.1 ms (two windows of 0.05 ms were both titled 999-999 ms), at most microseconds."""
    t = np.unique(np.asarray(times_us, np.int64))
    step = int(np.diff(t).min()) if t.size > 1 else 1000
    return min(3, max(1, 3 - len(str(max(step, 1))) + 1))


def saturated(maps) -> np.ndarray:
    """Whether each window of a recording's maps is a sensor-wide burst (events on more than
    :data:`~snn_fg.results.activity.SATURATED_SHARE` of the pixels: not a scene)."""
    return np.asarray(maps.extra["pixel_share"], float) > SATURATED_SHARE


def window_titles(maps) -> list[str]:
    """``window 3: 255-340 ms`` for every window (its number, :func:`~.timeline.window_numbers`; times
    from the recording's first event), a saturated window marked so."""
    starts, ends = maps.extra["t_start_us"], maps.extra["t_end_us"]
    d = _decimals(np.concatenate([np.ravel(starts), np.ravel(ends)]))
    spans = zip(window_numbers(maps), starts, ends, saturated(maps), strict=True)
    return [f"window {k}: {_ms(a, d)}-{_ms(b, d)} ms" + (", saturated" if s else "") for k, a, b, s in spans]


def grouping_top(maps) -> float:
    """The top of a recording's one grouping colour scale: the largest grouping value of its
    windows, leaving out saturated ones (a burst's grouping, 830 on dvs.es against 430-630 in
    its other windows, dimmed every scene; it is drawn clipped) unless every window is one."""
    burst = saturated(maps)
    keep = [i for i in range(len(burst)) if not burst[i]] or range(len(burst))
    return max((float(np.asarray(maps.grouping[i]).max(initial=0.0)) for i in keep), default=0.0)


def overview_options(maps, folder) -> dict:
    """The keywords of :func:`~.figures.maps_figure` for a recording's overview ``maps.png`` (its
    titles, one grouping scale for every window, how to draw the windows it leaves out)."""
    return {
        "titles": window_titles(maps),
        "max_rows": OVERVIEW_ROWS,
        "grouping_max": grouping_top(maps),
        "hint": f"snn-fg plot {folder} --windows I,J,... draws any",
        "input_note": input_note(maps),
        "labels": window_numbers(maps).tolist(),
        "made_by": made_from(maps.params),
    }


def write_run_tables(folder, maps, *, figures: bool, coverage: bool = True, table: bool = True) -> list[dict]:
    """``windows.csv`` (``table``) and (``figures``) ``timeline.png`` of a recording's run into
    ``folder``; the table's rows (``coverage``: see :func:`~.timeline.window_rows`)."""
    folder = Path(folder)
    rows = window_rows(maps, coverage=coverage)
    if table:
        save_table(folder / TABLE_NAME, rows)
    if figures:
        save_figure(timeline_of(maps, rows, folder), folder / TIMELINE_NAME, dpi=110)
    return rows


def timeline_of(maps, rows, folder):
    """``timeline.png`` of the recording's run in ``folder`` (its ``maps`` and their ``rows``,
    :func:`~.timeline.window_rows`): with a live run's hops skipped and windows dropped (its store
    keeps them), and for a run cut short (its store not complete: Ctrl-C, an error) the window
    where it stopped, the last one stored, skipped or dropped."""
    source = maps.params.get("source", {})
    title = f"{input_name(maps.params, Path(folder).name)}: {made_by(maps.params)}, window by window"
    skipped, dropped = (maps.params.get(k, ()) for k in ("skipped_windows", "dropped_windows"))
    store = Path(folder) / STORE_NAME
    if store.is_dir() and not read_attrs(store)["snn_fg"]["complete"]:
        last = max([int(window_numbers(maps)[-1]), *(hi for _, hi in number_ranges([*skipped, *dropped]))])
        title += f" up to window {last}, where the run was cut short"
    stride = source.get("stride_ms")
    return timeline_figure(
        rows,
        float(source.get("window_ms", 0.0)),
        title,
        rows_shown(len(rows), OVERVIEW_ROWS),
        skipped,
        dropped=dropped,
        stride_ms=None if stride is None else float(stride),
    )


def window_figure(maps, i: int, *, grouping_label: str, grouping_max: float, crop=None):
    """Window ``i`` of a recording's maps as a figure of its own (input, figure-ground, grouping),
    on the grouping scale ``grouping_max`` (the whole recording's, so that windows compare), under
    a title that names the model and the recording."""
    return maps_figure(
        input_images(maps),
        maps.fg_x,
        maps.fg_y,
        maps.grouping,
        window_titles(maps),
        rows=[i],
        grouping_label=grouping_label,
        grouping_max=grouping_max,
        input_note=input_note(maps),
        made_by=made_from(maps.params),
        **on_sensor(maps.params, crop, maps.fg_x.shape),
    )


def save_window_figures(maps, windows, folder, *, grouping_label: str, crop=None) -> list[Path]:
    """:func:`window_figure` of each of ``windows`` (places in ``maps``) into ``folder``, named
    by its number (:data:`~snn_fg.results.outputs.WINDOW_FIGURE`, :func:`~.timeline.window_numbers`)."""
    top = grouping_top(maps)
    folder = Path(folder)
    numbers = window_numbers(maps)
    return [
        save_figure(
            window_figure(maps, i, grouping_label=grouping_label, grouping_max=top, crop=crop),
            folder / WINDOW_FIGURE.format(numbers[i]),
            dpi=110,
        )
        for i in windows
    ]
