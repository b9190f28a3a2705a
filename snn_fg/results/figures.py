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

from ..validate import check_crop
from .atomic import save_figure
from .maps import SPIKING_GROUPING_LABEL

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


def _wheel_inset(ax):
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
    _wheel_inset(a1)
    a2.set_title("grouping: no activity" if silent else "grouping (proto-object centres are bright)", fontsize=9)
    bar.set_label(grouping_label, fontsize=8)
    for a in axes:
        a.set_xlabel("x (px)", fontsize=7)
    a0.set_ylabel("y (px, rows down)", fontsize=7)


def _panel_width(aspect: float) -> float:
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
    panel_w = _panel_width(aspect)
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


def compare_figure(a, b, rows, names=("A", "B"), max_rows: int = 6, where=None) -> Figure:
    """Two maps side by side and how they differ: per compared pair of
    windows (``rows`` of :func:`~snn_fg.scoring.metrics.compare_maps`) the
    figure-ground map of each and the angle between them where both have a
    vector (grey: only one has a vector). ``where`` (as ``compare_maps``
    takes it: ``(window_a, window_b) ->`` the pixels compared): the
    difference is drawn on those pixels only, as its numbers were taken,
    the rest of the frame pale."""
    from ..scoring.metrics import angle_difference_deg, frame_of

    idx = rows_shown(len(rows), max_rows)
    h, w = np.shape(a.fg_x)[-2:]
    panel_w = _panel_width(w / h)
    fig = Figure(figsize=(3 * panel_w + 2.4, PANEL_IN * len(idx) + 0.6), layout="constrained")
    axes = fig.subplots(len(idx), 3, squeeze=False)
    for ax, i in zip(axes, idx):
        r = rows[i]
        (ax_, ay_, _), (bx, by, _) = frame_of(a, r["window_a"]), frame_of(b, r["window_b"])
        when = "" if r["t_start_ms"] is None else f", {r['t_start_ms']:g} ms"
        sides = ((names[0], r["window_a"], ax_, ay_), (names[1], r["window_b"], bx, by))
        for panel, (name, win, fx, fy) in zip(ax, sides):
            panel.imshow(fg_rgb(fx, fy), interpolation="nearest")
            panel.set_title(f"{name}" + ("" if win is None else f" window {win}") + when, fontsize=9)
        inside = np.ones(np.shape(ax_), bool) if where is None else np.asarray(where(r["window_a"], r["window_b"]))
        has_a, has_b = (np.hypot(ax_, ay_) > 0) & inside, (np.hypot(bx, by) > 0) & inside
        diff = np.where(has_a & has_b, angle_difference_deg(ax_, ay_, bx, by), np.nan)
        ax[2].imshow(
            np.where(has_a ^ has_b, 0.75, np.where(inside, 1.0, 0.92)),
            cmap="gray",
            vmin=0,
            vmax=1,
            interpolation="nearest",
        )
        im = ax[2].imshow(diff, cmap="viridis", vmin=0, vmax=180, interpolation="nearest")
        bar = fig.colorbar(im, ax=ax[2], fraction=0.046, pad=0.02)
        bar.set_label("angle difference (deg)", fontsize=8)
        ax[2].set_title(
            f"difference{'' if where is None else ' on the compared pixels'}: mean "
            f"{r['angle_diff_mean_deg']:.0f}°, {r['angle_within_45_frac']:.0%} within 45° (grey: one map "
            f"only{'' if where is None else '; pale: not compared'})",
            fontsize=8,
        )
        for x in ax:
            x.tick_params(labelsize=7)
    _wheel_inset(axes[0][1])
    note = shown_note(idx, len(rows), "compared windows", [f"A {r['window_a']}" for r in rows])
    fig.suptitle(f"{names[0]} vs {names[1]}" + (f"; {note}" if note else ""), fontsize=9)
    return fig


def save_compare_figure(path, a, b, rows, names=("A", "B"), max_rows: int = 6, where=None) -> Path:
    """Write :func:`compare_figure` to ``path`` (atomically)."""
    return save_figure(compare_figure(a, b, rows, names, max_rows, where), path, dpi=110)


def raster_figure(record, window: int | None = None) -> Figure:
    """Spike raster of a :class:`~snn_fg.models.spiking.record.SpikingRecord`'s sample."""
    from ..models.spiking.record import RASTER_CELLS_PER_ROLE
    from ..network.roles import ROLE_ORDER

    where = "" if window is None else f" (window {window})"
    fig = Figure(figsize=(10, 8.6), layout="constrained")
    ax = fig.subplots()
    fig.get_layout_engine().set(rect=(0, 0.16, 1, 0.84))  # below: what the roles are
    fig.text(0.01, 0.15, role_caption(), fontsize=7, va="top")
    raster = record.raster
    if raster is not None and raster.row.size:
        cmap = mcolors.ListedColormap([f"C{i % 10}" for i in range(len(ROLE_ORDER))])
        for ri in np.unique(raster.role):
            m = raster.role == ri
            ax.scatter(raster.t_ms[m], raster.row[m], s=2, color=cmap(int(ri)), marker="|")
            ax.text(
                1.01,
                float(np.median(raster.row[m])),
                ROLE_ORDER[int(ri)],
                transform=ax.get_yaxis_transform(),
                fontsize=7,
                va="center",
            )
        ax.set_ylim(raster.row.max() + 1, -1)
    else:
        ax.text(
            0.5,
            0.5,
            "spike times were not recorded (record_spikes=False) or no cell fired",
            ha="center",
            transform=ax.transAxes,
        )
    ax.axvline(record.settle_ms, color="k", lw=0.8, ls="--")
    ax.set_xlim(0, record.duration_ms)
    ax.set_xlabel("time (ms); dashed: spikes after this are counted")
    ax.set_ylabel(f"sampled cells (up to {RASTER_CELLS_PER_ROLE} per role, level 1 first)")
    ax.set_title(f"Spike raster by population role{where}")
    return fig


def role_caption(width: int = 170) -> str:
    """What each population role's cells do, one line per family of roles."""
    import textwrap

    from ..network.roles import ROLE_MEANINGS

    return "\n".join(
        textwrap.fill(f"{', '.join(roles)}: {meaning}", width, subsequent_indent="    ")
        for roles, meaning in ROLE_MEANINGS
    )


def rate_histogram_figure(record, window: int | None = None) -> Figure:
    """Firing-rate histograms per population role (all levels pooled)."""
    from ..network.roles import ROLE_ORDER

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
    for ax in axes.ravel()[len(roles) :]:
        ax.axis("off")
    fig.suptitle(f"Firing rates per population role, counting window of {record.count_window_ms:g} ms{where}")
    fig.tight_layout()
    return fig


def save_spiking_figures(maps, out_dir, window: int | None = None, with_maps: bool = True) -> list[Path]:
    """Write ``maps.png``, ``spike_raster.png`` and ``rate_histograms.png`` of a
    spiking run's :class:`~snn_fg.results.maps.Maps` (or a saved one loaded with
    ``Maps.load``) into ``out_dir``. For a recording's maps the figures show
    one window (default: the one with the most spikes). ``with_maps=False``
    leaves ``maps.png`` out (for a caller that drew its own)."""
    from ..models.spiking.record import SpikingRecord

    maps = getattr(maps, "maps", maps)  # a SpikingResult is accepted too
    record, window = SpikingRecord.from_maps(maps, window)
    out = Path(out_dir)
    pick = (lambda a: a) if window is None else (lambda a: a[window])
    title = "" if window is None else f"(window {window})"
    written = (
        [
            save_maps_figure(
                out / "maps.png",
                event_frame_rgb(record.input_on, record.input_off),
                pick(maps.fg_x),
                pick(maps.fg_y),
                pick(maps.grouping),
                titles=[title],
                grouping_label=SPIKING_GROUPING_LABEL,
            )
        ]
        if with_maps
        else []
    )
    written.append(save_figure(raster_figure(record, window), out / "spike_raster.png", dpi=120))
    written.append(save_figure(rate_histogram_figure(record, window), out / "rate_histograms.png", dpi=110))
    return written
