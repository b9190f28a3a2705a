"""Unroll a network description into explicit connections for one input.

The description (:mod:`snn_fg.network.description`) keeps kernels as
weight-shared convolutions on full pyramid grids. A simulator needs explicit
cells and synapses, and at 321 x 481 over 10 levels a naive unrolling needs
more than 1e9 synapses. This module creates only what the input can use:

1. spike sources keep every pixel, but only pixels with input spikes get
   outgoing synapses;
2. each population's ``sites`` rule picks its cells (see
   :data:`~snn_fg.network.description.SITE_RULES`): the model's own edge mask
   for S/U/B cells, forward reachability for grouping cells and relays,
   backward need for relays and feedback cells;
3. kernel taps below ``prune * max|K|`` are dropped (the kept fraction of
   ``sum |K|`` is reported per projection).

Everything here is numpy; nothing depends on Brian2, so the same unrolled
graph can be checked against the rate model's convolutions (see the tests).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass, field

import cv2
import numpy as np

from ..frames.pyramid import level_shape, resize
from ..network.description import Conv, DescriptionError, Network, Population, Resize


_CHUNK = 1 << 22     # elements per vectorised block when unrolling kernels

# --------------------------------------------------------------------------
# Interpolation matrices of the pyramid resize
# --------------------------------------------------------------------------
@functools.lru_cache(maxsize=256)
def resize_matrix(n_in: int, n_out: int, interpolation: str = "cubic") -> np.ndarray:
    """1-D matrix ``A`` (n_out x n_in) of OpenCV's resize along one axis.

    ``cv2.resize`` is separable, so resizing an image ``X`` (rows x cols) to
    (R, C) equals ``A_rows @ X @ A_cols.T`` (checked in the tests).
    """
    flag = {"cubic": cv2.INTER_CUBIC, "linear": cv2.INTER_LINEAR}[interpolation]
    if n_in == n_out:
        return np.eye(n_in)
    eye = np.eye(n_in)
    # resize along the rows only: (n_in rows, n_in cols) -> (n_out rows, n_in cols)
    out = cv2.resize(eye, (n_in, n_out), interpolation=flag)
    out = np.asarray(out, dtype=np.float64).reshape(n_out, n_in)
    out.setflags(write=False)
    return out


def _keys_cubic(t, a=-0.75):
    t = np.abs(t)
    return np.where(t <= 1, (a + 2) * t**3 - (a + 3) * t**2 + 1,
                    np.where(t < 2, a * t**3 - 5 * a * t**2 + 8 * a * t - 4 * a, 0.0))


@functools.lru_cache(maxsize=512)
def interp_matrix(n_src: int, n_tgt: int, s_src: int = 1, s_tgt: int = 1,
                  interpolation: str = "cubic") -> np.ndarray:
    """1-D interpolation matrix from a source lattice onto a target lattice.

    ``n_src``, ``n_tgt`` are the level sizes along the axis, ``s_src``,
    ``s_tgt`` the lattice strides. Target lattice point ``i`` (level pixel
    ``s_tgt * i``) maps to source level coordinate
    ``(s_tgt*i + 0.5) * n_src / n_tgt - 0.5``, interpolated on the source
    lattice with clamped indices. With both strides 1 the matrix is OpenCV's
    own (:func:`resize_matrix`).
    """
    if s_src == 1 and s_tgt == 1:
        return resize_matrix(n_src, n_tgt, interpolation)
    l_src = -(-n_src // s_src)
    l_tgt = -(-n_tgt // s_tgt)
    x = s_tgt * np.arange(l_tgt, dtype=float)
    u = ((x + 0.5) * (n_src / n_tgt) - 0.5) / s_src
    f = np.floor(u)
    t = u - f
    a = np.zeros((l_tgt, l_src))
    rows = np.arange(l_tgt)
    taps = ((k, _keys_cubic(t - k)) for k in range(-1, 3)) if interpolation == "cubic" else \
        ((0, 1.0 - t), (1, t))
    for k, w in taps:
        np.add.at(a, (rows, np.clip(f + k, 0, l_src - 1).astype(int)), w)
    a.setflags(write=False)
    return a


def _sparse_rows(a: np.ndarray):
    """Per row of ``a``: column indices and values of its non-zeros, padded to
    a common width (index -1, value 0)."""
    nz = a != 0
    width = max(1, int(nz.sum(1).max()))
    idx = np.full((a.shape[0], width), -1, dtype=np.int64)
    val = np.zeros((a.shape[0], width))
    for r in range(a.shape[0]):
        c = np.nonzero(nz[r])[0]
        idx[r, :len(c)] = c
        val[r, :len(c)] = a[r, c]
    return idx, val


# --------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------
@dataclass
class Connections:
    """Explicit synapses of one projection: local cell indices and weights (mV)."""

    projection: object
    pre: np.ndarray        # int64, index into the source's sites
    post: np.ndarray       # int64, index into the target's sites
    w: np.ndarray          # float64, signed weight in mV
    kept_mass: float       # kept fraction of sum |K| after pruning (1.0 if none)
    taps: int              # kernel taps kept (Conv) or interpolation weights kept (Resize)
    n: int = field(init=False)   # synapses; kept when a simulator frees pre/post/w

    def __post_init__(self):
        self.n = int(self.pre.size)

    def free(self):
        """Drop the synapse arrays (a simulator holds its own copy); ``n`` stays."""
        self.pre, self.post, self.w = self.pre[:0], self.post[:0], self.w[:0]


@dataclass
class Unrolled:
    """Cells and synapses of a network for one input."""

    network: Network
    sites: dict                              # population name -> sorted flat indices into pop.shape
    connections: list                        # Connections, in network.projections order
    active: dict = field(default_factory=dict)  # spike-source name -> bool (rows, cols) of pixels with input
    edges: dict = field(default_factory=dict)   # level -> edge map used by the 'edges' rule

    def n_cells(self, name: str) -> int:
        return int(self.sites[name].size)

    def counts(self) -> dict:
        """Cells per population and synapses per target population."""
        cells = {p.name: self.n_cells(p.name) for p in self.network.populations}
        syn = {p.name: 0 for p in self.network.populations}
        for c in self.connections:
            syn[c.projection.target] += c.n
        return {"cells": cells, "synapses_in": syn}

    def table(self) -> str:
        """Neuron and synapse counts per population, as aligned text."""
        cnt = self.counts()
        rows = [f"{'population':12s} {'role':10s} {'lvl':>3s} {'cells':>10s} {'full grid':>10s} "
                f"{'synapses in':>12s}"]
        for p in self.network.populations:
            rows.append(f"{p.name:12s} {p.role:10s} {p.level:3d} {cnt['cells'][p.name]:10d} {p.size:10d} "
                        f"{cnt['synapses_in'][p.name]:12d}")
        tot_c = sum(cnt["cells"].values())
        tot_s = sum(cnt["synapses_in"].values())
        rows.append(f"{'total':12s} {'':10s} {'':3s} {tot_c:10d} {sum(p.size for p in self.network.populations):10d} "
                    f"{tot_s:12d}")
        return "\n".join(rows)


# --------------------------------------------------------------------------
# Geometry helpers
# --------------------------------------------------------------------------
def _positions(pop: Population, flat: np.ndarray):
    """Channel and level-pixel position of the cells ``flat`` of ``pop``."""
    c, i, j = np.unravel_index(flat, pop.shape)
    return c, i * pop.stride, j * pop.stride


def _index_map(pop: Population, sites: np.ndarray) -> np.ndarray:
    """Dense (channels*rows*cols,) array: local index of each instantiated cell, -1 elsewhere."""
    m = np.full(pop.size, -1, dtype=np.int64)
    m[sites] = np.arange(sites.size)
    return m


def _kernel_taps(proj: Conv, network: Network):
    """Kept taps of a Conv: arrays (c_out, c_in, dr, dc, k) and the kept mass."""
    k = proj.kernel.array(network.params)
    ab = np.abs(k)
    total = ab.sum()
    if total == 0:
        raise DescriptionError(f"Conv '{proj.name}': kernel is all zero")
    keep = ab >= proj.prune * ab.max() if proj.prune > 0 else ab > 0
    co, ci, r, c = np.nonzero(keep)
    cr, cc = k.shape[2] // 2, k.shape[3] // 2
    dr, dc = r - cr, c - cc
    if proj.mode == "conv":
        dr, dc = -dr, -dc
    return co, ci, dr, dc, k[co, ci, r, c], float(ab[keep].sum() / total)


def _conv_pairs(proj: Conv, src: Population, tgt: Population, src_sites, tgt_sites, network: Network,
                src_active=None, side: str = "auto"):
    """Synapses (pre, post, K) of a Conv between the given cell sets.

    ``src_active`` (optional, bool over src sites) restricts sources to those
    that can fire (spike sources: pixels with input).

    Every (tap, cell) pair is tried from whichever side has fewer: from each
    target cell, the sources its taps reach, or from each source cell, the
    targets its taps reach (edge cells are sparse, so a von Mises gather onto
    a dense grouping lattice is far cheaper from the source side). Both give
    the same synapses, in a different order. ``side`` ('auto', 'sources',
    'targets') forces one.
    """
    co, ci, dr, dc, kv, kept = _kernel_taps(proj, network)
    live = src_sites if src_active is None else src_sites[src_active]
    n_src_ch = np.bincount(live // (src.size // src.channels), minlength=src.channels)
    n_tgt_ch = np.bincount(tgt_sites // (tgt.size // tgt.channels), minlength=tgt.channels)
    wrap = proj.padding == "wrap"
    src_map = _index_map(src, src_sites)
    if side == "sources" or (side == "auto" and n_src_ch[ci].sum() < n_tgt_ch[co].sum()):
        # a source at level pixel p reaches the target at p - (dr, dc)
        post, pre, w = _walk_taps(src, live, src_map[live], ci, co, -dr, -dc, kv, tgt,
                                  _index_map(tgt, tgt_sites), wrap)
    else:
        # a target at level pixel p reads the source at p + (dr, dc)
        if src_active is not None:
            src_map[src_sites[~src_active]] = -1
        pre, post, w = _walk_taps(tgt, tgt_sites, np.arange(tgt_sites.size), co, ci, dr, dc, kv, src, src_map,
                                  wrap)
    if wrap and pre.size:
        lr, lc = tgt.level_shape
        kh = 2 * int(np.abs(dr).max()) + 1 if dr.size else 1
        kw = 2 * int(np.abs(dc).max()) + 1 if dc.size else 1
        if kh > lr or kw > lc:      # taps fold onto the same source: add them up
            pre, post, w = _merge(pre, post, w, src_sites.size)
    return pre, post, w, kept, int(co.size)


def _walk_taps(pop, cells, local, ch_from, ch_to, dr, dc, kv, other: Population, other_map, wrap: bool):
    """Follow every tap from the cells ``cells`` of ``pop`` (flat indices;
    ``local`` their numbers in the result) to the cells of ``other`` (same
    level; ``other_map`` gives their numbers, -1 where none): a tap leads from
    channel ``ch_from`` at level pixel p to channel ``ch_to`` at p + (dr, dc).

    Returns ``(other's numbers, local numbers, kernel values)`` of the hits.
    """
    lr, lc = pop.level_shape
    s_to = other.stride
    g_r, g_c = other.grid
    p_c, p_r, p_col = _positions(pop, cells)
    order = np.argsort(p_c, kind="stable")
    bounds = np.searchsorted(p_c[order], np.arange(pop.channels + 1))
    to_l, from_l, w_l = [], [], []
    for ch in np.unique(ch_from):
        loc = order[bounds[ch]:bounds[ch + 1]]
        if loc.size == 0:
            continue
        taps = np.nonzero(ch_from == ch)[0]
        r0, c0 = p_r[loc], p_col[loc]
        step = max(1, _CHUNK // loc.size)
        for a0 in range(0, taps.size, step):
            ta = taps[a0:a0 + step]
            r = r0[None, :] + dr[ta, None]
            c = c0[None, :] + dc[ta, None]
            if wrap:
                r %= lr
                c %= lc
                ok = np.ones(r.shape, bool)
            else:
                ok = (r >= 0) & (r < lr) & (c >= 0) & (c < lc)
            if s_to != 1:
                ok &= (r % s_to == 0) & (c % s_to == 0)
            flat = (ch_to[ta, None] * g_r + r // s_to) * g_c + c // s_to
            idx = np.where(ok, other_map[np.where(ok, flat, 0)], -1)
            ti, si = np.nonzero(idx >= 0)
            if ti.size == 0:
                continue
            to_l.append(idx[ti, si])
            from_l.append(local[loc[si]])
            w_l.append(kv[ta][ti])
    return _cat(to_l, from_l, w_l)


def _resize_pairs(proj: Resize, src: Population, tgt: Population, src_sites, tgt_sites, src_active=None):
    ar = interp_matrix(src.level_shape[0], tgt.level_shape[0], src.stride, tgt.stride, proj.interpolation)
    ac = interp_matrix(src.level_shape[1], tgt.level_shape[1], src.stride, tgt.stride, proj.interpolation)
    ri, rv = _sparse_rows(ar)
    cj, cv = _sparse_rows(ac)
    src_map = _index_map(src, src_sites)
    if src_active is not None:
        src_map[src_sites[~src_active]] = -1
    t_c, t_r, t_col = np.unravel_index(tgt_sites, tgt.shape)   # lattice indices
    peak = np.abs(ar).max() * np.abs(ac).max()
    pre_l, post_l, w_l = [], [], []
    kept_w = 0
    for a in range(ri.shape[1]):
        for b in range(cj.shape[1]):
            i_s = ri[t_r, a]
            j_s = cj[t_col, b]
            val = rv[t_r, a] * cv[t_col, b]
            ok = (i_s >= 0) & (j_s >= 0) & (val != 0)
            if proj.prune > 0:
                ok &= np.abs(val) >= proj.prune * peak
            kept_w += int(ok.sum())
            idx = np.where(ok, src_map[(t_c * src.grid[0] + np.maximum(i_s, 0)) * src.grid[1]
                                       + np.maximum(j_s, 0)], -1)
            hit = idx >= 0
            pre_l.append(idx[hit])
            post_l.append(np.nonzero(hit)[0])
            w_l.append(val[hit])
    pre, post, w = _cat(pre_l, post_l, w_l)
    kept = _resize_kept_mass(ar, ac, proj.prune, peak)
    return pre, post, w, kept, kept_w


def _resize_kept_mass(ar, ac, prune, peak):
    if prune <= 0:
        return 1.0
    full = np.abs(ar).sum(1)[:, None] * np.abs(ac).sum(1)[None]
    prod = np.abs(ar)[:, None, :, None] * np.abs(ac)[None, :, None, :] if ar.size * ac.size < 4e6 else None
    if prod is None:   # large levels: estimate on the first 64 rows/cols
        return _resize_kept_mass(ar[:64], ac[:64], prune, peak)
    kept = (prod * (prod >= prune * peak)).sum((2, 3))
    return float(kept.sum() / full.sum())


def _cat(pre_l, post_l, w_l):
    if not pre_l:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    return (np.concatenate(pre_l).astype(np.int64), np.concatenate(post_l).astype(np.int64),
            np.concatenate(w_l).astype(np.float64))


def _merge(pre, post, w, n_pre):
    key = post * n_pre + pre
    uniq, inv = np.unique(key, return_inverse=True)
    ws = np.bincount(inv, weights=w, minlength=uniq.size)
    keep = ws != 0
    return (uniq % n_pre)[keep], (uniq // n_pre)[keep], ws[keep]


# --------------------------------------------------------------------------
# Site rules
# --------------------------------------------------------------------------
def _all_sites(pop):
    return np.arange(pop.size, dtype=np.int64)


def _edge_maps(network: Network, edges1: np.ndarray) -> dict:
    out = {}
    for p in network.populations:
        if p.level not in out:
            e = edges1 if p.level == 1 else resize(edges1, level_shape(network.frame_shape, p.level), "cubic")
            out[p.level] = e
    return out


def _edge_sites(pop: Population, emap: np.ndarray, support_min: float) -> np.ndarray:
    e = emap[::pop.stride, ::pop.stride]
    mask = e > 0 if pop.level == 1 else e >= support_min
    pos = np.flatnonzero(mask.ravel())
    npos = e.size
    return (np.arange(pop.channels)[:, None] * npos + pos[None]).ravel()


def _pairs(network, proj, src, tgt, src_sites, tgt_sites, src_active=None):
    if isinstance(proj, Conv):
        return _conv_pairs(proj, src, tgt, src_sites, tgt_sites, network, src_active)
    return _resize_pairs(proj, src, tgt, src_sites, tgt_sites, src_active)


def _counting(pop: Population, proj, network: Network) -> bool:
    """Whether ``proj`` counts for ``pop``'s reachable/drive rule."""
    if proj.source == pop.name or proj.target != pop.name:
        return False
    return not pop.site_sources or proj.source in pop.site_sources


def _nominal_rates(network: Network, pop: Population, sites, conns_in, src_rates) -> np.ndarray:
    """Nominal firing rate (Hz) of each instantiated cell of a source used by
    an ``edges&drive`` rule: input pixels with events fire at
    ``input_rate_hz``; a relay fires at ``input_rate_hz`` times its resized
    input (clipped at 0), which is what its gain is set up to do."""
    if pop.neuron is None:
        return src_rates[pop.name]
    if pop.role.startswith("relay"):
        val = np.zeros(sites.size)
        for pr, pre, post, k in conns_in:
            np.add.at(val, post, k * (src_rates[pr.source][pre] > 0))
        return network.input_rate_hz * np.clip(val, 0.0, None)
    raise DescriptionError(f"Population '{pop.name}': the edges&drive rule can only use spike sources and "
                           f"relays as site sources, not role {pop.role!r}")


def unroll(network: Network, active: dict, progress=None, sites: dict | None = None) -> Unrolled:
    """Instantiate the cells and synapses ``network`` needs for this input.

    ``active`` maps each spike-source population name to a boolean (rows, cols)
    mask of pixels that receive input spikes. The edge map of level 1 is their
    union (stage 1: a pixel is an edge if any event fired there). ``sites``
    optionally fixes the cells of some populations (flat indices into their
    (channels, rows, cols) grid), overriding their site rule - for hand-built
    circuits.
    """
    fixed = {} if sites is None else {k: np.unique(np.asarray(v, dtype=np.int64)) for k, v in sites.items()}
    pops = {p.name: p for p in network.populations}
    sources = [p for p in network.populations if p.neuron is None]
    for p in sources:
        if p.name not in active:
            raise DescriptionError(f"Population '{p.name}': no input mask given for this spike source")
        a = np.asarray(active[p.name], dtype=bool)
        if a.shape != p.grid:
            raise DescriptionError(f"Population '{p.name}': input mask shape {a.shape} != grid {p.grid}")
    act = {p.name: np.asarray(active[p.name], dtype=bool) for p in sources}
    edges1 = np.zeros(network.frame_shape)
    for a in act.values():
        edges1 = np.maximum(edges1, a.astype(float))
    emaps = _edge_maps(network, edges1)

    sites: dict = {}
    for name, idx in fixed.items():
        pop = network.population(name)
        if idx.size and (idx[0] < 0 or idx[-1] >= pop.size):
            raise DescriptionError(f"Population '{name}': fixed site index outside its {pop.size} cells")
    src_act: dict = {p.name: act[p.name].ravel() for p in sources}
    rates: dict = {p.name: network.input_rate_hz * src_act[p.name] for p in sources}
    for p in sources:
        sites[p.name] = _all_sites(p)
    sites.update({k: v for k, v in fixed.items() if network.population(k).neuron is not None})
    pending = [p for p in network.populations if p.name not in sites]
    for p in pending:
        if p.sites == "all":
            sites[p.name] = _all_sites(p)
        elif p.sites == "edges":
            sites[p.name] = _edge_sites(p, emaps[p.level], network.support_min)
    pending = [p for p in pending if p.name not in sites]
    while pending:
        progressed = False
        for p in list(pending):
            rule = p.sites
            inc = [pr for pr in network.projections if _counting(p, pr, network)]
            out = [pr for pr in network.outgoing(p.name) if pr.target != p.name]
            if rule in ("reachable", "edges&drive") and any(pr.source not in sites for pr in inc):
                continue
            if rule == "needed" and any(pr.target not in sites for pr in out):
                continue
            if rule == "reachable":
                full = _all_sites(p)
                got = [np.zeros(0, np.int64)]
                for pr in inc:
                    src = pops[pr.source]
                    pre, post, k, _, _ = _pairs(network, pr, src, p, sites[src.name], full, src_act.get(src.name))
                    got.append(full[post[pr.sign * k > 0]])
                chosen = np.unique(np.concatenate(got))
            elif rule == "edges&drive":
                cand = _edge_sites(p, emaps[p.level], network.support_min)
                bound = np.zeros(cand.size)
                for pr in inc:
                    if pr.sign < 0:
                        continue
                    src = pops[pr.source]
                    if src.name not in rates:
                        conns_in = []
                        for q in network.incoming(src.name):
                            qs = pops[q.source]
                            pre, post, k, _, _ = _pairs(network, q, qs, src, sites[qs.name], sites[src.name],
                                                        src_act.get(qs.name))
                            conns_in.append((q, pre, post, k))
                        rates[src.name] = _nominal_rates(network, src, sites[src.name], conns_in, rates)
                    pre, post, k, _, _ = _pairs(network, pr, src, p, sites[src.name], cand, src_act.get(src.name))
                    np.add.at(bound, post, np.clip(pr.gain_mv * k, 0, None) * rates[src.name][pre])
                bound *= p.neuron.tau_exc_ms / 1000.0
                chosen = cand[bound >= network.drive_min * (p.neuron.v_th_mv - p.neuron.v_rest_mv)]
            else:   # needed
                full = _all_sites(p)
                got = [np.zeros(0, np.int64)]
                for pr in out:
                    t = pops[pr.target]
                    pre, post, k, _, _ = _pairs(network, pr, p, t, full, sites[t.name])
                    got.append(full[pre])
                chosen = np.unique(np.concatenate(got))
            sites[p.name] = chosen.astype(np.int64)
            pending.remove(p)
            progressed = True
        if not progressed:
            names = ", ".join(p.name for p in pending)
            raise DescriptionError(f"Network: cannot resolve the sites of {names} (circular site rules)")

    conns = []
    items = network.projections
    if progress is not None:
        items = progress(items)
    for pr in items:
        src, tgt = pops[pr.source], pops[pr.target]
        pre, post, k, kept, taps = _pairs(network, pr, src, tgt, sites[src.name], sites[tgt.name],
                                          src_act.get(src.name))
        conns.append(Connections(pr, pre.astype(np.int32), post.astype(np.int32),
                                 pr.sign * pr.gain_mv * k, kept, taps))
    return Unrolled(network, sites, conns, act, emaps)


def dense_drive(un: Unrolled, conn: Connections, src_values: np.ndarray) -> np.ndarray:
    """Apply one projection to per-cell source values; returns per-target-cell sums.

    ``src_values`` is indexed like the source's sites. Useful to check an
    unrolled projection against the rate model's convolution.
    """
    tgt = conn.projection.target
    out = np.zeros(un.n_cells(tgt))
    np.add.at(out, conn.post, conn.w * src_values[conn.pre])
    return out


def to_grid(un: Unrolled, name: str, values: np.ndarray) -> np.ndarray:
    """Scatter per-cell values of population ``name`` onto its full (channels, rows, cols) grid."""
    pop = un.network.population(name)
    out = np.zeros(pop.size)
    out[un.sites[name]] = values
    return out.reshape(pop.shape)
