"""The activity of a recording over time, as numbers and as a figure: events and the share of
the sensor's pixels they fall on, window by window (:class:`Activity`, which
:func:`snn_fg.events.activity.activity` reads from a recording), and a window that covers more
than :data:`SATURATED_SHARE` of them, a sensor-wide burst rather than a scene, drawn so that the
other windows still show (:func:`scene_bars`). ``snn-fg events --plot`` draws
:func:`activity_figure`; a recording's ``timeline.png`` (:mod:`snn_fg.results.timeline`) begins
with the same two panels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a window with events on more than this share of the sensor's pixels is saturated
#: (real scenes of the project's recordings reach 0.26 at most in 85 ms windows; start-up bursts 1.0)
SATURATED_SHARE = 0.5


@dataclass(frozen=True)
class Activity:
    """Per window of a recording: start and end (ms after its first event),
    events, and the share of the sensor's pixels that had an event."""

    t_start_ms: np.ndarray
    t_end_ms: np.ndarray
    events: np.ndarray
    share: np.ndarray
    window_ms: float

    @property
    def saturated(self) -> np.ndarray:
        """Indices of the windows with events on more than :data:`SATURATED_SHARE` of the pixels."""
        return np.flatnonzero(self.share > SATURATED_SHARE)


def scene_bars(ax, mid, width, values, burst, unit: str = "", color: str = "C0") -> bool:
    """Bars of ``values`` (one per window, in ``color``, the ``burst`` ones red) in ``ax``, the axis scaled to the
    windows that are not bursts where a burst would flatten them (dvs.es: 82,000 events in its
    first 17 ms, 5,000-7,000 in every later window): a burst's bar is then clipped and the axis
    says so with the largest value. Returns whether it clipped."""
    values, burst = np.asarray(values, float), np.asarray(burst, bool)
    ax.bar(mid, values, width=width, color=np.where(burst, "C3", color))
    calm = values[~burst]
    top = 1.5 * float(calm.max(initial=0.0))  # (room for the note above the bars)
    if not (burst.any() and top > 0 and values[burst].max() > top):
        return False
    ax.set_ylim(0, top)
    ax.text(
        0.995,
        0.96,
        f"red: saturated windows, clipped (largest {values[burst].max():,.0f}{unit})",
        ha="right",
        va="top",
        fontsize=7,
        transform=ax.transAxes,
    )
    return True


def draw_activity(ax_n, ax_s, act: Activity) -> None:
    """Events per window into ``ax_n`` and the share of pixels they cover into ``ax_s``, saturated
    windows in red (:func:`scene_bars`). The share's axis reaches just above its largest value (a
    DAVIS346 recording covers 0.2 % of its pixels a window: on 0-100 % it looked empty); the
    saturation threshold is drawn when it lies within it, and said otherwise."""
    mid = (act.t_start_ms + act.t_end_ms) / 2
    width = act.t_end_ms - act.t_start_ms
    burst = act.share > SATURATED_SHARE
    scene_bars(ax_n, mid, width, act.events, burst)
    ax_n.set_ylabel("events per window", fontsize=8)
    share = 100 * act.share
    if not scene_bars(ax_s, mid, width, share, burst, " %"):
        top = min(1.15 * float(share.max(initial=0.0)) or 1.0, 100.0)
        ax_s.set_ylim(0, top)
        if top >= 100 * SATURATED_SHARE:
            ax_s.axhline(100 * SATURATED_SHARE, color="k", ls="--", lw=0.8)
            said, at, where = f"saturated above {SATURATED_SHARE:.0%} (red)", 100 * SATURATED_SHARE, "data"
        else:  # (inside the panel's top corner: at the top's data value it sat across the frame's line)
            said, at, where = f"none saturated (above {SATURATED_SHARE:.0%})", 0.97, "axes"
        ax_s.text(
            0.995,
            at,
            said,
            ha="right",
            va="bottom" if where == "data" and at < top else "top",
            fontsize=8,
            transform=ax_s.get_yaxis_transform() if where == "data" else ax_s.transAxes,
        )
    ax_s.set_ylabel("pixels with an event (%)", fontsize=8)
    for ax in (ax_n, ax_s):
        ax.tick_params(labelsize=7)


def activity_figure(act: Activity, title: str = ""):
    """Events per window and the share of pixels they cover (:func:`draw_activity`)."""
    from matplotlib.figure import Figure  # (matplotlib: only when the figure is drawn)

    fig = Figure(figsize=(9, 4.5), layout="constrained")
    ax_n, ax_s = fig.subplots(2, 1, sharex=True)
    draw_activity(ax_n, ax_s, act)
    ax_s.set_xlabel(f"time after the first event (ms); {act.window_ms:g} ms windows", fontsize=8)
    fig.suptitle(title or "Activity over time", fontsize=10)
    return fig
