"""The input of a fast-engine run as its compiled loop reads it
(:class:`InputFeed`): input spikes as cell numbers grouped by step, loaded a
period or a segment of steps at a time."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..base import source_offsets
from . import tables as ft


def input_cells(tab: ft.EngineTables, first_cell: dict) -> np.ndarray:
    """Each input index's cell number (``first_cell``: population -> its first
    number), -1 for an index no population has (the clock of a network without one)."""
    first = source_offsets(tab.network)
    size = {name: tab.network.population(name).size for name in first}
    lut = np.full(max((start + size[name] for name, start in first.items()), default=0), -1, np.int64)
    for name, start in first.items():
        lut[start : start + size[name]] = first_cell[name] + np.arange(size[name])
    return lut


def input_events(cells: np.ndarray, idx, steps, length: int, first_step: int = 0):
    """Input spikes ``(idx, steps)`` as cell numbers (``cells``: :func:`input_cells`)
    grouped by step, ``(ptr, ids)``: the spikes of step ``first_step + s`` are
    ``ids[ptr[s]:ptr[s + 1]]``, for ``s`` below ``length``, by cell number within a step."""
    idx, steps = np.asarray(idx, dtype=np.int64), np.asarray(steps, dtype=np.int64)
    ptr, ids, grouped = _grouped(idx, steps, cells, length, first_step)
    if grouped:
        return ptr, ids
    steps = steps - first_step  # (not in step and cell order: sorted)
    keep = (steps >= 0) & (steps < length) & (idx < cells.size)
    idx, steps = idx[keep], steps[keep]
    ids = cells[idx]
    ids, steps = ids[ids >= 0], steps[ids >= 0]
    order = np.lexsort((ids, steps))
    ids, steps = ids[order], steps[order]
    return np.searchsorted(steps, np.arange(length + 1)).astype(np.int64), ids.astype(np.int32)


@njit(cache=True, nogil=True)
def _grouped(idx, steps, cells, length, first_step):
    """:func:`input_events` in one pass where the spikes come in step and cell
    order (a stream's segment: its spikes are in step and source order, and cells
    follow sources); ``(ptr, ids, False)`` where they do not."""
    ptr = np.zeros(length + 1, np.int64)
    ids = np.empty(idx.size, np.int32)
    k, last_s, last_c = 0, -1, -1
    for e in range(idx.size):
        s = steps[e] - first_step
        if s < 0 or s >= length or idx[e] >= cells.size or cells[idx[e]] < 0:
            continue
        c = cells[idx[e]]
        if s < last_s or (s == last_s and c < last_c):
            return ptr, ids, False
        ids[k] = c
        ptr[s + 1] += 1
        k += 1
        last_s, last_c = s, c
    for s in range(length):
        ptr[s + 1] += ptr[s]
    return ptr, ids[:k], True


class InputFeed:
    """The input of a run as the compiled loop reads it: ``ptr``/``ids``
    (:func:`input_events`) of one period of steps, the loop taking step
    ``n``'s spikes from ``n % period``. A repeating input (or a whole
    run's) is one period loaded once; a
    :class:`~snn_fg.lowering.input_stream.SegmentedInput` is loaded a
    segment at a time, each a period the run must stop at the end of
    (:meth:`stop_after`) for the next to be loaded (:meth:`reached`)."""

    def __init__(self, tab: ft.EngineTables, first_cell: dict, inputs, n_steps: int):
        self.tab, self.first_cell, self.inputs, self.n_steps = tab, first_cell, inputs, n_steps
        self.cells = input_cells(tab, first_cell)
        self.segmented = hasattr(inputs, "segment")
        self.total = 0  # input spikes of the segments loaded before the current one
        if self.segmented:  # (its first segment is loaded as the run starts: a live stream's may not be there yet)
            self.period, self.loaded = int(inputs.segment_steps), -1
        else:
            periodic = inputs.period_steps is not None and inputs.period_steps < n_steps
            self.period = int(inputs.period_steps) if periodic else max(n_steps, 1)
            self.ptr, self.ids = input_events(self.cells, inputs.indices, inputs.steps, self.period)

    def stop_after(self, n: int) -> int:
        """The last step (exclusive) a call of the loop from step ``n`` may reach."""
        return (n // self.period + 1) * self.period if self.segmented else self.n_steps

    def reached(self, n: int) -> None:
        """The run is at step ``n``: load its segment if it is a new one."""
        j = n // self.period
        if self.segmented and j != self.loaded and n < self.n_steps:
            if self.loaded >= 0:
                self.total += int(self.ptr[-1])
            idx, steps = self.inputs.segment(j)
            keep = steps < self.n_steps  # (the last segment may reach past the run's end)
            self.ptr, self.ids = input_events(self.cells, idx[keep], steps[keep], self.period, j * self.period)
            self.loaded = j

    def resume_at(self, n: int) -> int:
        """The step the run at step ``n`` goes on from: ``n``, or later where its
        input says the steps from ``n`` are not wanted (``inputs.resume_at``)."""
        resume_at = getattr(self.inputs, "resume_at", None) if self.segmented else None
        return n if resume_at is None else max(n, min(int(resume_at(n)), self.n_steps))

    def spikes_fed(self, n: int | None = None) -> int:
        """How many input spikes the run fed before step ``n`` (default: the
        whole run), without a pass over the spike log."""
        n = self.n_steps if n is None else n
        if self.segmented:  # (the segment loaded holds step n, or ends at it)
            return self.total + int(self.ptr[min(n - self.loaded * self.period, self.ptr.size - 1)])
        periods, rest = divmod(n, self.ptr.size - 1)
        return int(periods * self.ptr[-1] + self.ptr[rest])
