"""Activity of a recording over time, and windows that cover the whole sensor.

A window whose events fall on more than :data:`SATURATED_SHARE` of the
sensor's pixels is not a scene but a sensor-wide burst: the start-up reset
of an ATIS or DVS camera (tens of thousands of events on every pixel within
a millisecond or so), flicker, or a sudden change of light. The model maps
such a window as solid colour everywhere, so ``snn-fg events`` shows where
they are (:func:`activity`, :func:`timeline_text`, :func:`activity_figure`)
and ``snn-fg run`` warns about each one (:func:`saturated_lines`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np

from snn_fg.events.window import EmptyWindowWarning, iter_windows

#: a window with events on more than this share of the sensor's pixels is saturated
#: (real scenes of the project's recordings reach 0.26 at most in 85 ms windows; start-up bursts 1.0)
SATURATED_SHARE = 0.5
#: rows of the text timeline at most (consecutive windows are merged beyond)
TIMELINE_ROWS = 30
_BAR = 30


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


def pixel_share(window) -> float:
    """Share of the sensor's pixels with an event in ``window`` (an :class:`~snn_fg.events.EventWindow`)."""
    return float(np.count_nonzero(window.pos | window.neg) / window.pos.size)


def activity(recording, *, window_ms: float = 85.0, sensor_size=None) -> Activity:
    """Events and pixel share of every window of ``recording`` (a path, a
    stream or an array), cut as :func:`~snn_fg.events.iter_windows` cuts it
    from the first event."""
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EmptyWindowWarning)  # an empty window is a row of zeros
        for w in iter_windows(recording, window_ms=window_ms, sensor_size=sensor_size):
            a, b = w.span_ms
            rows.append((a, b, len(w.events), pixel_share(w)))
    a, b, n, share = (np.array(c) for c in zip(*rows))
    return Activity(t_start_ms=a, t_end_ms=b, events=n.astype(np.int64), share=share, window_ms=float(window_ms))


def saturated_lines(act: Activity, most: int = 5) -> list[str]:
    """The saturated windows in words (no line if none): one line per window
    (the first ``most``), then what they are and the ``--start-ms`` that skips
    the leading ones."""
    sat = act.saturated
    if not len(sat):
        return []
    lines = [
        f"window {i} ({act.t_start_ms[i]:g}-{act.t_end_ms[i]:g} ms): events on {100 * act.share[i]:.1f}% of "
        "the sensor's pixels"
        for i in sat[:most]
    ]
    if len(sat) > most:
        lines.append(f"and {len(sat) - most} more windows above {SATURATED_SHARE:.0%}")
    lead = 0
    while lead < len(sat) and sat[lead] == lead:
        lead += 1
    n = len(act.share)
    if lead == n:
        skip = "; every window here is in it: start later with --start-ms (snn-fg events INPUT shows where it ends)"
    elif lead:
        which = "window 0" if lead == 1 else f"windows 0-{lead - 1}"
        skip = (
            f"; --start-ms {act.t_start_ms[lead]:g} skips {which} (a shorter --window-ms in snn-fg events "
            "finds the burst's end more closely)"
        )
    else:
        skip = ""
    lines.append(
        f"{len(sat)} of {n} window{'s' if n > 1 else ''} {'have' if len(sat) > 1 else 'has'} events on more "
        f"than {SATURATED_SHARE:.0%} of the "
        "sensor's pixels: a sensor-wide burst (camera start-up, flicker or a change of light), not a "
        f"scene, which maps as solid colour{skip}"
    )
    return lines


def timeline_text(act: Activity) -> str:
    """The activity as a compact text timeline of at most :data:`TIMELINE_ROWS` rows
    (events as a bar, pixel share, saturated windows marked)."""
    n = len(act.share)
    group = math.ceil(n / TIMELINE_ROWS)
    top = max(int(act.events.max()), 1)
    per = f"{act.window_ms:g} ms windows" if group == 1 else f"{group} windows of {act.window_ms:g} ms each"
    lines = [
        f"rows: {per} from the first event; bar: events; share: pixels with an event"
        + ("" if group == 1 else " (largest of the row)"),
        f"{'t (ms)':>13}  {'events':>11}  {'share':>7}",
    ]
    for k in range(0, n, group):
        sl = slice(k, k + group)
        events, share = int(act.events[sl].sum()), float(act.share[sl].max())
        bar = "#" * round(_BAR * events / (top * group)) if events else ""
        flag = " saturated" if share > SATURATED_SHARE else ""
        span = f"{act.t_start_ms[k]:.0f}-{act.t_end_ms[min(k + group, n) - 1]:.0f}"
        lines.append(f"{span:>13}  {events:>11,}  {100 * share:5.1f} % |{bar:<{_BAR}}|{flag}")
    return "\n".join(lines)


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
            said, at = f"saturated above {SATURATED_SHARE:.0%} (red)", 100 * SATURATED_SHARE
        else:
            said, at = f"none saturated (above {SATURATED_SHARE:.0%})", top
        ax_s.text(
            0.995,
            at,
            said,
            ha="right",
            va="bottom" if at < top else "top",
            fontsize=8,
            transform=ax_s.get_yaxis_transform(),
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
