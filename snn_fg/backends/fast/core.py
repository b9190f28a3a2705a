"""The fast engine's step loop, compiled by numba.

One call of :func:`run_steps` advances the simulation over a range of time
steps. Each step follows Brian2's schedule as our Brian2 backend uses it
(``groups``, ``thresholds``, ``synapses``, ``resets``):

1. every *active* cell is updated exactly like Brian2's ``lif_step``
   (the exact propagators: ``v += (1 - d_m) (v_rest - v) + p_exc I_exc -
   p_inh I_inh`` unless refractory, then both currents decay) and spikes if ``v > v_th`` and it is not
   refractory; the input spikes of the step join them;
2. each projection takes the spikes its source emitted ``delay`` steps ago
   and sends each one through its stencil (Conv) or interpolation weights
   (Resize) into its target's summed input, which is then added to the
   cells it reached (:mod:`.deliver`);
3. cells that spiked are reset.

An active cell that can no longer reach threshold without new input is
*parked* (at the start of the next step): it is not touched until input
reaches it, and is then brought up to date in closed form (the update is
linear between spikes, see :func:`snn_fg.backends.fast.neurons.advance_tables`).
Parking is safe because, with no input, the potential stays under a bound
computed from the current state (:func:`.lif.safe`).

Cells are numbered compactly, population after population, only those
instantiated (``cells[q]``: first number ``C_OFF`` and count ``C_N`` of
population ``q``; ``pres`` from word ``C_PRES`` holds its presence bits,
one 64-bit word per 64 columns of each row of each channel, and ``rank``
the number of cells that exist before each word, so that a grid cell's
number is a ``popcount`` away; for a population with cells left out,
``flat_of[C_FLAT + local]`` gives the grid cell of a number). The active
cells are kept sorted by number, so that the per-step pass over them walks
memory in one direction.
State per cell (:data:`.lif.STATE`): ``v``, ``e`` (``I_exc``), ``i``
(``I_inh``) in volts, ``last`` (the step the values belong to, plus one; 0:
never touched, i.e. at rest) and ``spike`` (the step of the last spike, plus
one, 0 for none, in its low 31 bits; its sign bit set while the cell is
active).
"""

from __future__ import annotations

import sys
from collections import namedtuple

import numpy as np
from numba import njit, prange

from . import compiled, counting, deliver, handover, lif, lists
from .deliver import (
    C_N,
    C_OFF,
    N_ACTIVE_STEPS,
    N_EVENTS,
    N_FLUSHED,
    PH_ACTIVE,
    PH_CONV,
    PH_GATHER,
    PH_HANDOVER,
    PH_MERGE,
    PH_RESIZE,
    conv_spikes,
    resize_spikes,
)
from .handover import flush_rows
from .lif import ACTIVE, PHASES, SPIKE_STEP, U, advanced, borrowed, cycles, prefetch, safe
from .lists import gather_spikes, merge
from .neurons import DE, DI, DM, GAP, PE, PEAK, PI, SOURCE_TYPE, TIGHT, V_RESET, V_REST, V_TH
from .share import W_ACTIVE, W_EVENTS, W_FLUSHED, W_SPIKES
from .tables import CONV, J_COL, J_DELAY, J_KIND, J_SRC, J_TGT, P_TYPE

#: the arrays :func:`run_steps` changes that all threads share: cell state,
#: ``scalars`` (each thread's active cells, the log's length, and each
#: thread's spikes of the step, from the end), spike log (``log``,
#: ``step_start``), the input spikes (``in_ptr``, ``in_ids``) and the
#: scratch of a step's spikes
RunArrays = namedtuple("RunArrays", "state scalars log step_start in_ptr in_ids spike_tmp")
#: each thread's own arrays, one row per thread: its active cells (sorted),
#: those newly active, merge scratch, the cells it touched first (``fresh``),
#: counters, events per projection, the summed input of the group it is
#: at (threads move through the groups at their own pace), which cells
#: received it (``bits``; whether each row did, ``listed``;
#: the rows, ``dirty``, ``n_dirty``), hand-over batches (``found``, ``found_g``),
#: the work it did per population (``work``, columns :data:`.share.W_EVENTS` ...)
#: and the table of who owns each population (``owner``, shared, :mod:`.share`)
ThreadArrays = namedtuple(
    "ThreadArrays",
    "act new tmp radix fresh counters prj_events acc bits listed dirty n_dirty found found_g work owner",
)
#: how one run numbers its cells (module docstring): the neuron type of each
#: cell, the per-population table ``cells`` (columns ``C_*``) and the maps
#: between grid and number
CellNumbering = namedtuple("CellNumbering", "ctype cells flat_of pres rank")
#: the network at one time step (:class:`~snn_fg.backends.fast.tables.EngineTables`)
KernelTables = namedtuple(
    "KernelTables",
    "pops nrn ref_steps adv_k prj prj_w cls_ptr row_tab st_w csr_ptr csr_idx csr_val grp_ptr grp_prj",
)
#: how many cells ahead of the one being updated the active-cell pass asks
#: for a cell's state: a cell's 32 bytes are rarely in cache (24: side by
#: side with 12 in 6 rounds of two windows, 0.82-0.99 of its time; 6 was
#: slower, 32 and 48 about the same)
AHEAD = 24


@njit(cache=True)
def _step_active(n, act, n_act, state, pops, cells, nrn, ref, log, log_n, work):
    """Brian2's ``groups`` and ``thresholds`` slots for the active cells
    (sorted by number, hence walked population by population), parking
    those that cannot fire, counted per population in ``work``. Returns
    ``(active cells, log length)``."""
    kept = 0
    q = 0
    end = cells[0, C_OFF] + cells[0, C_N]
    t = pops[0, P_TYPE]
    # (the population's neuron type's row and refractory steps, taken when the population changes:
    # indexing them by t in every cell's update cost a sign fix-up and a product each time; a
    # spike source, without a row, has no active cell)
    t0 = t if t < nrn.shape[0] else 0
    nt, ref_t = nrn[t0], ref[t0]
    since = 0
    for a in range(n_act):
        if a + AHEAD < n_act:
            prefetch(state, U(act[U(a + AHEAD)]))
        g = act[U(a)]
        if g >= end:
            work[q, W_ACTIVE] += a - since
            since = a
            while g >= end:
                q += 1
                end = cells[q, C_OFF] + cells[q, C_N]
            t = pops[q, P_TYPE]
            nt, ref_t = nrn[t], ref[t]
        r = state[U(g)]
        spike = r.spike & SPIKE_STEP
        ready = spike == 0 or n - (spike - 1) >= ref_t
        if ready and safe(r.v, r.e, r.i, nt[V_REST], nt[TIGHT] > 0, nt[PEAK], nt[GAP]):
            r.spike = spike  # (parked: no longer active)
            continue
        v, e, i = r.v, r.e, r.i
        if ready:  # (Brian2's generated expression, operation for operation)
            v += ((e * nt[PE]) + ((1.0 - nt[DM]) * ((-v) + nt[V_REST]))) - (i * nt[PI])
        r.v = v
        r.e = e * nt[DE]
        r.i = i * nt[DI]
        r.last = n + 1
        if ready and v > nt[V_TH]:
            log[U(log_n)] = g
            log_n += 1
            r.spike = (n + 1) | ACTIVE
        act[U(kept)] = g
        kept += 1
    work[q, W_ACTIVE] += n_act - since
    return kept, log_n


@njit(cache=True)
def _active_part(t, n, run, th, numbering, tables, first):
    """Thread ``t``'s share of step ``n``'s ``groups``, ``thresholds`` and
    ``resets`` slots: its active cells updated, its spikes written from
    ``log[first]`` on and their potentials reset (the reset may come before
    the step's deliveries: they change the currents of a cell that spiked,
    which is active, not its potential)."""
    nrn, ctype = tables.nrn, numbering.ctype
    n_act = run.scalars[t]
    th.counters[t, N_ACTIVE_STEPS] += n_act
    c0 = cycles() if PHASES else 0
    kept, end = _step_active(
        n, th.act[t], n_act, run.state, tables.pops, numbering.cells, nrn, tables.ref_steps, run.log, first, th.work[t]
    )
    for x in range(first, end):
        g = run.log[x]
        run.state[g].v = nrn[ctype[g], V_RESET]
    run.scalars[t] = kept
    run.scalars[run.scalars.size - 1 - t] = end - first
    if PHASES:
        th.counters[t, PH_ACTIVE] += cycles() - c0


@njit(cache=True)
def _deliver_part(t, n_parts, n, run, th, numbering, tables):
    """Thread ``t``'s share of step ``n``'s ``synapses`` slot (the
    populations it owns and its rows of the banded ones, :mod:`.share`),
    group by group of projections sharing a target population and current:
    their input summed per target cell, then added to each cell once; the
    cells that may now fire join its active list."""
    log, step_start, cells, prj = run.log, run.step_start, numbering.cells, tables.prj
    grp_ptr, grp_prj, counters = tables.grp_ptr, tables.grp_prj, th.counters[t]
    stencil = (tables.cls_ptr, tables.row_tab, tables.st_w)
    factors = (tables.csr_ptr, tables.csr_idx, tables.csr_val)
    marks = (th.listed[t], th.dirty[t], th.n_dirty[t, :1], th.bits[t], th.found[t], th.found_g[t])
    acc, work = th.acc[t], th.work[t]
    n_new = 0
    for grp in range(grp_ptr.size - 1):
        qt = prj[grp_prj[grp_ptr[grp]], J_TGT]
        holder = th.owner[qt]
        if holder >= 0 and holder != t:  # (another thread's population)
            continue
        parts = n_parts if holder < 0 else 1  # (with one part, conv_spikes and resize_spikes take every row)
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
            if spikes.size == 0:
                continue
            work[qt, W_SPIKES] += spikes.size if parts == 1 or t == 0 else 0  # (counted once)
            c0 = cycles() if PHASES else 0
            if prj[p, J_KIND] == CONV:
                ev = conv_spikes(
                    p, spikes, tables.pops, cells, numbering.flat_of, numbering.pres, prj, stencil, acc, marks, t,
                    parts,
                )  # fmt: skip
            else:
                ev = resize_spikes(
                    p, spikes, tables.pops, cells, numbering.flat_of, numbering.pres, prj, tables.prj_w, factors, acc,
                    marks, t, parts,
                )  # fmt: skip
            if PHASES:
                counters[PH_CONV if prj[p, J_KIND] == CONV else PH_RESIZE] += cycles() - c0
            th.prj_events[t, p] += ev
            work[qt, W_EVENTS] += ev
            counters[N_EVENTS] += ev
        if th.n_dirty[t, 0]:
            p = grp_prj[grp_ptr[grp]]
            flushed = counters[N_FLUSHED]
            c0 = cycles() if PHASES else 0
            n_new = flush_rows(
                qt, prj[p, J_COL], n, tables.pops, cells, numbering.pres, numbering.rank, acc, marks,
                run.state, th.new[t], n_new, th.fresh[t], tables.nrn, tables.adv_k, counters,
            )  # fmt: skip
            work[qt, W_FLUSHED] += counters[N_FLUSHED] - flushed
            if PHASES:
                counters[PH_HANDOVER] += cycles() - c0
    c0 = cycles() if PHASES else 0
    run.scalars[t] = merge(th.act[t], run.scalars[t], th.new[t], n_new, th.tmp[t], th.radix[t], run.state.size)
    if PHASES:
        counters[PH_MERGE] += cycles() - c0


@njit(cache=True, nogil=True)
def run_steps(n0, n1, run, th, numbering, tables):
    """Simulate steps ``n0 .. n1-1``; returns the step reached (less than
    ``n1`` when the spike log is too small for the next step: grow it and
    call again from there). ``run`` (:class:`RunArrays`), ``th``
    (:class:`ThreadArrays`), ``numbering`` (:class:`CellNumbering`) and
    ``tables`` (:class:`KernelTables`) hold the arrays.

    With more than one row in ``th``, each step runs its two parts on that
    many threads: every thread's active cells (their spikes are then merged
    into the log, ascending, with the step's input spikes) and the target
    populations it owns, or its rows of a banded one (``th.owner``,
    :mod:`.share`). One thread adds a cell's input, in the order of the
    spikes, so it is summed in the same order whatever the number of
    threads and the table.

    It runs without Python's interpreter lock, so that the process's other
    threads (a recording's decoding and writing thread, a live stream's
    receiver) run beside it, not between its calls."""
    run, th, numbering, tables = _borrow(run, th, numbering, tables)
    return _steps(n0, n1, run, th, numbering, tables)


@njit(cache=True, parallel=True)
def _steps(n0, n1, run, th, numbering, tables):
    """:func:`run_steps` on arrays that count no references."""
    n_parts = th.act.shape[0]
    log, step_start, in_ptr, in_ids, scalars = run.log, run.step_start, run.in_ptr, run.in_ids, run.scalars
    # with every delay at least one step, a step's deliveries read only earlier steps' spikes:
    # each thread then runs both parts of a step in one go (one meeting of the threads a step)
    fused = tables.prj.shape[0] == 0 or tables.prj[:, J_DELAY].min() >= 1
    firsts = np.zeros(n_parts, np.int64)
    counts = np.zeros(n_parts, np.int64)
    for n in range(n0, n1):
        s = n % (in_ptr.size - 1)  # input spikes repeat with the period of in_ptr (if shorter than the run)
        log_n = scalars[n_parts]
        firsts[0] = log_n
        for t in range(1, n_parts):
            firsts[t] = firsts[t - 1] + scalars[t - 1]
        if firsts[n_parts - 1] + scalars[n_parts - 1] + (in_ptr[s + 1] - in_ptr[s]) > log.size:
            return n
        if n_parts == 1:
            _active_part(0, n, run, th, numbering, tables, log_n)
            if fused:
                _deliver_part(0, 1, n, run, th, numbering, tables)
        else:
            for t in prange(n_parts):
                _active_part(t, n, run, th, numbering, tables, firsts[t])
                if fused:
                    _deliver_part(t, n_parts, n, run, th, numbering, tables)
        for t in range(n_parts):
            counts[t] = scalars[scalars.size - 1 - t]
        c0 = cycles() if PHASES else 0
        log_n = gather_spikes(log, log_n, firsts, counts, in_ids[in_ptr[s] : in_ptr[s + 1]], run.spike_tmp)
        if PHASES:
            th.counters[0, PH_GATHER] += cycles() - c0
        scalars[n_parts] = log_n
        step_start[n + 1] = log_n
        if fused:
            continue
        if n_parts == 1:
            _deliver_part(0, 1, n, run, th, numbering, tables)
        else:
            for t in prange(n_parts):
                _deliver_part(t, n_parts, n, run, th, numbering, tables)
    return n1


@njit(cache=True)
def _borrow(run, th, numbering, tables):
    """The arrays as views that count no references (:func:`.lif.borrowed`):
    the loops pass them to a function per projection and step."""
    b = borrowed
    return (
        RunArrays(
            b(run.state), b(run.scalars), b(run.log), b(run.step_start), b(run.in_ptr), b(run.in_ids),
            b(run.spike_tmp),
        ),
        ThreadArrays(
            b(th.act), b(th.new), b(th.tmp), b(th.radix), b(th.fresh), b(th.counters), b(th.prj_events), b(th.acc),
            b(th.bits), b(th.listed), b(th.dirty), b(th.n_dirty), b(th.found), b(th.found_g), b(th.work),
            b(th.owner),
        ),
        CellNumbering(
            b(numbering.ctype), b(numbering.cells), b(numbering.flat_of), b(numbering.pres), b(numbering.rank)
        ),
        KernelTables(
            b(tables.pops), b(tables.nrn), b(tables.ref_steps), b(tables.adv_k), b(tables.prj), b(tables.prj_w),
            b(tables.cls_ptr), b(tables.row_tab), b(tables.st_w),
            b(tables.csr_ptr), b(tables.csr_idx), b(tables.csr_val), b(tables.grp_ptr), b(tables.grp_prj),
        ),
    )  # fmt: skip


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
            out[g, 0], out[g, 1], out[g, 2] = advanced(r.v, r.e, r.i, nrn[t, V_REST], adv[t], n_steps - r.last)
        else:
            out[g, 0], out[g, 1], out[g, 2] = r.v, r.e, r.i


@njit(cache=True)
def reset(state, fresh, n_fresh):
    """Put back at rest the cells a run touched (each thread's ``fresh``
    cells, ``n_fresh`` of them), so that the arrays serve the next run
    without being allocated (and their memory faulted in) again."""
    for t in range(fresh.shape[0]):
        for x in range(n_fresh[t]):
            r = state[U(fresh[t, x])]
            r.v, r.e, r.i, r.last, r.spike = 0.0, 0.0, 0.0, 0, 0


def code_is_cached() -> bool:
    """Whether :func:`run_steps` is compiled already (:func:`.compiled.code_is_cached`)."""
    return compiled.code_is_cached(run_steps)


compiled.drop_stale_caches(
    run_steps, (lif, deliver, handover, counting, lists, sys.modules[__name__]), b"phases" if PHASES else b""
)
