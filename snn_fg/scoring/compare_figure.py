"""The figure of two maps compared (``snn-fg compare --plot``): per compared
pair of windows, the figure-ground map of each and the angle between them;
with a run on a DAVIS recording's frames (``snn-fg run REC --model fbfg``),
first the APS frame and the event frame that the two models read."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from ..results.atomic import save_figure
from ..results.figures import PANEL_IN, event_frame_rgb, fg_rgb, panel_width, rows_shown, shown_note, wheel_inset
from ..results.map_image import brightness, departure, show_map
from ..results.maps import has_vector
from .metrics import angle_difference_deg, confident, frame_of, share_text


def aps_inputs(a, b) -> list:
    """The inputs drawn before the maps when ``a`` or ``b`` ran on a recording's
    APS frames: ``(title, image)`` functions of a compared row for the APS
    frame and for the event frame (none: an empty list)."""
    with_aps = [(m, f"window_{k}") for m, k in ((a, "a"), (b, "b")) if "aps_frame" in m.extra]
    with_events = [(m, f"window_{k}") for m, k in ((a, "a"), (b, "b")) if "event_frame" in m.extra]
    if not with_aps or not with_events:
        return []
    (m_aps, key_aps), (m_ev, key_ev) = with_aps[0], with_events[0]

    def aps(row):
        i = row[key_aps]
        if int(m_aps.extra["aps_index"][i]) < 0:
            return "no APS frame yet", np.zeros(np.shape(m_aps.fg_x)[-2:])
        at = int(m_aps.extra["aps_t_us"][i]) / 1000
        return f"APS frame {int(m_aps.extra['aps_index'][i])} ({at:.1f} ms)", np.asarray(m_aps.extra["aps_frame"][i])

    def events(row):
        frame = np.asarray(m_ev.extra["event_frame"][row[key_ev]])
        return "event frame", event_frame_rgb(frame > 0, frame < 0)

    return [aps, events]


#: the difference panel's colours where no angle is drawn (RGB): one map has a vector there, neither
#: has, and outside the pixels compared (a tint, not a second grey: two greys were told apart by nobody)
ONE_MAP, NEITHER, NOT_COMPARED = (0.6, 0.6, 0.6), (1.0, 1.0, 1.0), (0.98, 0.94, 0.86)


def _difference_title(r, where, when: str, sure: str) -> str:
    """The difference panel's title: the numbers of row ``r`` as the table gives them, or in words
    that no pixel was compared there (never "nan")."""
    on = "" if where is None else " on the compared pixels"
    if r.get("pixels_compared"):
        said = f"mean {r['angle_diff_mean_deg']:.0f}°, {r['angle_within_45_frac']:.0%} within 45°"
    else:
        said = f"no pixel where both maps have a vector{sure}: nothing compared"
    pale = "" if where is None else "; beige: not compared"
    return f"difference{on}{when}: {said}\n(grey: one map only; white: neither{pale})"


def compare_figure(
    a, b, rows, names=("A", "B"), max_rows: int = 6, where=None, inputs=(), min_confidence=None, described=()
) -> Figure:
    """Two maps side by side and how they differ: per compared pair of
    windows (``rows`` of :func:`~snn_fg.scoring.metrics.compare_maps`) the
    figure-ground map of each and the angle between them where both have a
    vector (grey: only one has a vector). ``where`` (as ``compare_maps``
    takes it: ``(window_a, window_b) ->`` the pixels compared): the
    difference is drawn on those pixels only, as its numbers were taken,
    the rest of the frame pale. ``inputs``: functions of a row giving
    ``(title, image)`` drawn first (:func:`aps_inputs`); a grey image is
    drawn on the 0-255 scale of a camera's frame. ``described``: the title's lines, one per map
    (which run and which model made it); by default ``A vs B`` by ``names``."""
    idx = rows_shown(len(rows), max_rows)
    h, w = np.shape(a.fg_x)[-2:]
    panel_w = panel_width(w / h)
    n_in = len(inputs)
    fig = Figure(figsize=((3 + n_in) * panel_w + 2.4, (PANEL_IN + 0.3) * len(idx) + 0.8), layout="constrained")
    axes = fig.subplots(len(idx), 3 + n_in, squeeze=False)
    for ax_row, i in zip(axes, idx, strict=True):
        r = rows[i]
        for panel, show in zip(ax_row, inputs, strict=False):
            title, image = show(r)
            grey = {"cmap": "gray", "vmin": 0, "vmax": 255} if np.ndim(image) == 2 else {}
            show_map(panel, image, departure, **grey)
            panel.set_title(title, fontsize=9)
            panel.tick_params(labelsize=7)
        ax = ax_row[n_in:]
        (ax_, ay_, _), (bx, by, _) = (_sure(m, r[f"window_{k}"], min_confidence) for m, k in ((a, "a"), (b, "b")))
        when = "" if r["t_start_ms"] is None else f", {r['t_start_ms']:g} ms"
        sides = ((names[0], "a", ax_, ay_), (names[1], "b", bx, by))
        for panel, (name, k, fx, fy) in zip(ax, sides):  # (each window by its own number)
            show_map(panel, fg_rgb(fx, fy), brightness)
            win = r.get(f"number_{k}")
            kept = r.get(f"confident_{k}")
            of = "it has no vector" if kept is None or np.isnan(kept) else f"{share_text(kept)} of them"
            left = "" if f"confident_{k}" not in r else f"\nonly vectors at confidence >= {min_confidence:g} ({of})"
            panel.set_title(f"{name}" + ("" if win is None else f" window {win}") + when + left, fontsize=9)
        inside = np.ones(np.shape(ax_), bool) if where is None else np.asarray(where(r["window_a"], r["window_b"]))
        has_a, has_b = has_vector(ax_, ay_) & inside, has_vector(bx, by) & inside
        diff = np.where(has_a & has_b, angle_difference_deg(ax_, ay_, bx, by), np.nan)
        marks = np.where((has_a ^ has_b)[..., None], ONE_MAP, np.where(inside[..., None], NEITHER, NOT_COMPARED))
        show_map(ax[2], marks, departure)
        im = show_map(ax[2], diff, brightness, cmap="viridis", vmin=0, vmax=180)
        bar = fig.colorbar(im, ax=ax[2], fraction=0.046, pad=0.02)
        bar.set_label("angle difference (deg)", fontsize=8)
        sure = "" if not any(f"confident_{k}" in r for k in "ab") else f" at confidence >= {min_confidence:g}"
        ax[2].set_title(_difference_title(r, where, when, sure), fontsize=8)
        for x in ax_row:
            x.tick_params(labelsize=7)
            x.set_xlabel("x (px)", fontsize=7, labelpad=1)
        ax_row[0].set_ylabel("y (px, rows down)", fontsize=7)
    wheel_inset(axes[0][n_in + 1])
    note = shown_note(idx, len(rows), "compared windows", [f"A {r.get('number_a')}" for r in rows])
    title = "\n".join(described) if described else f"{names[0]} vs {names[1]}"
    fig.suptitle(title + (f"\n{note}" if note else ""), fontsize=9)
    return fig


def _sure(m, i, min_confidence):
    """``(fg_x, fg_y, grouping)`` of window ``i`` of ``m``, its vectors under ``min_confidence`` left out
    (:func:`~snn_fg.scoring.metrics.confident`: none where ``m`` stores no confidence)."""
    fx, fy, g = frame_of(m, i)
    keep = confident(m, i, min_confidence)
    return (fx, fy, g) if keep is None else (np.where(keep, fx, 0), np.where(keep, fy, 0), g)


def save_compare_figure(
    path, a, b, rows, names=("A", "B"), max_rows: int = 6, where=None, inputs=(), min_confidence=None, described=()
) -> Path:
    """Write :func:`compare_figure` to ``path`` (atomically)."""
    figure = compare_figure(a, b, rows, names, max_rows, where, inputs, min_confidence, described)
    return save_figure(figure, path, dpi=110)
