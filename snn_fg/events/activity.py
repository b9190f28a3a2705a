"""Activity of a recording over time, and windows that cover the whole sensor.

A window whose events fall on more than :data:`~snn_fg.results.activity.SATURATED_SHARE` of the
sensor's pixels is not a scene but a sensor-wide burst: the start-up reset
of an ATIS or DVS camera (tens of thousands of events on every pixel within
a millisecond or so), flicker, or a sudden change of light. The model maps
such a window as solid colour everywhere, so ``snn-fg events`` shows where
they are (:func:`activity`, :func:`timeline_text`,
:func:`~snn_fg.results.activity.activity_figure`)
and ``snn-fg run`` warns about each one (:func:`saturated_lines`).
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from snn_fg.events.cutter import WINDOW_MS
from snn_fg.events.frame import EmptyWindowWarning
from snn_fg.events.window import iter_windows
from snn_fg.results.activity import SATURATED_SHARE, Activity

#: rows of the text timeline at most (consecutive windows are merged beyond)
TIMELINE_ROWS = 30
_BAR = 30


def pixel_share(window) -> float:
    """Share of the sensor's pixels with an event in ``window`` (an :class:`~snn_fg.events.EventWindow`)."""
    return float(np.count_nonzero(window.pos | window.neg) / window.pos.size)


def activity(recording, *, window_ms: float = WINDOW_MS, start_ms: float = 0.0, sensor_size=None) -> Activity:
    """Events and pixel share of every window of ``recording`` (a path, a
    stream or an array), cut as :func:`~snn_fg.events.iter_windows` cuts it
    from ``start_ms`` after the first event (the windows a run with that
    ``--start-ms`` is given, numbered as it numbers them)."""
    rows = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EmptyWindowWarning)  # an empty window is a row of zeros
        for w in iter_windows(recording, window_ms=window_ms, start_ms=start_ms, sensor_size=sensor_size):
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
    elif lead:  # (the windows count from the --start-ms the activity was cut from, as a run's do)
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
    start = act.t_start_ms[0] if n else 0
    since = "the first event" if not start else f"{start:g} ms (--start-ms; times from the first event)"
    lines = [
        f"rows: {per} from {since}; bar: events; share: pixels with an event"
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
