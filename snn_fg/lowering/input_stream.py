"""A recording's input spikes made as the simulation needs them.

:func:`~snn_fg.lowering.input_spikes.event_spikes` turns a whole set of
timed events into spikes at once; over a long recording that holds every
event and every spike of the run. :class:`SpikeStream` makes the same spikes
from events handed to it in time order, chunk by chunk, and gives them out
step range by step range (:meth:`SpikeStream.take_until`): the input
adapter's refractory period carries over from one chunk to the next (the
step each source last passed an event on), and two events of one source in
one step merge however the chunks cut them, since a step is given out only
once every event before its end has been added. :class:`SegmentedInput`
hands such a stream to a backend in segments of a fixed number of steps
(:meth:`SegmentedInput.segment`), so that the backend holds one segment of
the input, not the whole run's.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numba import njit

from .input_spikes import EventQueue, InputSpikes, _keep_after_gap, step_spikes


class SpikeStream(EventQueue):
    """Input spikes of timed events added in time order (:meth:`add`).

    Parameters
    ----------
    shape : (int, int)
        The input grid, ``(H, W)``: ON sources ``y * W + x``, OFF sources
        ``H * W + y * W + x``.
    dt_ms : float
        The simulation step.
    t0_us : float
        The time of step 0.
    refractory_ms : float
        A source passes on an event only this long after the last one it
        passed on (0: every event).

    ``merged`` counts the events that fell in a step their source already
    fired in; ``on`` and ``off`` mark the sources that have fired so far.
    """

    def __init__(self, shape, dt_ms: float, t0_us: float, refractory_ms: float = 0.0):
        super().__init__(shape, dt_ms, t0_us)
        self.gap = int(round(refractory_ms / dt_ms))
        self.last = np.full(2 * self.h * self.w, -max(self.gap, 1), dtype=np.int64)  # (every first event passes)

    def take_until(self, end_step: int) -> tuple[np.ndarray, np.ndarray]:
        """The spikes ``(indices, steps)`` of the steps before ``end_step``
        not taken yet, in step order and by source within a step; every
        event before that step's end must have been added."""
        step, idx = self.due(end_step)
        kept, steps, merged = _in_order_spikes(step, idx, self.gap, self.last, self.fired)
        if merged < 0:  # (never from a queue, whose events due are in step order: step_spikes sorts them)
            kept, steps, merged = step_spikes(step, idx, 2 * self.h * self.w, self.gap, self.last)
            self.fired[kept] = True
        idx, step = kept, steps
        self.merged += merged
        return idx, step


@njit(cache=True, nogil=True)
def _in_order_spikes(step, idx, gap, last, fired):
    """:func:`~snn_fg.lowering.input_spikes.step_spikes` of events whose steps do
    not decrease, in one compiled pass (a stream's segments), marking the
    sources that fire in ``fired``: ``(indices, steps, merged)``, with
    ``merged`` -1 (and nothing changed) if the steps decrease somewhere."""
    for e in range(1, step.size):
        if step[e] < step[e - 1]:
            return idx[:0], step[:0], -1
    kept = np.ones(step.size, np.bool_)
    if gap > 0:  # (through the refractory period, in the events' order)
        kept[:] = False
        _keep_after_gap(idx, step, gap, last, kept)
    out, steps = np.empty(step.size, np.int64), np.empty(step.size, np.int64)
    k, merged, e = 0, 0, 0
    while e < step.size:
        s, first = step[e], k
        while e < step.size and step[e] == s:  # (the step's events kept)
            if kept[e]:
                out[k] = idx[e]
                k += 1
            e += 1
        if k - first > 1:  # (by source, one spike each)
            out[first:k] = np.sort(out[first:k])
            j = first + 1
            for q in range(first + 1, k):
                if out[q] != out[j - 1]:
                    out[j] = out[q]
                    j += 1
            merged += k - j
            k = j
        for q in range(first, k):
            fired[out[q]] = True
            steps[q] = s
    return out[:k], steps[:k], merged


@dataclasses.dataclass
class SegmentedInput:
    """A recording's input spikes handed to a backend a segment at a time.

    Segment ``j`` holds the spikes of steps ``j * segment_steps`` to
    ``(j + 1) * segment_steps - 1`` (:meth:`segment`), asked for in order;
    ``spikes_until(end_step)`` gives the spikes not given yet of the steps
    before ``end_step``, as :meth:`SpikeStream.take_until`. ``on``,
    ``off`` (the sources that may fire), ``merged`` and ``rate_hz`` are
    known before the run starts (``snn_fg/models/spiking/stream_input.py``). The clock
    fires at ``clock_steps`` (ascending; index :attr:`clock_index`). ``resume_at(n)``
    (optional): the step a run at step ``n`` may go on from, the steps
    between unwanted and without input (a live stream's dropped time); a
    backend that can skips them with the network put at rest.
    """

    shape: tuple
    on: np.ndarray
    off: np.ndarray
    rate_hz: float
    merged: int
    segment_steps: int
    spikes_until: object
    clock_steps: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, np.int64))
    kind: str = "events"
    resume_at: object = None
    period_steps = None  # (never repeats)

    clock_index = InputSpikes.clock_index
    n_sources = InputSpikes.n_sources

    def segment(self, j: int) -> tuple[np.ndarray, np.ndarray]:
        """The spikes ``(indices, steps)`` of segment ``j``, steps counted
        from the run's start, sorted by step and index."""
        return self._until(j * self.segment_steps, (j + 1) * self.segment_steps)

    def whole(self) -> InputSpikes:
        """Every spike as one :class:`InputSpikes`, for a backend that takes
        the whole run's input at once; its ``fired`` marks the sources that
        fire in it (:attr:`on` and :attr:`off` mark those that may)."""
        idx, steps = self._until(0, np.iinfo(np.int64).max // (2 * self.clock_index + 2))
        fired = np.zeros(self.clock_index, bool)
        fired[idx[idx < self.clock_index]] = True
        on, off = fired.reshape(2, *self.shape)
        return InputSpikes(
            self.shape, idx, steps, None, self.on, self.off, self.rate_hz, self.merged, self.kind, (on, off)
        )

    def _until(self, a: int, b: int):
        """The spikes not given yet of the steps before ``b``, with the
        clock's of the steps from ``a`` on."""
        idx, steps = self.spikes_until(b)
        # (clock_steps is sorted and, for a live stream laid out an hour ahead, tens of thousands
        # long: a mask over it in every 5 ms segment cost more than the segment's own spikes)
        clock = self.clock_steps[np.searchsorted(self.clock_steps, a) : np.searchsorted(self.clock_steps, b)]
        if clock.size:  # (after every source's spike of its step: the clock's index is the last)
            merged = _with_clock(idx, steps, clock, self.clock_index)
            if merged is None:  # (spikes not in step and source order: sorted with the clock's)
                idx = np.concatenate([idx, np.full(clock.size, self.clock_index, dtype=np.int64)])
                steps = np.concatenate([steps, clock])
                order = np.lexsort((idx, steps))
                merged = idx[order], steps[order]
            idx, steps = merged
        return idx, steps


def _with_clock(idx, steps, clock, clock_index):
    """Spikes ``(idx, steps)`` sorted by step and index with the clock's spikes at
    the steps ``clock`` (ascending) put in their places, or None if they are not
    sorted so. (A merge: a sort of every 5 ms segment with a clock step cost a
    live run's feeding thread more than its spikes.)"""
    if idx.size > 1 and not _sorted_pairs(steps, idx):
        return None
    at = np.searchsorted(steps, clock, side="right")
    return np.insert(idx, at, clock_index), np.insert(steps, at, clock)


@njit(cache=True, nogil=True)
def _sorted_pairs(major, minor) -> bool:
    """Whether the pairs ``(major[i], minor[i])`` do not decrease."""
    for i in range(1, major.size):
        if major[i] < major[i - 1] or (major[i] == major[i - 1] and minor[i] < minor[i - 1]):
            return False
    return True
