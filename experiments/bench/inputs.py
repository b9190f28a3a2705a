"""The benchmark's inputs, rebuilt from a small spec in every measuring process.

* ``bsds:<id>`` - a BSDS event frame of the dataset ``bsds-edfg`` (``<id>.npz``);
* ``dvs:<k>[@<start_ms>]`` - the k-th 85 ms window of dvs.es (dataset
  ``events``) from ``start_ms`` (default 1: the first
  millisecond, a full-frame reset burst, dropped);
* ``synth:<n>`` - a synthetic 85 ms window of ``n`` events on a 320 x 240
  sensor: edge events of random discs and bars, a few events per pixel, as a
  moving scene gives. Deterministic for ``n``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

WINDOW_MS = 85.0
# dvs.es opens with a ~77k-event reset burst in its first ms: the bench's dvs section starts past it, at 1 ms,
# as its timings since 24 Nov were taken (--dvs-start-ms 100 gives the other experiments' start, DVS_FROM_MS)
DVS_START_MS = 1.0
SENSOR = (320, 240)  # width, height of dvs.es and of the synthetic windows
EVENTS_PER_PIXEL = 3  # a moving edge makes a pixel fire a few times per window
SEED = 13


@dataclass
class BenchInput:
    """One input: an event frame and, for windows, its timed events."""

    name: str
    pos: np.ndarray
    neg: np.ndarray
    events: np.ndarray | None = None
    t_start_us: int | None = None  # a window's own span (else its events')
    t_end_us: int | None = None

    @property
    def n_events(self) -> int | None:
        return None if self.events is None else int(len(self.events))

    @property
    def active_pixels(self) -> int:
        return int(((self.pos != 0) | (self.neg != 0)).sum())

    def window(self):
        """The input as an :class:`~snn_fg.events.EventWindow` (a window's
        own span, else its events')."""
        from snn_fg.events import EventWindow

        t = self.events["t"]
        return EventWindow(
            index=0,
            t_start_us=self.t_start_us if self.t_start_us is not None else int(t[0]),
            t_end_us=self.t_end_us if self.t_end_us is not None else int(t[-1]) + 1,
            events=self.events,
            pos=self.pos,
            neg=self.neg,
        )

    def describe(self) -> dict:
        return {
            "input": self.name,
            "shape": list(self.pos.shape),
            "n_events": self.n_events,
            "active_pixels": self.active_pixels,
        }


def bsds_names() -> list[str]:
    """The BSDS reference frames' ids (none when the dataset ``bsds-edfg`` is absent)."""
    from snn_fg import datasets

    folder = datasets.find("bsds-edfg")
    return sorted(p.stem for p in folder.glob("*.npz")) if folder is not None else []


def dvs_path() -> Path:
    """dvs.es; ends the benchmark with the fetch command when the dataset ``events`` is absent."""
    from experiments.common import dataset

    return dataset("events", "dvs.es")


#: each copy of dvs.es starts this long after the one before (us): its events span 0-999 ms
COPY_SPAN_US = 1_000_000


def dvs_played(path: Path, copies: int) -> Path:
    """``dvs.es`` played ``copies`` times in a row into ``path`` (.npy of
    events, sensor 320 x 240, written a copy at a time): a long recording
    made of the one we have. Returns ``path``."""
    from numpy.lib.format import open_memmap

    from experiments.common import fail
    from snn_fg.events import EVENT_DTYPE, open_recording

    ev = open_recording(dvs_path()).events
    if int(ev["t"][-1] - ev["t"][0]) >= COPY_SPAN_US:
        fail(f"dvs.es spans {int(ev['t'][-1] - ev['t'][0])} us, more than a copy's {COPY_SPAN_US} us")
    out = open_memmap(path, mode="w+", dtype=EVENT_DTYPE, shape=(len(ev) * copies,))
    for k in range(copies):
        part = out[k * len(ev) : (k + 1) * len(ev)]
        part[:] = ev
        part["t"] += k * COPY_SPAN_US - int(ev["t"][0])
    out.flush()
    del out
    return path


def dvs_windows(max_windows=None, start_ms: float = DVS_START_MS):
    """The 85 ms windows of dvs.es (EventWindow objects)."""
    from snn_fg.events import EmptyWindowWarning, iter_windows

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", EmptyWindowWarning)
        return list(iter_windows(dvs_path(), window_ms=WINDOW_MS, start_ms=start_ms, max_windows=max_windows))


def _contour_pixels(rng, width, height, want):
    """Edge pixels of random discs and bars until ``want`` distinct pixels."""
    img = np.zeros((height, width), bool)
    yy, xx = np.mgrid[0:height, 0:width]
    while img.sum() < want:
        if rng.random() < 0.5:
            cx, cy, r = rng.uniform(0, width), rng.uniform(0, height), rng.uniform(6, 40)
            d = np.hypot(xx - cx, yy - cy)
            img |= np.abs(d - r) < 0.7
        else:
            x0, y0 = rng.uniform(0, width), rng.uniform(0, height)
            ang, length = rng.uniform(0, np.pi), rng.uniform(20, 120)
            t = np.linspace(0, length, int(length * 2))
            x = np.clip((x0 + t * np.cos(ang)).astype(int), 0, width - 1)
            y = np.clip((y0 + t * np.sin(ang)).astype(int), 0, height - 1)
            img[y, x] = True
    ys, xs = np.nonzero(img)
    keep = rng.permutation(len(xs))[:want]
    return xs[keep], ys[keep]


def synthetic_window(n_events: int):
    """``(events, pos, neg)`` of a synthetic 85 ms window with ``n_events`` events."""
    from snn_fg.events import events_to_frame
    from snn_fg.events.core import pack_events

    rng = np.random.default_rng(SEED + n_events)
    width, height = SENSOR
    n_px = max(1, min(n_events // EVENTS_PER_PIXEL, width * height // 2))
    xs, ys = _contour_pixels(rng, width, height, n_px)
    pick = rng.integers(0, len(xs), n_events)
    t = np.sort(rng.integers(0, int(WINDOW_MS * 1000), n_events))
    # each pixel keeps one polarity (the side of the edge it sits on)
    pol = ((xs * 7 + ys * 13) % 2).astype(np.int8)
    events = pack_events(xs[pick], ys[pick], t, pol[pick])
    pos, neg = events_to_frame(events, (width, height, 2))
    return events, pos, neg


def load(spec: str) -> BenchInput:
    """The input named by ``spec`` (see the module docstring)."""
    kind, _, arg = spec.partition(":")
    if kind == "bsds":
        from experiments.common import dataset

        d = np.load(dataset("bsds-edfg", f"{arg}.npz"))
        return BenchInput(spec, d["pos"], d["neg"])
    if kind == "dvs":
        k, _, start = arg.partition("@")
        k = int(k)
        w = dvs_windows(max_windows=k + 1, start_ms=float(start) if start else DVS_START_MS)[k]
        return BenchInput(spec, w.pos, w.neg, w.events, w.t_start_us, w.t_end_us)
    if kind == "synth":
        events, pos, neg = synthetic_window(int(arg))
        return BenchInput(spec, pos, neg, events, 0, int(WINDOW_MS * 1000))
    raise ValueError(f"unknown input spec {spec!r}")
