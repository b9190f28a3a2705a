"""The fast engine's hand-over, compiled: the summed input that
:mod:`.deliver` left in ``acc`` added to each cell it reached
(:func:`flush_rows`), the cell brought up to the present in closed form
first. The numbering and state are described in :mod:`~snn_fg.backends.fast.core`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .deliver import C_OFF, C_PRES, C_WHOLE, EXC, N_ADVANCES, N_FLUSHED, N_FRESH, PH_FIND
from .lif import ACTIVE, PHASES, U, cycles, low_bits, ones, prefetch, safe, trailing_zeros
from .neurons import GAP, PEAK, TIGHT, V_REST
from .tables import P_GC, P_TYPE

#: how many cells ahead of the one being updated the hand-over asks for a cell's
#: state (the cells of a step are scattered: waiting for them was most of a run's time)
AHEAD = 48


@njit(cache=True)
def flush_rows(qt, col, n, pops, cells, pres, rank, acc, marks, state, new, n_new, fresh, nrn, adv_k, counters):
    """Add the summed input ``acc`` of the cells marked in ``marks`` to
    current ``col`` of the cells of population ``qt`` at step ``n``,
    bringing parked cells up to date first (and listing in ``fresh`` those
    touched for the first time); a cell that might now fire is appended to
    ``new``. Clears the marks and the input it read. Returns the new length
    of ``new``. ``adv_k``: the advance tables by steps (:func:`.neurons.by_steps`).

    The marked cells are listed a batch at a time (``found``, their grid
    index; ``found_g``, their number: for a population with cells left out,
    the number of cells that exist before it, from ``rank`` and the presence
    bits), so that each cell's state can be asked for :data:`AHEAD` cells
    before it is needed; the first :data:`AHEAD` of a batch are asked for as
    they are found. (A call hands over a few hundred cells: a batch's first
    cells were an eighth of them, each waiting for its state.)"""
    listed, dirty, n_dirty_a, bits, found, found_g = marks
    gc = pops[qt, P_GC]
    words, pbase = (gc + 63) >> 6, cells[qt, C_PRES]
    off, whole = cells[qt, C_OFF], cells[qt, C_WHOLE] == 1
    t = pops[qt, P_TYPE]
    v_rest, tight, peak, gap = nrn[t, V_REST], nrn[t, TIGHT] > 0, nrn[t, PEAK], nrn[t, GAP]
    kmax = adv_k.shape[1] - 1
    adv_t, top = adv_k[t].ravel(), kmax << 3  # (the type's tables, 8 values a step; where step kmax starts)
    now = n + 1
    advances = 0
    n_fresh = counters[N_FRESH]
    d, n_dirty = 0, n_dirty_a[0]
    while d < n_dirty:
        c0 = cycles() if PHASES else 0
        n_found = 0
        while d < n_dirty and n_found + gc <= found.size:
            rr = dirty[U(d)]
            d += 1
            for wd in range(rr * words, rr * words + words):
                word = bits[U(wd)]
                bits[U(wd)] = 0
                first = rr * gc + ((wd - rr * words) << 6)
                if not whole:
                    absent = word & ~pres[U(pbase + wd)]
                    word ^= absent
                    while absent != 0:  # (input to cells left out: dropped)
                        acc[U(first + np.int64(trailing_zeros(absent)))] = 0.0
                        absent &= absent - U(1)
                while word != 0:
                    bit = np.int64(trailing_zeros(word))
                    word &= word - U(1)
                    found[U(n_found)] = first + bit
                    if whole:
                        g = off + first + bit
                    else:
                        g = off + rank[U(pbase + wd)] + ones(pres[U(pbase + wd)] & low_bits(bit))
                    found_g[U(n_found)] = g
                    if n_found < AHEAD:  # (the batch's first cells, which the loop below asks for too late)
                        prefetch(state, U(g))
                    n_found += 1
            listed[U(rr)] = 0
        counters[N_FLUSHED] += n_found
        if PHASES:
            counters[PH_FIND] += cycles() - c0
        for x in range(n_found):
            if x + AHEAD < n_found:
                prefetch(state, U(found_g[U(x + AHEAD)]))
            loc, g = found[U(x)], found_g[U(x)]
            w = acc[U(loc)]
            acc[U(loc)] = 0.0
            if w == 0.0:
                continue  # (input that summed to 0)
            cell = state[U(g)]
            v, e, i, last = cell.v, cell.e, cell.i, cell.last
            if last == 0:  # (touched for the first time: at rest)
                v, last = v_rest, now
                fresh[U(n_fresh)] = g
                n_fresh += 1
            # brought up to the present in closed form (lif.advanced, written out: see the module's
            # docstring, in steps of at most kmax, the last one here); a cell already there (k = 0:
            # the group of its other current came first) keeps its values, chosen without a branch
            # (row 0 of the tables multiplies by 1). The type's tables are one flat run of 8 values
            # a step (adv_t), indexed by unsigned offsets (no sign fix-up or stride product).
            k = now - last
            advances += k > 0
            while k > kmax:  # (rare: longer than the tables)
                va = v_rest + ((adv_t[U(top)] * (v - v_rest) + e * adv_t[U(top + 3)]) - i * adv_t[U(top + 4)])
                e = e * adv_t[U(top + 1)]
                i = i * adv_t[U(top + 2)]
                v = va
                k -= kmax
            at = U(k << 3)
            va = v_rest + ((adv_t[at] * (v - v_rest) + e * adv_t[at + U(3)]) - i * adv_t[at + U(4)])
            e = e * adv_t[at + U(1)]
            i = i * adv_t[at + U(2)]
            v = va if k > 0 else v
            if col == EXC:
                e += w
            else:
                i += w
            cell.v, cell.e, cell.i, cell.last = v, e, i, now
            # a cell that might now fire joins the active list (appended without a branch: new has a spare slot)
            wake = (cell.spike >= 0) & (not safe(v, e, i, v_rest, tight, peak, gap))
            cell.spike |= ACTIVE if wake else 0
            new[U(n_new)] = g
            n_new += wake
    n_dirty_a[0] = 0
    counters[N_ADVANCES] += advances
    counters[N_FRESH] = n_fresh
    return n_new
