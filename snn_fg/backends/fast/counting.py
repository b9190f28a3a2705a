"""Counting a run's spikes, compiled: per cell, per counting bin and per
population, straight from the engine's spike log (cell numbers, grouped by
step), without sorting it."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..base import SparseCounts


class BinCounts(SparseCounts):
    """The fast engine's :class:`~snn_fg.backends.base.SparseCounts`: a counting bin's
    spike counts, population -> each cell's spikes (int32),
    kept as the cell numbers of the bin's spikes (``ids``, the engine's
    numbering; ``parts``: population -> the slice of it its cells take;
    ``cells``: the numbering's size). A bin holds a few thousand spikes
    among ~1e6 cells: a window's reader adds its bins spike by spike
    (:func:`count_cells` into one array, :meth:`into`) where cell-sized
    copies, sums and differences cost 2.5 ms a 10 ms hop; the populations'
    arrays are made only if read. ``steps``: the bin's time steps (a cell fires at
    most once a step, so no cell's count is larger)."""

    def __init__(self, ids: np.ndarray, parts: dict, cells: int, steps: int):
        self.ids, self.parts, self.cells, self.steps = ids, parts, cells, steps
        self._dense = None

    def into(self, out: np.ndarray):
        """Add the bin's spikes to ``out`` (every cell of the numbering)."""
        count_cells(self.ids, 0, self.ids.size, out)

    def __getitem__(self, name):
        if self._dense is None:
            self._dense = np.zeros(self.cells, np.int32)
            self.into(self._dense)
        return self._dense[self.parts[name]]

    def __iter__(self):
        return iter(self.parts)

    def __len__(self):
        return len(self.parts)


@njit(cache=True, nogil=True)
def bin_counts(ids, cuts, out):
    """``out[b, g]`` += spikes of cell ``g`` among ``ids[cuts[b]:cuts[b + 1]]``
    (one pass, into an array allocated once: a bincount per bin would fault
    in a fresh cell-sized array each time)."""
    for b in range(cuts.size - 1):
        for x in range(cuts[b], cuts[b + 1]):
            out[b, ids[x]] += 1


@njit(cache=True, nogil=True)
def count_cells(ids, lo, hi, out):
    """``out[g]`` += spikes of cell ``g`` among ``ids[lo:hi]`` (``np.bincount``
    would first copy the int32 log to a machine-int array)."""
    for x in range(lo, hi):
        out[ids[x]] += 1


@njit(cache=True, nogil=True)
def population_totals(ids, starts, out):
    """``out[q]`` = spikes of population ``q`` in ``ids`` (``starts``: each
    population's first cell number, ascending)."""
    for x in range(ids.size):
        out[np.searchsorted(starts, ids[x], side="right") - 1] += 1


@njit(cache=True, nogil=True)
def group_by_population(ids, step_start, starts, keep, cuts, local, step_of):
    """The spike log regrouped population by population, time order kept
    within each (a counting sort: two passes, no sort keys).

    ``cuts`` (the kept populations' spike totals as an exclusive prefix sum)
    says where each population's spikes go; ``local[j]`` is the cell's
    number within its population and ``step_of[j]`` its step. Spikes of
    populations with ``keep[q] == 0`` are dropped."""
    pos = cuts[:-1].copy()
    for s in range(step_start.size - 1):
        for x in range(step_start[s], step_start[s + 1]):
            q = np.searchsorted(starts, ids[x], side="right") - 1
            if keep[q]:
                j = pos[q]
                local[j] = ids[x] - starts[q]
                step_of[j] = s
                pos[q] = j + 1
