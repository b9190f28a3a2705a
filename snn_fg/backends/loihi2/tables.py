"""A network in Loihi 2's integers as the arrays the compiled loop reads,
and its input as cell numbers step by step.

The registers and synapses are those of the Lava export, made by the same
code: :mod:`snn_fg.lowering.loihi2` lowers the network, each projection's
weight-shared table (:mod:`snn_fg.lowering.kernel_tables`) is unrolled by
:func:`snn_fg.lava.synapses.connection` into its stored weights ``W = 2 m``,
its weight exponent and its delay. Here each connection's synapses are sorted by
source (a CSR table) and, where the exponent can be applied synapse by
synapse without changing a sum (:mod:`.kernel`), its weights come shifted.

Cells are numbered population after population, spike sources included,
in the network's order; every cell of the network exists in the arrays
(as on the chip, which holds the board network), and those a run leaves
out (the populations' site hints) are marked absent.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from ...lava import fixed
from ...lava.synapses import connection
from ...lowering.kernel_tables import ConvTable, geometry, table, table_fields
from ...lowering.loihi2 import lower
from ...network.graph import Network
from ..base import source_offsets
from . import rest as r


@dataclass(frozen=True)
class Loihi2Tables:
    """One network at one time step as the compiled loop's arrays.

    ``pops`` (a row per population, columns ``kernel.P_*``), ``conns`` (a
    row per connection with synapses, ``kernel.C_*``), ``ptr``/``post``/``w``
    (every connection's synapses by source: those of source cell ``s`` of
    connection row ``c`` are ``ptr[conns[c, C_PTR] + s]`` to ``[+ 1]``;
    ``post`` the target's cell number), ``depth`` (the slots of steps ahead
    a connection can reach, plus this step's), ``first`` (population name
    -> its first cell number), ``pop_of`` (each cell's row of ``pops``), ``unit_per_mv`` (population -> integer steps
    of its voltage per mV above its reset) and ``synapses`` per projection."""

    network: Network
    dt_ms: float
    pops: np.ndarray
    conns: np.ndarray
    ptr: np.ndarray
    post: np.ndarray
    w: np.ndarray
    depth: int
    first: dict
    pop_of: np.ndarray
    unit_per_mv: dict
    synapses: dict

    @property
    def n_cells(self) -> int:
        """Cells of every population, spike sources included."""
        return int(self.pops[:, r.P_SIZE].sum())


def _population_row(pop: dict, first: int) -> list[int]:
    """A population's row of ``pops`` from its ``network.json`` entry (its ``lava`` registers)."""
    row = [0] * r.N_POP_COLUMNS
    row[r.P_FIRST], row[r.P_SIZE] = first, int(pop["size"])
    lava = pop.get("lava")
    if lava is not None:
        row[r.P_LIF] = 1
        row[r.P_KU] = fixed.DECAY_UNITY - (int(lava["du"]) + fixed.DU_OFFSET)
        row[r.P_KV] = fixed.DECAY_UNITY - int(lava["dv"])
        row[r.P_BIAS] = fixed.effective_bias(lava["bias_mant"], lava["bias_exp"])
        row[r.P_VTH] = int(lava["vth"]) << fixed.VTH_SHIFT
        row[r.P_REFR] = int(lava["refractory_steps"])
        row[r.P_PILE] = r.pile_factor(row[r.P_KU], row[r.P_KV])
    return row


def linear(w2m: np.ndarray, weight_exp: int) -> bool:
    """Whether shifting each weight by ``weight_exp`` gives what shifting
    their sum gives, for every set of them: an exponent of 0 or more, or
    every weight a multiple of ``2**-weight_exp``."""
    return weight_exp >= 0 or not np.any(np.asarray(w2m) % (1 << -weight_exp))


def build_tables(network: Network, dt_ms: float) -> Loihi2Tables:
    """The arrays of ``network`` lowered to Loihi 2 at ``dt_ms`` as its Lava
    export holds it (a network Loihi 2's LIF cannot hold is refused with
    :class:`~snn_fg.errors.InputError`)."""
    net = dataclasses.replace(network, dt_ms=network.time_step(dt_ms, "Loihi2Backend"))
    try:
        low = lower(net)
    except ValueError as e:  # (the lowering's: a delay beyond 64 steps, no unit that fits 24 bits)
        raise InputError("the network", f"Loihi 2 cannot hold it: {e}") from None
    pops = [
        {"name": p.name, "size": p.size, **geometry(p), "lava": p.neuron and low.neurons[p.name].to_dict()}
        for p in net.populations
    ]
    return tables_from(network, dt_ms, {"populations": pops}, _connections(net, low, {p["name"]: p for p in pops}))


def _connections(net: Network, low, pops: dict):
    """Each projection's :class:`~snn_fg.lava.synapses.Connection`, made one at
    a time from its weight-shared table as the Lava export's ``run.py`` makes it."""
    for pr in net.projections:
        tab = table(net, pr)
        entry = {
            "name": pr.name,
            "source": pr.source,
            "target": pr.target,
            "sign": pr.sign,
            "gain_mv": pr.gain_mv,
            "lava": low.synapses[pr.name].to_dict(),
            **table_fields(tab),
        }
        yield connection(entry, pops, (tab.taps, tab.values) if isinstance(tab, ConvTable) else (tab.rows, tab.cols))


def tables_from(network: Network, dt_ms: float, meta: dict, conns) -> Loihi2Tables:
    """The arrays of an export's ``network.json`` data ``meta`` and its
    :class:`~snn_fg.lava.synapses.Connection` s ``conns`` (an iterable)."""
    first, rows, at = {}, [], 0
    for p in meta["populations"]:
        first[p["name"]] = at
        rows.append(_population_row(p, at))
        at += int(p["size"])
    sizes = {p["name"]: int(p["size"]) for p in meta["populations"]}
    names = list(first)
    table, ptrs, posts, ws, synapses = [], [], [], [], {}
    n_ptr = n_syn = 0
    depth = 1
    for c in conns:
        synapses[c.name] = int(c.pre.size)
        if not c.pre.size:
            continue
        order = np.argsort(c.pre * sizes[c.target] + c.post)  # (by source, then target)
        is_linear = linear(c.w2m, c.weight_exp)
        w = fixed.shift(c.w2m[order], c.weight_exp) if is_linear else c.w2m[order]
        ptrs.append(n_syn + np.searchsorted(c.pre[order], np.arange(sizes[c.source] + 1)))
        posts.append((first[c.target] + c.post[order]).astype(np.int32))
        ws.append(w.astype(np.int32))
        table.append([names.index(c.source), c.delay_steps, c.weight_exp, int(is_linear), n_ptr])
        n_ptr, n_syn = n_ptr + sizes[c.source] + 1, n_syn + int(c.pre.size)
        depth = max(depth, c.delay_steps + 2)
    pops = np.array(rows, np.int64).reshape(-1, r.N_POP_COLUMNS)
    return Loihi2Tables(
        network=network,
        dt_ms=float(dt_ms),
        pops=pops,
        conns=np.array(table, np.int64).reshape(-1, 5),
        ptr=np.concatenate(ptrs).astype(np.int64) if ptrs else np.zeros(1, np.int64),
        post=np.concatenate(posts) if posts else np.zeros(1, np.int32),
        w=np.concatenate(ws) if ws else np.zeros(1, np.int32),
        depth=depth,
        first=first,
        pop_of=np.repeat(np.arange(len(pops), dtype=np.int32), pops[:, r.P_SIZE]),
        unit_per_mv={p["name"]: p["lava"]["unit_per_mv"] for p in meta["populations"] if p.get("lava")},
        synapses=synapses,
    )


def input_cells(tab: Loihi2Tables, idx, steps, a: int, b: int) -> tuple[np.ndarray, np.ndarray]:
    """Input spikes ``(idx, steps)`` (the sources' numbering,
    :func:`~snn_fg.backends.base.source_offsets`) of steps ``a`` to ``b - 1``
    as ``(ptr, ids)``: the cell numbers of step ``n``'s spikes are
    ``ids[ptr[n - a]:ptr[n - a + 1]]``, sorted, each once (a source spikes
    at most once a step, as the export's input schedule has it)."""
    idx, steps = np.asarray(idx, np.int64), np.asarray(steps, np.int64)
    ids = np.full(idx.size, -1, np.int64)
    for name, start in source_offsets(tab.network).items():
        size = tab.network.population(name).size
        sel = (idx >= start) & (idx < start + size)
        ids[sel] = tab.first[name] + idx[sel] - start
    keep = (ids >= 0) & (steps >= a) & (steps < b)  # (clock spikes for a network without a clock go)
    key = np.unique((steps[keep] - a) * tab.n_cells + ids[keep])
    at, ids = np.divmod(key, tab.n_cells)
    return np.searchsorted(at, np.arange(b - a + 1)).astype(np.int64), ids.astype(np.int32)


class InputFeed:
    """A run's input as the loop reads it, a block of steps at a time: a
    whole :class:`~snn_fg.lowering.input_spikes.InputSpikes` (its periods
    repeated) as one block, a
    :class:`~snn_fg.lowering.input_stream.SegmentedInput` a segment at a time."""

    def __init__(self, tab: Loihi2Tables, inputs, n_steps: int):
        self.tab, self.inputs, self.n_steps = tab, inputs, n_steps
        self.segmented = hasattr(inputs, "segment")
        self.block_steps = int(inputs.segment_steps) if self.segmented else max(n_steps, 1)
        self.loaded, self.spikes = -1, 0

    def block(self, n: int) -> tuple[int, int, np.ndarray, np.ndarray]:
        """``(first step, end step, ptr, ids)`` of the block holding step ``n``."""
        j = n // self.block_steps
        if j != self.loaded:
            a, b = j * self.block_steps, min((j + 1) * self.block_steps, self.n_steps)
            if self.segmented:
                idx, steps = self.inputs.segment(j)
            else:
                idx, steps = self.inputs.spike_times_steps(self.n_steps)
            self.ptr, self.ids = input_cells(self.tab, idx, steps, a, b)
            self.spikes += int(self.ids.size)
            self.loaded, self.a, self.b = j, a, b
        return self.a, self.b, self.ptr, self.ids
