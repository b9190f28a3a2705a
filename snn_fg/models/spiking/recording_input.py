"""A recording's input to the spiking network, read twice with bounded memory.

The network's input gains are calibrated to the mean rate of an active
input over the recording's windows before the run starts, so the recording
is read twice: :func:`plan_recording` reads it once, keeping only what the
calibration and the run's layout need (one rate and two read-out span ends
per window, the input pixels that ever fire); :class:`WindowFeed` reads it
again while the network runs, turning each window's events into input
spikes as the backend asks for the next segment of steps
(:class:`~snn_fg.lowering.input_stream.SegmentedInput`) and holding each
window only until it is decoded. Neither keeps the recording's events or
spikes: memory is bounded by a few windows, whatever the length.

Each event is fed once: where windows overlap, a window adds only its
events from the previous window's end on.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ...errors import InputError
from ...frames.pool import pool_events, pooled_shape
from ...lowering.held_input import HeldStream
from ...lowering.input_stream import SegmentedInput, SpikeStream

#: simulated time per segment of input handed to a backend that streams it (ms)
SEGMENT_MS = 100.0


@dataclasses.dataclass
class RecordingPlan:
    """What the first pass over a recording's windows found
    (:func:`plan_recording`): the network (its ``origin``), the first
    window's start ``t0_us`` and frame ``shape``, each window's read-out
    ``spans`` (ms from ``t0_us``, lag included) and first step (``window_steps``;
    ``clock_steps`` the same where the window clock fires), the input
    sources that fire (``on``, ``off``), the events merged in a step, and
    the mean rate of an active pixel (``event_rate_hz``, of the events) and
    of an active input source (``spike_rate_hz``, after the input adapter's
    pooling and refractory period), and the run's time step ``dt_ms``."""

    network: object
    origin: dict
    t0_us: float
    shape: tuple
    spans: list
    clock_steps: np.ndarray
    on: np.ndarray
    off: np.ndarray
    merged: int
    event_rate_hz: float
    spike_rate_hz: float
    dt_ms: float

    seed: int = 0
    window_steps: np.ndarray | None = None

    @property
    def held(self) -> bool:
        """Whether the events are held as the window's frame (the ``window`` input coding)."""
        return self.network.input_coding == "window"

    @property
    def adapted(self) -> bool:
        """Whether an input adapter stands between the events and the sources."""
        return self.network.params.input_pool > 1 or self.network.input_refractory_ms > 0

    @property
    def rate_hz(self) -> float:
        """The rate the gains are calibrated to: what reaches the sources
        (a held source fires at the network's own input rate)."""
        if self.held:
            return self.network.input_rate_hz
        return self.spike_rate_hz if self.adapted else self.event_rate_hz


def input_stream(net, shape, dt_ms: float, t0_us: float, seed: int = 0):
    """The stream that turns a recording's events into ``net``'s input spikes
    on its (pooled) input grid of ``shape``: each event a spike
    (:class:`~snn_fg.lowering.input_stream.SpikeStream`, through the input
    adapter's refractory period), or the window's frame held as it is built
    (:class:`~snn_fg.lowering.held_input.HeldStream`; windows are marked with
    :meth:`_NewEvents.add`)."""
    if net.input_coding == "window":
        return HeldStream(shape, dt_ms, t0_us, net.input_rate_hz, (), seed)
    return SpikeStream(shape, dt_ms, t0_us, net.input_refractory_ms)


def read_out_span(window, t0_us: float, lag_ms: float, dt_ms: float) -> tuple[float, float]:
    """A window's read-out span (ms from the first window's start, lag
    included) on the step grid, at least one step long: a recording's last
    window can be shorter than a step (it ends 1 us after the last event),
    and a span of no steps would count no spikes."""
    a = round(((window.t_start_us - t0_us) / 1000.0 + lag_ms) / dt_ms)
    b = round(((window.t_end_us - t0_us) / 1000.0 + lag_ms) / dt_ms)
    return a * dt_ms, max(b, a + 1) * dt_ms


class _NewEvents:
    """Each window's events not in the window before (overlapping windows
    share events), on the network's input grid, into a :class:`SpikeStream`;
    :attr:`complete_before` is the first step whose events may still come."""

    def __init__(self, stream: SpikeStream, pool: int, t0_us: float, dt_ms: float):
        self.stream, self.pool, self.t0_us, self.step_us = stream, pool, t0_us, dt_ms * 1000.0
        self.prev_end = None
        self.complete_before = 0

    def add(self, w) -> int:
        """Adds window ``w``'s new events; returns how many."""
        ev = w.events
        if isinstance(self.stream, HeldStream):  # (every hold ends as a window starts or ends)
            self.stream.resets = np.union1d(self.stream.resets, _window_steps(w, self.t0_us, self.step_us / 1000))
        if self.prev_end is not None and w.t_start_us < self.prev_end:
            ev = ev[ev["t"] >= self.prev_end]
        self.stream.add(pool_events(ev, self.pool))
        self.prev_end = w.t_end_us
        self.complete_before = int(np.floor((w.t_end_us - self.t0_us) / self.step_us))
        return len(ev)


def _window_steps(w, t0_us: float, dt_ms: float) -> tuple[int, int]:
    """The steps ``a .. b - 1`` a window's input spikes are counted over (at least one)."""
    a = int(np.floor((w.t_start_us - t0_us) / (dt_ms * 1000.0)))
    return a, max(int(np.floor((w.t_end_us - t0_us) / (dt_ms * 1000.0))), a + 1)


class _SpikeRates:
    """Each window's rate of an active input source (spikes per source that
    fired, per second of the window's steps), from the spikes taken out of
    the stream in step order; keeps only the spikes of windows not yet counted."""

    def __init__(self, dt_ms: float):
        self.dt_ms, self.rates, self.pending, self.last_a = dt_ms, [], [], 0
        self.idx, self.steps = np.zeros(0, np.int64), np.zeros(0, np.int64)

    def window(self, a: int, b: int):
        """The next window's steps (windows come in order of their start)."""
        self.pending.append((a, b))
        self.last_a = a

    def spikes(self, idx, steps, complete_before: int):
        """Spikes of the steps before ``complete_before`` (all of those)."""
        self.idx, self.steps = np.concatenate([self.idx, idx]), np.concatenate([self.steps, steps])
        while self.pending and self.pending[0][1] <= complete_before:
            a, b = self.pending.pop(0)
            lo, hi = np.searchsorted(self.steps, [a, b])
            sel = self.idx[lo:hi]
            if sel.size:
                self.rates.append(sel.size / np.unique(sel).size / ((b - a) * self.dt_ms / 1000.0))
        first = min([a for a, _ in self.pending] + [self.last_a])  # (the next window starts after the last)
        cut = int(np.searchsorted(self.steps, first))
        self.idx, self.steps = self.idx[cut:], self.steps[cut:]


def _event_rate(w, dt_ms: float) -> float | None:
    """A window's rate of an active pixel (events per pixel with an event,
    per second of the window), or None without events."""
    if not len(w.events):
        return None
    active = int(np.count_nonzero(w.pos) + np.count_nonzero(w.neg))
    span_s = max((w.t_end_us - w.t_start_us) / 1e6, dt_ms / 1000.0)
    return len(w.events) / max(active, 1) / span_s


def plan_recording(
    windows, network_options, simulator, lag_ms: float, window_clock: bool, source: str, seed: int = 0
) -> RecordingPlan:
    """The first pass over ``windows`` (an iterable read once): the network
    for the first window's frame (``network_options.resolve``), stepped at
    ``simulator.step_for(network)``, and what the run needs to know before
    it starts (:class:`RecordingPlan`); ``seed``: of the held sources' phases
    (the ``window`` input coding)."""
    plan, feed, rates, event_rates, n_events, clock = None, None, None, [], 0, []
    for w in windows:
        if plan is None:
            net, origin = network_options.resolve(w.pos.shape)
            pool, t0, dt_ms = net.params.input_pool, w.t_start_us, simulator.step_for(net)
            stream = input_stream(net, pooled_shape(w.pos.shape, pool), dt_ms, t0, seed)
            feed, rates = _NewEvents(stream, pool, t0, dt_ms), _SpikeRates(dt_ms)
            plan = RecordingPlan(
                network=net,
                origin=origin,
                t0_us=t0,
                shape=w.pos.shape,
                spans=[],
                clock_steps=None,
                on=None,
                off=None,
                merged=0,
                event_rate_hz=0.0,
                spike_rate_hz=0.0,
                dt_ms=dt_ms,
                seed=seed,
            )
        plan.spans.append(read_out_span(w, plan.t0_us, lag_ms, dt_ms))
        clock.append(_window_steps(w, plan.t0_us, dt_ms)[0])
        rate = _event_rate(w, dt_ms)
        if rate is not None:
            event_rates.append(rate)
        n_events += feed.add(w)
        rates.window(*_window_steps(w, plan.t0_us, dt_ms))
        rates.spikes(*stream.take_until(feed.complete_before), feed.complete_before)
    if plan is None:
        raise InputError(source, "no window to process")
    if not n_events:
        raise InputError(source, "no window has an event: nothing to simulate")
    end = np.iinfo(np.int64).max // (2 * stream.h * stream.w + 2)
    rates.spikes(*stream.take_until(end), end)
    plan.event_rate_hz = float(np.mean(event_rates)) if event_rates else 0.0
    plan.spike_rate_hz = float(np.mean(rates.rates)) if rates.rates else 0.0
    plan.on, plan.off, plan.merged = stream.on.copy(), stream.off.copy(), stream.merged
    has_clock = bool(window_clock and plan.network.by_role("clock"))
    plan.window_steps = np.unique(np.asarray(clock, dtype=np.int64))
    plan.clock_steps = plan.window_steps if has_clock else None
    return plan


class WindowFeed:
    """The second pass over a recording's ``windows``: the input spikes of
    their events, made as the backend asks for them (:attr:`input`, a
    :class:`~snn_fg.lowering.input_stream.SegmentedInput`), and each window
    held until :meth:`window` gives it out (``keep``: held to the end, for a
    run decoded once it is over)."""

    def __init__(self, windows, plan: RecordingPlan, *, keep: bool = False):
        net, dt_ms = plan.network, plan.dt_ms
        stream = input_stream(net, pooled_shape(plan.shape, net.params.input_pool), dt_ms, plan.t0_us, plan.seed)
        self.it, self.keep, self.held, self.done = iter(windows), keep, {}, False
        self.events = _NewEvents(stream, net.params.input_pool, plan.t0_us, dt_ms)
        self.n = 0
        clock = plan.clock_steps if plan.clock_steps is not None else np.zeros(0, np.int64)
        self.input = SegmentedInput(
            (stream.h, stream.w),
            plan.on,
            plan.off,
            plan.rate_hz,
            plan.merged,
            max(1, int(round(SEGMENT_MS / dt_ms))),
            self._spikes_until,
            clock,
        )
        self.stream = stream

    def _pull(self) -> bool:
        w = next(self.it, None)
        if w is None:
            self.done = True
            return False
        self.held[self.n] = w
        self.n += 1
        self.events.add(w)
        return True

    def _spikes_until(self, end_step: int):
        while not self.done and self.events.complete_before < end_step:
            self._pull()
        return self.stream.take_until(end_step)

    def window(self, k: int):
        """Window ``k`` (its position in ``windows``), forgotten unless ``keep``."""
        while k not in self.held and self._pull():
            pass
        return self.held[k] if self.keep else self.held.pop(k)
