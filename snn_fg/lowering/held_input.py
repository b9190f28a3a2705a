"""A recording's events as the window's event frame, built while they arrive.

The model reads a recording window by window (stage 1, ``docs/model.md``):
each pixel keeps the polarity of its last event in the window. With the
``window`` input coding (:attr:`~snn_fg.network.Network.input_coding`) the
spike sources do the same, causally: an event sets its pixel's state to its
polarity, and from that step the source of that polarity fires a regular
train at the network's input rate, until the pixel's next event (which may
switch it to the other source) or the window's end (or the next window's
start, if windows overlap), when every pixel is cleared. With the
``sliding`` input coding no window edge clears a pixel: its hold ends one
window's length after its last event (a sliding window, the same for every
pixel), so that the input does not fall silent as each window starts and
the network need not build its answer afresh. Either way, at a window's end the sources that fire are exactly the
window's event frame, and each fires as a frame's pixel does
(:func:`~snn_fg.lowering.input_spikes.frame_spikes`: regular, with a phase
of its own). The phases are drawn once per source from a seed, so that
pixels an edge sweeps over together do not fire together.

:class:`HeldStream` gives the same interface as
:class:`~snn_fg.lowering.input_stream.SpikeStream` (events added in time
order, spikes taken out step range by step range); :func:`held_spikes` is
the rule itself, over one chunk of events.
"""

from __future__ import annotations

import numpy as np

from .input_spikes import EventQueue


def hold_period_steps(rate_hz: float, dt_ms: float) -> int:
    """Steps between two spikes of a held source: the network's input rate
    on the step grid (as :func:`~snn_fg.lowering.input_spikes.frame_spikes`
    makes a regular train)."""
    return max(1, int(round(1000.0 / rate_hz / dt_ms)))


def hold_phases(n_sources: int, period: int, seed: int = 0) -> np.ndarray:
    """Each source's phase (``0 .. period - 1``), drawn once from ``seed``."""
    return np.random.default_rng(seed).integers(0, period, size=n_sources).astype(np.int64)


def held_spikes(
    steps: np.ndarray,
    sources: np.ndarray,
    n_pixels: int,
    period: int,
    phase: np.ndarray,
    start: int,
    end: int,
    resets: np.ndarray,
    carried: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    hold: int | None = None,
):
    """The spikes ``(sources, steps)`` of steps ``start .. end - 1``.

    ``steps``, ``sources``: the events of those steps in time order (a
    source is ``pixel`` for ON and ``n_pixels + pixel`` for OFF); ``carried``:
    the pixels held at ``start``, the source each holds and the step of the
    event that set it; ``resets``: sorted steps at which every hold ends (a
    window's start); ``hold``: a hold also ends this many steps after its
    event (None: only at its pixel's next event or a reset). A held source
    fires at the steps ``s`` with ``(s - phase[source]) % period == 0``.
    Returns the spikes sorted by step and source, and the holds carried on
    to ``end`` (pixels, sources, event steps)."""
    none = np.zeros(0, np.int64)
    c_pix, c_src, c_since = carried if carried is not None else (none, none, none)
    pix = np.concatenate([c_pix, sources % n_pixels])
    src = np.concatenate([c_src, sources])
    begin = np.concatenate([np.full(c_pix.size, start, np.int64), steps])
    since = np.concatenate([c_since, steps])  # (the step of the event that set the hold)
    # a hold ends at its pixel's next event, at the next reset after it began, ``hold`` steps after its event,
    # or at the chunk's end
    order = np.lexsort((np.arange(pix.size), pix))  # by pixel, then in time order (carried first)
    stop = np.full(pix.size, end, np.int64)
    same = pix[order][1:] == pix[order][:-1]
    stop[order[:-1][same]] = begin[order[1:][same]]
    if resets.size:
        r = np.searchsorted(resets, since, side="right")
        stop = np.minimum(stop, np.where(r < resets.size, resets[np.minimum(r, resets.size - 1)], end))
    if hold is not None:
        stop = np.minimum(stop, since + hold)
    ph = phase[src]
    first = begin + (ph - begin) % period
    count = np.maximum(0, -(-(stop - first) // period))
    rep = np.repeat(np.arange(pix.size), count)
    k = np.arange(rep.size) - np.repeat(np.cumsum(count) - count, count)
    out_steps = first[rep] + k * period
    out_src = src[rep]
    last = np.ones(pix.size, bool)
    last[order[:-1][same]] = False
    alive = last & (stop >= end)
    key = np.unique(out_steps * (2 * n_pixels) + out_src)
    return (key % (2 * n_pixels), key // (2 * n_pixels)), (pix[alive], src[alive], since[alive])


class HeldStream(EventQueue):
    """The ``window`` coding's input spikes of timed events added in time
    order (:meth:`add`), given out step range by step range
    (:meth:`take_until`), as :class:`~snn_fg.lowering.input_stream.SpikeStream`.

    Parameters
    ----------
    shape : (int, int)
        The input grid ``(H, W)``: ON sources ``y * W + x``, OFF sources
        ``H * W + y * W + x``.
    dt_ms, t0_us : float
        The simulation step, and the time of step 0.
    rate_hz : float
        The rate of a held source (the network's input rate).
    window_steps : array of int
        The steps at which windows start and end: every hold ends there
        (:attr:`resets`, which may grow as windows come).
    seed : int
        Seed of the sources' phases.
    hold_steps : int or None
        A hold ends this many steps after its event (the ``sliding`` coding:
        one window's length; give no ``window_steps`` then).

    ``on`` and ``off`` mark the sources that have fired so far; ``merged``
    is 0 (a held source fires once a period whatever its events).
    """

    def __init__(self, shape, dt_ms: float, t0_us: float, rate_hz: float, window_steps, seed: int = 0, hold_steps=None):
        super().__init__(shape, dt_ms, t0_us)
        self.hold = None if hold_steps is None else max(1, int(hold_steps))
        self.period = hold_period_steps(rate_hz, dt_ms)
        self.phase = hold_phases(2 * self.h * self.w, self.period, seed)
        self.resets = np.unique(np.asarray(window_steps, dtype=np.int64))
        self.carried = None
        self.taken = None  # steps before this one have been given out

    def take_until(self, end_step: int) -> tuple[np.ndarray, np.ndarray]:
        """The spikes ``(indices, steps)`` of the steps before ``end_step``
        not taken yet, in step order and by source within a step; every
        event before that step's end must have been added."""
        step, idx = self.due(end_step)
        order = np.argsort(step, kind="stable")
        step, idx = step[order], idx[order]
        if self.taken is None:  # (nothing is held before the first event)
            self.taken = int(step[0]) if step.size else end_step
        start = self.taken
        if end_step <= start:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        (out_idx, out_steps), self.carried = held_spikes(
            step, idx, self.h * self.w, self.period, self.phase, start, end_step, self.resets, self.carried, self.hold
        )
        self.taken = end_step
        self.fired[out_idx] = True
        return out_idx, out_steps


def held_window(events, shape, dt_ms: float, t0_us: float, t_end_us: float, rate_hz: float, seed: int = 0):
    """One window's events ``[t0_us, t_end_us)`` held as its frame: the
    spikes ``(sources, steps)`` from step 0 (``t0_us``) to the window's end
    step, which is also returned (a board that replays the window repeats
    them with that period)."""
    end = max(1, int(np.floor((t_end_us - t0_us) / (dt_ms * 1000.0))))
    st = HeldStream(shape, dt_ms, t0_us, rate_hz, (0, end), seed)
    st.add(events)
    idx, steps = st.take_until(end)
    return idx, steps, end
