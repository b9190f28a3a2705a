"""A continuous run's windows read as its counting bins arrive: each window
counts exactly its own bins, however many windows overlap (a read-out that
hops by less than a window), and a window the live stream dropped is not
counted."""

from types import SimpleNamespace

import numpy as np
import pytest

from snn_fg.models.spiking.window_reader import WindowReader


@pytest.mark.parametrize(
    "spans",
    [
        [(0, 4), (1, 5), (2, 6), (3, 7), (4, 8), (6, 8)],
        [(0, 2), (0, 3), (3, 4), (4, 6), (4, 8), (6, 8)],  # (two windows begin in one bin)
    ],
)
def test_overlapping_windows_each_count_the_sum_of_their_bins_and_a_dropped_one_none(spans):
    # (ms; the bins are 1 ms)
    feed = SimpleNamespace(
        ended=False, n=len(spans), dropped=lambda i: i == 2, window=lambda i: i, stale=lambda w: False
    )
    reader = WindowReader(feed, spans, np.arange(9.0), pool=1, run=SimpleNamespace(t_start=0.0))
    got = {}
    reader._finish = lambda i, w, result, counts, spikes, skip: got.setdefault(i, (counts, spikes))
    rng = np.random.default_rng(0)
    bins = [{"S": rng.integers(0, 9, 7, dtype=np.int32), "G": rng.integers(0, 3, 4, dtype=np.int32)} for _ in range(8)]
    for k, counts in enumerate(bins):
        reader(k, SimpleNamespace(counts=counts, spikes={"k": k}))
    assert sorted(got) == list(range(len(spans)))
    for i, (a, b) in enumerate(spans):
        counts, spikes = got[i]
        if i == 2:
            assert counts == {} and spikes == []
            continue
        for name in ("S", "G"):
            np.testing.assert_array_equal(counts[name], sum(bins[k][name].astype(np.int64) for k in range(a, b)))
        assert [s["k"] for s in spikes] == list(range(a, b))


def test_a_windows_summary_counts_cells_spikes_active_cells_and_the_most_of_one_cell_in_place_or_apart():
    from snn_fg.models.spiking.record import count_summary
    from snn_fg.models.spiking.window_reader import RunningCounts

    bins = {"A": np.array([0, 3, 0, 1], np.int32), "E": np.zeros(0, np.int32), "B": np.array([2, 0, 5], np.int32)}
    want = [(3, 7, 2, 5), (4, 4, 2, 3), (0, 0, 0, 0)]  # (cells, spikes, cells that fired, most of one cell)
    assert count_summary(bins, ["B", "A", "E"]) == want
    total = RunningCounts()
    total.restart(bins)
    total.add(bins)
    mark = total.mark()
    total.add(bins)
    total.add(bins)
    window = total.since(mark)  # (twice the bin)
    assert [c.base is window.flat for c in window.values()] == [True] * 3
    assert count_summary(window, ["B", "A", "E"]) == [(3, 14, 2, 10), (4, 8, 2, 6), (0, 0, 0, 0)]


@pytest.mark.parametrize("spans", [[(0, 4), (1, 5), (2, 6), (3, 7), (4, 8), (6, 8)], [(0, 8)]])
def test_bins_kept_as_their_spikes_give_each_window_the_counts_and_summary_of_the_dense_bins(spans):
    # the fast engine hands each bin over as its spikes' cell numbers (BinCounts); the cells 0, 1
    # and 13 are no population's (a spike source's), as in the engine's numbering
    from snn_fg.backends.fast.counting import BinCounts
    from snn_fg.models.spiking.record import count_summary

    parts = {"S": slice(2, 9), "G": slice(9, 13)}
    rng = np.random.default_rng(1)
    sparse = [BinCounts(rng.integers(0, 14, rng.integers(0, 40)).astype(np.int32), parts, 14, 40) for _ in range(8)]
    dense = [{n: np.bincount(b.ids, minlength=14)[s].astype(np.int32) for n, s in parts.items()} for b in sparse]
    assert [{n: b[n].tolist() for n in b} for b in sparse] == [{n: b[n].tolist() for n in b} for b in dense]
    got = ({}, {})
    for bins, out in zip((sparse, dense), got):
        feed = SimpleNamespace(
            ended=False, n=len(spans), dropped=lambda i: False, window=lambda i: i, stale=lambda w: False
        )
        reader = WindowReader(feed, spans, np.arange(9.0), pool=1, run=SimpleNamespace(t_start=0.0))
        reader._finish = lambda i, w, result, counts, spikes, skip, out=out: out.setdefault(i, counts)
        for k, counts in enumerate(bins):
            reader(k, SimpleNamespace(counts=counts, spikes=None))
    for i, (a, b) in enumerate(spans):
        s, d = got[0][i], got[1][i]
        assert list(s) == list(d) == ["S", "G"]
        for name in parts:
            want = sum(dense[k][name].astype(np.int64) for k in range(a, b))
            np.testing.assert_array_equal(s[name], want)
            np.testing.assert_array_equal(d[name], want)
        assert count_summary(s, ["G", "S"]) == count_summary(d, ["G", "S"])
