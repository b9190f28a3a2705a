"""The fast engine's inner loops, compiled by numba.

One call of :func:`run_steps` advances the simulation over a range of time
steps. Each step follows Brian2's schedule as our Brian2 backend uses it
(``groups``, ``thresholds``, ``synapses``, ``resets``):

1. every *active* cell is updated exactly like Brian2's ``lif_step``
   (``v += (1 - d_m) ((I_exc + v_rest) - (I_inh + v))`` unless refractory,
   then both currents decay) and spikes if ``v > v_th`` and it is not
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

The active cells are kept sorted by number, so that the per-step pass over
them walks memory in one direction (in a random order it would wait for
memory at nearly every cell). State per cell (:data:`STATE`): ``v``,
``e`` (``I_exc``), ``i`` (``I_inh``) in volts, ``last`` (the step the values
belong to, plus one; 0: never touched, i.e. at rest) and ``spike`` (the
step of the last spike, plus one; 0: none).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .fast_tables import (ABSENT_TYPE, CONV, DE, DI, DM, GAP, J_BASE, J_COL, J_COLBASE, J_DELAY, J_INH, J_KIND,
                          J_PRUNE, J_RADIUS, J_SRC, J_TGT, J_WRAP, MV, P_GC, P_GR, P_OFF, P_SIZE, P_STRIDE, P_TYPE,
                          PEAK, SOURCE_TYPE, TIGHT, V_RESET, V_REST, V_TH)

#: one cell's state (32 bytes, one half cache line)
STATE = np.dtype([("v", "f8"), ("e", "f8"), ("i", "f8"), ("last", "i4"), ("spike", "i4")], align=True)
#: counters returned by run_steps
N_EVENTS, N_ADVANCES, N_ACTIVE_STEPS = range(3)
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
def _flush(acc, touched, n_touched, off, col, n, t, state, inact, new, n_new, nrn, adv, counters):
    """Add the accumulated input ``acc[x]`` to current ``col`` of cell
    ``off + x`` (neuron type ``t``) at step ``n``, for the ``touched`` cells,
    bringing parked cells up to date first; a cell that might now fire is
    appended to ``new``. Returns the new length of ``new``."""
    nrn_row = nrn[t]
    v_rest = nrn_row[V_REST]
    adv_row = adv[t]
    now = n + 1
    advances = 0
    for x in range(n_touched):
        loc = touched[x]
        w = acc[loc]
        if w == 0.0:
            continue          # (a cell listed twice after its input summed to zero)
        acc[loc] = 0.0
        g = off + loc
        r = state[g]
        if r.last != now:
            if r.last == 0:
                r.v = v_rest
            else:
                r.v, r.e, r.i = _advanced(r.v, r.e, r.i, v_rest, adv_row, now - r.last)
                advances += 1
            r.last = now
        if col == EXC:
            r.e += w
        else:
            r.i += w
        if inact[g] == 0 and not _safe(r.v, r.e, r.i, nrn_row):
            inact[g] = 1
            new[n_new] = g
            n_new += 1
    counters[N_ADVANCES] += advances
    return n_new


@njit(cache=True)
def _conv(p, spikes, x0, pops, prj, ntype, complete, ch_ptr, tap_co, tap_qr, tap_qc, tap_w, tap_off, acc, touched,
          n_touched, counters):
    """Accumulate what ``spikes[x0:]`` (global cell numbers) send through the
    taps of Conv ``p`` into ``acc`` (indexed by target cell within its
    population), listing newly touched cells in ``touched``. Returns the
    list's length and the first spike not sent (when the list is full)."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    off_s, gc_s, st_s = pops[qs, P_OFF], pops[qs, P_GC], pops[qs, P_STRIDE]
    plane = pops[qs, P_GR] * gc_s
    off_t, gr, gc, st = pops[qt, P_OFF], pops[qt, P_GR], pops[qt, P_GC], pops[qt, P_STRIDE]
    whole, wrap, rad = complete[qt] == 1, prj[p, J_WRAP] == 1, prj[p, J_RADIUS]
    base_ch = prj[p, J_BASE]
    events = 0
    for x in range(x0, spikes.size):
        loc = spikes[x] - off_s
        c = loc // plane
        ii = (loc - c * plane) // gc_s
        pr = ii * st_s
        pc = (loc - c * plane - ii * gc_s) * st_s
        if st == 1:
            cls, row, column = base_ch + c, pr, pc
        else:
            cls = base_ch + (c * st + pr % st) * st + pc % st
            row, column = pr // st, pc // st
        k0, k1 = ch_ptr[cls], ch_ptr[cls + 1]
        if n_touched + (k1 - k0) > touched.size:
            counters[N_EVENTS] += events
            return n_touched, x
        if row >= rad and column >= rad and row + rad < gr and column + rad < gc:
            base = row * gc + column          # the whole footprint lies inside the level
            for k in range(k0, k1):
                lt = base + tap_off[k]
                if whole or ntype[off_t + lt] != ABSENT_TYPE:
                    if acc[lt] == 0.0:
                        touched[n_touched] = lt
                        n_touched += 1
                    acc[lt] += tap_w[k]
                    events += 1
            continue
        if not wrap:
            # the taps are sorted by row offset: those landing inside the level
            # (row - qr in [0, gr)) are the range with qr in [row - gr + 1, row]
            a, b = k0, k1
            while a < b:
                h = (a + b) // 2
                if tap_qr[h] < row - gr + 1:
                    a = h + 1
                else:
                    b = h
            k0, b = a, k1
            while a < b:
                h = (a + b) // 2
                if tap_qr[h] <= row:
                    a = h + 1
                else:
                    b = h
            k1 = a
        for k in range(k0, k1):
            r = row - tap_qr[k]
            cc = column - tap_qc[k]
            if wrap:            # offsets lie within one level size (folded if the kernel is larger)
                r += gr if r < 0 else (-gr if r >= gr else 0)
                cc += gc if cc < 0 else (-gc if cc >= gc else 0)
            elif cc < 0 or cc >= gc:
                continue
            lt = (tap_co[k] * gr + r) * gc + cc
            if whole or ntype[off_t + lt] != ABSENT_TYPE:
                if acc[lt] == 0.0:
                    touched[n_touched] = lt
                    n_touched += 1
                acc[lt] += tap_w[k]
                events += 1
    counters[N_EVENTS] += events
    return n_touched, spikes.size


@njit(cache=True)
def _resize(p, spikes, x0, pops, prj, prj_w, ntype, complete, csr_ptr, csr_idx, csr_val, acc, touched, n_touched,
            counters):
    """Like :func:`_conv` for Resize ``p``: weight ``sign * gain * A_r[i, i'] * A_c[j, j']``."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    off_s, gc_s = pops[qs, P_OFF], pops[qs, P_GC]
    plane = pops[qs, P_GR] * gc_s
    off_t, gr, gc = pops[qt, P_OFF], pops[qt, P_GR], pops[qt, P_GC]
    whole = complete[qt] == 1
    sg, thr = prj_w[p, 0], prj_w[p, 1]
    prune, inh = prj[p, J_PRUNE] == 1, prj[p, J_INH] == 1
    events = 0
    for x in range(x0, spikes.size):
        loc = spikes[x] - off_s
        c = loc // plane
        si = (loc - c * plane) // gc_s
        rb, cb = prj[p, J_BASE] + si, prj[p, J_COLBASE] + (loc - c * plane - si * gc_s)
        if n_touched + (csr_ptr[rb + 1] - csr_ptr[rb]) * (csr_ptr[cb + 1] - csr_ptr[cb]) > touched.size:
            counters[N_EVENTS] += events
            return n_touched, x
        cbase = c * gr * gc
        for xr in range(csr_ptr[rb], csr_ptr[rb + 1]):
            a = csr_val[xr]
            rbase = cbase + csr_idx[xr] * gc
            for xc in range(csr_ptr[cb], csr_ptr[cb + 1]):
                val = a * csr_val[xc]
                if val == 0.0 or (prune and abs(val) < thr):
                    continue
                lt = rbase + csr_idx[xc]
                if whole or ntype[off_t + lt] != ABSENT_TYPE:
                    w = sg * val
                    if inh:
                        w = abs(w)
                    if acc[lt] == 0.0:
                        touched[n_touched] = lt
                        n_touched += 1
                    acc[lt] += w * MV
                    events += 1
    counters[N_EVENTS] += events
    return n_touched, spikes.size


@njit(cache=True)
def _step_active(n, act, n_act, state, inact, pops, nrn, ref, log, log_n):
    """Brian2's ``groups`` and ``thresholds`` slots for the active cells
    (sorted by number, hence walked population by population), parking
    those that cannot fire. Returns ``(active cells, log length)``."""
    kept = 0
    q = 0
    end = pops[0, P_OFF] + pops[0, P_SIZE]
    t = pops[0, P_TYPE]
    for a in range(n_act):
        g = act[a]
        while g >= end:
            q += 1
            end = pops[q, P_OFF] + pops[q, P_SIZE]
            t = pops[q, P_TYPE]
        r = state[g]
        ready = r.spike == 0 or n - (r.spike - 1) >= ref[t]
        if ready and _safe(r.v, r.e, r.i, nrn[t]):
            inact[g] = 0
            continue
        v, e, i = r.v, r.e, r.i
        if ready:
            v += (1.0 - nrn[t, DM]) * ((e + nrn[t, V_REST]) - (i + v))
        r.v = v
        r.e = e * nrn[t, DE]
        r.i = i * nrn[t, DI]
        r.last = n + 1
        if ready and v > nrn[t, V_TH]:
            log[log_n] = g
            log_n += 1
            r.spike = n + 1
        act[kept] = g
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
        if b == n_new or (a < n_act and act[a] < new[b]):
            tmp[k] = act[a]
            a += 1
        else:
            tmp[k] = new[b]
            b += 1
        k += 1
    act[:k] = tmp[:k]
    return k


@njit(cache=True)
def run_steps(n0, n1, state, ntype, inact, act, new, tmp, scalars, log, step_start, in_ptr, in_ids,
              pops, complete, nrn, ref, adv, prj, prj_w, ch_ptr, tap_co, tap_qr, tap_qc, tap_w, tap_off,
              csr_ptr, csr_idx, csr_val, grp_ptr, grp_prj, acc, touched, counters, prj_events):
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
        n_act, log_n = _step_active(n, act, n_act, state, inact, pops, nrn, ref, log, log_n)
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
            off_t, t_t, col = pops[prj[p, J_TGT], P_OFF], pops[prj[p, J_TGT], P_TYPE], prj[p, J_COL]
            n_touched = 0
            for y in range(grp_ptr[grp], grp_ptr[grp + 1]):
                p = grp_prj[y]
                m = n - prj[p, J_DELAY]
                if m < 0 or step_start[m] == step_start[m + 1]:
                    continue
                q = prj[p, J_SRC]
                spikes = log[step_start[m]:step_start[m + 1]]
                spikes = spikes[np.searchsorted(spikes, pops[q, P_OFF]):
                                np.searchsorted(spikes, pops[q, P_OFF] + pops[q, P_SIZE])]
                before = counters[N_EVENTS]
                x = 0
                while True:
                    if prj[p, J_KIND] == CONV:
                        n_touched, x = _conv(p, spikes, x, pops, prj, ntype, complete, ch_ptr, tap_co, tap_qr,
                                             tap_qc, tap_w, tap_off, acc, touched, n_touched, counters)
                    else:
                        n_touched, x = _resize(p, spikes, x, pops, prj, prj_w, ntype, complete, csr_ptr, csr_idx,
                                               csr_val, acc, touched, n_touched, counters)
                    if x >= spikes.size:
                        break
                    # the touched list is full: deliver what it holds, then go on
                    n_new = _flush(acc, touched, n_touched, off_t, col, n, t_t, state, inact, new, n_new, nrn, adv,
                                   counters)
                    n_touched = 0
                prj_events[p] += counters[N_EVENTS] - before
            if n_touched:
                n_new = _flush(acc, touched, n_touched, off_t, col, n, t_t, state, inact, new, n_new, nrn, adv,
                               counters)
        for x in range(start, log_n):
            g = log[x]
            if ntype[g] < SOURCE_TYPE:
                state[g].v = nrn[ntype[g], V_RESET]
        n_act = _merge(act, n_act, new, n_new, tmp)
    scalars[0], scalars[1] = n_act, log_n
    return n1


@njit(cache=True)
def final_state(state, ntype, nrn, adv, n_steps):
    """Bring every touched cell to the end of step ``n_steps - 1`` and put
    untouched cells at rest (for reporting the final state)."""
    for g in range(state.shape[0]):
        t = ntype[g]
        if t >= SOURCE_TYPE:
            continue
        r = state[g]
        if r.last == 0:
            r.v = nrn[t, V_REST]
        elif r.last < n_steps:
            r.v, r.e, r.i = _advanced(r.v, r.e, r.i, nrn[t, V_REST], adv[t], n_steps - r.last)
        r.last = n_steps
