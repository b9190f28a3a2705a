"""Synapse counts, fan-in and fan-out of the whole network, without unrolling it.

At 321 x 481 the whole network has about a billion synapses, too many to
list; but every projection is weight shared and separable along rows and
columns, so its counts follow from 1-D arithmetic on its table
(:mod:`.board`): a kernel tap ``(dr, dc)`` connects every target row whose
source row ``r + dr`` lies inside the level (and on the source lattice)
with every such column. ``tests/test_export.py`` checks the numbers against
an explicit unrolling at small size.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..network.graph import Network
from ..network.nodes import Population
from ..network.projections import Projection
from .board import ConvTable, table, whole_pairs

#: projections with fewer (tap, cell) pairs than this are counted by unrolling them
_EXPLICIT_MAX = 2_000_000


@dataclass(frozen=True)
class ProjectionCounts:
    """Synapses of one projection; fan-in per target cell and fan-out per
    source cell (maxima over cells and channels)."""

    synapses: int
    max_fan_in: int
    max_fan_out: int
    fan_in_by_channel: np.ndarray  # max fan-in of each target channel
    fan_out_by_channel: np.ndarray  # max fan-out of each source channel


def _valid(n_from: int, s_from: int, n_level: int, s_to: int, offsets: np.ndarray) -> np.ndarray:
    """(len(offsets), n_from) bool: lattice point ``i`` (level pixel
    ``s_from * i``) plus offset lands inside the level and on the ``s_to`` lattice."""
    pos = s_from * np.arange(n_from)[None, :] + offsets[:, None]
    return (pos >= 0) & (pos < n_level) & (pos % s_to == 0)


def _conv_counts(tab: ConvTable, src: Population, tgt: Population) -> ProjectionCounts:
    co, ci, dr, dc = tab.taps.T
    lr, lc = tgt.level_shape
    if tab.wrap:  # stride 1 both ends: every tap lands on every cell
        vr_in = np.ones((co.size, tgt.grid[0]), bool)
        vc_in = np.ones((co.size, tgt.grid[1]), bool)
        vr_out = np.ones((co.size, src.grid[0]), bool)
        vc_out = np.ones((co.size, src.grid[1]), bool)
    else:
        vr_in = _valid(tgt.grid[0], tgt.stride, lr, src.stride, dr)
        vc_in = _valid(tgt.grid[1], tgt.stride, lc, src.stride, dc)
        vr_out = _valid(src.grid[0], src.stride, lr, tgt.stride, -dr)
        vc_out = _valid(src.grid[1], src.stride, lc, tgt.stride, -dc)
    n = int((vr_in.sum(1).astype(np.int64) * vc_in.sum(1)).sum())
    fan_in = np.zeros(tgt.channels, np.int64)
    for c in np.unique(co):
        m = co == c
        fan_in[c] = int((vr_in[m].T.astype(np.float32) @ vc_in[m].astype(np.float32)).max())
    fan_out = np.zeros(src.channels, np.int64)
    for c in np.unique(ci):
        m = ci == c
        fan_out[c] = int((vr_out[m].T.astype(np.float32) @ vc_out[m].astype(np.float32)).max())
    return ProjectionCounts(n, int(fan_in.max(initial=0)), int(fan_out.max(initial=0)), fan_in, fan_out)


def _explicit_counts(network: Network, pr: Projection, tab, src: Population, tgt: Population):
    pre, post, _ = whole_pairs(network, pr, tab)
    fin = np.bincount(post, minlength=tgt.size).reshape(tgt.channels, -1).max(1)
    fout = np.bincount(pre, minlength=src.size).reshape(src.channels, -1).max(1)
    return ProjectionCounts(int(pre.size), int(fin.max(initial=0)), int(fout.max(initial=0)), fin, fout)


def _resize_counts(tab, src: Population, tgt: Population) -> ProjectionCounts:
    (ri, rv), (cj, cv) = tab.rows, tab.cols
    fin = np.zeros(tgt.grid, np.int64)
    fout = np.zeros(src.grid, np.int64)
    for a in range(ri.shape[1]):
        for b in range(cj.shape[1]):
            val = rv[:, a, None] * cv[None, :, b]
            ok = (ri[:, a, None] >= 0) & (cj[None, :, b] >= 0) & (val != 0) & (np.abs(val) >= tab.k_min)
            fin += ok
            ti, tj = np.nonzero(ok)
            np.add.at(fout, (ri[ti, a], cj[tj, b]), 1)
    ch = src.channels
    return ProjectionCounts(
        int(fin.sum()) * ch,
        int(fin.max(initial=0)),
        int(fout.max(initial=0)),
        np.full(ch, fin.max(initial=0)),
        np.full(ch, fout.max(initial=0)),
    )


def projection_counts(network: Network, pr: Projection, tab=None) -> ProjectionCounts:
    """Synapses, fan-in and fan-out of ``pr`` in the whole network."""
    tab = table(network, pr) if tab is None else tab
    src, tgt = network.population(pr.source), network.population(pr.target)
    if isinstance(tab, ConvTable):
        small = tab.values.size * tgt.grid[0] * tgt.grid[1] <= _EXPLICIT_MAX
        folds = tab.wrap and any(
            2 * int(np.abs(tab.taps[:, 2 + a]).max(initial=0)) + 1 > tgt.level_shape[a] for a in (0, 1)
        )
        if small or folds:  # taps folding onto one source add up: count them explicitly
            return _explicit_counts(network, pr, tab, src, tgt)
        return _conv_counts(tab, src, tgt)
    return _resize_counts(tab, src, tgt)
