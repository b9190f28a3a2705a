"""The fast engine delivers a spike as the synapses of the one rule
(:mod:`snn_fg.pynn.tables`): every Conv of a small network, sources on
every edge, corner and stride class, the kernels that wrap around and fold
onto a small level, the strided lattices both ways, and targets with cells
left out."""

import numpy as np
import pytest

from snn_fg.backends.fast import deliver
from snn_fg.backends.fast.run import presence_words
from snn_fg.backends.fast.stencils import tap_weights
from snn_fg.backends.fast.tables import CONV, J_KIND, build_tables
from snn_fg.lowering.connect import kernel_taps
from snn_fg.network import build_network
from snn_fg.params import ModelParams
from snn_fg.pynn import tables as rule


def _geometry(pop) -> dict:
    return {"grid": pop.grid, "stride": pop.stride, "level_shape": pop.level_shape, "channels": pop.channels}


@pytest.fixture(scope="module")
def network():
    # levels 3 and 4 of a 36 x 32 frame are smaller than the 31 x 31 DoG: it folds
    return build_network(ModelParams(levels=4), (36, 32))


def _deliver_one(tab, p, src_flat, present):
    """What one spike of source cell ``src_flat`` adds through Conv ``p``:
    ``{target flat index: volts}`` and the events counted."""
    net = tab.network
    pops = net.populations
    cells = np.full((len(pops), 5), -1, np.int64)
    cells[:, 0] = np.cumsum([0] + [q.size for q in pops[:-1]])
    cells[:, 1] = [q.size for q in pops]
    pres, n_words = [], 0
    for q, pop in enumerate(pops):
        sites = present if pop.name == net.projections[p].target else np.arange(pop.size)
        words = presence_words(pop, sites)
        cells[q, deliver.C_PRES], cells[q, deliver.C_WHOLE] = n_words, int(sites.size == pop.size)
        pres.append(words)
        n_words += words.size
    tgt = net.population(net.projections[p].target)
    q_src = [q.name for q in pops].index(net.projections[p].source)
    acc = np.zeros(tgt.size)
    rows, words = tgt.channels * tgt.grid[0], (tgt.grid[1] + 63) // 64
    marks = (
        np.zeros(rows, np.uint8),
        np.zeros(rows + 1, np.int64),  # (a spare slot, as the engine has)
        np.zeros(1, np.int64),
        np.zeros(rows * words, np.uint64),
    )
    stencil = (tab.cls_ptr, tab.row_tab, tab.st_w)
    spikes = np.array([cells[q_src, 0] + src_flat], np.int32)
    events = deliver.conv_spikes(
        p, spikes, tab.pops, cells, np.zeros(1, np.int32), np.concatenate(pres), tab.prj, stencil, acc, marks, 0, 1
    )
    bits = np.unpackbits(marks[3].view(np.uint8), bitorder="little").reshape(rows, words * 64)[:, : tgt.grid[1]]
    marked = np.nonzero(bits.ravel())[0]
    kept = set(present.tolist())
    return {int(t): acc[t] for t in marked if t in kept}, events, acc


@pytest.mark.parametrize("kept", [1.0, 0.4])
def test_a_spike_reaches_the_synapses_of_the_rule(network, kept):
    tab = build_tables(network, 0.5)
    rng = np.random.default_rng(3)
    checked = {"folded": 0, "strided": 0, "edges": 0}
    for p, pr in enumerate(network.projections):
        if tab.prj[p, J_KIND] != CONV:
            continue
        src, tgt = network.population(pr.source), network.population(pr.target)
        co, ci, dr, dc, k, _ = kernel_taps(pr, network)
        taps = np.stack([co, ci, dr, dc], axis=1)
        pre, post, kk = rule.conv_pairs(taps, k, _geometry(src), _geometry(tgt), pr.padding == "wrap")
        present = np.sort(rng.choice(tgt.size, max(1, int(kept * tgt.size)), replace=False))
        c, gr, gc = src.shape
        corners = [(ch, r, col) for ch in {0, c - 1} for r in {0, 1, gr - 1} for col in {0, 1, gc - 2, gc - 1}]
        for ch, r, col in corners + [(0, gr // 2, gc // 2), (c - 1, gr // 2 + 1, gc // 2 + 1)]:
            s_flat = (ch * gr + max(r, 0)) * gc + max(col, 0)
            got, events, acc = _deliver_one(tab, p, s_flat, present)
            sel = (pre == s_flat) & np.isin(post, present)
            want = dict(zip(post[sel].tolist(), tap_weights(pr, kk[sel]).tolist(), strict=True))
            assert got.keys() == want.keys(), (pr.name, s_flat)
            assert all(got[t] == want[t] for t in want), pr.name  # (bit for bit)
            assert events == sel.sum(), pr.name
            assert not np.delete(acc, list(want)).any() or kept < 1, pr.name  # (nothing else but cells left out)
        folded = pr.padding == "wrap" and 31 > min(tgt.grid)
        checked["folded"] += folded
        checked["strided"] += src.stride != tgt.stride
        checked["edges"] += 1
    assert checked["folded"] and checked["strided"] and checked["edges"] > 20, checked
