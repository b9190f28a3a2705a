"""Figures people look at: the maps (input, figure-ground, grouping), one row
per frame or window, with the colour key their panels share (the figures of
two maps compared are :mod:`snn_fg.scoring.compare_figure`'s, the spiking
model's raster and rate histograms :mod:`snn_fg.models.spiking.figures`').

Every figure is drawn on its own :class:`matplotlib.figure.Figure` (no
pyplot state, no backend switching), so these functions work the same in a
script, a headless test and a notebook, where a returned Figure displays
itself. Conventions: hue is the direction towards the owning object (0 deg
right, 90 deg up, as the colour wheel shows), brightness the vector's
strength; grouping maps use a perceptual colour map with a labelled colour bar.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import matplotlib.colors as mcolors
import numpy as np
from matplotlib.figure import Figure

from ..validate import check_crop
from .atomic import save_figure
from .map_image import brightness, departure, show_map
from .maps import maps_scale

GROUPING_CMAP = "magma"
#: darkest brightness of a non-zero figure-ground vector (0: invisible)
MIN_VALUE = 0.35
#: height of a map panel, inches (width by the frame's aspect ratio)
PANEL_IN = 3.4


def fg_rgb(fg_x, fg_y) -> np.ndarray:
    """RGB image of a figure-ground field: hue = direction, brightness = magnitude.

    Magnitudes are scaled by the 95th percentile of the non-zero ones, so a
    few strong vectors do not leave the rest dark.
    """
    mag = np.hypot(fg_x, fg_y)
    top = np.percentile(mag[mag > 0], 95) if (mag > 0).any() else 1.0
    hue = (np.arctan2(fg_y, fg_x) % (2 * np.pi)) / (2 * np.pi)
    val = np.clip(mag / max(top, 1e-12), 0, 1)
    val = np.where(mag > 0, MIN_VALUE + (1 - MIN_VALUE) * val, 0.0)
    return mcolors.hsv_to_rgb(np.stack([hue, np.ones_like(hue), val], axis=-1))


def event_frame_rgb(pos, neg) -> np.ndarray:
    """Grey background, ON events white, OFF events black."""
    img = np.full(np.shape(pos) + (3,), 0.5)
    img[np.asarray(pos) > 0] = 1.0
    img[np.asarray(neg) > 0] = 0.0
    return img


def signed_frame_rgb(frame) -> np.ndarray:
    """:func:`event_frame_rgb` of a stored event frame (+1 ON, -1 OFF; on blocks 2, ON and OFF
    pixels both, drawn ON: :func:`~snn_fg.frames.pool.signed_frame`)."""
    frame = np.asarray(frame)
    return event_frame_rgb(frame > 0, frame < 0)


def draw_wheel(ax) -> None:
    """The colour wheel of :func:`fg_rgb` in ``ax``: hue = direction (0° right, 90° up, each
    labelled), brightness growing from the centre with strength."""
    n = 101
    y, x = np.mgrid[1 : -1 : n * 1j, -1 : 1 : n * 1j]
    r = np.hypot(x, y)
    hue = (np.arctan2(y, x) % (2 * np.pi)) / (2 * np.pi)
    val = MIN_VALUE + (1 - MIN_VALUE) * np.clip(r, 0, 1)  # brightness grows with strength
    rgb = mcolors.hsv_to_rgb(np.stack([hue, np.ones_like(r), val], -1))
    ax.imshow(np.concatenate([rgb, (r <= 1)[..., None].astype(float)], -1), extent=(-1, 1, -1, 1))
    for angle, label in ((0, "0°"), (90, "90°"), (180, "180°"), (270, "270°")):
        a = np.radians(angle)
        ax.text(1.3 * np.cos(a), 1.3 * np.sin(a), label, ha="center", va="center", fontsize=7)
    ax.set_xlim(-1.7, 1.7)
    ax.set_ylim(-1.55, 1.55)
    ax.set_axis_off()
    ax.set_label("colour wheel")


def wheel_inset(ax, caption: bool = True):
    """:func:`draw_wheel` outside the axes ``ax``, right of their top right corner, so that it
    hides no data (the layout makes room for it), with what its hue means under it (``caption``;
    a reader of a compare figure was not told; a figure whose title says it leaves it out)."""
    wheel = ax.inset_axes([1.02, 0.55, 0.45, 0.45])
    draw_wheel(wheel)
    if caption:
        wheel.text(0.5, -0.2, "hue: direction towards\nthe owning object", transform=wheel.transAxes,
                   ha="center", va="top", fontsize=7)  # fmt: skip


def plot_maps_row(axes, input_img, fields, title: str = "", *, norm=None, extent=None) -> None:
    """Draw input, figure-ground map and grouping map into three axes, each titled and with its
    axes labelled. ``fields`` is ``(fg_x, fg_y, grouping)`` of one frame; ``norm`` the grouping's
    colour scale (:class:`matplotlib.colors.Normalize`, one for every row of a figure; by default
    0 to this frame's largest value); ``extent`` (imshow's) places a crop at its own pixel coordinates.
    A panel smaller than its map shows each screen pixel's most salient map pixel
    (:mod:`~snn_fg.results.map_image`), so that one-pixel lines stay."""
    a0, a1, a2 = axes
    fg_x, fg_y, grouping = fields
    if norm is None:
        norm = mcolors.Normalize(0.0, float(np.max(grouping, initial=0.0)) or 1.0)
    show_map(a0, input_img, departure, cmap="gray" if np.ndim(input_img) == 2 else None, extent=extent)
    show_map(a1, fg_rgb(fg_x, fg_y), brightness, extent=extent)
    show_map(a2, grouping, brightness, cmap=GROUPING_CMAP, norm=norm, extent=extent)
    silent = not np.any(grouping)
    for a, what in zip(axes, ("input", "figure-ground", "grouping")):
        a.set_title(f"{what} {title}".strip() + (": no activity" if a is a2 and silent else ""), fontsize=9)
        a.tick_params(labelsize=7)
        a.set_xlabel("x (px)", fontsize=7, labelpad=1)
    a0.set_ylabel("y (px, rows down)", fontsize=7)


#: what the key says the input column shows: a window's events, or the APS frame the frame-based model ran on
EVENTS_INPUT = "input: the event frame (a window's events, or an image's)\nwhite ON, black OFF, grey none"
APS_INPUT = "input: the camera's APS frame\nthe fbfg model ran on"
#: the input column's note for a model that reads an image itself (fbfg on a photo: its panel is the image)
IMAGE_INPUT = "input: the image\nthe fbfg model ran on"


#: the narrowest column (inches) the key's words fit in: a portrait frame's panels are narrower
KEY_COLUMN_IN = 2.6
#: characters of the key's 8-point text to an inch of column
CHARS_PER_IN = 15
#: characters of the 9-point title to an inch of figure
TITLE_CHARS_PER_IN = 13


def _wrapped(text: str, inches: float) -> str:
    """``text`` with each of its lines wrapped to ``inches`` of 8-point text; a bracketed phrase that fits
    a line is kept whole (its spaces made non-breaking: it wrapped as "(... or an / image's)")."""
    width = max(12, int(inches * CHARS_PER_IN))
    whole = lambda m: m.group(0).replace(" ", "\u00a0") if len(m.group(0)) <= width else m.group(0)  # noqa: E731
    lines = (textwrap.fill(re.sub(r"\([^()]*\)", whole, line), width) for line in text.split("\n"))
    return "\n".join(lines).replace("\u00a0", " ")  # (plain spaces again, once the lines are made)


def _key(
    fig, cells, norm, grouping_label: str, shared: bool, input_note: str = EVENTS_INPUT, column_in=KEY_COLUMN_IN
) -> None:
    """The strip above the rows that explains each column once: what the input shows, the colour
    wheel of the figure-ground map, and the grouping's colour bar (one scale for every row); its
    words wrapped to the columns, ``column_in`` inches wide."""
    from matplotlib.cm import ScalarMappable

    text = {"fontsize": 8, "va": "center", "ha": "left"}
    a0 = fig.add_subplot(cells[0])
    a0.set_axis_off()
    a0.text(0.0, 0.5, _wrapped(input_note, column_in), **text)
    wheel_cell, words = cells[1].subgridspec(1, 2, width_ratios=(1, 1.6), wspace=0.05)
    draw_wheel(fig.add_subplot(wheel_cell))
    a1 = fig.add_subplot(words)
    a1.set_axis_off()
    a1.text(
        0.0,
        0.5,
        "figure-ground: hue = direction\ntowards the owning object\n(wheel: 0° right, 90° up),\n"
        "brightness = strength;\nblack: no vector",
        **text,
    )
    bar_cell = cells[2].subgridspec(3, 1, height_ratios=(1, 0.5, 1.4))[1]
    cax = fig.add_subplot(bar_cell, label="<colorbar>")  # (the label matplotlib gives the colour bars it makes)
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=GROUPING_CMAP), cax=cax, orientation="horizontal")
    bar.ax.tick_params(labelsize=7)
    label = grouping_label + (", one scale for every window" if shared else "")
    bar.set_label(_wrapped(label, column_in), fontsize=8)
    bar.ax.set_title(_wrapped("grouping: proto-object centres are bright", column_in), fontsize=8)


def panel_width(aspect: float, height: float = PANEL_IN) -> float:
    """Width (inches) of a map panel of ``aspect`` = width / height and ``height``; very wide frames are capped."""
    return min(height * max(aspect, 0.6), 1.8 * height)


def rows_shown(n: int, max_rows: int) -> np.ndarray:
    """Which of ``n`` windows a figure of at most ``max_rows`` rows draws: evenly spaced, first and last included."""
    return np.unique(np.linspace(0, n - 1, min(n, max_rows)).round().astype(int))


def shown_note(shown, n: int, what: str = "windows", labels=None) -> str:
    """What a figure of rows ``shown`` out of ``n`` leaves out, in words ("" when
    it shows them all); ``labels`` names each row (default: its index)."""
    if len(shown) == n:
        return ""
    listed = ", ".join(str(i if labels is None else labels[i]) for i in shown)
    # (labels that are not the rows' places, a live run's window numbers with windows dropped or skipped
    # between: evenly spaced among the rows, not by number)
    among = f" among the {n}" if labels is not None and any(labels[i] != i for i in shown) else ""
    return f"{len(shown)} of {n} {what} shown, evenly spaced{among}: {listed}"


#: height of a map panel in a figure of several rows, inches (a frame's: PANEL_IN)
ROW_PANEL_IN = 2.5
#: height of the key above the rows, inches
KEY_IN = 1.3


def maps_figure(
    inputs,
    fg_x,
    fg_y,
    grouping,
    titles=None,
    max_rows: int = 6,
    grouping_label: str = "grouping",
    crop=None,
    placed=None,
    rows=None,
    grouping_max: float | None = None,
    hint: str = "",
    input_note: str = EVENTS_INPUT,
    labels=None,
    made_by: str = "",
) -> Figure:
    """One row per frame (input, figure-ground, grouping), under a key that explains each column
    once (the colour wheel, the grouping's colour bar).

    ``inputs`` is a list of images (grey or RGB), one per frame; arrays of ndim 2 are one frame.
    ``rows`` chooses the frames drawn; by default at most ``max_rows``, evenly spaced, and the
    figure's title says which (``hint`` follows, say how to draw others; ``labels``: each frame's
    name there, its number in a recording, default its place). Every row's grouping map
    has one colour scale, 0 to ``grouping_max`` (default: the largest value drawn). ``crop``
    ``(x0, y0, x1, y1)`` (pixels, x1 and y1 exclusive) draws only that part of every panel, at
    its own coordinates. ``placed`` ``(x0, y0, scale)``: the maps are a part of a sensor, their
    pixel ``(0, 0)`` its ``scale x scale`` pixels from ``(x0, y0)`` on (an export's crop, of
    blocks where it pools; maps kept on blocks: :func:`on_sensor`), drawn at the sensor's
    coordinates (``crop`` then counts the maps' pixels). ``input_note``: what the key says
    the input column shows (:data:`EVENTS_INPUT`, :data:`APS_INPUT`, :data:`IMAGE_INPUT`). ``made_by``: which model made
    the maps, said in the figure's title (:func:`~snn_fg.results.maps.made_by`).
    """
    # (a recording's maps may be read on indexing, snn_fg.results.store.ZarrArray: only the rows drawn are read)
    fg_x, fg_y, grouping = (v if hasattr(v, "ndim") else np.asarray(v) for v in (fg_x, fg_y, grouping))
    if fg_x.ndim == 2:
        fg_x, fg_y, grouping = fg_x[None], fg_y[None], grouping[None]
        inputs = [inputs]
    n = fg_x.shape[0]
    x0, y0, x1, y1 = check_crop(crop, fg_x.shape[1:]) if crop is not None else (0, 0) + fg_x.shape[:0:-1]
    cut = (slice(y0, y1), slice(x0, x1))
    extent = None if crop is None else (x0 - 0.5, x1 - 0.5, y1 - 0.5, y0 - 0.5)
    if placed is not None:  # (a crop of placed maps: its own part of the sensor)
        px, py, k = placed
        extent = (px + k * x0 - 0.5, px + k * x1 - 0.5, py + k * y1 - 0.5, py + k * y0 - 0.5)
    idx = rows_shown(n, max_rows) if rows is None else np.asarray(rows, int)
    note = shown_note(idx, n, labels=labels) if rows is None else ""  # (chosen rows are named in their titles)
    note = f"{note}; {hint}" if note and hint else note
    note = "; ".join(part for part in (made_by[:1].upper() + made_by[1:], note) if part)
    fields = [(fg_x[i][cut], fg_y[i][cut], grouping[i][cut]) for i in idx]
    top = grouping_max if grouping_max is not None else max(float(np.max(f[2], initial=0.0)) for f in fields)
    norm = mcolors.Normalize(0.0, top if top > 0 else 1.0)
    aspect = (x1 - x0) / (y1 - y0)  # (the same for a placed frame: its pixels are square)
    panel_h = PANEL_IN if len(idx) == 1 else ROW_PANEL_IN
    panel_w = panel_width(aspect, panel_h)
    row_h = min(panel_h, panel_w / aspect) + 0.75  # (titles, tick and axis labels)
    # (a portrait frame's panels are narrower than the key's words: its columns are not)
    column_w = max(panel_w, KEY_COLUMN_IN)
    fig_w = 3 * column_w + 1.6
    # (the title wrapped to the figure's width: a run's hint names its folder, which may be long)
    note = textwrap.fill(note, max(40, int(fig_w * TITLE_CHARS_PER_IN))) if note else ""
    note_in = 0.2 + 0.15 * (note.count("\n") + 1) if note else 0.0
    fig = Figure(figsize=(fig_w, KEY_IN + row_h * len(idx) + note_in), layout="constrained")
    grid = fig.add_gridspec(1 + len(idx), 3, height_ratios=(KEY_IN, *[row_h] * len(idx)))
    shared = len(idx) > 1 or grouping_max is not None
    _key(fig, [grid[0, c] for c in range(3)], norm, grouping_label, shared, input_note, column_w)
    for row, (i, f) in enumerate(zip(idx, fields), start=1):
        axes = [fig.add_subplot(grid[row, c]) for c in range(3)]
        title = titles[i] if titles is not None else ""
        plot_maps_row(axes, np.asarray(inputs[i])[cut], f, title, norm=norm, extent=extent)
    if note:
        fig.suptitle(note, fontsize=9)
    return fig


def on_sensor(params: dict, crop=None, shape=None) -> dict:
    """:func:`maps_figure`'s ``crop`` and ``placed`` for maps made with ``params``: maps kept on
    blocks are drawn at the sensor's coordinates, and a ``crop`` (sensor pixels, x1 and y1
    exclusive; checked against the blocks' ``shape`` times their size, where given) takes the
    blocks it touches."""
    s = maps_scale(params)
    if s == 1:
        return {"crop": crop}
    if crop is not None:
        if shape is not None:
            check_crop(crop, (shape[-2] * s, shape[-1] * s), "--crop")
        x0, y0, x1, y1 = crop
        crop = (x0 // s, y0 // s, -(-x1 // s), -(-y1 // s))
    return {"crop": crop, "placed": (0, 0, s)}


def save_maps_figure(path, inputs, fg_x, fg_y, grouping, **options) -> Path:
    """Write :func:`maps_figure` to ``path`` (atomically); ``options``: its keywords."""
    return save_figure(maps_figure(inputs, fg_x, fg_y, grouping, **options), path, dpi=110)
