"""Which cells of each population one input can use.

A backend that unrolls the network for one input instantiates only these
cells (an optimisation: the description itself is input-independent). Each
population's hint (:data:`~snn_fg.network.nodes.SITE_RULES`) is resolved in
dependency order:

* ``all``: every cell (spike sources keep every pixel; only pixels with
  input get outgoing synapses);
* ``edges``: the model's own edge mask of stage 4 (level 1: event pixels;
  coarser levels: the bicubic-resized edge map >= ``support_min``);
* ``edges&drive``: the ``edges`` cells whose excitation, with every source at
  its nominal rate, holds the membrane at least ``drive_min`` of the way from
  reset to threshold (inhibition only lowers it, so with ``drive_min`` below
  1 a cell left out is kept away from threshold with a margin);
* ``reachable``: cells with an excitatory connection from an instantiated
  cell that can fire;
* ``needed``: cells with a connection onto an instantiated cell.
"""

from __future__ import annotations

import numpy as np

from .. import validate as check
from ..frames.pyramid import level_shape, resize
from ..network.graph import Network
from ..network.nodes import Population
from .connect import pairs


def all_sites(pop: Population) -> np.ndarray:
    return np.arange(pop.size, dtype=np.int64)


def edge_maps(network: Network, edges1: np.ndarray) -> dict:
    """Edge map of every level: the level-1 map resized bicubically (stage 2)."""
    levels = sorted({p.level for p in network.populations})
    per_octave = network.params.levels_per_octave
    return {
        lv: edges1 if lv == 1 else resize(edges1, level_shape(network.frame_shape, lv, per_octave), "cubic")
        for lv in levels
    }


def masked_edge_maps(network: Network, active: dict, edges1=None) -> dict:
    """Edge map of every level for one input (``active``, as :func:`input_edges`
    takes it): resized from ``edges1``, the level-1 map the populations' edge
    masks are made from (None: the pixels with input), and at level 1 kept to
    the pixels with input, where alone its gated cells can fire (``docs/model.md``)."""
    given = input_edges(network, active)
    if edges1 is None:
        return edge_maps(network, given)
    emaps = edge_maps(network, np.asarray(edges1, float).reshape(network.frame_shape))
    emaps[1] = np.minimum(emaps[1], given)
    return emaps


def input_edges(network: Network, active: dict) -> np.ndarray:
    """The level-1 edge map: pixels where either input polarity (``active``:
    source name -> bool mask, flat or 2-D) has events. The window clock is
    no pixel and takes no part."""
    edges1 = np.zeros(network.frame_shape)
    for role in ("input_on", "input_off"):
        a = active[network.one(role, 1).name]
        edges1 = np.maximum(edges1, np.asarray(a).reshape(network.frame_shape).astype(float))
    return edges1


def edge_sites(pop: Population, emap: np.ndarray, support_min: float) -> np.ndarray:
    e = emap[:: pop.stride, :: pop.stride]
    mask = e > 0 if pop.level == 1 else e >= support_min
    where = np.flatnonzero(mask.ravel())
    return (np.arange(pop.channels)[:, None] * e.size + where[None]).ravel()


def _counts_for(pop: Population, proj) -> bool:
    """Whether ``proj`` counts for ``pop``'s reachable/drive hint."""
    if proj.source == pop.name or proj.target != pop.name:
        return False
    return not pop.site_sources or proj.source in pop.site_sources


class _Resolver:
    def __init__(self, network: Network, active: dict, fixed: dict, edges1=None):
        self.net = network
        self.active = active  # source name -> bool over its pixels (flat)
        self.sites = {p.name: all_sites(p) for p in network.sources}
        self.sites.update(fixed)
        self.rates = {name: network.input_rate_hz * a for name, a in active.items()}
        self.emaps = masked_edge_maps(network, active, edges1)

    def pairs(self, proj, src_sites=None, tgt_sites=None):
        src, tgt = self.net.population(proj.source), self.net.population(proj.target)
        return pairs(
            self.net,
            proj,
            src,
            tgt,
            self.sites[src.name] if src_sites is None else src_sites,
            self.sites[tgt.name] if tgt_sites is None else tgt_sites,
            self.active.get(src.name),
        )

    def ready(self, pop: Population, incoming, outgoing) -> bool:
        if pop.sites in ("reachable", "edges&drive"):
            return all(pr.source in self.sites for pr in incoming)
        if pop.sites == "needed":
            return all(pr.target in self.sites for pr in outgoing)
        return True

    def resolve(self, pop: Population, incoming, outgoing) -> np.ndarray:
        rule = pop.sites
        if rule == "all":
            return all_sites(pop)
        if rule == "edges":
            return edge_sites(pop, self.emaps[pop.level], self.net.support_min)
        if rule == "reachable":
            full = all_sites(pop)
            got = [
                full[post[pr.sign * k > 0]]
                for pr in incoming
                for pre, post, k, _, _ in [self.pairs(pr, tgt_sites=full)]
            ]
            return np.unique(np.concatenate([np.zeros(0, np.int64)] + got))
        if rule == "needed":
            full = all_sites(pop)
            got = [full[pre] for pr in outgoing for pre, post, k, _, _ in [self.pairs(pr, src_sites=full)]]
            return np.unique(np.concatenate([np.zeros(0, np.int64)] + got))
        return self._driven(pop, incoming)

    def _driven(self, pop: Population, incoming) -> np.ndarray:
        cand = edge_sites(pop, self.emaps[pop.level], self.net.support_min)
        bound = np.zeros(cand.size)
        for pr in incoming:
            if pr.sign < 0:
                continue
            rate = self.nominal_rate(self.net.population(pr.source))
            pre, post, k, _, _ = self.pairs(pr, tgt_sites=cand)
            np.add.at(bound, post, np.clip(pr.gain_mv * k, 0, None) * rate[pre])
        bound *= pop.neuron.tau_exc_ms / 1000.0
        # the potential the excitation alone holds the cell at must reach
        # drive_min of the way from reset to threshold
        nrn = pop.neuron
        return cand[nrn.v_rest_mv + bound >= nrn.v_reset_mv + self.net.drive_min * (nrn.v_th_mv - nrn.v_reset_mv)]

    def nominal_rate(self, pop: Population) -> np.ndarray:
        """Nominal rate (Hz) of the instantiated cells of a spike source
        (``input_rate_hz`` at pixels with input) or of a relay
        (``input_rate_hz`` times its resized input, clipped at 0, which is what
        its gain makes it do)."""
        if pop.name in self.rates:
            return self.rates[pop.name]
        if not pop.role.startswith("relay"):
            check.fail(
                f"Population '{pop.name}'",
                None,
                None,
                f"the edges&drive hint can only use spike sources and relays as sources, not role {pop.role!r}",
            )
        val = np.zeros(self.sites[pop.name].size)
        for q in self.net.incoming(pop.name):
            pre, post, k, _, _ = self.pairs(q)
            np.add.at(val, post, k * (self.rates[q.source][pre] > 0))
        self.rates[pop.name] = self.net.input_rate_hz * np.clip(val, 0.0, None)
        return self.rates[pop.name]


def resolve_sites(network: Network, active: dict, fixed: dict | None = None, edges1=None) -> tuple[dict, dict]:
    """Instantiated cells of every population for one input.

    ``active`` maps each spike source's name to a flat bool array over its
    pixels (those with input); ``fixed`` fixes the cells of some populations
    (flat indices), overriding their hints; ``edges1``: the level-1 map the
    edge masks are made from, where it is not the pixels with input
    (:func:`masked_edge_maps`). Returns ``(sites, edge_maps)``.
    """
    res = _Resolver(network, active, dict(fixed or {}), edges1)
    pending = [p for p in network.populations if p.name not in res.sites]
    while pending:
        progressed = False
        for p in list(pending):
            incoming = [pr for pr in network.projections if _counts_for(p, pr)]
            outgoing = [pr for pr in network.outgoing(p.name) if pr.target != p.name]
            if not res.ready(p, incoming, outgoing):
                continue
            res.sites[p.name] = res.resolve(p, incoming, outgoing).astype(np.int64)
            pending.remove(p)
            progressed = True
        if not progressed:
            check.fail(
                "Network",
                None,
                None,
                f"cannot resolve the cells of {', '.join(p.name for p in pending)} (circular instantiation hints)",
            )
    return res.sites, res.emaps
