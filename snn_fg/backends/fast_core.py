"""The fast engine's inner loops, compiled by numba.

One call of :func:`run_steps` advances the simulation over a range of time
steps. Each step follows Brian2's schedule as our Brian2 backend uses it
(``groups``, ``thresholds``, ``synapses``, ``resets``):

1. every *active* cell is updated exactly like Brian2's ``lif_step``
   (the exact propagators: ``v += (1 - d_m) (v_rest - v) + p_exc I_exc -
   p_inh I_inh`` unless refractory, then both currents decay) and spikes if ``v > v_th`` and it is not
   refractory; the input spikes of the step join them;
2. each projection takes the spikes its source emitted ``delay`` steps ago
   and sends each one through its kernel footprint (Conv taps, Resize
   interpolation weights), adding the weight to the target's current;
3. cells that spiked are reset.

An active cell that can no longer reach threshold without new input is
*parked* (at the start of the next step): it is not touched until input
reaches it, and is then brought up to date in closed form (the update is
linear between spikes, see :func:`snn_fg.backends.fast_tables.advance_tables`).
Parking is safe because, with no input, the potential stays under a bound
computed from the current state (:func:`_safe`).

Cells are numbered compactly, population after population, only those
instantiated (``cells[q]``: first number ``C_OFF`` and count ``C_N`` of
population ``q``; for a population with cells left out, ``cmap[C_MAP + flat]``
gives the local number of grid cell ``flat`` or -1, ``flat_of[C_FLAT +
local]`` the way back and ``column_of[C_FLAT + local]`` its lattice column;
its cells on lattice row ``r`` of channel ``c`` are the local numbers
``row_ptr[C_ROW + c * rows + r]`` .. ``[+ 1]``; bit ``flat`` of the bytes
from ``bits[C_BITS]`` says whether grid cell ``flat`` exists: a test that
stays in cache where the map would not). The active cells are kept sorted
by number, so that the per-step pass over them walks memory in one
direction (in a random order it would wait for memory at nearly every
cell). State per cell (:data:`STATE`): ``v``,
``e`` (``I_exc``), ``i`` (``I_inh``) in volts, ``last`` (the step the values
belong to, plus one; 0: never touched, i.e. at rest) and ``spike`` (the
step of the last spike, plus one; 0: none).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .fast_tables import (CONV, DE, DI, DM, GAP, J_BASE, J_COL, J_COLBASE, J_DELAY, J_DENSE, J_GBASE, J_INH,
                          J_KIND, J_KR, J_PRUNE, J_RADIUS, J_SRC, J_TGT, J_WRAP, MV, P_CH, P_GC, P_GR, P_LC, P_LR,
                          P_STRIDE, P_TYPE, PE, PEAK, PI, SOURCE_TYPE, TIGHT, V_RESET, V_REST, V_TH)

#: one cell's state (32 bytes, one half cache line)
STATE = np.dtype([("v", "f8"), ("e", "f8"), ("i", "f8"), ("last", "i4"), ("spike", "i4")], align=True)
#: array indices are converted to this unsigned type in the hot loops: numba
#: then skips its negative-index handling, which otherwise doubles their cost
U = np.uint64
#: counters returned by run_steps
N_EVENTS, N_ADVANCES, N_ACTIVE_STEPS, N_FRESH = range(4)
#: columns of the per-run cell table ``cells``
C_OFF, C_N, C_MAP, C_FLAT, C_ROW, C_BITS = range(6)
EXC = 1


@njit(cache=True, inline="always")
def _advanced(v, e, i, v_rest, adv_row, k):
    """``(v, I_exc, I_inh)`` after ``k`` silent steps (``adv_row``: the
    advance tables of the cell's neuron type)."""
    kmax = adv_row.shape[1] - 1
    while k > 0:
        s = k if k <= kmax else kmax
        v = v_rest + ((adv_row[0, s] * (v - v_rest) + e * adv_row[3, s]) - i * adv_row[4, s])
        e = e * adv_row[1, s]
        i = i * adv_row[2, s]
        k -= s
    return v, e, i


@njit(cache=True, inline="always")
def _safe(v, e, i, nrn_row):
    """Whether a cell in this state cannot reach threshold without new input.

    With ``u = v - v_rest`` and no input, ``u_k = d_m^k u + e P_e(k) - i
    P_i(k)``, where ``0 <= P_e(k) <= min(1 - d_m^k, peak)``. If the
    inhibitory current decays no faster than the excitatory one
    (``TIGHT``), ``P_i >= P_e`` and ``i >= 0`` let the inhibition be
    subtracted: ``u_k <= d_m^k u + x P_e(k)`` with ``x = max(e - i, 0)``,
    which is at most ``max(u, x)`` and at most ``max(u, 0) + peak x``.
    Otherwise ``u_k <= max(u, e^+ + i^-)``.
    """
    u = v - nrn_row[V_REST]
    if nrn_row[TIGHT] > 0 and i >= 0:
        x = max(e - i, 0.0)
        bound = min(max(u, x), max(u, 0.0) + nrn_row[PEAK] * x)
    else:
        bound = max(u, max(e, 0.0) + max(-i, 0.0))
    return bound <= nrn_row[GAP]


@njit(cache=True)
def _flush(acc, touched, n_touched, off, col, n, t, state, inact, new, n_new, fresh, nrn, adv, counters):
    """Add the accumulated input ``acc[x]`` to current ``col`` of cell
    ``off + x`` (neuron type ``t``) at step ``n``, for the ``touched`` cells,
    bringing parked cells up to date first (and listing in ``fresh`` those
    touched for the first time); a cell that might now fire is appended to
    ``new``. Returns the new length of ``new``."""
    nrn_row = nrn[t]
    v_rest = nrn_row[V_REST]
    adv_row = adv[t]
    now = n + 1
    advances = 0
    for x in range(n_touched):
        loc = touched[U(x)]
        w = acc[U(loc)]
        if w == 0.0:
            continue          # (a cell listed twice after its input summed to zero)
        acc[U(loc)] = 0.0
        g = off + loc
        r = state[U(g)]
        if r.last != now:
            if r.last == 0:
                r.v = v_rest
                fresh[U(counters[N_FRESH])] = g
                counters[N_FRESH] += 1
            else:
                r.v, r.e, r.i = _advanced(r.v, r.e, r.i, v_rest, adv_row, now - r.last)
                advances += 1
            r.last = now
        if col == EXC:
            r.e += w
        else:
            r.i += w
        if inact[U(g)] == 0 and not _safe(r.v, r.e, r.i, nrn_row):
            inact[U(g)] = 1
            new[U(n_new)] = g
            n_new += 1
    counters[N_ADVANCES] += advances
    return n_new


@njit(cache=True, inline="always")
def _flat(g, q, cells, flat_of):
    """Grid (flat) index of the cell numbered ``g`` of population ``q``."""
    loc = g - cells[q, C_OFF]
    return loc if cells[q, C_FLAT] < 0 else flat_of[cells[q, C_FLAT] + loc]


@njit(cache=True)
def _conv(p, spikes, x0, pops, cells, cmap, flat_of, bits, prj, ch_ptr, tap_co, tap_qr, tap_qc, tap_w, tap_off,
          acc, touched, n_touched, counters):
    """Accumulate what ``spikes[x0:]`` (cell numbers) send through the taps
    of Conv ``p`` into ``acc`` (indexed by target cell within its
    population), listing newly touched cells in ``touched``. Returns the
    list's length and the first spike not sent (when the list is full)."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    gc_s, st_s = pops[qs, P_GC], pops[qs, P_STRIDE]
    plane = pops[qs, P_GR] * gc_s
    gr, gc, st = pops[qt, P_GR], pops[qt, P_GC], pops[qt, P_STRIDE]
    mbase, bbase = cells[qt, C_MAP], cells[qt, C_BITS]
    whole, wrap, rad = mbase < 0, prj[p, J_WRAP] == 1, prj[p, J_RADIUS]
    base_ch = prj[p, J_BASE]
    events = 0
    for x in range(x0, spikes.size):
        loc = _flat(spikes[U(x)], qs, cells, flat_of)
        c = loc // plane
        ii = (loc - c * plane) // gc_s
        pr = ii * st_s
        pc = (loc - c * plane - ii * gc_s) * st_s
        if st == 1:
            cls, row, column = base_ch + c, pr, pc
        else:
            cls = base_ch + (c * st + pr % st) * st + pc % st
            row, column = pr // st, pc // st
        k0, k1 = ch_ptr[U(cls)], ch_ptr[U(cls + 1)]
        if n_touched + (k1 - k0) > touched.size:
            counters[N_EVENTS] += events
            return n_touched, x
        # (the delivery below is written out in both branches on purpose: an
        # inlined helper shared by them made a dvs.es window 4.5x slower, 4.4 -> 21 s)
        if row >= rad and column >= rad and row + rad < gr and column + rad < gc:
            base = row * gc + column          # the whole footprint lies inside the level
            for k in range(k0, k1):
                lt = base + tap_off[U(k)]
                if not whole:
                    if (bits[U(bbase + (lt >> 3))] >> (lt & 7)) & 1 == 0:
                        continue
                    lt = cmap[U(mbase + lt)]
                if acc[U(lt)] == 0.0:
                    touched[U(n_touched)] = lt
                    n_touched += 1
                acc[U(lt)] += tap_w[U(k)]
                events += 1
            continue
        if not wrap:
            # the taps are sorted by row offset: those landing inside the level
            # (row - qr in [0, gr)) are the range with qr in [row - gr + 1, row]
            a, b = k0, k1
            while a < b:
                h = (a + b) // 2
                if tap_qr[U(h)] < row - gr + 1:
                    a = h + 1
                else:
                    b = h
            k0, b = a, k1
            while a < b:
                h = (a + b) // 2
                if tap_qr[U(h)] <= row:
                    a = h + 1
                else:
                    b = h
            k1 = a
        for k in range(k0, k1):
            r = row - tap_qr[U(k)]
            cc = column - tap_qc[U(k)]
            if wrap:            # offsets lie within one level size (folded if the kernel is larger)
                r += gr if r < 0 else (-gr if r >= gr else 0)
                cc += gc if cc < 0 else (-gc if cc >= gc else 0)
            elif cc < 0 or cc >= gc:
                continue
            lt = (tap_co[U(k)] * gr + r) * gc + cc
            if not whole:
                if (bits[U(bbase + (lt >> 3))] >> (lt & 7)) & 1 == 0:
                    continue
                lt = cmap[U(mbase + lt)]
            if acc[U(lt)] == 0.0:
                touched[U(n_touched)] = lt
                n_touched += 1
            acc[U(lt)] += tap_w[U(k)]
            events += 1
    counters[N_EVENTS] += events
    return n_touched, spikes.size


@njit(cache=True)
def _conv_gather(p, spikes, x0, pops, cells, flat_of, column_of, row_ptr, prj, dense, pair_ptr, pair_co, pair_rlo,
                 pair_rhi, acc, touched, n_touched, counters):
    """Like :func:`_conv`, for a target population with few cells: instead
    of following every tap, each spike visits the target's cells on the
    rows its kernel covers and reads the weight of each by its offset (the
    same synapses, found from the other side)."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    gc_s, st_s, c_in = pops[qs, P_GC], pops[qs, P_STRIDE], pops[qs, P_CH]
    plane = pops[qs, P_GR] * gc_s
    gr, st, lr, lc = pops[qt, P_GR], pops[qt, P_STRIDE], pops[qt, P_LR], pops[qt, P_LC]
    wrap = prj[p, J_WRAP] == 1
    rad = prj[p, J_KR]
    size = 2 * rad + 1
    fold = wrap and size > lc
    kbase, gbase = prj[p, J_DENSE], prj[p, J_GBASE]
    rbase, fbase = cells[qt, C_ROW], cells[qt, C_FLAT]
    bound = pops[qt, P_CH] * size * size
    events = 0
    for x in range(x0, spikes.size):
        if n_touched + bound > touched.size:
            counters[N_EVENTS] += events
            return n_touched, x
        loc = _flat(spikes[U(x)], qs, cells, flat_of)
        c = loc // plane
        ii = (loc - c * plane) // gc_s
        pr = ii * st_s
        pc = (loc - c * plane - ii * gc_s) * st_s
        for y in range(pair_ptr[gbase + c], pair_ptr[gbase + c + 1]):
            co = pair_co[U(y)]
            kc = kbase + (co * c_in + c) * size * size
            for dr in range(pair_rlo[U(y)], pair_rhi[U(y)] + 1):
                tr = pr - dr
                if wrap:
                    tr %= lr
                elif tr < 0 or tr >= lr:
                    continue
                if tr % st != 0:
                    continue
                a, b = row_ptr[U(rbase + co * gr + tr // st)], row_ptr[U(rbase + co * gr + tr // st + 1)]
                if a == b:
                    continue
                kr = kc + (dr + rad) * size + rad
                if fold:            # every cell of the row, each through all its folded offsets
                    for lt in range(a, b):
                        d = (pc - column_of[U(fbase + lt)]) % lc
                        d -= lc * ((d + rad) // lc)
                        while d <= rad:
                            w = dense[U(kr + d)]
                            if w != 0.0:
                                if acc[U(lt)] == 0.0:
                                    touched[U(n_touched)] = lt
                                    n_touched += 1
                                acc[U(lt)] += w
                                events += 1
                            d += lc
                    continue
                # level columns covered, [pc - rad, pc + rad], as up to two intervals inside
                # the level; a column wrapped around is ``lc`` further from the source
                lo, hi, shift = max(pc - rad, 0), min(pc + rad, lc - 1), 0
                n_int = 1
                if wrap and pc - rad < 0:
                    lo2, hi2, shift2, n_int = pc - rad + lc, lc - 1, lc, 2
                elif wrap and pc + rad >= lc:
                    lo2, hi2, shift2, n_int = 0, pc + rad - lc, -lc, 2
                else:
                    lo2, hi2, shift2 = 0, -1, 0
                for part in range(n_int):
                    if part == 1:
                        lo, hi, shift = lo2, hi2, shift2
                    a = row_ptr[U(rbase + co * gr + tr // st)]
                    b = row_ptr[U(rbase + co * gr + tr // st + 1)]
                    end = b
                    while a < b:        # first cell at or after lo
                        h = (a + b) // 2
                        if column_of[U(fbase + h)] * st < lo:
                            a = h + 1
                        else:
                            b = h
                    for lt in range(a, end):
                        col = column_of[U(fbase + lt)] * st
                        if col > hi:
                            break
                        w = dense[U(kr + pc - col + shift)]
                        if w != 0.0:
                            if acc[U(lt)] == 0.0:
                                touched[U(n_touched)] = lt
                                n_touched += 1
                            acc[U(lt)] += w
                            events += 1
    counters[N_EVENTS] += events
    return n_touched, spikes.size


@njit(cache=True)
def _resize(p, spikes, x0, pops, cells, cmap, flat_of, bits, prj, prj_w, csr_ptr, csr_idx, csr_val, acc, touched,
            n_touched, counters):
    """Like :func:`_conv` for Resize ``p``: weight ``sign * gain * A_r[i, i'] * A_c[j, j']``."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    gc_s = pops[qs, P_GC]
    plane = pops[qs, P_GR] * gc_s
    gr, gc = pops[qt, P_GR], pops[qt, P_GC]
    mbase, bbase = cells[qt, C_MAP], cells[qt, C_BITS]
    whole = mbase < 0
    sg, thr = prj_w[p, 0], prj_w[p, 1]
    prune, inh = prj[p, J_PRUNE] == 1, prj[p, J_INH] == 1
    events = 0
    for x in range(x0, spikes.size):
        loc = _flat(spikes[U(x)], qs, cells, flat_of)
        c = loc // plane
        si = (loc - c * plane) // gc_s
        rb, cb = prj[p, J_BASE] + si, prj[p, J_COLBASE] + (loc - c * plane - si * gc_s)
        if n_touched + (csr_ptr[U(rb + 1)] - csr_ptr[U(rb)]) * (csr_ptr[U(cb + 1)] - csr_ptr[U(cb)]) > touched.size:
            counters[N_EVENTS] += events
            return n_touched, x
        cbase = c * gr * gc
        for xr in range(csr_ptr[U(rb)], csr_ptr[U(rb + 1)]):
            a = csr_val[U(xr)]
            rbase = cbase + csr_idx[U(xr)] * gc
            for xc in range(csr_ptr[U(cb)], csr_ptr[U(cb + 1)]):
                val = a * csr_val[U(xc)]
                if val == 0.0 or (prune and abs(val) < thr):
                    continue
                lt = rbase + csr_idx[U(xc)]
                if not whole:
                    if (bits[U(bbase + (lt >> 3))] >> (lt & 7)) & 1 == 0:
                        continue
                    lt = cmap[U(mbase + lt)]
                w = sg * val
                if inh:
                    w = abs(w)
                if acc[U(lt)] == 0.0:
                    touched[U(n_touched)] = lt
                    n_touched += 1
                acc[U(lt)] += w * MV
                events += 1
    counters[N_EVENTS] += events
    return n_touched, spikes.size


@njit(cache=True)
def _step_active(n, act, n_act, state, inact, pops, cells, nrn, ref, log, log_n):
    """Brian2's ``groups`` and ``thresholds`` slots for the active cells
    (sorted by number, hence walked population by population), parking
    those that cannot fire. Returns ``(active cells, log length)``."""
    kept = 0
    q = 0
    end = cells[0, C_OFF] + cells[0, C_N]
    t = pops[0, P_TYPE]
    for a in range(n_act):
        g = act[U(a)]
        while g >= end:
            q += 1
            end = cells[q, C_OFF] + cells[q, C_N]
            t = pops[q, P_TYPE]
        r = state[U(g)]
        ready = r.spike == 0 or n - (r.spike - 1) >= ref[t]
        if ready and _safe(r.v, r.e, r.i, nrn[t]):
            inact[U(g)] = 0
            continue
        v, e, i = r.v, r.e, r.i
        if ready:       # (Brian2's generated expression, operation for operation)
            v += ((e * nrn[t, PE]) + ((1.0 - nrn[t, DM]) * ((-v) + nrn[t, V_REST]))) - (i * nrn[t, PI])
        r.v = v
        r.e = e * nrn[t, DE]
        r.i = i * nrn[t, DI]
        r.last = n + 1
        if ready and v > nrn[t, V_TH]:
            log[U(log_n)] = g
            log_n += 1
            r.spike = n + 1
        act[U(kept)] = g
        kept += 1
    return kept, log_n


@njit(cache=True)
def _merge(act, n_act, new, n_new, tmp):
    """Merge the newly active cells into the sorted active list."""
    if n_new == 0:
        return n_act
    new[:n_new].sort()
    a = b = k = 0
    while a < n_act or b < n_new:
        if b == n_new or (a < n_act and act[U(a)] < new[U(b)]):
            tmp[U(k)] = act[U(a)]
            a += 1
        else:
            tmp[U(k)] = new[U(b)]
            b += 1
        k += 1
    act[:k] = tmp[:k]
    return k


@njit(cache=True)
def run_steps(n0, n1, state, ctype, inact, act, new, tmp, fresh, scalars, log, step_start, in_ptr, in_ids,
              pops, cells, cmap, flat_of, column_of, row_ptr, bits, gather, nrn, ref, adv, prj, prj_w, ch_ptr, tap_co,
              tap_qr, tap_qc, tap_w, tap_off, dense, pair_ptr, pair_co, pair_rlo, pair_rhi, csr_ptr, csr_idx,
              csr_val, grp_ptr, grp_prj, acc, touched, counters, prj_events):
    """Simulate steps ``n0 .. n1-1``; returns the step reached (less than
    ``n1`` when the spike log is too small for the next step: grow it and
    call again from there). ``scalars`` holds (active cells, log length).

    Synaptic input is delivered per group of projections sharing a target
    population and current (``grp_prj[grp_ptr[k]:grp_ptr[k+1]]``): summed
    per target cell in ``acc`` first, then added to each touched cell once.
    """
    n_act, log_n = scalars[0], scalars[1]
    for n in range(n0, n1):
        s = n % (in_ptr.size - 1)     # input spikes repeat with the period of in_ptr (if shorter than the run)
        if log_n + n_act + (in_ptr[s + 1] - in_ptr[s]) > log.size:
            scalars[0], scalars[1] = n_act, log_n
            return n
        start = log_n
        counters[N_ACTIVE_STEPS] += n_act
        n_act, log_n = _step_active(n, act, n_act, state, inact, pops, cells, nrn, ref, log, log_n)
        mid = log_n
        for x in range(in_ptr[s], in_ptr[s + 1]):
            log[log_n] = in_ids[x]
            log_n += 1
        if mid > start and log_n > mid:
            log[start:log_n].sort()
        step_start[n + 1] = log_n
        n_new = 0
        for grp in range(grp_ptr.size - 1):
            p = grp_prj[grp_ptr[grp]]
            off_t, t_t, col = cells[prj[p, J_TGT], C_OFF], pops[prj[p, J_TGT], P_TYPE], prj[p, J_COL]
            n_touched = 0
            for y in range(grp_ptr[grp], grp_ptr[grp + 1]):
                p = grp_prj[y]
                m = n - prj[p, J_DELAY]
                if m < 0 or step_start[m] == step_start[m + 1]:
                    continue
                q = prj[p, J_SRC]
                spikes = log[step_start[m]:step_start[m + 1]]
                spikes = spikes[np.searchsorted(spikes, cells[q, C_OFF]):
                                np.searchsorted(spikes, cells[q, C_OFF] + cells[q, C_N])]
                before = counters[N_EVENTS]
                x = 0
                while True:
                    if gather[p]:
                        n_touched, x = _conv_gather(p, spikes, x, pops, cells, flat_of, column_of, row_ptr, prj,
                                                    dense, pair_ptr, pair_co, pair_rlo, pair_rhi, acc, touched,
                                                    n_touched, counters)
                    elif prj[p, J_KIND] == CONV:
                        n_touched, x = _conv(p, spikes, x, pops, cells, cmap, flat_of, bits, prj, ch_ptr, tap_co,
                                             tap_qr, tap_qc, tap_w, tap_off, acc, touched, n_touched, counters)
                    else:
                        n_touched, x = _resize(p, spikes, x, pops, cells, cmap, flat_of, bits, prj, prj_w, csr_ptr,
                                               csr_idx, csr_val, acc, touched, n_touched, counters)
                    if x >= spikes.size:
                        break
                    # the touched list is full: deliver what it holds, then go on
                    n_new = _flush(acc, touched, n_touched, off_t, col, n, t_t, state, inact, new, n_new, fresh,
                                   nrn, adv, counters)
                    n_touched = 0
                prj_events[p] += counters[N_EVENTS] - before
            if n_touched:
                n_new = _flush(acc, touched, n_touched, off_t, col, n, t_t, state, inact, new, n_new, fresh, nrn,
                               adv, counters)
        for x in range(start, log_n):
            g = log[x]
            if ctype[g] < SOURCE_TYPE:
                state[g].v = nrn[ctype[g], V_RESET]
        n_act = _merge(act, n_act, new, n_new, tmp)
    scalars[0], scalars[1] = n_act, log_n
    return n1


@njit(cache=True)
def final_state(state, ctype, nrn, adv, n_steps, out):
    """Every cell's ``(v, I_exc, I_inh)`` at the end of step ``n_steps - 1``
    into ``out`` (untouched cells at rest), leaving ``state`` as it is: an
    untouched cell must stay marked so (``last == 0``), since the arrays
    serve the next run, whose cell numbering may differ."""
    for g in range(state.shape[0]):
        t = ctype[g]
        if t >= SOURCE_TYPE:
            continue
        r = state[g]
        if r.last == 0:
            out[g, 0], out[g, 1], out[g, 2] = nrn[t, V_REST], 0.0, 0.0
        elif r.last < n_steps:
            out[g, 0], out[g, 1], out[g, 2] = _advanced(r.v, r.e, r.i, nrn[t, V_REST], adv[t], n_steps - r.last)
        else:
            out[g, 0], out[g, 1], out[g, 2] = r.v, r.e, r.i


@njit(cache=True)
def reset(state, inact, act, n_act, fresh, n_fresh):
    """Put back at rest the cells a run touched (``fresh``) and clear the
    active flags, so that the arrays serve the next run without being
    allocated (and their memory faulted in) again."""
    for x in range(n_fresh):
        r = state[U(fresh[U(x)])]
        r.v, r.e, r.i, r.last, r.spike = 0.0, 0.0, 0.0, 0, 0
    for x in range(n_act):
        inact[U(act[U(x)])] = 0


@njit(cache=True)
def bin_counts(ids, cuts, out):
    """``out[b, g]`` += spikes of cell ``g`` among ``ids[cuts[b]:cuts[b + 1]]``
    (one pass, into an array allocated once: a bincount per bin would fault
    in a fresh cell-sized array each time)."""
    for b in range(cuts.size - 1):
        for x in range(cuts[b], cuts[b + 1]):
            out[b, ids[x]] += 1
