"""What the fast engine counts of its own work (issue 59): the cells handed
input, the cycles of each phase of a step when asked for
(``SNN_FG_ENGINE_PHASES=1``, :data:`snn_fg.backends.fast.lif.PHASES`), the
cached code dropped when that changes, and how
``experiments.bench.phases`` turns the counts into a table."""

import types

import numpy as np
import pytest

from experiments.bench.floor import LAZY_STATE, example_tables, lazy_visit, step, visit
from experiments.bench.phases import TOP, at_every_floor, phase_rows, without_delivery
from snn_fg.backends import RunSettings, get_backend
from snn_fg.backends.fast import compiled
from snn_fg.backends.fast.deliver import PHASE_NAMES
from snn_fg.backends.fast.lif import STATE, advanced
from snn_fg.events import image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.lowering.input_spikes import frame_spikes
from snn_fg.network import build_network
from snn_fg.params import ModelParams

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


def test_a_run_counts_the_cells_it_handed_input_between_its_advances_and_its_events():
    """Every closed-form advance happens as a cell is handed input, and every
    cell handed input received at least one synaptic event: advances <= cells
    handed input <= events. No cycle is counted unless asked for."""
    pos, neg = image_to_frame(disc(12).image)
    net = build_network(ModelParams(levels=1), pos.shape)
    inp = frame_spikes(pos, neg, 200.0, 0.5, 40.0, seed=1)
    st = get_backend("fast").simulate(net, inp, RunSettings(duration_ms=40.0, dt_ms=net.dt_ms)).stats
    assert 0 < st["closed_form_advances"] <= st["cells_handed_input"] <= st["synaptic_events_total"]
    assert st["cells_handed_input"] < st["synaptic_events_total"]  # (a cell takes its step's events at once)
    assert not [k for k in st if k.startswith("cycles_")]


class _Cache:
    def __init__(self, path):
        self._cache_path, self.flushed = str(path), 0

    def flush(self):
        self.flushed += 1


def test_the_cached_code_is_dropped_when_a_constant_compiled_in_changes(tmp_path):
    """The phases' flag is compiled in as a constant that the sources do not
    show: turning it on or off must drop the cached code, or the other
    variant's code would run."""
    fn = types.SimpleNamespace(_cache=_Cache(tmp_path))
    module = types.SimpleNamespace(fn=fn)
    compiled.drop_stale_caches(fn, [module], b"")
    first = fn._cache.flushed
    compiled.drop_stale_caches(fn, [module], b"")
    assert fn._cache.flushed == first  # (the same sources and variant: kept)
    compiled.drop_stale_caches(fn, [module], b"phases")
    assert fn._cache.flushed == first + 1
    compiled.drop_stale_caches(fn, [module], b"")
    assert fn._cache.flushed == first + 2


def test_the_phase_table_gives_each_phase_its_time_share_and_cost_per_unit_of_work():
    stats = {f"cycles_{name}": 0 for name in PHASE_NAMES}
    stats.update(cycles_active=2e9, cycles_conv=1e9, cycles_handover=4e9, cycles_handover_find=1e9)
    stats.update(active_cell_steps=1e8, synaptic_events_conv=5e8, cells_handed_input=2e8, spikes=1e6)
    rows = {r["phase"]: r for r in phase_rows(stats, run_cpu_s=4.0, ticks_per_s=2e9)}
    assert rows["active"]["seconds"] == pytest.approx(1.0)
    assert rows["active"]["ns_per_unit"] == pytest.approx(10.0)  # 1 s over 1e8 active cell-steps
    assert rows["conv"]["ns_per_unit"] == pytest.approx(1.0)  # 0.5 s over 5e8 events
    assert rows["handover"]["ns_per_unit"] == pytest.approx(10.0)
    assert rows["handover_find"]["share"] == pytest.approx(0.125)
    # the find is part of the hand-over: counted once, the rest of the run is "other"
    assert rows["other"]["seconds"] == pytest.approx(4.0 - 3.5)
    assert sum(rows[p]["share"] for p in TOP) + rows["other"]["share"] == pytest.approx(1.0)
    assert rows["resize"]["seconds"] == 0.0


def test_without_delivery_leaves_every_phase_but_conv_and_resize():
    stats = {f"cycles_{name}": 1e9 for name in PHASE_NAMES}
    stats.update(active_cell_steps=1, synaptic_events_conv=1, synaptic_events_resize=1, cells_handed_input=1, spikes=1)
    rows = phase_rows(stats, run_cpu_s=4.0, ticks_per_s=1e9)  # six top phases of 1 s each: "other" is -2 s
    assert without_delivery(rows, events=1_000_000_000) == pytest.approx(4.0 - 2.0)


def test_an_engine_at_every_floor_pays_the_floor_an_event_and_its_visits_at_their_least_cost():
    stats = {"synaptic_events_total": 1000, "cells_handed_input": 450, "active_cell_steps": 180}
    assert at_every_floor(stats, floor=0.8, visit=3.0, step=2.0) == pytest.approx(0.8 + 0.45 * 3.0 + 0.18 * 2.0)


def test_the_floor_of_a_visit_does_the_engines_arithmetic():
    """The least cost of a visit is only a floor of the engine's if it does the
    same work: the closed-form advance of lif.advanced, the input added, and
    the cell listed where the bound says it might fire."""
    tab = example_tables()
    adv = tab.reshape(-1, 8)[:, :5].T.copy()  # (lif.advanced reads the tables by row: decays, then responses)
    state = np.zeros(3, STATE)
    state["v"], state["e"], state["i"] = [-0.07, -0.055, -0.05], [0.0, 2e-3, 1e-3], [0.0, 1e-3, 5e-4]
    before = state.copy()
    idx, k, w = np.array([0, 1, 2], np.uint64), np.array([3, 1, 7], np.uint64), np.array([1e-3, 0.0, 2e-3])
    new = np.zeros(3, np.int64)
    listed = visit(idx, w, k, state, tab, -0.07, 0.2, 0.01, new)
    for c in range(3):
        v, e, i = advanced(before["v"][c], before["e"][c], before["i"][c], -0.07, adv, int(k[c]))
        assert (state["v"][c], state["e"][c], state["i"][c]) == pytest.approx((v, e + w[c], i), rel=1e-12)
    assert listed == 2 and list(new[:2]) == [1, 2]  # (cell 0 at rest with a little input cannot reach 10 mV)
    fired = np.zeros(3, np.int64)
    state["v"] = [-0.07, -0.04, -0.07]  # (above the -0.05 threshold of the call below: fires and is reset)
    assert step(idx, state, tab[8:16].copy(), -0.07, -0.05, -0.07, fired) == 1 and fired[0] == 1
    assert state["v"][1] == -0.07


def test_the_floor_of_a_visit_that_only_adds_input_raises_the_bound_and_the_pending_sums():
    """The route of fewer visits is measured by a visit that only adds: the bound raised by the most the
    input can raise the potential, the input pending with the step's two factors, the cell listed
    once the bound reaches the gap."""
    state = np.zeros(2, LAZY_STATE)
    state["bound"] = [0.0, 0.009]
    new = np.zeros(2, np.int64)
    listed = lazy_visit(np.array([0, 1], np.uint64), np.array([0.01, 0.01]), 2.0, 3.0, state, 0.2, 0.01, new)
    assert state["bound"].tolist() == pytest.approx([0.002, 0.011])
    assert state["pe"].tolist() == pytest.approx([0.02, 0.02]) and state["pm"].tolist() == pytest.approx([0.03, 0.03])
    assert listed == 1 and new[0] == 1
