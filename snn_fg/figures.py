"""Figures people look at: the maps (input, figure-ground, grouping), and for
the spiking model a spike raster and firing-rate histograms.

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
from matplotlib.ticker import NullLocator

from .atomic import save_figure

GROUPING_CMAP = "magma"
#: darkest brightness of a non-zero figure-ground vector (0: invisible)
MIN_VALUE = 0.35


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


def _wheel_inset(ax):
    """Colour wheel with its directions labelled, and the brightness convention."""
    inset = ax.inset_axes([0.74, 0.70, 0.26, 0.30])
    n = 101
    y, x = np.mgrid[1:-1:n * 1j, -1:1:n * 1j]
    r = np.hypot(x, y)
    hue = (np.arctan2(y, x) % (2 * np.pi)) / (2 * np.pi)
    val = MIN_VALUE + (1 - MIN_VALUE) * np.clip(r, 0, 1)     # brightness grows with strength
    rgb = mcolors.hsv_to_rgb(np.stack([hue, np.ones_like(r), val], -1))
    inset.imshow(np.concatenate([rgb, (r <= 1)[..., None].astype(float)], -1), extent=(-1, 1, -1, 1))
    for angle, label in ((0, "0°"), (90, "90°"), (180, "180°"), (270, "270°")):
        a = np.radians(angle)
        inset.text(1.25 * np.cos(a), 1.25 * np.sin(a), label, ha="center", va="center", fontsize=6,
                   color="white", bbox={"facecolor": "black", "alpha": 0.5, "pad": 0.5, "lw": 0})
    inset.set_xlim(-1.6, 1.6)
    inset.set_ylim(-1.6, 1.6)
    inset.set_axis_off()


def plot_maps_row(axes, input_img, fg_x, fg_y, grouping, title: str = "", grouping_label: str = "grouping",
                  key: bool = True):
    """Draw input, figure-ground map and grouping map into three axes.

    ``grouping_label`` labels the grouping colour bar (say its unit).
    ``key=False`` leaves out what repeats from row to row of a figure (the
    colour wheel, the panels' explanations and axis labels): drawing them
    on every row of a recording's figure took most of its 7 s.
    """
    a0, a1, a2 = axes
    a0.imshow(input_img, cmap="gray" if np.ndim(input_img) == 2 else None, interpolation="nearest")
    a0.set_title(f"input {title}".strip(), fontsize=9)
    a1.imshow(fg_rgb(fg_x, fg_y), interpolation="nearest")
    im = a2.imshow(grouping, cmap=GROUPING_CMAP, interpolation="nearest")
    bar = a2.figure.colorbar(im, ax=a2, fraction=0.046, pad=0.02)
    bar.ax.tick_params(labelsize=7)
    for a in axes:
        a.tick_params(labelsize=7)
    if not key:
        for a in axes:
            a.locator_params(nbins=3)
        a1.set_title(f"figure-ground {title}".strip(), fontsize=9)
        a2.set_title(f"grouping {title}".strip(), fontsize=9)
        return
    a1.set_title("figure-ground: hue = direction to the owner,\nbrightness = strength (wheel: 0° right, 90° up)",
                 fontsize=8)
    _wheel_inset(a1)
    a2.set_title("grouping (proto-object centres are bright)", fontsize=9)
    bar.set_label(grouping_label, fontsize=8)
    for a in axes:
        a.set_xlabel("x (px)", fontsize=7)
    a0.set_ylabel("y (px, rows down)", fontsize=7)


def maps_figure(inputs, fg_x, fg_y, grouping, titles=None, max_rows: int = 12,
                grouping_label: str = "grouping") -> Figure:
    """One row per frame (input, figure-ground, grouping).

    ``inputs`` is a list of images (grey or RGB), one per frame; arrays of
    ndim 2 are one frame. At most ``max_rows`` frames are drawn, evenly spaced.
    """
    fg_x, fg_y, grouping = (np.asarray(v) for v in (fg_x, fg_y, grouping))
    if fg_x.ndim == 2:
        fg_x, fg_y, grouping = fg_x[None], fg_y[None], grouping[None]
        inputs = [inputs]
    n = fg_x.shape[0]
    idx = np.unique(np.linspace(0, n - 1, min(n, max_rows)).round().astype(int))
    h, w = fg_x.shape[1:]
    width = 3 * 3.4 * max(w / h, 0.6) + 1.2
    fig = Figure(figsize=(width, 3.4 * len(idx) + 0.3))
    axes = fig.subplots(len(idx), 3, squeeze=False)
    for row, i in enumerate(idx):      # (the key, on the first row, explains every row)
        plot_maps_row(axes[row], inputs[i], fg_x[i], fg_y[i], grouping[i],
                      titles[i] if titles is not None else "", grouping_label, key=row == 0)
    fig.tight_layout()
    return fig


def save_maps_figure(path, inputs, fg_x, fg_y, grouping, titles=None, max_rows: int = 12,
                     grouping_label: str = "grouping") -> Path:
    """Write :func:`maps_figure` to ``path`` (atomically)."""
    return save_figure(maps_figure(inputs, fg_x, fg_y, grouping, titles, max_rows, grouping_label), path, dpi=110)


def raster_figure(record, window: int | None = None) -> Figure:
    """Spike raster of a :class:`~snn_fg.spiking.record.SpikingRecord`'s sample."""
    from .spiking.record import RASTER_CELLS_PER_ROLE, ROLE_ORDER

    where = "" if window is None else f" (window {window})"
    fig = Figure(figsize=(10, 7))
    ax = fig.subplots()
    raster = record.raster
    if raster is not None and raster.row.size:
        cmap = mcolors.ListedColormap([f"C{i % 10}" for i in range(len(ROLE_ORDER))])
        for ri in np.unique(raster.role):
            m = raster.role == ri
            ax.scatter(raster.t_ms[m], raster.row[m], s=2, color=cmap(int(ri)), marker="|")
            ax.text(1.01, float(np.median(raster.row[m])), ROLE_ORDER[int(ri)], transform=ax.get_yaxis_transform(),
                    fontsize=7, va="center")
        ax.set_ylim(raster.row.max() + 1, -1)
    else:
        ax.text(0.5, 0.5, "spike times were not recorded (record_spikes=False) or no cell fired",
                ha="center", transform=ax.transAxes)
    ax.axvline(record.settle_ms, color="k", lw=0.8, ls="--")
    ax.set_xlim(0, record.duration_ms)
    ax.set_xlabel("time (ms); dashed: spikes after this are counted")
    ax.set_ylabel(f"sampled cells (up to {RASTER_CELLS_PER_ROLE} per role, level 1 first)")
    ax.set_title(f"Spike raster by population role{where}")
    fig.tight_layout()
    return fig


def rate_histogram_figure(record, window: int | None = None) -> Figure:
    """Firing-rate histograms per population role (all levels pooled)."""
    from .spiking.record import ROLE_ORDER

    where = "" if window is None else f" (window {window})"
    by_role: dict = {}
    for name in record.names:
        by_role.setdefault(record.populations[name]["role"], []).append(record.all_rates(name))
    roles = [r for r in ROLE_ORDER if r in by_role]
    ncol = 4
    nrow = max(1, -(-len(roles) // ncol))
    fig = Figure(figsize=(12, 2.4 * nrow + 0.5))
    axes = fig.subplots(nrow, ncol, squeeze=False)
    for ax, role in zip(axes.ravel(), roles):
        r = np.concatenate(by_role[role])
        counts, edges = np.histogram(r, bins=40)
        ax.stairs(counts, edges, fill=True, color="C0")
        ax.set_yscale("log")
        # (no minor ticks: over six decades of cells they made this figure take 5 s to draw)
        ax.yaxis.set_minor_locator(NullLocator())
        ax.set_title(f"{role}: mean {r.mean():.1f} Hz, {100 * (r > 0).mean():.0f}% active", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.set_xlabel("rate (Hz)", fontsize=7)
        ax.set_ylabel("cells", fontsize=7)
    for ax in axes.ravel()[len(roles):]:
        ax.axis("off")
    fig.suptitle(f"Firing rates per population role, counting window of {record.count_window_ms:g} ms{where}")
    fig.tight_layout()
    return fig


def save_spiking_figures(maps, out_dir, window: int | None = None, with_maps: bool = True) -> list[Path]:
    """Write ``maps.png``, ``spike_raster.png`` and ``rate_histograms.png`` of a
    spiking run's :class:`~snn_fg.maps.Maps` (or a saved one loaded with
    ``Maps.load``) into ``out_dir``. For a recording's maps the figures show
    one window (default: the one with the most spikes). ``with_maps=False``
    leaves ``maps.png`` out (for a caller that drew its own)."""
    from .spiking.record import SpikingRecord

    maps = getattr(maps, "maps", maps)       # a SpikingResult is accepted too
    record, window = SpikingRecord.from_maps(maps, window)
    out = Path(out_dir)
    pick = (lambda a: a) if window is None else (lambda a: a[window])
    title = "" if window is None else f"(window {window})"
    written = [save_maps_figure(out / "maps.png", event_frame_rgb(record.input_on, record.input_off),
                                pick(maps.fg_x), pick(maps.fg_y), pick(maps.grouping), [title],
                                grouping_label=SPIKING_GROUPING_LABEL)] if with_maps else []
    written.append(save_figure(raster_figure(record, window), out / "spike_raster.png", dpi=120))
    written.append(save_figure(rate_histogram_figure(record, window), out / "rate_histograms.png", dpi=110))
    return written


SPIKING_GROUPING_LABEL = "grouping rate (Hz, summed over levels)"
