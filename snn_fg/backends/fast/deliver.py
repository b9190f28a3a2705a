"""Spike delivery of the fast engine: one source spike through a projection's
weight-shared taps (:func:`_conv`, :func:`_conv_gather`) or a resize's sparse
rows (:func:`_resize`), summed per target cell and current and handed over
once per cell (:func:`_flush`), which brings each touched cell up to the
present in closed form first. The numbering and state are described in
:mod:`.core`."""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

from .tables import (
    GAP,
    J_BASE,
    J_COLBASE,
    J_DENSE,
    J_GBASE,
    J_INH,
    J_KR,
    J_PRUNE,
    J_RADIUS,
    J_SRC,
    J_TGT,
    J_WRAP,
    MV,
    P_CH,
    P_GC,
    P_GR,
    P_LC,
    P_LR,
    P_STRIDE,
    PEAK,
    TIGHT,
    V_REST,
)

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
#: how many cells ahead of the one being updated :func:`_flush` and the
#: active-cell pass ask for a cell's state: a cell's 32 bytes are rarely in
#: cache, and waiting for them was most of a run's time (asking 12 cells ahead
#: took a dvs.es window's simulation from 4.2 to 3.0 s of CPU; 8 and 24 were
#: no better then). Since the cell arrays sit in 2 MB pages, 24 is better:
#: side by side with 12 in 6 rounds of two windows, 0.82-0.99 of its time
#: (mean 0.91); 6 was slower, 32 and 48 about the same as 24
AHEAD = 24


@intrinsic
def prefetch(typingctx, arr, idx):
    """Ask the CPU to bring ``arr[idx]`` into cache, to be written (LLVM's
    ``prefetch`` intrinsic: a hint, with no effect on any result)."""

    def codegen(context, builder, signature, args):
        aty = signature.args[0]
        ary = context.make_array(aty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer2(
            context,
            builder,
            data=ary.data,
            shape=cgutils.unpack_tuple(builder, ary.shape),
            strides=cgutils.unpack_tuple(builder, ary.strides),
            layout=aty.layout,
            inds=[args[1]],
            wraparound=False,
            boundscheck=False,
        )
        i8p, i32 = ir.IntType(8).as_pointer(), ir.IntType(32)
        # (the name without its pointer-type suffix: LLVM renames it to its own
        # version's, p0i8 before opaque pointers and p0 after)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]), "llvm.prefetch"
        )
        # (address, 1: for writing, 3: keep in every cache level, 1: data)
        builder.call(fn, [builder.bitcast(ptr, i8p), ir.Constant(i32, 1), ir.Constant(i32, 3), ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return types.void(arr, idx), codegen


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
        if x + AHEAD < n_touched:
            later = touched[U(x + AHEAD)]
            prefetch(state, U(off + later))
            prefetch(inact, U(off + later))
            prefetch(acc, U(later))  # (its summed input: 10 MB for dvs.es simple cells)
        loc = touched[U(x)]
        w = acc[U(loc)]
        if w == 0.0:
            continue  # (a cell listed twice after its input summed to zero)
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
def _conv(
    p,
    spikes,
    x0,
    pops,
    cells,
    cmap,
    flat_of,
    bits,
    prj,
    ch_ptr,
    tap_co,
    tap_qr,
    tap_qc,
    tap_w,
    tap_off,
    acc,
    touched,
    n_touched,
    counters,
):
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
            base = row * gc + column  # the whole footprint lies inside the level
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
            if wrap:  # offsets lie within one level size (folded if the kernel is larger)
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
def _conv_gather(
    p,
    spikes,
    x0,
    pops,
    cells,
    flat_of,
    column_of,
    row_ptr,
    prj,
    dense,
    pair_ptr,
    pair_co,
    pair_rlo,
    pair_rhi,
    acc,
    touched,
    n_touched,
    counters,
):
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
                if fold:  # every cell of the row, each through all its folded offsets
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
                    while a < b:  # first cell at or after lo
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
def _resize(
    p,
    spikes,
    x0,
    pops,
    cells,
    cmap,
    flat_of,
    bits,
    prj,
    prj_w,
    csr_ptr,
    csr_idx,
    csr_val,
    acc,
    touched,
    n_touched,
    counters,
):
    """Like :func:`_conv` for Resize ``p``: weight ``sign * gain * A_r[i, i'] * A_c[j, j']``, the
    product rounded to the projection's quantisation step where it has one."""
    qs, qt = prj[p, J_SRC], prj[p, J_TGT]
    gc_s = pops[qs, P_GC]
    plane = pops[qs, P_GR] * gc_s
    gr, gc = pops[qt, P_GR], pops[qt, P_GC]
    mbase, bbase = cells[qt, C_MAP], cells[qt, C_BITS]
    whole = mbase < 0
    sg, thr, step = prj_w[p, 0], prj_w[p, 1], prj_w[p, 2]
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
                if step > 0.0:
                    val = np.round(val / step) * step
                    if val == 0.0:
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
