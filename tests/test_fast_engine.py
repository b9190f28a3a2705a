"""The fast engine (snn_fg.backends.fast) verified against Brian2, and its
own guarantees: parked cells cannot fire, the closed-form advance is the
step-by-step update, and memory follows cells, not synapses."""

import numpy as np
import pytest

from snn_fg.backends import RunSettings, available_backends, get_backend
from snn_fg.backends.base import STATE_VARIABLES
from snn_fg.backends.fast.lif import advanced, safe
from snn_fg.backends.fast.lists import gather_spikes, merge, radix_sort
from snn_fg.backends.fast.neurons import DE, DI, DM, GAP, PE, PEAK, PI, TIGHT, V_RESET, V_REST, V_TH
from snn_fg.backends.fast.tables import build_tables
from snn_fg.events import image_to_events, image_to_frame
from snn_fg.frames.scenes import disc
from snn_fg.lowering.input_spikes import event_spikes, frame_spikes
from snn_fg.network import build_network
from snn_fg.params import ModelParams

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

BRIAN2 = pytest.mark.skipif(not available_backends()["brian2"][0], reason="needs Brian2 to compare with")


def _trains(result, name):
    """Spikes of population ``name`` as (step, cell) sorted by step then cell."""
    cell, t = result.spikes[name]
    steps = np.round(t / result.dt_ms).astype(np.int64)
    order = np.lexsort((cell, steps))
    return steps[order], result.sites[name][cell[order]]


def _both(net, inp, settings):
    return {name: get_backend(name).simulate(net, inp, settings) for name in ("brian2", "fast")}


#: counting bins of the disc runs (ms): uneven, one edge off the step grid's multiples of 10
BINS_MS = (20.0, 37.5, 60.0, 100.0, 150.0)


@pytest.fixture(scope="module")
def disc_runs():
    """Two levels, every kind of projection and delay (feedback on, gated
    border-ownership cells, excess cells), 150 ms of regular input."""
    pos, neg = image_to_frame(disc(16).image)
    inp = frame_spikes(pos, neg, 200.0, 0.5, 150.0, seed=1)
    net = build_network(ModelParams(levels=2), pos.shape).calibrated(inp.rate_hz)
    return _both(
        net,
        inp,
        RunSettings(
            duration_ms=150.0, dt_ms=net.dt_ms, count_from_ms=50.0, record_state=STATE_VARIABLES, count_bins_ms=BINS_MS
        ),
    )


def _assert_identical(runs, min_spikes):
    fast, ref = runs["fast"], runs["brian2"]
    assert fast.populations == ref.populations
    total = 0
    for name in ref.populations:
        np.testing.assert_array_equal(fast.sites[name], ref.sites[name], err_msg=name)
        for got, want in zip(_trains(fast, name), _trains(ref, name), strict=True):
            np.testing.assert_array_equal(got, want, err_msg=name)
        np.testing.assert_array_equal(fast.counts[name], ref.counts[name], err_msg=name)
        total += ref.spikes[name][0].size
    assert total >= min_spikes


@pytest.mark.slow
@BRIAN2
def test_spike_trains_are_identical_to_brian2s(disc_runs):
    """Every population's spike cells and times, and the counts, equal."""
    _assert_identical(disc_runs, min_spikes=40_000)
    net = disc_runs["brian2"].network
    fired = {
        p.role
        for p in net.populations
        if p.name in disc_runs["brian2"].counts and disc_runs["brian2"].counts[p.name].sum() > 0
    }
    roles = {p.role for p in net.populations if not p.is_source}
    assert any(r.startswith("excess_") for r in roles) and any(r.startswith("feedback_") for r in roles)
    assert roles <= fired, f"roles that never fired: {sorted(roles - fired)}"
    gated = [p.neuron for p in net.populations if p.role.startswith("bo_")]
    assert all(n.v_rest_mv < n.v_reset_mv for n in gated)  # the gate: rest far below reset


@pytest.mark.slow
@BRIAN2
def test_binned_counts_are_identical_to_brian2s(disc_runs):
    fast, ref = disc_runs["fast"], disc_runs["brian2"]
    assert fast.count_bins_ms == ref.count_bins_ms == BINS_MS
    for name in ref.populations:
        assert fast.binned_counts[name].shape == (len(BINS_MS) - 1, ref.sites[name].size)
        np.testing.assert_array_equal(fast.binned_counts[name], ref.binned_counts[name], err_msg=name)
    # the bins count the spikes of the trains between their edges
    cell, t = ref.spikes[ref.populations[-1]]
    in_bin = np.histogram(t, bins=BINS_MS)[0]
    np.testing.assert_array_equal(ref.binned_counts[ref.populations[-1]].sum(axis=1), in_bin)


@pytest.mark.slow
@BRIAN2
def test_spikes_between_two_times_are_those_the_times_select(disc_runs):
    """``SpikeTrains.between`` (bisection, used for each window of a
    recording) gives what masking every population's times gives, on spans
    whose ends fall on a step, between steps and outside the run."""
    trains = disc_runs["fast"].spikes
    checked = 0
    for a, b in ((0.0, 150.0), (20.0, 37.5), (37.25, 37.75), (37.5, 60.0), (49.9, 50.1), (140.0, 400.0), (60.0, 60.0)):
        got = trains.between(a, b)
        assert set(got) == set(trains)
        for name in trains:
            cell, t = trains[name]
            inside = (t >= a) & (t < b)
            np.testing.assert_array_equal(got[name][0], cell[inside], err_msg=f"{name} [{a}, {b})")
            np.testing.assert_array_equal(got[name][1], t[inside], err_msg=f"{name} [{a}, {b})")
            checked += int(inside.sum())
    assert checked > 40_000


@pytest.mark.slow
@BRIAN2
def test_final_state_is_brian2s_up_to_rounding(disc_runs):
    fast, ref = disc_runs["fast"], disc_runs["brian2"]
    for name in ref.populations:
        for var in STATE_VARIABLES:
            np.testing.assert_allclose(
                fast.state[name][var], ref.state[name][var], rtol=1e-9, atol=1e-9, err_msg=f"{name}.{var}"
            )


@pytest.mark.slow
@BRIAN2
def test_timed_events_on_every_cell_are_identical_to_brian2s():
    """Replayed timed events (a periodic input), instantiate='all', and four
    levels of a 32 x 32 frame: at levels 3 and 4 (16 x 16, 12 x 12) the
    25 x 25 wrap-around DoG folds onto itself."""
    rec = image_to_events(disc(10).image[16:48, 16:48])
    inp = event_spikes(rec.events, rec.sensor_size, 0.5, replay=True)
    net = build_network(ModelParams(levels=4), inp.shape).calibrated(inp.rate_hz)
    runs = _both(net, inp, RunSettings(duration_ms=60.0, dt_ms=net.dt_ms, instantiate="all"))
    # (every cell outside the edge masks: the grouping and feedback cells of level 1 are all there)
    assert all(
        runs["fast"].sites[p.name].size == p.size
        for p in net.populations
        if p.level == 1 and not p.is_source and not p.edge_mask
    )
    _assert_identical(runs, min_spikes=5_000)


def _brian2_steps(v, e, i, row, k):
    """Brian2's update of our Brian2 backend, ``k`` steps, no input; the largest v."""
    top = -np.inf
    for _ in range(k):
        v = v + (((e * row[PE]) + ((1.0 - row[DM]) * ((-v) + row[V_REST]))) - (i * row[PI]))
        e, i = e * row[DE], i * row[DI]
        top = max(top, v)
    return v, e, i, top


@pytest.mark.slow
def test_a_parked_cell_cannot_reach_threshold_without_input():
    """Random states of every neuron type: whenever the parking bound says
    safe, 400 steps of the update stay below threshold; and the bound is not
    vacuous (some unsafe states do cross)."""
    tab = build_tables(build_network(ModelParams(levels=1), (20, 20)), 0.5)
    assert (tab.nrn[:, V_RESET] - tab.nrn[:, V_REST] > 0.5 * (tab.nrn[:, V_TH] - tab.nrn[:, V_REST])).any(), (
        "no gated neuron (rest far below reset) to check the bound on"
    )
    rng = np.random.default_rng(4)
    crossed_unsafe = 0
    for row in tab.nrn:
        gap = row[V_TH] - row[V_REST]
        for k in range(300):  # every third state just after a reset
            v = row[V_RESET] if k % 3 == 0 else row[V_REST] + gap * rng.uniform(-2, 1.2)
            e, i = gap * rng.uniform(-1, 4), gap * rng.uniform(0, 3) * rng.integers(0, 2)
            top = _brian2_steps(v, e, i, row, 400)[3]
            if safe(v, e, i, row[V_REST], row[TIGHT] > 0, row[PEAK], row[GAP]):
                assert top <= row[V_TH], (v, e, i)
            else:
                crossed_unsafe += top > row[V_TH]
    assert crossed_unsafe > 50


def test_the_closed_form_advance_is_the_step_by_step_update():
    tab = build_tables(build_network(ModelParams(levels=1), (20, 20)), 0.5)
    for t, row in enumerate(tab.nrn):
        for k in (1, 7, 100, tab.adv.shape[2] - 1, 1500):
            v0, e0, i0 = row[V_REST] + 0.004, 0.02, 0.013
            want = _brian2_steps(v0, e0, i0, row, k)[:3]
            got = advanced(v0, e0, i0, row[V_REST], tab.adv[t], k)
            np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-15)


@pytest.mark.parametrize("n_cells", [100, 340_000, 13_000_000])
def test_the_step_lists_come_out_sorted_as_a_comparison_sort_puts_them(n_cells):
    rng = np.random.default_rng(n_cells)
    for n in (0, 1, 63, 64, 5000):
        cells = rng.choice(n_cells, size=min(n, n_cells), replace=False).astype(np.int32)
        # (a thread's scratch holds its share of the cells: shorter than the numbers it sorts)
        tmp, counts = np.zeros(max(cells.size, 1), np.int32), np.zeros(2048, np.int64)
        a = np.concatenate([cells, rng.integers(0, n_cells, 7, dtype=np.int32)])  # (a tail left as it is)
        want = a.copy()
        want[: cells.size] = np.sort(cells)
        radix_sort(a, cells.size, tmp, counts, n_cells)
        np.testing.assert_array_equal(a, want)
        # the active list and the new cells, disjoint, merged into one sorted list
        act = np.zeros(max(cells.size, 1), np.int32)
        old, new = np.sort(cells[: cells.size // 2]), cells[cells.size // 2 :].copy()
        act[: old.size] = old
        k = merge(act, old.size, new, new.size, tmp, counts, n_cells)
        np.testing.assert_array_equal(act[:k], np.sort(cells))
        # a step's spikes: two threads' ascending runs, anywhere in the log, and the input spikes
        runs = [np.sort(cells[::3]), np.sort(cells[1::3])]
        inputs = np.sort(cells[2::3])
        log = np.full(3 * cells.size + 10, -9, np.int32)
        firsts = np.array([4, 4 + runs[0].size + 2], np.int64)
        for f, r in zip(firsts, runs, strict=True):
            log[f : f + r.size] = r
        end = gather_spikes(
            log, 2, firsts, np.array([r.size for r in runs], np.int64), inputs, np.zeros(log.size, np.int32)
        )
        assert end == 2 + cells.size
        np.testing.assert_array_equal(log[2:end], np.sort(cells))
        assert (log[:2] == -9).all()


def test_memory_follows_cells_not_synapses():
    """The whole 320 x 240 network over ten levels (9 million cells, more
    than 1e9 synapses) is held as stencil rows and interpolation factors."""
    import dataclasses

    tab = build_tables(build_network(ModelParams(), (240, 320)), 0.5)
    assert tab.n_cells > 9_000_000
    held = sum(
        getattr(tab, f.name).nbytes for f in dataclasses.fields(tab) if isinstance(getattr(tab, f.name), np.ndarray)
    )
    assert held < 20e6


def test_a_reused_engine_gives_the_spikes_of_a_fresh_one():
    """The engine keeps its cell arrays from run to run (put back at rest):
    a second input on the same backend gives what a fresh backend gives."""
    net = build_network(ModelParams(levels=1), (64, 64))
    settings = RunSettings(duration_ms=60.0, dt_ms=net.dt_ms, record_state=("v",))
    a, b = (frame_spikes(*image_to_frame(disc(r).image), 200.0, 0.5, 60.0) for r in (16, 12))
    reused = get_backend("fast")
    reused.simulate(net, a, settings)
    again = reused.simulate(net, b, settings)
    fresh = get_backend("fast").simulate(net, b, settings)
    assert sum(int(c.sum()) for c in fresh.counts.values()) > 1000
    for name in fresh.populations:
        for got, want in zip(_trains(again, name), _trains(fresh, name), strict=True):
            np.testing.assert_array_equal(got, want, err_msg=name)
        np.testing.assert_array_equal(again.state[name]["v"], fresh.state[name]["v"], err_msg=name)


@pytest.mark.slow
def test_tables_made_again_for_other_gains_equal_a_fresh_build():
    """A recording's window (or a frame) is calibrated for its own input
    rate: the engine then remakes only the weights of the tables it holds,
    and they must be exactly (bit for bit) those a fresh build gives."""
    import dataclasses

    from snn_fg.backends.fast.tables import gains_only

    net = build_network(ModelParams(levels=3), (40, 56))
    other = net.calibrated(net.input_rate_hz * 1.7)
    assert gains_only(net, other) and not gains_only(net, net.without_feedback())
    delayed = dataclasses.replace(other.projections[0], delay_ms=other.projections[0].delay_ms + 1)
    assert not gains_only(net, dataclasses.replace(other, projections=(delayed, *other.projections[1:])))
    regained, fresh = build_tables(net, 0.5).with_gains(other), build_tables(other, 0.5)
    assert regained.network is other
    changed = 0
    for f in dataclasses.fields(fresh):
        got, want = getattr(regained, f.name), getattr(fresh, f.name)
        if isinstance(want, np.ndarray):
            assert got.dtype == want.dtype and got.tobytes() == want.tobytes(), f.name
            changed += not np.array_equal(got, getattr(build_tables(net, 0.5), f.name))
    assert changed >= 2  # stencil weights and gains did change


def test_a_backend_keeps_its_tables_across_calibrated_runs():
    """Two frames with different input rates on one backend object: the
    second run reuses the tables (weights remade) and gives a fresh backend's spikes."""
    net = build_network(ModelParams(levels=1), (64, 64))
    settings = RunSettings(duration_ms=60.0, dt_ms=net.dt_ms)
    a, b = (frame_spikes(*image_to_frame(disc(r).image), hz, 0.5, 60.0) for r, hz in ((12, 200.0), (10, 330.0)))
    backend = get_backend("fast")
    backend.simulate(net.calibrated(a.rate_hz), a, settings)
    first = backend._tables
    again = backend.simulate(net.calibrated(b.rate_hz), b, settings)
    assert backend._tables is not first and backend._tables.row_tab is first.row_tab  # remade, not rebuilt
    fresh = get_backend("fast").simulate(net.calibrated(b.rate_hz), b, settings)
    assert sum(int(c.sum()) for c in fresh.counts.values()) > 500
    for name in fresh.populations:
        np.testing.assert_array_equal(again.counts[name], fresh.counts[name], err_msg=name)


def test_large_cell_arrays_start_at_zero():
    """Cell arrays from the huge-page map are zeroed like np.zeros, writable, any dtype."""
    from snn_fg.backends.fast.lif import STATE
    from snn_fg.backends.fast.run import HUGE_FROM, zeroed

    for dtype in (STATE, np.int32, np.float64):
        n = 2 * HUGE_FROM // np.dtype(dtype).itemsize + 3
        a = zeroed(n, dtype)
        assert a.shape == (n,) and a.dtype == np.dtype(dtype) and not a.view(np.uint8).any()
        a[-1] = a[-1]  # writable
        a.view(np.uint8)[:] = 7
        assert a.view(np.uint8).min() == 7


@pytest.mark.slow
@pytest.mark.parametrize("timed", [False, True])
def test_the_cells_left_out_by_the_edge_masks_never_fire(timed):
    """Level-1 simple and untuned cells outside the event pixels, and
    border-ownership and excess cells outside their level's edge mask, exist
    in the whole network (``instantiate="all"``) only if ``edge_mask`` is
    dropped. They are gated by their pixel's own input or by their simple
    cell, so the network with them must fire exactly the same spikes, at the
    same cells, as the network without them; and they must be most of the
    cells of their populations, or the masks would save nothing."""
    import dataclasses

    sc = disc(12, False)
    if timed:
        rec = image_to_events(sc.image)
        inp = event_spikes(rec.events, rec.sensor_size, 0.5, replay=True)
    else:
        pos, neg = image_to_frame(sc.image)
        inp = frame_spikes(pos, neg, 200.0, 0.5, 120.0, seed=2)
    net = build_network(ModelParams(levels=3), inp.shape).calibrated(inp.rate_hz)
    gated = {
        p.name
        for p in net.populations
        if p.role.startswith(("bo_", "excess_")) or (p.level == 1 and p.role in ("simple", "untuned"))
    }
    assert all(net.population(n).edge_mask for n in gated)
    whole = dataclasses.replace(
        net,
        populations=tuple(dataclasses.replace(p, edge_mask=False) if p.name in gated else p for p in net.populations),
    )
    settings = RunSettings(duration_ms=120.0, dt_ms=net.dt_ms, count_from_ms=40.0, instantiate="all")
    masked, full = (get_backend("fast").simulate(n, inp, settings) for n in (net, whole))
    total = 0
    for name in full.populations:
        got, want = _trains(masked, name), _trains(full, name)
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b, err_msg=name)
        total += want[0].size
    assert total > 10_000
    kept = sum(masked.sites[n].size for n in gated) / sum(full.sites[n].size for n in gated)
    assert kept < 0.5


@pytest.mark.skipif(__import__("numba").config.NUMBA_NUM_THREADS < 2, reason="numba allows one thread here")
@pytest.mark.parametrize("dealt", ["measured", "rotated"])
def test_two_threads_give_the_spike_trains_of_one(dealt, monkeypatch):
    """A step shared by two threads (each population owned whole by one of
    them or banded, the table dealt again as the run goes, the cells that
    change hands moved between the threads' lists: :mod:`.share`) gives one
    thread's spike trains and final potentials, bit for bit. ``measured``:
    the tables the run's measured work deals (some populations whole to each
    thread); ``rotated``: every deal moves every population to the other
    thread, one of them banded. (A cell listed active by the wrong thread
    would be updated by one thread while another hands it input.)"""
    import numba

    from snn_fg.backends.fast import share

    tables = []
    if dealt == "rotated":

        def rotated(work, threads):  # (work: chunks, populations, W_*)
            owner = (np.arange(work.shape[1]) + len(tables)) % threads
            owner[len(tables) % work.shape[1]] = share.BANDED
            return owner

        monkeypatch.setattr(share, "deal", rotated)
        monkeypatch.setattr(share, "BETTER", np.inf)  # (every deal taken)
    chunk_done = share.Sharing.chunk_done

    def recorded(self, run):  # (and each thread's active cells are those it owns)
        chunk_done(self, run)
        tables.append(self.owner.copy())
        for t in range(self.threads):
            held = run.act[t, : run.scalars[t]]
            owners = share.cell_owners(held, self.owner, run.cells, run.flat_of, run.tab.pops, self.threads)
            assert (owners == t).all()

    monkeypatch.setattr(share.Sharing, "chunk_done", recorded)
    pos, neg = image_to_frame(disc(16).image)
    inp = frame_spikes(pos, neg, 200.0, 0.5, 120.0, seed=3)
    net = build_network(ModelParams(levels=2), pos.shape).calibrated(inp.rate_hz)
    settings = RunSettings(duration_ms=120.0, dt_ms=net.dt_ms, record_state=("v",))
    one = get_backend("fast", threads=1, chunk_ms=2.0).simulate(net, inp, settings)
    tables.clear()
    two = get_backend("fast", threads=2, chunk_ms=2.0).simulate(net, inp, settings)
    numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)
    dealt_whole = [t for t in tables if (t == 0).any() and (t == 1).any()]
    assert len({t.tobytes() for t in dealt_whole}) >= (4 if dealt == "rotated" else 1)
    assert dealt == "measured" or any((t == share.BANDED).any() for t in dealt_whole)
    assert sum(int(c.sum()) for c in one.counts.values()) > 10_000
    for name in one.populations:
        for got, want in zip(_trains(two, name), _trains(one, name), strict=True):
            np.testing.assert_array_equal(got, want, err_msg=name)
        np.testing.assert_array_equal(two.state[name]["v"], one.state[name]["v"], err_msg=name)


def test_the_step_loop_lets_go_of_the_interpreter_lock():
    """A recording's decoding thread and a live stream's receiver run beside the step loop only if
    it releases Python's lock (numba's nogil); a rewrite of the engine lost it once (28 Nov), and two
    cores then kept fewer live windows than one."""
    from snn_fg.backends.fast import core

    assert core.run_steps.targetoptions.get("nogil") is True


def test_the_docs_give_the_cells_of_a_320_x_240_recordings_network():
    """For recorded events the fast engine creates every cell of the network: the count the docs
    give for dvs.es (320 x 240) is the network's (its run prints it as ``fast engine: N cells``)."""
    import re
    from pathlib import Path

    from snn_fg.backends.base import lif_populations
    from snn_fg.network import SpikingParams

    root = Path(__file__).resolve().parents[1]
    said = re.search(r"13\.9 M \(([\d,]+)\) for the 320 x 240 `dvs.es`", (root / "docs/spiking-network.md").read_text())
    net = build_network(ModelParams(), (240, 320), SpikingParams())
    assert int(said.group(1).replace(",", "")) == sum(p.size for p in lif_populations(net))
    assert "(13.9 M for `dvs.es`'s 320 x 240 sensor)" in (root / "docs/usage.md").read_text()
