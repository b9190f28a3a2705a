"""Spike delivery of the fast engine, compiled: one step's spikes through a
projection into the summed input of its target (:func:`conv_spikes`,
:func:`resize_spikes`), then that input handed to each cell it reached
(:func:`.handover.flush_rows`), which brings the cell up to the present in
closed form first. The numbering and state are described in :mod:`~snn_fg.backends.fast.core`.

The summed input ``acc`` of a target population has the layout of its grid,
``(channel, row, column)``: a Conv's stencil row (:mod:`.stencils`) is one
contiguous run of values, its taps (the bits of its ``R_NZ`` value) added one by one. Which cells received
input is kept as bits (``bits``, one 64-bit word per 64 columns of a row,
and the list of rows with any, ``dirty``), each masked by the population's
presence bits (``pres``: the cells that exist) where it matters: the synaptic events
are the marked bits of existing cells, counted with ``popcount``, and the
hand-over visits the cells that exist and received input, row by row in
memory order (and clears what reached cells left out). A cell's
inputs of one step are summed in the order of the spikes (ascending cell
number), projection by projection: the sums, and hence the spikes, do not
depend on how the deliveries are laid out.

The loops are written out, not split into helpers: a helper that takes an
array costs two atomic reference-count operations per call.

``owner`` and ``n_parts`` split a banded population's rows between threads
(:mod:`.share`): a thread handles the rows ``r`` with ``(r >> BAND) % n_parts
== owner`` (every row when ``n_parts`` is 1: a population it owns whole), and
every thread sees every spike in the same order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .lif import U, divide, low_bits, ones, prefetch, trailing_zeros
from .stencils import MV, R_CO, R_DR, R_NCOL, R_NZ, R_OFF, R_QC, R_QR, R_W0
from .tables import (
    J_BASE,
    J_COLBASE,
    J_INH,
    J_PRUNE,
    J_RADIUS,
    J_SRC,
    J_TGT,
    J_WRAP,
    P_GC,
    P_GR,
    P_STRIDE,
)

#: counters returned by run_steps (``N_FLUSHED``: cells handed input)
N_EVENTS, N_ADVANCES, N_ACTIVE_STEPS, N_FRESH, N_FLUSHED = range(5)
#: where the same counters hold the cycles of each phase of a step, when they are
#: counted (:data:`.lif.PHASES`): the active cells' update, Conv and Resize
#: delivery, the hand-over (of which finding the cells that received input),
#: merging the newly active cells into the list, and gathering the step's spikes
PH_ACTIVE, PH_CONV, PH_RESIZE, PH_HANDOVER, PH_FIND, PH_MERGE, PH_GATHER = range(8, 15)
PHASE_NAMES = ("active", "conv", "resize", "handover", "handover_find", "merge", "gather")
#: columns of the per-run cell table ``cells``: first number and count of a
#: population's cells, where its presence bits and their ranks start (in
#: words), whether all its cells exist (1) and (when not) where its map from
#: number to grid cell starts
C_OFF, C_N, C_PRES, C_WHOLE, C_FLAT = range(5)
EXC = 1
#: rows are handed to threads in bands of 2**BAND rows
BAND = 3
#: how many spikes ahead of the one being delivered its grid cell is asked for
SPIKES_AHEAD = 8
#: how many stencil rows ahead of the one being added the summed input it lands on is
#: asked for (a spike's rows are scattered over the target's channels: waiting for their
#: input was a fifth of the delivery's time)
ROWS_AHEAD = 4


@njit(cache=True, inline="always")
def foreign(rr, owner, n_parts, inv_parts):
    """Whether row ``rr`` belongs to another thread than ``owner`` (never with
    one thread; the band's remainder without an integer division)."""
    return n_parts > 1 and divide(rr >> BAND, n_parts, inv_parts)[1] != owner


@njit(cache=True, inline="always")
def mark_row(listed, dirty, n_dirty, rr):
    """Note that row ``rr`` received input: listed in ``dirty`` when it is
    new; returns the new length of ``dirty``. (The hand-over reads all the
    words of a listed row: a row is a few words, and keeping the span that
    received input cost more per stencil row than the zero words it skips.)
    Without a branch (a quarter of the stencil rows reach a new row, in no
    order a predictor follows): written past the list's end whatever, the
    list grows only when the row is new (``dirty`` has a spare slot)."""
    dirty[U(n_dirty)] = rr
    n_dirty += 1 - np.int64(listed[U(rr)])
    listed[U(rr)] = 1
    return n_dirty


@njit(cache=True, inline="always")
def mark_taps(bits, pres, pbase, words, rr, lo, m, whole, listed, dirty, n_dirty):
    """The targets of row ``rr`` at columns ``lo + k`` for the set bits ``k`` of
    ``m`` (< 64 columns, so at most two words) marked, and the row noted
    (:func:`mark_row`); returns the targets counted where a cell exists (all
    of them in a ``whole`` population) and the new length of ``dirty``.

    Both words are marked and counted without asking whether the second
    holds any (``spill`` is then 0): a branch around an array's element here
    made numba count references to the arrays, four calls per stencil row.
    ``bits`` and ``pres`` end with a spare word, for the last row's."""
    sh, wa = U(lo & 63), (lo >> 6) + rr * words
    spill = (m >> U(63 - sh)) >> U(1)  # (the bits past the word: none when sh is 0)
    bits[U(wa)] |= m << sh
    bits[U(wa + 1)] |= spill
    if whole:
        events = ones(m)
    else:
        events = ones((m << sh) & pres[U(pbase + wa)]) + ones(spill & pres[U(pbase + wa + 1)])
    return events, mark_row(listed, dirty, n_dirty, rr)


@njit(cache=True, inline="always")
def spike_site(spikes, x, c_off, c_flat, flat_of, plane, inv_plane, gc_s, inv_gc):
    """Spike ``x``'s source cell as (channel, row, column) of its population's
    grid: its place in the population, through ``flat_of`` where only some of
    its cells exist (``c_flat`` >= 0; the spike ``SPIKES_AHEAD`` on prefetched)."""
    loc = spikes[U(x)] - c_off
    if c_flat >= 0:
        if x + SPIKES_AHEAD < spikes.size:
            prefetch(flat_of, U(c_flat + spikes[U(x + SPIKES_AHEAD)] - c_off))
        loc = flat_of[U(c_flat + loc)]
    c, rest = divide(loc, plane, inv_plane)
    i, j = divide(rest, gc_s, inv_gc)
    return c, i, j


@njit(cache=True, inline="always")
def conv_site(at, x):
    """Spike ``x``'s stencil class and lattice point ``(row, column)`` on its Conv's target
    (``at``: the spikes and what :func:`spike_site` needs, the source's and target's strides
    and the Conv's first class)."""
    spikes, c_off, c_flat, flat_of, plane, inv_plane, gc_s, inv_gc, st_s, st, inv_st, base_cls = at
    c, ii, jj = spike_site(spikes, x, c_off, c_flat, flat_of, plane, inv_plane, gc_s, inv_gc)
    pr, pc = ii * st_s, jj * st_s
    if st == 1:
        return base_cls + c, pr, pc
    # (the level pixel over the target's stride, without an integer division)
    row, r_mod = divide(pr, st, inv_st)
    column, c_mod = divide(pc, st, inv_st)
    return base_cls + (c * st + r_mod) * st + c_mod, row, column


@njit(cache=True)
def conv_spikes(p, spikes, pops, cells, flat_of, pres, prj, stencil, acc, marks, owner, n_parts):
    """Add what ``spikes`` (cell numbers, ascending) send through Conv ``p``
    to ``acc``; ``stencil`` holds the tables' ``cls_ptr, row_tab, st_w``
    (a row's values at ``row_tab[8 s + R_*]``, :mod:`.stencils`) and ``marks`` the run's
    ``listed, dirty, n_dirty, bits`` (whether each row received input, the
    rows that did, and the cells). Returns the synaptic events:
    the taps that landed on a cell that exists. (``R_DR``, ``R_OFF``: a row's
    place from lattice point ``(0, 0)``, which a spike that lands whole adds
    to its own.)"""
    cls_ptr, rt, st_w = stencil
    listed, dirty, n_dirty_a, bits = marks[0], marks[1], marks[2], marks[3]
    n_dirty = n_dirty_a[0]
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    c_off, c_flat = cells[qs, C_OFF], cells[qs, C_FLAT]
    gc_s, st_s = pops[qs, P_GC], pops[qs, P_STRIDE]
    plane = pops[qs, P_GR] * gc_s
    inv_plane, inv_gc = 1.0 / plane, 1.0 / gc_s
    gr, gc, st = pops[qt, P_GR], pops[qt, P_GC], pops[qt, P_STRIDE]
    inv_st = 1.0 / st
    words, pbase, whole = (gc + 63) >> 6, cells[qt, C_PRES], cells[qt, C_WHOLE] == 1
    wrap, rad = prj[p, J_WRAP] == 1, prj[p, J_RADIUS]
    base_cls = prj[p, J_BASE]
    inv_parts = 1.0 / n_parts
    events = 0
    # each spike's class and lattice point are found one spike ahead, and the input its first rows land
    # on asked for (a spike of a strided projection has 2-3 rows: asking within its own rows came too late)
    at = (spikes, c_off, c_flat, flat_of, plane, inv_plane, gc_s, inv_gc, st_s, st, inv_st, base_cls)
    next_cls, next_row, next_column = conv_site(at, 0) if spikes.size else (0, 0, 0)
    for x in range(spikes.size):
        cls, row, column = next_cls, next_row, next_column
        here = row * gc + column  # (the spike's lattice point in a channel's summed input)
        if x + 1 < spikes.size:
            next_cls, next_row, next_column = conv_site(at, x + 1)
            first, there = cls_ptr[U(next_cls)], next_row * gc + next_column
            for sa in range(first, min(first + ROWS_AHEAD, cls_ptr[U(next_cls + 1)])):  # (a hint: no effect)
                prefetch(acc, U(there + rt[U((sa << 3) + R_OFF)]))
        inside = row >= rad and column >= rad and row + rad < gr and column + rad < gc
        s1 = cls_ptr[U(cls + 1)]
        for s in range(cls_ptr[U(cls)], s1):
            r8 = s << 3  # (the row's values: row_tab[r8 + R_*], one cache line)
            if s + ROWS_AHEAD < s1:
                prefetch(acc, U(here + rt[U(r8 + (ROWS_AHEAD << 3) + R_OFF)]))
            t0, ncol, w0 = column - rt[U(r8 + R_QC)], rt[U(r8 + R_NCOL)], rt[U(r8 + R_W0)]
            if inside and ncol == 1:  # (one tap: what the loops below do for it, without them)
                rr = row + rt[U(r8 + R_DR)]
                if foreign(rr, owner, n_parts, inv_parts):
                    continue
                acc[U(here + rt[U(r8 + R_OFF)])] += st_w[U(w0)]
                wa = (t0 >> 6) + rr * words
                bit = U(1) << U(t0 & 63)
                bits[U(wa)] |= bit
                events += 1 if whole else ones(bit & pres[U(pbase + wa)])
                n_dirty = mark_row(listed, dirty, n_dirty, rr)
                continue
            a, b, parts = 0, ncol, 1
            tr = row - rt[U(r8 + R_QR)]
            if not inside:  # the row may be cut, or wrap around, at the level's edges
                if wrap:
                    tr += gr if tr < 0 else (-gr if tr >= gr else 0)
                    t0 += gc if t0 < 0 else (-gc if t0 >= gc else 0)
                    b = min(ncol, gc - t0)  # (a row is at most the level wide: it folds back once at most)
                    parts = 2 if b < ncol else 1
                elif tr < 0 or tr >= gr:
                    continue
                else:
                    a, b = max(0, -t0), min(ncol, gc - t0)
                    if a >= b:
                        continue
            rr = rt[U(r8 + R_CO)] * gr + tr
            if foreign(rr, owner, n_parts, inv_parts):
                continue
            nz = U(rt[U(r8 + R_NZ)])  # (the tap bits, held as int64)
            for part in range(parts):
                if part == 1:  # the columns wrapped around to the row's start
                    a, b, t0 = b, ncol, t0 - gc
                # the taps of columns [t0 + a, t0 + b): added one by one (a loop over the row's
                # few taps costs less than a vector loop's set-up; the gaps' zeros are skipped,
                # which changes no sum), marked, and counted where a cell exists
                m = (nz >> U(a)) & low_bits(b - a)
                dst, src, left = rr * gc + t0 + a, w0 + a, m
                while left != 0:
                    j = trailing_zeros(left)
                    acc[U(dst + j)] += st_w[U(src + j)]
                    left &= left - U(1)
                got, n_dirty = mark_taps(bits, pres, pbase, words, rr, t0 + a, m, whole, listed, dirty, n_dirty)
                events += got
    n_dirty_a[0] = n_dirty
    return events


@njit(cache=True)
def resize_spikes(p, spikes, pops, cells, flat_of, pres, prj, prj_w, factors, acc, marks, owner, n_parts):
    """Like :func:`conv_spikes` for Resize ``p`` (``factors``: the tables'
    ``csr_ptr, csr_idx, csr_val``): weight ``sign * gain * A_r[i, i'] *
    A_c[j, j']``, the product rounded to the projection's quantisation step
    where it has one."""
    csr_ptr, csr_idx, csr_val = factors
    listed, dirty, n_dirty_a, bits = marks[0], marks[1], marks[2], marks[3]
    n_dirty = n_dirty_a[0]
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    c_off, c_flat = cells[qs, C_OFF], cells[qs, C_FLAT]
    gc_s = pops[qs, P_GC]
    plane = pops[qs, P_GR] * gc_s
    inv_plane, inv_gc = 1.0 / plane, 1.0 / gc_s
    gr, gc = pops[qt, P_GR], pops[qt, P_GC]
    words, pbase, whole = (gc + 63) >> 6, cells[qt, C_PRES], cells[qt, C_WHOLE] == 1
    sg, thr, step = prj_w[p, 0], prj_w[p, 1], prj_w[p, 2]
    prune, inh = prj[p, J_PRUNE] == 1, prj[p, J_INH] == 1
    inv_parts = 1.0 / n_parts
    events = 0
    for x in range(spikes.size):
        c, si, sj = spike_site(spikes, x, c_off, c_flat, flat_of, plane, inv_plane, gc_s, inv_gc)
        rb, cb = prj[p, J_BASE] + si, prj[p, J_COLBASE] + sj
        c0, c1 = csr_ptr[U(cb)], csr_ptr[U(cb + 1)]
        if c0 == c1:
            continue
        for xr in range(csr_ptr[U(rb)], csr_ptr[U(rb + 1)]):
            rr = c * gr + csr_idx[U(xr)]
            if foreign(rr, owner, n_parts, inv_parts):
                continue
            a = csr_val[U(xr)]
            dst = rr * gc
            m, lo = U(0), csr_idx[U(c0)]
            for xc in range(c0, c1 + 1):
                col = csr_idx[U(xc)] if xc < c1 else lo + 64
                if col - lo >= 64:
                    # the targets of columns [lo, lo + 64): marked, and counted where a cell
                    # exists (as conv_spikes does)
                    got, n_dirty = mark_taps(bits, pres, pbase, words, rr, lo, m, whole, listed, dirty, n_dirty)
                    events += got
                    if xc == c1:
                        break
                    m, lo = U(0), col
                val = a * csr_val[U(xc)]
                if val == 0.0 or (prune and abs(val) < thr):
                    continue
                if step > 0.0:
                    val = np.round(val / step) * step
                    if val == 0.0:
                        continue
                w = sg * val
                if inh:
                    w = abs(w)
                acc[U(dst + col)] += w * MV
                m |= U(1) << U(col - lo)
    n_dirty_a[0] = n_dirty
    return events
