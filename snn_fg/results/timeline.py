"""A recording's run window by window: a table (``windows.csv``) and a figure over time
(``timeline.png``).

Per window: its span (ms after the recording's first event), its events and the share of the
sensor's pixels they cover (a share above
:data:`~snn_fg.results.activity.SATURATED_SHARE` is a sensor-wide burst, not a scene), the pixels
with a figure-ground vector and their share of the pixels with an event (``fg_coverage``: how much
of the input the model decided on; empty for a model that gives every event pixel a vector by
construction, the rate models, whose share is 1 in every window), and the grouping map's peak and
where it lies (the strongest proto-object centre, in sensor pixels also for maps kept on blocks:
their pixels and coverage are counted in blocks).

Example
-------
>>> import numpy as np
>>> from snn_fg.results.maps import Maps
>>> g = np.zeros((2, 4, 6), np.float32); g[1, 2, 5] = 3.0
>>> fx = np.zeros_like(g); fx[0, 1, 1] = 1.0
>>> frame = np.zeros((2, 4, 6), np.int8); frame[0, 1, 1:3] = 1
>>> extra = {"event_frame": frame, "t_start_us": np.array([0, 85_000]), "t_end_us": np.array([85_000, 170_000]),
...          "event_count": np.array([40, 0]), "pixel_share": np.array([2 / 24, 0.0])}
>>> rows = window_rows(Maps(fx, np.zeros_like(g), g, extra=extra))
>>> [(r["window"], r["events"], r["fg_pixels"], r["fg_coverage"], r["grouping_peak"], r["peak_x"]) for r in rows]
[(0, 40, 1, 0.5, 0.0, None), (1, 0, 0, None, 3.0, 5)]
"""

from __future__ import annotations

import csv
import io
import textwrap

import numpy as np

from .activity import SATURATED_SHARE, Activity, draw_activity, scene_bars
from .atomic import save_text
from .maps import has_vector, maps_scale, sensor_pixel

#: the file names of the table and the figures in a run's output folder (the maps' figure: a still's too)
TABLE_NAME = "windows.csv"
TIMELINE_NAME = "timeline.png"
MAPS_FIGURE = "maps.png"
#: the table's columns
COLUMNS = (
    "window",
    "t_start_ms",
    "t_end_ms",
    "events",
    "pixel_share",
    "saturated",
    "fg_pixels",
    "fg_coverage",
    "grouping_peak",
    "peak_x",
    "peak_y",
)


#: the characters of a title line in the 9-inch figure (a longer title is wrapped)
TITLE_CHARS = 110


def window_numbers(maps) -> np.ndarray:
    """Each stored window's number in its recording or stream: window ``k`` begins ``k`` strides
    after the first window's start. A live run that dropped windows keeps the others under their
    own numbers (``extra["window"]``, written with each window); a store written without them
    holds every window from 0, numbered by its place."""
    n = maps.fg_x.shape[0]
    return np.asarray(maps.extra["window"], np.int64) if "window" in maps.extra else np.arange(n, dtype=np.int64)


def window_rows(maps, *, coverage: bool = True) -> list[dict]:
    """One row of :data:`COLUMNS` per window of a recording's :class:`~snn_fg.results.maps.Maps`
    (read a block of windows at a time, a block being a store's chunk: its lazy arrays stay on
    disk, and each chunk is decoded once); ``coverage=False``: ``fg_coverage`` left empty (a
    model whose share is 1 by construction)."""
    ex = maps.extra
    numbers = window_numbers(maps)
    n = maps.fg_x.shape[0]
    step = max(1, int(getattr(maps.fg_x, "chunks", (BLOCK,))[0]))
    scale = maps_scale(maps.params)
    rows = []
    for a in range(0, n, step):
        b = min(n, a + step)
        fg_x, fg_y, g_all, frames = (
            np.asarray(x[a:b]) for x in (maps.fg_x, maps.fg_y, maps.grouping, ex["event_frame"])
        )
        times = {k: np.asarray(ex[k][a:b]) for k in ("t_start_us", "t_end_us", "event_count", "pixel_share")}
        for j in range(b - a):
            rows.append(
                _row(
                    int(numbers[a + j]),
                    fg_x[j],
                    fg_y[j],
                    g_all[j],
                    frames[j],
                    {k: v[j] for k, v in times.items()},
                    coverage,
                    scale,
                )
            )
    return rows


#: windows read at a time from maps whose arrays are not chunked (in memory)
BLOCK = 64


def _row(number, fg_x, fg_y, g, frame, at, coverage, scale=1) -> dict:
    """Window ``number``'s row of :func:`window_rows` from its maps, event frame and times (``at``);
    ``scale``: the maps' pixel in sensor pixels (:func:`~snn_fg.results.maps.maps_scale`)."""
    has = has_vector(fg_x, fg_y)
    events = frame != 0
    peak = float(g.max(initial=0.0))
    py, px = np.unravel_index(int(np.argmax(g)), g.shape) if peak > 0 else (None, None)
    share = float(at["pixel_share"])
    return {
        "window": number,
        "t_start_ms": float(at["t_start_us"]) / 1000,
        "t_end_ms": float(at["t_end_us"]) / 1000,
        "events": int(at["event_count"]),
        "pixel_share": round(share, 6),
        "saturated": share > SATURATED_SHARE,
        "fg_pixels": int(has.sum()),
        "fg_coverage": round(float((has & events).sum() / events.sum()), 4) if coverage and events.any() else None,
        "grouping_peak": float(f"{peak:.5g}"),
        "peak_x": None if px is None else sensor_pixel(int(px), scale),
        "peak_y": None if py is None else sensor_pixel(int(py), scale),
    }


def save_table(path, rows) -> None:
    """``rows`` of :func:`window_rows` as CSV (an empty cell where a value does not exist)."""
    text = io.StringIO()
    writer = csv.DictWriter(text, COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows({k: ("" if v is None else v) for k, v in r.items()} for r in rows)
    save_text(path, text.getvalue())


def timeline_figure(rows, window_ms: float, title: str = "", shown=(), skipped=(), *, dropped=(), stride_ms=None):
    """The run over time, one bar per window: events, the share of pixels with an event, the
    pixels with a figure-ground vector (and their coverage of the event pixels), the grouping
    peak. ``shown``: windows an overview figure draws, marked on the time axis. A live run's
    missing windows are shaded by why: ``skipped`` (the hops whose read-out was passed over for
    a newer hop's, as ranges ``[first, last]``: :func:`number_ranges`; the network took their
    events) in blue, ``dropped`` (their events not simulated; as ranges too) in grey, before the
    first window stored and after the last as between them; a window missing between two stored
    ones and in neither is dropped (a run stored before 30 Nov kept no ``dropped``). ``stride_ms``:
    from one window's start to the next's (None: the stored windows' own)."""
    from matplotlib.figure import Figure  # (matplotlib: only when the figure is drawn)

    a, b = (np.array([r[k] for r in rows], float) for k in ("t_start_ms", "t_end_ms"))
    act = Activity(
        t_start_ms=a,
        t_end_ms=b,
        events=np.array([r["events"] for r in rows]),
        share=np.array([r["pixel_share"] for r in rows]),
        window_ms=window_ms,
    )
    fig = Figure(figsize=(9, 7.5), layout="constrained")
    ax_n, ax_s, ax_f, ax_g = fig.subplots(4, 1, sharex=True)
    draw_activity(ax_n, ax_s, act)
    mid, width = (a + b) / 2, b - a
    burst = act.share > SATURATED_SHARE
    scene_bars(ax_f, mid, width, [r["fg_pixels"] for r in rows], burst, color="C2")
    ax_f.set_ylabel("pixels with a\nfigure-ground vector", fontsize=8)
    cover = np.array([np.nan if r["fg_coverage"] is None else 100 * r["fg_coverage"] for r in rows])
    if not np.isnan(cover).all():  # (a model with a vector at every event pixel has none)
        twin = ax_f.twinx()
        twin.plot(mid, cover, "k.-", ms=3, lw=0.8)
        twin.set_ylim(0, 125)  # (the line below the note a clipped axis carries)
        twin.set_yticks([0, 25, 50, 75, 100])
        twin.set_ylabel("of the event\npixels (%, line)", fontsize=8)
        twin.tick_params(labelsize=7)
    scene_bars(ax_g, mid, width, [r["grouping_peak"] for r in rows], burst, color="C4")
    ax_g.set_ylabel("grouping peak", fontsize=8)
    drawn = "; numbers on top: the windows maps.png draws" if len(shown) else ""
    every = f", one every {stride_ms:g} ms" if stride_ms and stride_ms != window_ms else ""
    gaps = _missing_spans(rows, a, stride_ms, skipped, dropped)
    for lo, hi, kind in gaps:  # (a live run's missing windows: their time shaded by why, not left as a blank)
        for ax in (ax_n, ax_s, ax_f, ax_g):
            ax.axvspan(lo, hi, color=MISSING_COLOURS[kind], lw=0, zorder=0)
    kinds = {kind for *_, kind in gaps}
    missing = "; ".join(MISSING_WORDS[k] for k in ("dropped", "skipped") if k in kinds)  # (a line of its own)
    ax_g.set_xlabel(
        f"time after the first event (ms); {window_ms:g} ms windows{every}{drawn}"
        + (f"\n{missing}" if missing else ""),
        fontsize=8,
    )
    for ax in (ax_f, ax_g):
        ax.tick_params(labelsize=7)
    for i in shown:
        ax_n.annotate(
            str(rows[i].get("window", i)),
            (mid[i], 1.0),
            xycoords=("data", "axes fraction"),
            ha="center",
            va="bottom",
            fontsize=7,
        )
    # (wrapped: a live run's title, its source's address and how the run ended, ran off both sides)
    fig.suptitle("\n".join(textwrap.wrap(title or "The run window by window", TITLE_CHARS)), fontsize=10)
    return fig


#: the shades of a live run's missing windows, and what each says (the time axis is the windows' starts)
MISSING_COLOURS = {"dropped": "0.85", "skipped": "#cfe2f3"}
MISSING_WORDS = {
    "dropped": "grey: windows dropped, the model behind (events not simulated)",
    "skipped": "blue: hops skipped for a newer one (events simulated, no read-out)",
}


def number_ranges(numbers) -> list[tuple[int, int]]:
    """A live run's skipped hops or dropped windows (its store's ``skipped_windows``,
    ``dropped_windows``) as sorted ranges ``(first, last)``: stored so since 30 Nov (one entry a hop
    before: a long --hop-ms run kept thousands), a bare number (a run of before) a range of one."""
    return sorted((k, k) if isinstance(k, int) else (int(k[0]), int(k[1])) for k in numbers)


def _missing_spans(rows, starts, stride_ms=None, skipped=(), dropped=()) -> list[tuple[float, float, str]]:
    """Where a live run's window numbers (``window``) miss some: ``(from, to, kind)`` over the
    missing windows' starts (ms; a window's start ``stride_ms`` after the one before, None: the
    stored windows' median step), ``kind`` "skipped" for the numbers in the ranges ``skipped``
    (:func:`number_ranges`), else "dropped": between stored windows every number missing, before
    the first and after the last those of ``skipped`` and ``dropped``; neighbours of one kind merged."""
    numbers = [r.get("window") for r in rows]
    if not rows or any(k is None for k in numbers):
        return []
    k = np.asarray(numbers, float)
    if stride_ms is None:
        if len(rows) < 2:
            return []
        stride_ms = float(np.median(np.diff(starts) / np.diff(k)))
    listed = {"skipped": number_ranges(skipped), "dropped": number_ranges(dropped)}
    held = {int(n) for n in numbers}
    kinds: dict[int, str] = {}
    for kind in ("dropped", "skipped"):
        for lo, hi in listed[kind]:
            kinds.update((n, kind) for n in range(lo, hi + 1) if n not in held)
    kinds.update((n, kinds.get(n, "dropped")) for n in range(int(k[0]), int(k[-1])) if n not in held)
    origin = starts[0] - k[0] * stride_ms  # (window n starts n strides after window 0)
    spans: list = []
    for n in sorted(kinds):
        lo, kind = origin + n * stride_ms, kinds[n]
        if spans and spans[-1][2] == kind and abs(spans[-1][1] - lo) < 1e-6:
            spans[-1] = (spans[-1][0], lo + stride_ms, kind)
        else:
            spans.append((lo, lo + stride_ms, kind))
    return spans
