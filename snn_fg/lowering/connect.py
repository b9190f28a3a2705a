"""Explicit synapses of one projection between two sets of cells.

A weight-shared projection of the description becomes, for given cells at
its two ends, arrays ``(pre, post, K)``: local source index, local target
index and kernel (or interpolation) value of every synapse. Kernel taps
under ``prune`` times the largest |value| are left out; the kept fraction of
``sum |K|`` is reported. How taps become synapses (padding, strides,
folding) is defined once, in the standalone :mod:`snn_fg.pynn.tables`; this
module applies it to the cells a backend instantiates.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from .. import validate as check
from ..network.graph import Network
from ..network.nodes import Population
from ..network.projections import Conv, Resize
from ..pynn import tables as rule
from .interp import interp_matrix, sparse_rows


def positions(pop: Population, flat: np.ndarray):
    """Channel and level-pixel position of the cells ``flat`` of ``pop``."""
    c, i, j = np.unravel_index(flat, pop.shape)
    return c, i * pop.stride, j * pop.stride


def index_map(pop: Population, sites: np.ndarray) -> np.ndarray:
    """Dense (channels*rows*cols,) array: local index of each instantiated cell, -1 elsewhere."""
    m = np.full(pop.size, -1, dtype=np.int64)
    m[sites] = np.arange(sites.size)
    return m


def pairs(network: Network, proj, src: Population, tgt: Population, src_sites, tgt_sites, src_active=None):
    """Synapses ``(pre, post, K, kept_mass, taps)`` of ``proj`` between the
    cells ``src_sites`` and ``tgt_sites``; ``src_active`` (bool over
    ``src_sites``) keeps only sources that can fire."""
    if isinstance(proj, Conv):
        return conv_cell_pairs(proj, src, tgt, src_sites, tgt_sites, network, src_active)
    return resize_cell_pairs(proj, src, tgt, src_sites, tgt_sites, src_active)


def kernel_taps(proj: Conv, network: Network):
    """Kept taps of a Conv: arrays ``(c_out, c_in, dr, dc, k)`` and the kept
    mass. A target cell at level pixel ``P`` reads the source cell at
    ``P + (dr, dc)`` (the mode is already applied; :func:`snn_fg.pynn.tables.kernel_taps`)."""
    k = proj.kernel.array(network.params)
    if not np.abs(k).sum():
        check.fail(proj._owner, None, None, "kernel is all zero")
    return rule.kernel_taps(k, proj.prune, proj.mode)


def conv_cell_pairs(
    proj: Conv,
    src: Population,
    tgt: Population,
    src_sites,
    tgt_sites,
    network: Network,
    src_active=None,
    side: str = "auto",
):
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
    co, ci, dr, dc, kv, kept = kernel_taps(proj, network)
    live = src_sites if src_active is None else src_sites[src_active]
    n_src_ch = np.bincount(live // (src.size // src.channels), minlength=src.channels)
    n_tgt_ch = np.bincount(tgt_sites // (tgt.size // tgt.channels), minlength=tgt.channels)
    wrap = proj.padding == "wrap"
    src_map = index_map(src, src_sites)
    if side == "sources" or (side == "auto" and n_src_ch[ci].sum() < n_tgt_ch[co].sum()):
        # a source at level pixel p reaches the target at p - (dr, dc)
        post, pre, w = _walk_taps(
            src, live, src_map[live], Taps(ci, co, -dr, -dc, kv), tgt, index_map(tgt, tgt_sites), wrap
        )
    else:
        # a target at level pixel p reads the source at p + (dr, dc)
        if src_active is not None:
            src_map[src_sites[~src_active]] = -1
        pre, post, w = _walk_taps(
            tgt, tgt_sites, np.arange(tgt_sites.size), Taps(co, ci, dr, dc, kv), src, src_map, wrap
        )
    if wrap and pre.size:
        lr, lc = tgt.level_shape
        kh = 2 * int(np.abs(dr).max()) + 1 if dr.size else 1
        kw = 2 * int(np.abs(dc).max()) + 1 if dc.size else 1
        if kh > lr or kw > lc:  # taps fold onto the same source: add them up
            pre, post, w = rule.fold(pre, post, w, src_sites.size)
    return pre, post, w, kept, int(co.size)


#: a kernel's taps as walked from one side: tap ``i`` leads from channel
#: ``ch_from[i]`` at level pixel p to channel ``ch_to[i]`` at p + (``dr[i]``,
#: ``dc[i]``), with kernel value ``value[i]``
Taps = namedtuple("Taps", "ch_from ch_to dr dc value")


def _walk_taps(pop, cells, local, taps: Taps, other: Population, other_map, wrap: bool):
    """Follow every tap (:data:`Taps`) from the cells ``cells`` of ``pop``
    (flat indices; ``local`` their numbers in the result) to the cells of
    ``other`` (same level; ``other_map`` gives their numbers, -1 where none),
    channel by channel (:func:`snn_fg.pynn.tables.walk_taps`).

    Returns ``(other's numbers, local numbers, kernel values)`` of the hits.
    """
    ch_from, ch_to, dr, dc, kv = taps
    p_c, p_r, p_col = positions(pop, cells)
    order = np.argsort(p_c, kind="stable")
    bounds = np.searchsorted(p_c[order], np.arange(pop.channels + 1))
    where = {"grid": other.grid, "stride": other.stride, "level_shape": other.level_shape}
    to_l, from_l, w_l = [], [], []
    for ch in np.unique(ch_from):
        loc = order[bounds[ch] : bounds[ch + 1]]
        if loc.size == 0:
            continue
        of_ch = np.nonzero(ch_from == ch)[0]
        to, si, ti = rule.walk_taps(p_r[loc], p_col[loc], ch_to[of_ch], dr[of_ch], dc[of_ch], where, other_map, wrap)
        to_l.append(to)
        from_l.append(local[loc[si]])
        w_l.append(kv[of_ch][ti])
    return _cat(to_l, from_l, w_l)


def resize_factors(proj: Resize, src: Population, tgt: Population):
    """The separable weights of a Resize: row and column interpolation
    matrices ``(A_r, A_c)`` (target lattice x source lattice) and the peak
    ``max|A_r| * max|A_c|``. A synapse's value is ``A_r[i, i'] * A_c[j, j']``,
    kept when non-zero and (with ``prune``) at least ``prune * peak``."""
    ar = interp_matrix(src.level_shape[0], tgt.level_shape[0], src.stride, tgt.stride, proj.interpolation)
    ac = interp_matrix(src.level_shape[1], tgt.level_shape[1], src.stride, tgt.stride, proj.interpolation)
    return ar, ac, np.abs(ar).max() * np.abs(ac).max()


def resize_cell_pairs(proj: Resize, src: Population, tgt: Population, src_sites, tgt_sites, src_active=None):
    ar, ac, peak = resize_factors(proj, src, tgt)
    ri, rv = sparse_rows(ar)
    cj, cv = sparse_rows(ac)
    src_map = index_map(src, src_sites)
    if src_active is not None:
        src_map[src_sites[~src_active]] = -1
    t_c, t_r, t_col = np.unravel_index(tgt_sites, tgt.shape)  # lattice indices
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
            idx = np.where(ok, src_map[(t_c * src.grid[0] + np.maximum(i_s, 0)) * src.grid[1] + np.maximum(j_s, 0)], -1)
            hit = idx >= 0
            pre_l.append(idx[hit])
            post_l.append(np.nonzero(hit)[0])
            w_l.append(val[hit])
    pre, post, w = _cat(pre_l, post_l, w_l)
    kept = resize_kept_mass(ar, ac, proj.prune, peak)
    return pre, post, w, kept, kept_w


def resize_kept_mass(ar, ac, prune, peak):
    """Kept fraction of a Resize's weight mass ``sum |A_r[i,i'] A_c[j,j']|`` after pruning."""
    if prune <= 0:
        return 1.0
    # Each product |A_r[i,i']| |A_c[j,j']| pairs one non-zero entry of each
    # matrix, so the sums run over the two lists of entries.
    a = np.abs(ar[ar != 0])
    c = np.sort(np.abs(ac[ac != 0]))
    above = np.concatenate([np.cumsum(c[::-1])[::-1], [0.0]])  # sum of c[k:]
    first = np.searchsorted(c, prune * peak / a, side="left")
    return float((a * above[first]).sum() / (a.sum() * c.sum()))


def _cat(pre_l, post_l, w_l):
    if not pre_l:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    return (
        np.concatenate(pre_l).astype(np.int64),
        np.concatenate(post_l).astype(np.int64),
        np.concatenate(w_l).astype(np.float64),
    )
