"""The spiking model's own figures: a raster of the sampled cells' spikes by
population role and the firing-rate histograms per role, beside the maps
(:mod:`snn_fg.results.figures`) that every model draws."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib.colors as mcolors
import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import NullLocator

from ...network.roles import ROLE_MEANINGS, ROLE_ORDER
from ...results.atomic import save_figure
from ...results.figures import event_frame_rgb, save_maps_figure
from ...results.maps import SPIKING_GROUPING_LABEL, made_from
from ...results.timeline import MAPS_FIGURE
from .record import RASTER_CELLS_PER_ROLE, SpikingRecord

#: the raster's axes (inches high), and a line of the caption under them that says what the roles are
RASTER_AXES_IN, CAPTION_LINE_IN = 7.2, 0.125


def raster_figure(record, window: int | None = None, made: str = "") -> Figure:
    """Spike raster of a :class:`~snn_fg.models.spiking.record.SpikingRecord`'s sample (``made``:
    which model and network, :func:`~snn_fg.results.maps.made_by`, for the title)."""
    where = ("" if window is None else f" (window {window})") + (f", {made}" if made else "")
    raster = record.raster
    drawn = None if raster is None or not raster.row.size else {ROLE_ORDER[int(r)] for r in np.unique(raster.role)}
    caption = role_caption(drawn)
    below = CAPTION_LINE_IN * (caption.count("\n") + 1) + 0.2  # (inches under the axes: what the roles are)
    height = RASTER_AXES_IN + below
    fig = Figure(figsize=(10, height), layout="constrained")
    ax = fig.subplots()
    fig.get_layout_engine().set(rect=(0, below / height, 1, 1 - below / height))
    fig.text(0.01, (below - 0.1) / height, caption, fontsize=7, va="top")
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


def role_caption(roles=None, width: int = 170) -> str:
    """What each population role's cells do, one line per family of roles
    (``roles``: only the families with one of these; None: every family)."""
    return "\n".join(
        textwrap.fill(f"{', '.join(family)}: {meaning}", width, subsequent_indent="    ")
        for family, meaning in ROLE_MEANINGS
        if roles is None or set(family) & set(roles)
    )


def rate_histogram_figure(record, window: int | None = None, made: str = "") -> Figure:
    """Firing-rate histograms per population role (all levels pooled; ``made``: as :func:`raster_figure`)."""
    where = ("" if window is None else f" (window {window})") + (f",\n{made}" if made else "")
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
    maps = getattr(maps, "maps", maps)  # a SpikingResult is accepted too
    record, window = SpikingRecord.from_maps(maps, window)
    out = Path(out_dir)
    pick = (lambda a: a) if window is None else (lambda a: a[window])
    title = "" if window is None else f"(window {window})"
    written = (
        [
            save_maps_figure(
                out / MAPS_FIGURE,
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
    # (the network named: runs of a description and of its edit could not be told apart)
    made = made_from(maps.params)
    written.append(save_figure(raster_figure(record, window, made), out / "spike_raster.png", dpi=120))
    written.append(save_figure(rate_histogram_figure(record, window, made), out / "rate_histograms.png", dpi=110))
    return written
