"""What a live run gives out as each window's maps are made: one JSON line per
window to ``--publish udp://HOST:PORT`` (its time span and strongest
proto-objects, for a gaze controller), and the run's record, ``live.json``
(every window's latency, and their median, 95th percentile and worst).

A window's latency is the time from the arrival of its last event to its
maps being written and published.
"""

from __future__ import annotations

import json
import socket
import time

import numpy as np

from snn_fg.results.atomic import save_text
from snn_fg.results.peaks import grouping_peaks

#: the drop policy, as live.json states it
DROP_POLICY = (
    "whole windows: a stride's slot of events is dropped when it begins while more than max_behind complete "
    "windows wait for their maps; a window holding a dropped slot is neither written nor published"
)


class Publisher:
    """One JSON line per window, in a UDP datagram to ``address`` ``(host, port)``."""

    def __init__(self, address: tuple[str, int]):
        self.address = address
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send(self, message: dict) -> None:
        self.sock.sendto((json.dumps(message) + "\n").encode(), self.address)

    def close(self):
        self.sock.close()


class LiveRecord:
    """The windows of a live run as they are published, and ``live.json`` at its end."""

    def __init__(self, stream, publisher: Publisher | None = None, peaks: int = 3):
        self.stream, self.publisher, self.k = stream, publisher, peaks
        self.rows: list = []
        self.t_start = time.perf_counter()

    def window(self, w, maps) -> None:
        """Window ``w``'s maps are written: publish them, note the latency."""
        arrived = self.stream.arrival(w)
        origin = self.stream.origin - self.stream.start
        message = {
            "window": len(self.rows),
            "t_start_us": int(w.t_start_us - origin),
            "t_end_us": int(w.t_end_us - origin),
            "events": int(len(w.events)),
            "peaks": grouping_peaks(maps, self.k),
        }
        now = time.perf_counter()
        message["latency_ms"] = None if arrived is None else round((now - arrived) * 1000, 3)
        if self.publisher is not None:
            self.publisher.send(message)
        self.rows.append({k: message[k] for k in ("window", "t_start_us", "t_end_us", "events", "latency_ms")})

    def summary(self, ended: str) -> dict:
        lat = np.array([r["latency_ms"] for r in self.rows if r["latency_ms"] is not None], dtype=np.float64)
        latency = (
            {"median": float(np.median(lat)), "p95": float(np.percentile(lat, 95)), "max": float(lat.max())}
            if lat.size
            else None
        )
        return {
            "windows": len(self.rows),
            **self.stream.stats(),
            "latency_ms": latency,
            "ended": ended,
            "seconds": round(time.perf_counter() - self.t_start, 3),
            "drop_policy": DROP_POLICY,
            "max_behind": self.stream.max_behind,
            "per_window": self.rows,
        }

    def save(self, path, ended: str) -> dict:
        out = self.summary(ended)
        save_text(path, json.dumps(out, indent=1) + "\n")
        return out


class LiveModel:
    """``model`` as :func:`~snn_fg.cli.runner.run_recording` runs it, with each
    window's maps published (``record``) once written, and the windows that
    hold a dropped slot left out."""

    def __init__(self, model, stream, record: LiveRecord):
        self.model, self.stream, self.record = model, stream, record

    def __getattr__(self, name):
        return getattr(self.model, name)

    def run_windows_into(self, windows, emit, start: int = 0) -> dict:
        def each(w, maps):
            if not self.stream.dropped_window(w):  # (counted as its slot was dropped)
                emit(w, maps)
                self.record.window(w, maps)
            self.stream.done(w)

        return self.model.run_windows_into(windows, each, start)
