"""How the fast engine shares a step between threads: who owns each
population's cells.

A thread *owns* a cell when it adds the cell's summed input to it and
updates it while it is active (:mod:`~snn_fg.backends.fast.core`). Ownership is dealt per target
population, from a table (``owner``): a population owned whole by one
thread (``owner[q] >= 0``) is skipped by the others, projection by
projection, so that they walk neither its projections' spikes nor their
stencil rows; a *banded* population (``owner[q] == BANDED``) has its rows
dealt out in bands (rows ``r`` with ``(r >> BAND) % threads == t``, see
:mod:`.deliver`), every thread walking every spike of its projections and
skipping the others' rows. A cell's input is summed by one thread in the
order of the spikes whatever the table, so the spikes do not depend on it.

The table is dealt from the work the run has measured per population
(``work``, columns ``W_*``: synaptic events into it, spikes its projections
walked, cells handed input, active cell-steps), chunk by chunk of steps,
weighed by :data:`COST_NS`: whole populations, costliest first, each to the
thread that lengthens the run least (the threads meet at every step, so
what counts is each chunk's busiest thread), after banding none, one or two
of the costliest, whichever is shortest (:func:`deal`). A run starts with
every population banded (which needs no measurement) and is dealt again as
its measured work grows (:class:`Sharing`), the cells that change hands
moving between the threads' lists (:func:`move_cells`).
"""

from __future__ import annotations

import numpy as np

#: columns of the work measured per thread and population: synaptic events
#: into the population, spikes its projections walked (counted once however
#: many threads walk them), cells handed input, active cell-steps
W_EVENTS, W_SPIKES, W_FLUSHED, W_ACTIVE = range(4)
#: a population whose rows are dealt out in bands (and, while a table is dealt, one not dealt yet)
BANDED, UNDEALT = -1, -2
#: the most populations :func:`deal` bands (the costliest ones)
MAX_BANDED = 2
#: estimated nanoseconds of one unit of each column of ``work`` where its
#: owner does it, and ``SKIP_NS`` of a synaptic event for a thread that walks
#: a banded population's stencil row only to skip it. Rough costs on this
#: machine (a spike: finding its lattice point and stencil class; a cell
#: handed input: its state fetched and advanced): only their ratios matter
COST_NS = np.array([3.0, 20.0, 10.0, 8.0])
SKIP_NS = 1.0
#: a new table is taken when its predicted :func:`span` is shorter than the
#: current table's by this factor at least
BETTER = 0.95


def loads(owner: np.ndarray, work: np.ndarray, threads: int) -> np.ndarray:
    """Each thread's predicted cost (ns) of ``work`` (``(..., populations,
    W_*)``: e.g. one row per chunk of steps) under the table ``owner``
    (populations not yet dealt, :data:`UNDEALT`, left out), ``(..., threads)``."""
    whole = work @ COST_NS
    out = np.stack([whole[..., owner == t].sum(axis=-1) for t in range(threads)], axis=-1)
    band = work[..., owner == BANDED, :]
    # (every thread walks a banded population's spikes and stencil rows; the rest is shared out)
    walked = band[..., W_SPIKES] * COST_NS[W_SPIKES]
    shared = (walked + band[..., W_EVENTS] * SKIP_NS).sum(axis=-1) + (band @ COST_NS - walked).sum(axis=-1) / threads
    return out + shared[..., None]


def span(owner: np.ndarray, work: np.ndarray, threads: int) -> float:
    """The predicted time of ``work`` (one row per chunk of steps, as for
    :func:`loads`) under the table ``owner``: the threads meet at every step,
    so each chunk takes its busiest thread's time."""
    return float(loads(owner, work, threads).max(axis=-1).sum())


def deal(work: np.ndarray, threads: int) -> np.ndarray:
    """The table (one entry per population, :data:`BANDED` or a thread) that
    shares ``work`` (one row per chunk of steps, populations, ``W_*``)
    between ``threads`` threads: after banding the ``k`` costliest
    populations, each of the others, costliest first, to the thread that
    lengthens the :func:`span` least (a whole run's least loaded thread
    would leave the threads' shares apart from chunk to chunk), for the ``k``
    (up to :data:`MAX_BANDED`) with the shortest span. One thread: every
    population to thread 0."""
    n = work.shape[-2]
    if threads == 1:
        return np.zeros(n, np.int64)
    cost = work @ COST_NS  # (chunks, populations)
    order = np.argsort(-cost.sum(axis=0), kind="stable")
    best, best_span = None, np.inf
    for k in range(min(n, MAX_BANDED) + 1):
        owner = np.full(n, UNDEALT, np.int64)
        owner[order[:k]] = BANDED
        held = loads(owner, work, threads)
        for q in order[k:]:
            spans = []
            for t in range(threads):
                held[:, t] += cost[:, q]
                spans.append(held.max(axis=1).sum())
                held[:, t] -= cost[:, q]
            t = int(np.argmin(spans))
            owner[q] = t
            held[:, t] += cost[:, q]
        total = held.max(axis=1).sum()
        if total < best_span:
            best, best_span = owner, total
    return best


def band_thread(rows, threads: int):
    """The thread whose band holds each of ``rows`` (``channel * rows + row`` of a
    banded population): bands of ``2**BAND`` rows dealt out in turn, as
    :func:`.deliver.foreign` deals them inside the compiled loop."""
    from .deliver import BAND

    return (rows >> BAND) % threads


def cell_owners(g: np.ndarray, owner: np.ndarray, cells: np.ndarray, flat_of: np.ndarray, pops, threads: int):
    """The thread that owns each cell of numbers ``g`` under the table
    ``owner`` (``cells``, ``flat_of``: the run's numbering, :mod:`~snn_fg.backends.fast.core`;
    ``pops``: the tables' population array)."""
    from .deliver import C_FLAT, C_N, C_OFF, C_WHOLE
    from .tables import P_GC

    q = np.searchsorted(cells[:, C_OFF] + cells[:, C_N], g, side="right")
    local = g - cells[q, C_OFF]
    flat = np.where(cells[q, C_WHOLE] == 1, local, flat_of[np.clip(cells[q, C_FLAT] + local, 0, flat_of.size - 1)])
    return np.where(owner[q] >= 0, owner[q], band_thread(flat // pops[q, P_GC], threads))


def band_cells(populations, chosen: dict, threads: int) -> np.ndarray:
    """How many of each population's chosen cells (``chosen``: population
    name -> flat indices; ``populations``: the network's, in order) are in
    each thread's bands, one row per population."""
    out = np.zeros((len(populations), threads), np.int64)
    for q, p in enumerate(populations):
        if not p.is_source:
            rows = chosen[p.name] // p.grid[1]  # (channel * rows + row)
            out[q] = np.bincount(band_thread(rows, threads), minlength=threads)
    return out


class Sharing:
    """The table of a run on ``threads`` threads (:attr:`owner`, every
    population banded at first), the work the threads measure in it
    (:attr:`work`, one ``(populations, W_*)`` block per thread; and
    :attr:`chunk_work`, summed over the threads, one block per call of the
    compiled loop), and the deals as that work grows: after the 1st, 2nd,
    4th, 8th ... call (:meth:`chunk_done`)."""

    def __init__(self, populations, chosen: dict, threads: int):
        n = len(populations)
        self.threads, self.chunks, self.next_deal, self.deals = threads, 0, 1, 0
        self.owner = np.full(n, BANDED if threads > 1 else 0, np.int64)
        self.work = np.zeros((threads, n, 4), np.int64)
        self.chunk_work, self.counted = [], np.zeros((n, 4), np.int64)  # (the work of each chunk, and the sum)
        self.bands = band_cells(populations, chosen, threads)

    def owned_cells(self, owner: np.ndarray | None = None) -> np.ndarray:
        """How many cells each thread owns under ``owner`` (default: the current table)."""
        owner = self.owner if owner is None else owner
        out = self.bands[owner == BANDED].sum(axis=0)
        np.add.at(out, owner[owner >= 0], self.bands[owner >= 0].sum(axis=1))
        return out

    def chunk_done(self, run) -> None:
        """A call of the compiled loop is done: on a deal's turn, deal the
        table again from the work measured so far and, when its predicted
        :func:`span` is the current table's times :data:`BETTER` or less,
        take it and move the cells that change hands (:func:`move_cells`)."""
        self.chunks += 1
        if self.threads == 1:
            return
        total = self.work.sum(axis=0)
        self.chunk_work.append(total - self.counted)
        self.counted = total
        if self.chunks < self.next_deal:
            return
        self.next_deal *= 2
        work = np.array(self.chunk_work)
        owner = deal(work, self.threads)
        if span(owner, work, self.threads) < BETTER * span(self.owner, work, self.threads):
            move_cells(run, owner, int(self.owned_cells(owner).max()) + 1)
            self.owner[:] = owner
            self.deals += 1


def move_cells(run, owner: np.ndarray, cap: int) -> None:
    """Hand each of ``run``'s active cells (:class:`.run.Run`, between two
    calls of the compiled loop) and the cells it lists as touched to the
    thread that owns it under ``owner``, in the threads' lists (room for
    ``cap`` cells each, reallocated when they hold fewer)."""
    from .deliver import N_FRESH

    threads = run.threads
    act = np.concatenate([run.act[t, : run.scalars[t]] for t in range(threads)])
    fresh = np.concatenate([run.fresh[t, : run.counters[t, N_FRESH]] for t in range(threads)])
    if cap > run.act.shape[1]:  # (the lists' contents are copied out above)
        run.act, run.new, run.tmp, run.fresh = (
            run.pool.zeros(name, threads * cap, np.int32).reshape(threads, cap)
            for name in ("act", "new", "tmp", "fresh")
        )
    of_act = cell_owners(act, owner, run.cells, run.flat_of, run.tab.pops, threads)
    of_fresh = cell_owners(fresh, owner, run.cells, run.flat_of, run.tab.pops, threads)
    for t in range(threads):
        mine = np.sort(act[of_act == t])
        run.act[t, : mine.size] = mine
        run.scalars[t] = mine.size
        mine = fresh[of_fresh == t]
        run.fresh[t, : mine.size] = mine
        run.counters[t, N_FRESH] = mine.size
