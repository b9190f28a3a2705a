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
linear between spikes, see :func:`snn_fg.backends.fast.tables.advance_tables`).
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

import hashlib
from collections import namedtuple
from pathlib import Path

import numpy as np
from numba import njit

from .deliver import (
    AHEAD,
    C_BITS,
    C_FLAT,
    C_MAP,
    C_N,
    C_OFF,
    C_ROW,
    EXC,
    N_ACTIVE_STEPS,  # noqa: F401
    N_ADVANCES,
    N_EVENTS,
    N_FRESH,
    STATE,
    U,
    _advanced,
    _conv,
    _conv_gather,
    _flush,
    _resize,
    _safe,
    prefetch,
)
from .tables import (
    CONV,
    DE,
    DI,
    DM,
    J_COL,
    J_DELAY,
    J_KIND,
    J_SRC,
    J_TGT,
    P_TYPE,
    PE,
    PI,
    SOURCE_TYPE,
    V_RESET,
    V_REST,
    V_TH,
)

#: the arrays :func:`run_steps` changes: cell state, active set, newly
#: active and touched cells, spike log (``log``, ``step_start``), the input
#: spikes (``in_ptr``, ``in_ids``), the delivery buffers and the counters
RunArrays = namedtuple(
    "RunArrays",
    "state inact act new tmp radix fresh scalars log step_start in_ptr in_ids acc touched counters prj_events",
)
#: how one run numbers its cells (module docstring): the neuron type of each
#: cell, the per-population table ``cells`` (columns ``C_*``), the maps
#: between grid and number, and which projections gather (:func:`_conv_gather`)
CellNumbering = namedtuple("CellNumbering", "ctype cells cmap flat_of column_of row_ptr bits gather")
#: the network at one time step (:class:`~snn_fg.backends.fast.tables.EngineTables`)
KernelTables = namedtuple(
    "KernelTables",
    "pops nrn ref_steps adv prj prj_w ch_ptr tap_co tap_qr tap_qc tap_w tap_off "
    "dense pair_ptr pair_co pair_rlo pair_rhi csr_ptr csr_idx csr_val grp_ptr "
    "grp_prj",
)


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
        if a + AHEAD < n_act:
            prefetch(state, U(act[U(a + AHEAD)]))
            prefetch(inact, U(act[U(a + AHEAD)]))  # (written when the cell is parked)
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
        if ready:  # (Brian2's generated expression, operation for operation)
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
def _radix_sort(a, n, tmp, counts):
    """Sort ``a[:n]`` (cell numbers, below ``tmp.size``) in place, by
    counting passes of 11 bits through ``tmp`` (``counts``: 2048 slots): a
    comparison sort of the few thousand cells that become active in a step
    took longer than the rest of the step's merge."""
    if n < 64:
        a[:n].sort()
        return
    src, dst = a, tmp
    shift, flips = 0, 0
    while shift == 0 or (tmp.size - 1) >> shift:
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
def _merge_into(x, y, out):
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
def _merge(act, n_act, new, n_new, tmp, counts):
    """Merge the newly active cells into the sorted active list."""
    if n_new == 0:
        return n_act
    _radix_sort(new, n_new, tmp, counts)
    k = _merge_into(act[:n_act], new[:n_new], tmp)
    act[:k] = tmp[:k]
    return k


@njit(cache=True)
def _merge_runs(log, start, mid, end, tmp):
    """Sort ``log[start:end]``, made of two sorted runs split at ``mid``
    (the cells that fired, in number order, then the step's input spikes,
    also in number order), by merging them through ``tmp``."""
    k = _merge_into(log[start:mid], log[mid:end], tmp)
    log[start:end] = tmp[:k]


@njit(cache=True, nogil=True)
def run_steps(n0, n1, run, numbering, tables):
    """Simulate steps ``n0 .. n1-1``; returns the step reached (less than
    ``n1`` when the spike log is too small for the next step: grow it and
    call again from there). ``run`` (:class:`RunArrays`), ``numbering``
    (:class:`CellNumbering`) and ``tables`` (:class:`KernelTables`) hold the
    arrays; ``run.scalars`` holds (active cells, log length).

    Synaptic input is delivered per group of projections sharing a target
    population and current (``grp_prj[grp_ptr[k]:grp_ptr[k+1]]``): summed
    per target cell in ``acc`` first, then added to each touched cell once.
    """
    (
        state,
        inact,
        act,
        new,
        tmp,
        radix,
        fresh,
        scalars,
        log,
        step_start,
        in_ptr,
        in_ids,
        acc,
        touched,
        counters,
        prj_events,
    ) = run
    ctype, cells, cmap, flat_of, column_of, row_ptr, bits, gather = numbering
    (
        pops,
        nrn,
        ref_steps,
        adv,
        prj,
        prj_w,
        ch_ptr,
        tap_co,
        tap_qr,
        tap_qc,
        tap_w,
        tap_off,
        dense,
        pair_ptr,
        pair_co,
        pair_rlo,
        pair_rhi,
        csr_ptr,
        csr_idx,
        csr_val,
        grp_ptr,
        grp_prj,
    ) = tables
    n_act, log_n = scalars[0], scalars[1]
    for n in range(n0, n1):
        s = n % (in_ptr.size - 1)  # input spikes repeat with the period of in_ptr (if shorter than the run)
        if log_n + n_act + (in_ptr[s + 1] - in_ptr[s]) > log.size:
            scalars[0], scalars[1] = n_act, log_n
            return n
        start = log_n
        counters[N_ACTIVE_STEPS] += n_act
        n_act, log_n = _step_active(n, act, n_act, state, inact, pops, cells, nrn, ref_steps, log, log_n)
        mid = log_n
        for x in range(in_ptr[s], in_ptr[s + 1]):
            log[log_n] = in_ids[x]
            log_n += 1
        if mid > start and log_n > mid:
            _merge_runs(log, start, mid, log_n, tmp)
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
                spikes = log[step_start[m] : step_start[m + 1]]
                spikes = spikes[
                    np.searchsorted(spikes, cells[q, C_OFF]) : np.searchsorted(spikes, cells[q, C_OFF] + cells[q, C_N])
                ]
                before = counters[N_EVENTS]
                x = 0
                while True:
                    if gather[p]:
                        n_touched, x = _conv_gather(
                            p,
                            spikes,
                            x,
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
                        )
                    elif prj[p, J_KIND] == CONV:
                        n_touched, x = _conv(
                            p,
                            spikes,
                            x,
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
                        )
                    else:
                        n_touched, x = _resize(
                            p,
                            spikes,
                            x,
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
                        )
                    if x >= spikes.size:
                        break
                    # the touched list is full: deliver what it holds, then go on
                    n_new = _flush(
                        acc, touched, n_touched, off_t, col, n, t_t, state, inact, new, n_new, fresh, nrn, adv, counters
                    )
                    n_touched = 0
                prj_events[p] += counters[N_EVENTS] - before
            if n_touched:
                n_new = _flush(
                    acc, touched, n_touched, off_t, col, n, t_t, state, inact, new, n_new, fresh, nrn, adv, counters
                )
        for x in range(start, log_n):
            g = log[x]
            if ctype[g] < SOURCE_TYPE:
                state[g].v = nrn[ctype[g], V_RESET]
        n_act = _merge(act, n_act, new, n_new, tmp, radix)
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


def code_is_cached() -> bool:
    """Whether :func:`run_steps` is compiled already, in this process or in
    numba's cache, so that a first run can say it compiles first. Best
    effort (numba's cache object is not public API): ``True`` when it cannot
    tell."""
    if getattr(run_steps, "signatures", True):  # (compiled here, or not numba's function at all)
        return True
    try:
        return bool(run_steps._cache._cache_file._load_index())  # (empty when stale or flushed)
    except Exception:  # noqa: BLE001 - whatever numba's private cache does, we cannot tell
        return True


def _drop_stale_caches() -> None:
    """Forget compiled code cached from older versions of the engine's files.

    numba checks a cached function against the file that defines it, and no
    other. :func:`run_steps` compiles in the functions and constants of
    ``deliver.py`` and ``tables.py``, so after an edit there it kept
    running the old code. The caches of both modules' functions are therefore
    dropped whenever the three files change. Best effort: numba's cache
    object is not public API, and if it changes this check is skipped.
    """
    from . import deliver

    here = Path(__file__).parent
    digest = hashlib.sha256(
        b"".join((here / name).read_bytes() for name in ("core.py", "deliver.py", "tables.py"))
    ).hexdigest()
    try:
        stamp = Path(run_steps._cache._cache_path) / "snn_fg_fast_engine.sources"
        if stamp.exists() and stamp.read_text() == digest:
            return
        for f in [*vars(deliver).values(), *globals().values()]:
            if hasattr(f, "_cache") and hasattr(f._cache, "flush"):
                f._cache.flush()
        stamp.write_text(digest)
    except (AttributeError, OSError):
        pass


_drop_stale_caches()
