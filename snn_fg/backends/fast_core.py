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
3. cells that spiked are reset;
4. active cells that can no longer reach threshold without new input are
   *parked*.

A parked cell is not touched until input reaches it; it is then brought up
to date in closed form (the update is linear between spikes, see
:func:`snn_fg.backends.fast_tables._advance_tables`). Parking is safe
because, with no input, ``v - v_rest`` never exceeds
``max(v - v_rest, I_exc^+ + I_inh^-)``: a cell whose bound lies below
threshold (by a margin) cannot spike before its next input.

State per cell (``state[g]``): ``v``, ``I_exc``, ``I_inh`` (volts) and the
step its values belong to plus one (0: never touched, i.e. at rest).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .fast_tables import (ABSENT_TYPE, CONV, DE, DI, DM, GAP, J_BASE, J_COL, J_COLBASE, J_DELAY, J_INH, J_KIND,
                          J_PRUNE, J_RADIUS, J_SRC, J_TGT, J_WRAP, MV, P_GC, P_GR, P_OFF, P_SIZE,
                          P_STRIDE, P_TYPE, SOURCE_TYPE, V_RESET, V_REST, V_TH)

#: counters returned by run_steps
N_EVENTS, N_ADVANCES, N_ACTIVE_STEPS = range(3)


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
def _safe(v, e, i, v_rest, gap):
    """Whether a cell in this state cannot reach threshold without new input."""
    return max(v - v_rest, max(e, 0.0) + max(-i, 0.0)) <= gap


@njit(cache=True)
def _deliver(buf_g, buf_w, m, col, n, t, state, inact, act, n_act, nrn, adv, counters):
    """Add ``buf_w[x]`` to current ``col`` of cell ``buf_g[x]`` (neuron type
    ``t``) at step ``n``, for ``x < m``, bringing parked cells up to date
    first; a cell that might now fire joins the active set. Returns the new
    size of the active set.

    (One loop over a buffer rather than a helper per event: numba counts
    references to every array passed to a function, which per event would
    cost more than the event.)"""
    v_rest, gap = nrn[t, V_REST], nrn[t, GAP]
    adv_row = adv[t]
    now = n + 1.0
    advances = 0
    for x in range(m):
        g = buf_g[x]
        last = state[g, 3]
        if last != now:
            if last == 0.0:
                state[g, 0] = v_rest
            else:
                state[g, 0], state[g, 1], state[g, 2] = _advanced(state[g, 0], state[g, 1], state[g, 2], v_rest,
                                                                  adv_row, n + 1 - np.int64(last))
                advances += 1
            state[g, 3] = now
        state[g, col] += buf_w[x]
        if inact[g] == 0 and not _safe(state[g, 0], state[g, 1], state[g, 2], v_rest, gap):
            inact[g] = 1
            act[n_act] = g
            n_act += 1
    counters[N_ADVANCES] += advances
    counters[N_EVENTS] += m
    return n_act


@njit(cache=True)
def _conv(p, spikes, n, pops, prj, ntype, complete, ch_ptr, tap_co, tap_qr, tap_qc, tap_w, tap_off,
          buf_g, buf_w, state, inact, act, n_act, nrn, adv, counters):
    """Send ``spikes`` (global cell numbers) through the taps of Conv ``p``."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    off_s, gc_s, st_s = pops[qs, P_OFF], pops[qs, P_GC], pops[qs, P_STRIDE]
    plane = pops[qs, P_GR] * gc_s
    off_t, gr, gc, st = pops[qt, P_OFF], pops[qt, P_GR], pops[qt, P_GC], pops[qt, P_STRIDE]
    t, col = pops[qt, P_TYPE], prj[p, J_COL]
    whole, wrap, rad = complete[qt] == 1, prj[p, J_WRAP] == 1, prj[p, J_RADIUS]
    base_ch = prj[p, J_BASE]
    m = 0
    for x in range(spikes.size):
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
        if m + (k1 - k0) > buf_g.size:
            n_act = _deliver(buf_g, buf_w, m, col, n, t, state, inact, act, n_act, nrn, adv, counters)
            m = 0
        if row >= rad and column >= rad and row + rad < gr and column + rad < gc:
            base = off_t + row * gc + column          # the whole footprint lies inside the level
            for k in range(k0, k1):
                gt = base + tap_off[k]
                if whole or ntype[gt] != ABSENT_TYPE:
                    buf_g[m] = gt
                    buf_w[m] = tap_w[k]
                    m += 1
            continue
        for k in range(k0, k1):
            r = row - tap_qr[k]
            cc = column - tap_qc[k]
            if wrap:
                r %= gr
                cc %= gc
            elif r < 0 or r >= gr or cc < 0 or cc >= gc:
                continue
            gt = off_t + (tap_co[k] * gr + r) * gc + cc
            if whole or ntype[gt] != ABSENT_TYPE:
                buf_g[m] = gt
                buf_w[m] = tap_w[k]
                m += 1
    return _deliver(buf_g, buf_w, m, col, n, t, state, inact, act, n_act, nrn, adv, counters)


@njit(cache=True)
def _resize(p, spikes, n, pops, prj, prj_w, ntype, complete, csr_ptr, csr_idx, csr_val,
            buf_g, buf_w, state, inact, act, n_act, nrn, adv, counters):
    """Send ``spikes`` through the interpolation weights of Resize ``p``:
    weight ``sign * gain * A_r[i, i'] * A_c[j, j']``."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    off_s, gc_s = pops[qs, P_OFF], pops[qs, P_GC]
    plane = pops[qs, P_GR] * gc_s
    off_t, gr, gc = pops[qt, P_OFF], pops[qt, P_GR], pops[qt, P_GC]
    t, col = pops[qt, P_TYPE], prj[p, J_COL]
    whole = complete[qt] == 1
    sg, thr = prj_w[p, 0], prj_w[p, 1]
    prune, inh = prj[p, J_PRUNE] == 1, prj[p, J_INH] == 1
    m = 0
    for x in range(spikes.size):
        loc = spikes[x] - off_s
        c = loc // plane
        si = (loc - c * plane) // gc_s
        rb, cb = prj[p, J_BASE] + si, prj[p, J_COLBASE] + (loc - c * plane - si * gc_s)
        n_r, n_c = csr_ptr[rb + 1] - csr_ptr[rb], csr_ptr[cb + 1] - csr_ptr[cb]
        if m + n_r * n_c > buf_g.size:
            n_act = _deliver(buf_g, buf_w, m, col, n, t, state, inact, act, n_act, nrn, adv, counters)
            m = 0
        cbase = off_t + c * gr * gc
        for xr in range(csr_ptr[rb], csr_ptr[rb + 1]):
            a = csr_val[xr]
            rbase = cbase + csr_idx[xr] * gc
            for xc in range(csr_ptr[cb], csr_ptr[cb + 1]):
                val = a * csr_val[xc]
                if val == 0.0 or (prune and abs(val) < thr):
                    continue
                gt = rbase + csr_idx[xc]
                if whole or ntype[gt] != ABSENT_TYPE:
                    w = sg * val
                    if inh:
                        w = abs(w)
                    buf_g[m] = gt
                    buf_w[m] = w * MV
                    m += 1
    return _deliver(buf_g, buf_w, m, col, n, t, state, inact, act, n_act, nrn, adv, counters)


@njit(cache=True)
def _update_active(n, act, n_act, state, ntype, last_spike, nrn, ref, log, log_n):
    """Brian2's ``groups`` and ``thresholds`` slots for the active cells."""
    for a in range(n_act):
        g = act[a]
        t = ntype[g]
        ls = last_spike[g]
        ready = ls == 0 or n - (ls - 1) >= ref[t]
        v = state[g, 0]
        e = state[g, 1]
        i = state[g, 2]
        if ready:
            v += (1.0 - nrn[t, DM]) * ((e + nrn[t, V_REST]) - (i + v))
        state[g, 0] = v
        state[g, 1] = e * nrn[t, DE]
        state[g, 2] = i * nrn[t, DI]
        state[g, 3] = n + 1
        if ready and v > nrn[t, V_TH]:
            log[log_n] = g
            log_n += 1
            last_spike[g] = n + 1
    return log_n


@njit(cache=True)
def _park(n, act, n_act, state, ntype, inact, last_spike, ref, nrn):
    """Remove from the active set the cells that cannot fire without input."""
    a = 0
    while a < n_act:
        g = act[a]
        t = ntype[g]
        ls = last_spike[g]
        if (ls == 0 or n + 1 - (ls - 1) >= ref[t]) and _safe(state[g, 0], state[g, 1], state[g, 2],
                                                               nrn[t, V_REST], nrn[t, GAP]):
            inact[g] = 0
            n_act -= 1
            act[a] = act[n_act]
        else:
            a += 1
    return n_act


@njit(cache=True)
def run_steps(n0, n1, state, last_spike, ntype, inact, act, scalars, log, step_start, in_ptr, in_ids,
              pops, complete, nrn, ref, adv, prj, prj_w, ch_ptr, tap_co, tap_qr, tap_qc, tap_w, tap_off,
              csr_ptr, csr_idx, csr_val, buf_g, buf_w, counters, prj_events):
    """Simulate steps ``n0 .. n1-1``; returns the step reached (less than
    ``n1`` when the spike log is too small for the next step: grow it and
    call again from there). ``scalars`` holds (active cells, log length)."""
    n_act, log_n = scalars[0], scalars[1]
    for n in range(n0, n1):
        if log_n + n_act + (in_ptr[n + 1] - in_ptr[n]) > log.size:
            scalars[0], scalars[1] = n_act, log_n
            return n
        start = log_n
        counters[N_ACTIVE_STEPS] += n_act
        log_n = _update_active(n, act, n_act, state, ntype, last_spike, nrn, ref, log, log_n)
        for x in range(in_ptr[n], in_ptr[n + 1]):
            log[log_n] = in_ids[x]
            log_n += 1
        log[start:log_n].sort()
        step_start[n + 1] = log_n
        for p in range(prj.shape[0]):
            m = n - prj[p, J_DELAY]
            if m < 0 or step_start[m] == step_start[m + 1]:
                continue
            q = prj[p, J_SRC]
            spikes = log[step_start[m]:step_start[m + 1]]
            lo = np.searchsorted(spikes, pops[q, P_OFF])
            hi = np.searchsorted(spikes, pops[q, P_OFF] + pops[q, P_SIZE])
            if lo == hi:
                continue
            before = counters[N_EVENTS]
            if prj[p, J_KIND] == CONV:
                n_act = _conv(p, spikes[lo:hi], n, pops, prj, ntype, complete, ch_ptr, tap_co, tap_qr, tap_qc,
                              tap_w, tap_off, buf_g, buf_w, state, inact, act, n_act, nrn, adv, counters)
            else:
                n_act = _resize(p, spikes[lo:hi], n, pops, prj, prj_w, ntype, complete, csr_ptr, csr_idx, csr_val,
                                buf_g, buf_w, state, inact, act, n_act, nrn, adv, counters)
            prj_events[p] += counters[N_EVENTS] - before
        for x in range(start, log_n):
            g = log[x]
            if ntype[g] < SOURCE_TYPE:
                state[g, 0] = nrn[ntype[g], V_RESET]
        n_act = _park(n, act, n_act, state, ntype, inact, last_spike, ref, nrn)
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
        last = state[g, 3]
        if last == 0.0:
            state[g, 0] = nrn[t, V_REST]
        elif last < n_steps:
            state[g, 0], state[g, 1], state[g, 2] = _advanced(state[g, 0], state[g, 1], state[g, 2],
                                                              nrn[t, V_REST], adv[t], n_steps - np.int64(last))
        state[g, 3] = n_steps
