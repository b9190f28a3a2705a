"""Input spike trains for the spiking network.

Two kinds of input, both ending as one spike source per pixel and polarity
(ON neurons ``0..H*W-1``, OFF neurons ``H*W..2*H*W-1``, pixel ``y*W + x``;
neuron ``2*H*W`` is the window clock of a recording, see
:meth:`InputSpikes.with_clock`):

* timed events (a tonic-style structured array with fields ``x``, ``y``,
  ``t`` in microseconds and ``p``): each event is a spike at its own time,
  relative to the window's first event. With ``replay`` the window repeats
  (like the iCub's periodic micro-saccades) until the simulation ends;
* an event frame without timing (``pos``/``neg`` uint8): every pixel with an
  event fires at ``rate_hz`` for the whole presentation, either regularly
  with a random phase or as a Poisson process; deterministic for a seed.

Spike times are put on the simulation grid (multiples of ``dt``); two spikes
of one neuron in the same step are merged (Brian2 allows one per step).
"""

from __future__ import annotations

import dataclasses
from collections import deque
from dataclasses import dataclass

import numba as nb
import numpy as np

from .. import validate as check
from ..errors import InputError
from ..events.core import check_sensor_size


@dataclass
class InputSpikes:
    """Spikes of the input sources, ready for a ``SpikeGeneratorGroup``.

    ``indices``/``steps`` are the neuron index and time step of each spike in
    one period; the pattern repeats every ``period_steps`` if that is not
    ``None``. ``on``/``off`` are the (H, W) masks of pixels that get spikes;
    ``rate_hz`` is the mean rate of an active pixel (used to calibrate gains).
    ``fired``: ``(on, off)``, the pixels whose sources do fire, where
    ``on``/``off`` mark more (None): a stream's, every source, as its network
    was laid out before its events; once it has been read whole
    (:meth:`~snn_fg.lowering.input_stream.SegmentedInput.whole`), a backend
    that creates only the cells an input reaches may take these (the edge
    masks stay those of ``on``/``off``: :func:`~snn_fg.lowering.unroll.unroll`).
    """

    shape: tuple
    indices: np.ndarray
    steps: np.ndarray
    period_steps: int | None
    on: np.ndarray
    off: np.ndarray
    rate_hz: float
    merged: int = 0  # spikes dropped because they fell in an occupied step
    kind: str = "frame"
    fired: tuple | None = None

    @property
    def clock_index(self) -> int:
        """Index of the window clock's spikes (after every pixel's ON and OFF source)."""
        return 2 * self.shape[0] * self.shape[1]

    @property
    def n_sources(self) -> int:
        return self.clock_index + 1

    def with_clock(self, steps) -> InputSpikes:
        """The same input plus window-clock spikes at ``steps`` (a network
        without a clock ignores them). Only for an input that does not repeat."""
        if self.period_steps is not None:
            check.fail(
                "InputSpikes.with_clock",
                "period_steps",
                self.period_steps,
                "must be None: a repeating input has no windows to mark",
            )
        steps = np.unique(np.asarray(steps, dtype=np.int64))
        idx = np.concatenate([self.indices, np.full(steps.size, self.clock_index, dtype=np.int64)])
        st = np.concatenate([self.steps, steps])
        order = np.lexsort((idx, st))
        return dataclasses.replace(self, indices=idx[order], steps=st[order])

    def spike_times_steps(self, n_steps: int) -> tuple[np.ndarray, np.ndarray]:
        """All (index, step) pairs up to ``n_steps`` (periodic patterns expanded)."""
        if self.period_steps is None:
            keep = self.steps < n_steps
            return self.indices[keep], self.steps[keep]
        reps = -(-n_steps // self.period_steps)
        idx = np.tile(self.indices, reps)
        st = (self.steps[None, :] + self.period_steps * np.arange(reps)[:, None]).ravel()
        keep = st < n_steps
        return idx[keep], st[keep]


def _check_dt(dt_ms):
    if not (isinstance(dt_ms, (int, float)) and np.isfinite(dt_ms) and dt_ms > 0):
        check.fail("input spikes", "dt_ms", dt_ms, "must be a positive number")


#: how an event frame's pixels fire: regular trains with a random phase, or Poisson trains
INPUT_PROCESSES = ("regular", "poisson")


def check_trains(owner: str, rate_hz, process) -> float:
    """An event frame's trains as ``owner`` is given them: ``rate_hz`` a positive number and
    ``process`` one of :data:`INPUT_PROCESSES`; returns the rate as a float."""
    if isinstance(rate_hz, bool) or not (isinstance(rate_hz, (int, float)) and np.isfinite(rate_hz) and rate_hz > 0):
        check.fail(owner, "rate_hz", rate_hz, "must be a positive number")
    check.choice(owner, "input_process", process, INPUT_PROCESSES)
    return float(rate_hz)


def frame_spikes(
    pos, neg, rate_hz: float, dt_ms: float, duration_ms: float, seed: int = 0, process: str = "regular"
) -> InputSpikes:
    """Spike trains for an event frame without timing.

    ``regular``: each active pixel fires every ``round(1000 / rate_hz / dt)``
    steps with a random phase (so the realised rate is ``1000 / (k * dt)``
    Hz); ``poisson``: a Poisson train at ``rate_hz`` sampled per time step.
    """
    _check_dt(dt_ms)
    pos = np.asarray(pos)
    neg = np.asarray(neg)
    if pos.ndim != 2 or pos.shape != neg.shape:
        raise InputError("<frame>", f"pos and neg must be 2-D arrays of one shape, got {pos.shape} and {neg.shape}")
    check_trains("frame_spikes", rate_hz, process)
    on = pos != 0
    off = neg != 0
    h, w = pos.shape
    src = np.concatenate([np.flatnonzero(on), h * w + np.flatnonzero(off)]).astype(np.int64)
    rng = np.random.default_rng(seed)
    n_steps = int(round(duration_ms / dt_ms))
    if process == "regular":
        k = max(1, int(round(1000.0 / rate_hz / dt_ms)))
        if 1000.0 / (k * dt_ms) > 1.5 * rate_hz or 1000.0 / (k * dt_ms) < rate_hz / 1.5:
            check.fail(
                "frame_spikes", "rate_hz", rate_hz, f"is not representable as a regular train with dt={dt_ms} ms"
            )
        phase = rng.integers(0, k, size=src.size)
        order = np.lexsort((src, phase))
        return InputSpikes((h, w), src[order], phase[order], k, on, off, 1000.0 / (k * dt_ms), 0, "frame-regular")
    p = rate_hz * dt_ms / 1000.0
    if p >= 1:
        check.fail("frame_spikes", "rate_hz", rate_hz, f"means at least one spike per step at dt={dt_ms} ms")
    idx_l, st_l = [], []
    for s0 in range(0, n_steps, 1000):  # bounded memory for long presentations
        block = min(1000, n_steps - s0)
        hit = rng.random((block, src.size)) < p
        st, j = np.nonzero(hit)
        idx_l.append(src[j])
        st_l.append(st + s0)
    idx = np.concatenate(idx_l) if idx_l else np.zeros(0, np.int64)
    st = np.concatenate(st_l) if st_l else np.zeros(0, np.int64)
    return InputSpikes(
        (h, w), idx.astype(np.int64), st.astype(np.int64), None, on, off, float(rate_hz), 0, "frame-poisson"
    )


def _field(events, name):
    try:
        return np.asarray(events[name])
    except (ValueError, KeyError, IndexError):
        raise InputError("<events>", f"structured array needs fields x, y, t, p; missing {name!r}") from None


def keep_after_refractory(step: np.ndarray, idx: np.ndarray, gap: int, last: np.ndarray | None = None):
    """The events ``(step, idx)`` of every source at least ``gap`` steps
    after the one it last kept, in their own order. ``last[source]``: the
    step each source last kept an event at (updated; default: none yet), so
    that a recording's events can be handed over chunk by chunk
    (:class:`~snn_fg.lowering.input_stream.SpikeStream`)."""
    if last is None:
        last = np.full(int(idx.max(initial=0)) + 1, -gap, dtype=np.int64)
    order = np.argsort(step, kind="stable")
    keep = np.zeros(idx.size, bool)
    _keep_after_gap(idx[order], step[order], gap, last, keep)
    keep = np.sort(order[keep])
    return step[keep], idx[keep]


@nb.njit(cache=True)
def _keep_after_gap(idx, step, gap, last, keep):
    for e in range(idx.size):
        if step[e] - last[idx[e]] >= gap:
            keep[e] = True
            last[idx[e]] = step[e]


@nb.njit(cache=True, nogil=True)
def steps_and_sources(t, x, y, p, t0_us, step_us, h, w):
    """Each event's time step, ``floor((t - t0_us) / step_us)``, and input
    source on a grid of ``(h, w)``: ON ``y * w + x``, OFF ``h * w + y * w + x``
    (one compiled pass), and whether the steps never decrease (a stream's
    chunk, every 5 ms of a live run: :class:`EventQueue`)."""
    step, idx = np.empty(t.size, np.int64), np.empty(t.size, np.int64)
    ordered = True
    for e in range(t.size):
        step[e] = np.int64(np.floor((np.float64(t[e]) - t0_us) / step_us))
        idx[e] = np.int64(y[e]) * w + np.int64(x[e]) + (0 if p[e] > 0 else h * w)
        if e > 0 and step[e] < step[e - 1]:
            ordered = False
    return step, idx, ordered


def step_spikes(step: np.ndarray, idx: np.ndarray, n_sources: int, gap: int, last: np.ndarray | None = None):
    """Spikes ``(indices, steps, merged)`` of events ``(step, idx)``: each
    source's events ``gap`` steps apart at least (:func:`keep_after_refractory`,
    ``last`` as there), then one spike per source and step, sorted by step
    and source; ``merged`` counts the events that fell in a step their
    source already fired in."""
    if gap > 0:
        step, idx = keep_after_refractory(step, idx, gap, last)
    key = np.unique(step * n_sources + idx)
    return key % n_sources, key // n_sources, int(idx.size - key.size)


def event_spikes(
    events,
    sensor_size,
    dt_ms: float,
    replay: bool = True,
    source: str = "<events>",
    t0_us: float | None = None,
    refractory_ms: float = 0.0,
) -> InputSpikes:
    """Spike trains from timed events (tonic-style: x, y, t in microseconds, p).

    ``sensor_size`` is ``(W, H)`` or ``(W, H, 2)``. Times are taken relative to
    ``t0_us`` (default: the first event); the window is ``[t0, t_last]``. With
    ``replay`` the window repeats with period ``ceil((t_last - t0 + 1 us) / dt)``
    steps. With ``refractory_ms`` a source passes on an event only that long
    after the last one it passed on
    (:attr:`~snn_fg.network.Network.input_refractory_ms`).
    """
    _check_dt(dt_ms)
    if not isinstance(events, np.ndarray) or events.dtype.names is None:
        raise InputError(source, "events must be a structured array with fields x, y, t, p")
    w, h, _ = check_sensor_size(sensor_size, source)
    x, y, t, p = (_field(events, k) for k in ("x", "y", "t", "p"))
    if x.size == 0:
        raise InputError(source, "no events in the window")
    bad = np.flatnonzero((x < 0) | (x >= w) | (y < 0) | (y >= h))
    if bad.size:
        raise InputError(
            source, f"event at x={x[bad[0]]}, y={y[bad[0]]} outside the {w} x {h} sensor", f"event {bad[0]}"
        )
    if not np.issubdtype(t.dtype, np.number) or not np.all(np.isfinite(t)):
        raise InputError(source, "timestamps t must be finite numbers (microseconds)")
    t = t.astype(np.float64)
    t0 = t.min() if t0_us is None else float(t0_us)
    if t.min() < t0:
        raise InputError(
            source, f"an event at t={t.min():g} us lies before the start t0={t0:g} us", f"event {int(np.argmin(t))}"
        )
    step, idx, _ = steps_and_sources(t, x, y, p, t0, dt_ms * 1000.0, h, w)
    gap = int(round(refractory_ms / dt_ms)) if refractory_ms > 0 else 0
    idx_u, st_u, merged = step_spikes(step, idx, 2 * h * w, gap)
    period = int(st_u.max()) + 1 if replay else None
    on = np.zeros(h * w, bool)
    off = np.zeros(h * w, bool)
    on[idx_u[idx_u < h * w]] = True
    off[idx_u[idx_u >= h * w] - h * w] = True
    n_active = int(on.sum() + off.sum())
    span_s = (period if period else int(st_u.max()) + 1) * dt_ms / 1000.0
    rate = idx_u.size / max(n_active, 1) / span_s
    return InputSpikes((h, w), idx_u, st_u, period, on.reshape(h, w), off.reshape(h, w), float(rate), merged, "events")


class EventQueue:
    """Events handed over in time order, chunk by chunk, queued as input
    sources and steps until a stream gives them out as spikes
    (:class:`~snn_fg.lowering.input_stream.SpikeStream`,
    :class:`~snn_fg.lowering.held_input.HeldStream`): ``shape`` the input
    grid ``(H, W)`` (sources as :func:`steps_and_sources` numbers them), step 0 at
    ``t0_us``. ``on`` and ``off`` mark the sources that have fired so far
    (the stream sets :attr:`fired`)."""

    def __init__(self, shape, dt_ms: float, t0_us: float):
        self.h, self.w = shape
        self.step_us, self.t0_us = dt_ms * 1000.0, float(t0_us)
        # the queue: chunks of (steps, sources) in the order added, the first from ``_at`` on. The steps
        # of events in time order never decrease, so the events due are a prefix of the queue, found by
        # bisection: a live run a window behind holds a window of events here, and masking and copying
        # all of them in every 5 ms segment cost it more the further it fell behind
        self._chunks: deque = deque()
        self._at = 0
        self._last_step = np.iinfo(np.int64).min  # (the last step queued; an earlier one breaks the order)
        self.fired = np.zeros(2 * self.h * self.w, bool)
        self.merged = 0

    def add(self, events) -> None:
        """Events (fields ``x``, ``y``, ``t`` in microseconds, ``p``) later
        than every step already taken, in time order."""
        if not len(events):
            return
        step, idx, ordered = steps_and_sources(
            events["t"], events["x"], events["y"], events["p"], self.t0_us, self.step_us, self.h, self.w
        )
        if step[0] < self._last_step or not ordered:
            # (never from a stream, whose cutter refuses time running backwards: the queue made one
            # chunk again, ordered by step, so that what is due stays a prefix)
            self._chunks.append((step, idx))
            step, idx = self.due(np.iinfo(np.int64).max)
            order = np.argsort(step, kind="stable")
            step, idx = step[order], idx[order]
        self._last_step = int(step[-1])
        self._chunks.append((step, idx))

    def due(self, end_step: int) -> tuple[np.ndarray, np.ndarray]:
        """The queued events of the steps before ``end_step`` as ``(steps, sources)``,
        in the order they were added, taken off the queue."""
        steps, sources = [], []
        while self._chunks:
            step, idx = self._chunks[0]
            cut = max(int(np.searchsorted(step, end_step, side="left")), self._at)
            steps.append(step[self._at : cut])
            sources.append(idx[self._at : cut])
            if cut < step.size:  # (the rest of this chunk, and every later one, is not due yet)
                self._at = cut
                break
            self._chunks.popleft()
            self._at = 0
        if len(steps) == 1:
            return steps[0], sources[0]
        if not steps:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        return np.concatenate(steps), np.concatenate(sources)

    @property
    def on(self) -> np.ndarray:
        return self.fired[: self.h * self.w].reshape(self.h, self.w)

    @property
    def off(self) -> np.ndarray:
        return self.fired[self.h * self.w :].reshape(self.h, self.w)
