"""Unroll a network description into explicit cells and synapses for one input.

The description keeps kernels weight-shared on whole pyramid grids; a
simulator that needs explicit synapses (Brian2, NEST) gets them from here. At
321 x 481 over 10 levels the whole network has more than 1e9 synapses, so by
default only the cells the input can use are created (:mod:`.sites`); with
``instantiate="all"`` every cell is, and the spikes must be the same (the
tests check it at small size).

Everything here is numpy; nothing depends on a simulator, so the unrolled
graph can be checked against the rate model's own convolutions.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import validate as check
from ..network.graph import Network
from ..network.projections import Projection
from .connect import pairs
from .sites import all_sites, edge_sites, input_edges, masked_edge_maps, resolve_sites

INSTANTIATE = ("input", "all")


@dataclass
class Connections:
    """Explicit synapses of one projection: local cell indices and weights (mV)."""

    projection: Projection
    pre: np.ndarray  # index into the source's sites
    post: np.ndarray  # index into the target's sites
    w: np.ndarray  # float64, signed weight in mV
    kept_mass: float  # kept fraction of sum |K| after pruning (1.0 if none)
    taps: int  # kernel taps (Conv) or interpolation weights (Resize) kept
    n: int = field(init=False)  # synapses; survives free()

    def __post_init__(self):
        self.n = int(self.pre.size)

    def free(self):
        """Drop the synapse arrays (a simulator holds its own copy); ``n`` stays."""
        self.pre, self.post, self.w = self.pre[:0], self.post[:0], self.w[:0]


@dataclass
class Unrolled:
    """Cells and synapses of a network for one input."""

    network: Network
    sites: dict  # population -> sorted flat indices into its shape
    connections: list  # Connections, in network.projections order
    active: dict = field(default_factory=dict)  # spike source -> bool (rows, cols): pixels with input
    edges: dict = field(default_factory=dict)  # level -> edge map of the 'edges' hint

    def n_cells(self, name: str) -> int:
        return int(self.sites[name].size)

    def synapses_in(self) -> dict:
        """Synapses per target population."""
        syn = {p.name: 0 for p in self.network.populations}
        for c in self.connections:
            syn[c.projection.target] += c.n
        return syn

    def kept_mass(self) -> dict:
        """Kept fraction of each projection's kernel mass after pruning."""
        return {c.projection.name: round(c.kept_mass, 4) for c in self.connections}

    def table(self) -> str:
        """Cells and synapses per population, as aligned text."""
        syn = self.synapses_in()
        rows = [f"{'population':14s} {'role':12s} {'lvl':>3s} {'cells':>10s} {'full grid':>10s} {'synapses in':>12s}"]
        for p in self.network.populations:
            rows.append(
                f"{p.name:14s} {p.role:12s} {p.level:3d} {self.n_cells(p.name):10d} {p.size:10d} {syn[p.name]:12d}"
            )
        rows.append(
            f"{'total':14s} {'':12s} {'':3s} {sum(map(self.n_cells, self.sites)):10d} "
            f"{sum(p.size for p in self.network.populations):10d} {sum(syn.values()):12d}"
        )
        return "\n".join(rows)


def _source_masks(network: Network, active: dict) -> dict:
    """Spike-source name -> bool (rows, cols) mask, checked against its grid (the window clock's one cell added)."""
    act = {}
    for p in network.sources:
        if p.role == "clock" and p.name not in active:
            active = {**active, p.name: np.ones(p.grid, bool)}  # one cell, always there
        if p.name not in active:
            check.fail(f"Population '{p.name}'", None, None, "no input mask given for this spike source")
        a = np.asarray(active[p.name], dtype=bool)
        if a.shape != p.grid:
            check.fail(f"Population '{p.name}'", "input mask shape", a.shape, f"differs from its grid {p.grid}")
        act[p.name] = a
    return act


def choose_sites(
    network: Network, active: dict, sites: dict | None = None, instantiate: str = "input", fired: dict | None = None
):
    """The cells of every population a simulator instantiates for one input.

    Parameters are those of :func:`unroll`. Returns ``(chosen, masks, edge_maps)``:
    population -> sorted flat indices, spike source -> bool (rows, cols) mask of
    pixels with input (``fired``'s where given), level -> edge map. Shared by
    every backend that honours the instantiation hints (an unrolling one, or an
    event-driven engine that marks the cells it leaves out).
    """
    check.choice("unroll", "instantiate", instantiate, INSTANTIATE)
    act, edges1 = _source_masks(network, active), None
    if fired is not None:  # (the edge masks are made from active, the cells chosen for fired)
        edges1, act = input_edges(network, act), _source_masks(network, fired)
    fixed = {}
    for name, idx in (sites or {}).items():
        pop = network.population(name)
        if pop.is_source:
            continue  # a spike source keeps every pixel
        idx = np.unique(np.asarray(idx, dtype=np.int64))
        if idx.size and (idx[0] < 0 or idx[-1] >= pop.size):
            check.fail(f"Population '{name}'", None, None, f"fixed site index outside its {pop.size} cells")
        fixed[name] = idx
    flat = {k: v.ravel() for k, v in act.items()}
    if instantiate == "all":
        emaps = masked_edge_maps(network, act, edges1)
        whole = {
            p.name: edge_sites(p, emaps[p.level], network.support_min) if p.edge_mask else all_sites(p)
            for p in network.populations
            if not p.is_source
        }
        fixed = whole | fixed
    chosen, emaps = resolve_sites(network, flat, fixed, edges1)
    return chosen, act, emaps


def unroll(
    network: Network,
    active: dict,
    progress=None,
    sites: dict | None = None,
    instantiate: str = "input",
    fired: dict | None = None,
) -> Unrolled:
    """Instantiate the cells and synapses of ``network`` for one input.

    Parameters
    ----------
    network : Network
        The description.
    active : dict
        Spike-source population name -> bool (rows, cols) mask of the pixels
        that receive input spikes (their union is the level-1 edge map).
    progress : callable, optional
        Wraps the iteration over projections (e.g. a tqdm factory).
    sites : dict, optional
        Fixed cells (flat indices) for some populations, overriding their
        hints: for hand-built circuits.
    instantiate : {"input", "all"}
        ``input``: only the cells this input can use; ``all``: every cell
        (of an ``edge_mask`` population, every cell inside the mask).
    fired : dict, optional
        Spike-source name -> bool (rows, cols) mask of the pixels whose
        sources fire, where ``active`` marks more (every source of a stream,
        whose network was laid out before its events: the ``fired`` of
        :class:`~snn_fg.lowering.input_spikes.InputSpikes`):
        the cells are chosen for these, the edge masks made from ``active``
        (:func:`~snn_fg.lowering.sites.masked_edge_maps`).
    """
    chosen, act, emaps = choose_sites(network, active, sites, instantiate, fired)
    flat = {k: v.ravel() for k, v in act.items()}
    conns = []
    items = network.projections if progress is None else progress(network.projections)
    for pr in items:
        src, tgt = network.population(pr.source), network.population(pr.target)
        pre, post, k, kept, taps = pairs(network, pr, src, tgt, chosen[src.name], chosen[tgt.name], flat.get(src.name))
        conns.append(Connections(pr, pre.astype(np.int32), post.astype(np.int32), pr.sign * pr.gain_mv * k, kept, taps))
    return Unrolled(network, chosen, conns, act, emaps)


def dense_drive(un: Unrolled, conn: Connections, src_values: np.ndarray) -> np.ndarray:
    """Apply one projection to per-cell source values; returns per-target-cell sums.

    ``src_values`` is indexed like the source's sites. Useful to check an
    unrolled projection against the rate model's convolution.
    """
    out = np.zeros(un.n_cells(conn.projection.target))
    np.add.at(out, conn.post, conn.w * src_values[conn.pre])
    return out


def to_grid(un: Unrolled, name: str, values: np.ndarray) -> np.ndarray:
    """Scatter per-cell values of population ``name`` onto its full (channels, rows, cols) grid."""
    pop = un.network.population(name)
    out = np.zeros(pop.size)
    out[un.sites[name]] = values
    return out.reshape(pop.shape)
