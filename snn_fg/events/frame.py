"""Stage 1 of the model: a window's event frames (:func:`events_to_frame`) and the window itself
(:class:`EventWindow`), which every model reads."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from snn_fg.events.core import as_events, check_in_sensor, sensor_size_parameter


def events_to_frame(events, sensor_size, source="<array>", offset: int = 0):
    """Return ``(pos, neg)``, uint8 ``H x W`` event frames (model.md stage 1).

    Each pixel keeps the polarity of its last event: ``pos`` is 1 where that
    event was ON, ``neg`` where it was OFF; pixels without events are 0 in
    both (``edges = pos | neg``).  "Last" means latest timestamp; among equal
    timestamps the later one in the array wins.  Events outside the sensor
    raise :class:`~snn_fg.errors.InputError` naming the event index.
    """
    w, h, _ = sensor_size_parameter("events_to_frame", sensor_size)
    ev = as_events(events, source, offset)
    check_in_sensor(ev, (w, h), source, offset)
    pos = np.zeros(h * w, dtype=np.uint8)
    neg = np.zeros(h * w, dtype=np.uint8)
    if len(ev):
        t = ev["t"]
        if len(t) > 1 and (np.diff(t) < 0).any():
            ev = ev[np.argsort(t, kind="stable")]
        _last_polarity(ev["x"], ev["y"], ev["p"], w, pos, neg)
    return pos.reshape(h, w), neg.reshape(h, w)


@njit(cache=True, nogil=True)
def _last_polarity(x, y, p, w, pos, neg):
    """Each pixel's last event in array order sets it in ``pos`` (ON) or ``neg`` (OFF)."""
    for k in range(x.size):
        i = np.int64(y[k]) * w + np.int64(x[k])
        on = p[k] > 0
        pos[i] = on
        neg[i] = not on


class EmptyWindowWarning(UserWarning):
    """A time window contained no events; its frames are all zero."""


@dataclass(frozen=True)
class EventWindow:
    """One time window ``[t_start_us, t_end_us)`` and its event frame.

    ``events`` are the window's events (after the optional denoise and
    refractory filters); ``pos``/``neg`` come from :func:`events_to_frame`.
    Times are in the recording's own clock (some formats stamp Unix time);
    ``t_first_event_us``, the recording's first event, is the origin of every
    time shown to a user (:attr:`span_ms`).
    """

    index: int
    t_start_us: int
    t_end_us: int
    events: np.ndarray
    pos: np.ndarray
    neg: np.ndarray
    t_first_event_us: int | None = None

    @property
    def span_ms(self) -> tuple[float, float]:
        """Start and end, ms after the recording's first event (after the
        window's own start when that is unknown)."""
        origin = self.t_start_us if self.t_first_event_us is None else self.t_first_event_us
        return (self.t_start_us - origin) / 1000.0, (self.t_end_us - origin) / 1000.0

    @property
    def edges(self) -> np.ndarray:
        """1 where any event fired (model.md stage 1)."""
        return self.pos | self.neg
