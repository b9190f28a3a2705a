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

from pathlib import Path

import matplotlib.colors as mcolors
import numpy as np
from matplotlib.figure import Figure

from ..validate import check_crop
from .atomic import save_figure

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


def wheel_inset(ax):
    """Colour wheel with its directions labelled, and the brightness convention:
    outside the axes, right of their top right corner, so that it hides no data
    (``tight_layout`` makes room for it)."""
    inset = ax.inset_axes([1.02, 0.62, 0.38, 0.38])
    n = 101
    y, x = np.mgrid[1 : -1 : n * 1j, -1 : 1 : n * 1j]
    r = np.hypot(x, y)
    hue = (np.arctan2(y, x) % (2 * np.pi)) / (2 * np.pi)
    val = MIN_VALUE + (1 - MIN_VALUE) * np.clip(r, 0, 1)  # brightness grows with strength
    rgb = mcolors.hsv_to_rgb(np.stack([hue, np.ones_like(r), val], -1))
    inset.imshow(np.concatenate([rgb, (r <= 1)[..., None].astype(float)], -1), extent=(-1, 1, -1, 1))
    for angle, label in ((0, "0°"), (90, "90°"), (180, "180°"), (270, "270°")):
        a = np.radians(angle)
        inset.text(
            1.25 * np.cos(a),
            1.25 * np.sin(a),
            label,
            ha="center",
            va="center",
            fontsize=6,
            color="white",
            bbox={"facecolor": "black", "alpha": 0.5, "pad": 0.5, "lw": 0},
        )
    inset.set_xlim(-1.6, 1.6)
    inset.set_ylim(-1.6, 1.6)
    inset.set_axis_off()


def plot_maps_row(
    axes, input_img, fields, title: str = "", *, grouping_label: str = "grouping", key: bool = True, extent=None
):
    """Draw input, figure-ground map and grouping map into three axes.

    ``fields`` is ``(fg_x, fg_y, grouping)`` of one frame.
    ``grouping_label`` labels the grouping colour bar (say its unit).
    ``key=False`` leaves out what repeats from row to row of a figure (the
    colour wheel, the panels' explanations and axis labels): drawing them
    on every row of a recording's figure took most of its 7 s.
    ``extent`` (imshow's) places a crop at its own pixel coordinates.
    """
    a0, a1, a2 = axes
    fg_x, fg_y, grouping = fields
    a0.imshow(input_img, cmap="gray" if np.ndim(input_img) == 2 else None, interpolation="nearest", extent=extent)
    a0.set_title(f"input {title}".strip(), fontsize=9)
    a1.imshow(fg_rgb(fg_x, fg_y), interpolation="nearest", extent=extent)
    silent = not np.any(grouping)  # (drawn dark, not at the middle of an autoscaled range)
    im = a2.imshow(
        grouping,
        cmap=GROUPING_CMAP,
        interpolation="nearest",
        extent=extent,
        **({"vmin": 0.0, "vmax": 1.0} if silent else {}),
    )
    bar = a2.figure.colorbar(im, ax=a2, fraction=0.046, pad=0.02)
    bar.ax.tick_params(labelsize=7)
    for a in axes:
        a.tick_params(labelsize=7)
    if not key:
        for a in axes:
            a.locator_params(nbins=3)
        a1.set_title(f"figure-ground {title}".strip(), fontsize=9)
        a2.set_title(f"grouping {title}".strip() + (": none" if silent else ""), fontsize=9)
        return
    a1.set_title(
        "figure-ground: hue = direction to the owner,\nbrightness = strength (wheel: 0° right, 90° up)", fontsize=8
    )
    wheel_inset(a1)
    a2.set_title("grouping: no activity" if silent else "grouping (proto-object centres are bright)", fontsize=9)
    bar.set_label(grouping_label, fontsize=8)
    for a in axes:
        a.set_xlabel("x (px)", fontsize=7)
    a0.set_ylabel("y (px, rows down)", fontsize=7)


def panel_width(aspect: float) -> float:
    """Width (inches) of a map panel of ``aspect`` = width / height; very wide frames are capped."""
    return min(PANEL_IN * max(aspect, 0.6), 1.8 * PANEL_IN)


def rows_shown(n: int, max_rows: int) -> np.ndarray:
    """Which of ``n`` windows a figure of at most ``max_rows`` rows draws: evenly spaced, first and last included."""
    return np.unique(np.linspace(0, n - 1, min(n, max_rows)).round().astype(int))


def shown_note(shown, n: int, what: str = "windows", labels=None) -> str:
    """What a figure of rows ``shown`` out of ``n`` leaves out, in words ("" when
    it shows them all); ``labels`` names each row (default: its index)."""
    if len(shown) == n:
        return ""
    listed = ", ".join(str(i if labels is None else labels[i]) for i in shown)
    return f"{len(shown)} of {n} {what} shown, evenly spaced: {listed}"


def maps_figure(
    inputs,
    fg_x,
    fg_y,
    grouping,
    titles=None,
    max_rows: int = 12,
    grouping_label: str = "grouping",
    crop=None,
    placed=None,
) -> Figure:
    """One row per frame (input, figure-ground, grouping).

    ``inputs`` is a list of images (grey or RGB), one per frame; arrays of
    ndim 2 are one frame. At most ``max_rows`` frames are drawn, evenly
    spaced, and the figure's title says which. ``crop`` ``(x0, y0, x1, y1)``
    (pixels, x1 and y1 exclusive) draws only that part of every panel, at
    its own coordinates. ``placed`` ``(x0, y0, scale)``: the maps are a
    part of a sensor, their pixel ``(0, 0)`` its ``scale x scale`` pixels
    from ``(x0, y0)`` on (an export's crop, of blocks where it pools), drawn
    at the sensor's coordinates.
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
    if placed is not None:
        if crop is not None:
            raise ValueError("maps_figure: crop and placed go alone")
        px, py, k = placed
        extent = (px - 0.5, px + k * (x1 - x0) - 0.5, py + k * (y1 - y0) - 0.5, py - 0.5)
    idx = rows_shown(n, max_rows)
    note = shown_note(idx, n)
    aspect = (x1 - x0) / (y1 - y0)  # (the same for a placed frame: its pixels are square)
    panel_w = panel_width(aspect)
    row_h = min(PANEL_IN, max(panel_w / aspect + 0.9, 1.8))  # (0.9 in: titles and tick labels)
    note_in = 0.45 if note else 0.0  # (a strip of its own at the top, whatever the figure's height)
    height = row_h * len(idx) + 0.3 + note_in
    fig = Figure(figsize=(3 * panel_w + 2.4, height))
    axes = fig.subplots(len(idx), 3, squeeze=False)
    for row, i in enumerate(idx):  # (the key, on the first row, explains every row)
        plot_maps_row(
            axes[row],
            np.asarray(inputs[i])[cut],
            (fg_x[i][cut], fg_y[i][cut], grouping[i][cut]),
            titles[i] if titles is not None else "",
            grouping_label=grouping_label,
            key=row == 0,
            extent=extent,
        )
    if note:
        fig.suptitle(note, fontsize=9, y=1 - 0.1 / height, va="top")
    fig.tight_layout(rect=(0, 0, 1, 1 - note_in / height))
    return fig


def save_maps_figure(path, inputs, fg_x, fg_y, grouping, **options) -> Path:
    """Write :func:`maps_figure` to ``path`` (atomically); ``options``: its keywords."""
    return save_figure(maps_figure(inputs, fg_x, fg_y, grouping, **options), path, dpi=110)
