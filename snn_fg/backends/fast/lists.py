"""The engine's sorted lists of cells, compiled: each step's newly active
cells are sorted (:func:`radix_sort`) and merged into the active list
(:func:`merge`), and the threads' spikes of a step are merged with the
step's input spikes into the log (:func:`gather_spikes`). Sorted lists let
the per-step passes walk memory in one direction."""

from __future__ import annotations

import numpy as np
from numba import njit

from .lif import U


@njit(cache=True)
def radix_sort(a, n, tmp, counts, top):
    """Sort ``a[:n]`` (cell numbers, below ``top``) in place, by
    counting passes of 11 bits through ``tmp`` (``counts``: 2048 slots): a
    comparison sort of the few thousand cells that become active in a step
    took longer than the rest of the step's merge."""
    if n < 64:
        a[:n].sort()
        return
    src, dst = a, tmp
    shift, flips = 0, 0
    while shift == 0 or (top - 1) >> shift:
        counts[:] = 0
        for x in range(n):
            counts[(src[U(x)] >> shift) & 2047] += 1
        total = 0
        for b in range(2048):
            c = counts[b]
            counts[b] = total
            total += c
        for x in range(n):
            v = src[U(x)]
            b = (v >> shift) & 2047
            dst[U(counts[b])] = v
            counts[b] += 1
        src, dst = dst, src
        shift += 11
        flips += 1
    if flips % 2:
        a[:n] = tmp[:n]


@njit(cache=True)
def merge_into(x, y, out):
    """Merge the sorted arrays ``x`` and ``y`` into ``out``; returns the length."""
    a = b = k = 0
    while a < x.size or b < y.size:
        if b == y.size or (a < x.size and x[U(a)] < y[U(b)]):
            out[U(k)] = x[U(a)]
            a += 1
        else:
            out[U(k)] = y[U(b)]
            b += 1
        k += 1
    return k


@njit(cache=True)
def merge(act, n_act, new, n_new, tmp, counts, top):
    """Merge the newly active cells into the sorted active list (cell numbers below ``top``)."""
    if n_new == 0:
        return n_act
    radix_sort(new, n_new, tmp, counts, top)
    k = merge_into(act[:n_act], new[:n_new], tmp)
    act[:k] = tmp[:k]
    return k


@njit(cache=True)
def gather_spikes(log, start, firsts, counts, inputs, out):
    """The spikes of a step as one ascending run at ``log[start:]``: each
    thread's (ascending, ``counts[t]`` from ``log[firsts[t]]``) and the
    input spikes (ascending), merged through ``out``. Returns the log's new length."""
    n = 0
    for t in range(firsts.size):
        out[n : n + counts[t]] = log[firsts[t] : firsts[t] + counts[t]]
        n += counts[t]
    out[n : n + inputs.size] = inputs
    n += inputs.size
    # (at most three ascending runs: two threads' and the inputs)
    heads = np.zeros(firsts.size + 1, np.int64)
    ends = np.zeros(firsts.size + 1, np.int64)
    for t in range(firsts.size):
        ends[t] = heads[t] + counts[t]
        heads[t + 1] = ends[t]
    ends[firsts.size] = n
    if (inputs.size > 0) + (counts > 0).sum() <= 1:
        log[start : start + n] = out[:n]  # (one run at most)
        return start + n
    for k in range(n):
        best = -1
        for r in range(heads.size):
            if heads[r] < ends[r] and (best < 0 or out[heads[r]] < out[heads[best]]):
                best = r
        log[start + k] = out[heads[best]]
        heads[best] += 1
    return start + n
