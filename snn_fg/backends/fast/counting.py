"""Counting a run's spikes, compiled: per cell, per counting bin and per
population, straight from the engine's spike log (cell numbers, grouped by
step), without sorting it."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def bin_counts(ids, cuts, out):
    """``out[b, g]`` += spikes of cell ``g`` among ``ids[cuts[b]:cuts[b + 1]]``
    (one pass, into an array allocated once: a bincount per bin would fault
    in a fresh cell-sized array each time)."""
    for b in range(cuts.size - 1):
        for x in range(cuts[b], cuts[b + 1]):
            out[b, ids[x]] += 1


@njit(cache=True)
def count_cells(ids, lo, hi, out):
    """``out[g]`` += spikes of cell ``g`` among ``ids[lo:hi]`` (``np.bincount``
    would first copy the int32 log to a machine-int array)."""
    for x in range(lo, hi):
        out[ids[x]] += 1


@njit(cache=True)
def population_totals(ids, starts, out):
    """``out[q]`` = spikes of population ``q`` in ``ids`` (``starts``: each
    population's first cell number, ascending)."""
    for x in range(ids.size):
        out[np.searchsorted(starts, ids[x], side="right") - 1] += 1


@njit(cache=True)
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
