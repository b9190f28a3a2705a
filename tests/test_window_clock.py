"""The window clock of a continuous run over a recording: one spike source
that fires as each window starts and inhibits every grouping cell, so that
each window's light and dark grouping cells compete afresh."""

import numpy as np
import pytest

from snn_fg.backends import RunSettings, available_backends, get_backend
from snn_fg.errors import ParameterError
from snn_fg.events import image_to_events, iter_windows
from snn_fg.frames.scenes import disc, flipping_disc_recording
from snn_fg.lowering.input_spikes import event_spikes
from snn_fg.models import get_model
from snn_fg.models.spiking.continuous import run_spiking_windows
from snn_fg.network import Gains, SpikingParams, build_network
from snn_fg.params import ModelParams
from snn_fg.scoring.outline import inward_score

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)

BRIAN2 = pytest.mark.skipif(not available_backends()["brian2"][0], reason="needs Brian2 to compare with")


def test_the_network_has_one_clock_onto_every_grouping_population():
    net = build_network(ModelParams(levels=3), (40, 52))
    clock = net.one("clock", 1)
    assert clock.size == 1 and clock.is_source
    targets = sorted(pr.target for pr in net.outgoing(clock.name))
    assert targets == sorted(p.name for p in net.populations if p.role in ("group_L", "group_D"))
    assert all(pr.sign == -1 for pr in net.outgoing(clock.name))
    assert not build_network(ModelParams(levels=3), (40, 52), SpikingParams(gains=Gains(clock_inh_group=0))).by_role(
        "clock"
    )
    # a resized network keeps its one-cell clock
    assert net.resized((64, 48)).one("clock", 1).level_shape == (1, 1)


def _flip_recording(window_ms=85.0):
    scenes, rec = flipping_disc_recording(24, windows=4, window_ms=window_ms)
    return scenes, list(iter_windows(rec, window_ms=window_ms))


@pytest.fixture(scope="module")
def flip_runs():
    scenes, windows = _flip_recording()
    runs = {
        clock: run_spiking_windows(
            windows, params=ModelParams(levels=4), backend="fast", window_clock=clock, progress=False
        )
        for clock in (True, False)
    }
    return scenes, runs


@pytest.mark.slow
def test_one_window_of_a_recording_runs_as_a_recording_of_that_window():
    """The spiking model's ``run_window`` simulates the window and the
    read-out lag once, its events fed once (no replay up to a frame's
    400 ms), with the window clock: the dark disc after a light one, run
    alone, still points inwards."""
    scenes, windows = _flip_recording()
    maps = get_model("spiking", ModelParams(levels=4), backend="fast").run_window(windows[1])
    sim = maps.params["simulation"]
    span_ms = (windows[1].t_end_us - windows[1].t_start_us) / 1000.0
    assert sim["mode"] == "continuous" and sim["network_builds"] == 1 and sim["window_clock"] is True
    assert sim["simulated_ms"] == pytest.approx(span_ms + sim["readout_lag_ms"], abs=0.5)
    frac, n = inward_score(maps.fg_x, maps.fg_y, scenes[1].labels > 0)
    assert frac >= 0.95 and n >= 30, (frac, n)


def test_a_last_window_cut_short_by_the_recording_is_read_out_over_a_whole_window():
    """A recording's last window ends 1 us after its last event; when that
    event sits on a window boundary the window is shorter than a step. A
    stream's end is not known ahead, so it is read out over a whole window's
    span like every other (not over none, which gave NaN maps), and the run
    simulates no further than that span's end."""
    from snn_fg.events import Recording

    _, rec = flipping_disc_recording(24, windows=2, window_ms=60.0)
    last = rec.events[-1:].copy()
    last["t"] = 120_000  # on the boundary after the second window
    rec = Recording(events=np.concatenate([rec.events, last]), sensor_size=rec.sensor_size, format="synthetic")
    windows = list(iter_windows(rec, window_ms=60.0))
    assert len(windows) == 3 and windows[-1].t_end_us - windows[-1].t_start_us == 1
    maps = run_spiking_windows(windows, params=ModelParams(levels=3), backend="fast", progress=False)
    for m in maps:
        assert all(np.isfinite(getattr(m, k)).all() for k in ("fg_x", "fg_y", "grouping"))
    sim = maps[-1].params["simulation"]
    assert sim["count_to_ms"] - sim["count_from_ms"] == pytest.approx(60.0)
    assert sim["simulated_ms"] == pytest.approx(180.0 + sim["readout_lag_ms"])


def _inward(scenes, maps):
    return [inward_score(m.fg_x, m.fg_y, sc.labels > 0) for sc, m in zip(scenes, maps)]


@pytest.mark.slow
def test_with_the_clock_every_window_groups_its_own_figure(flip_runs):
    """With the clock, every window of the polarity-flipping disc points
    inwards (the discs differ only in polarity, so each window must pick the
    other family); the run records that the clock fired."""
    scenes, runs = flip_runs
    scores = _inward(scenes, runs[True])
    assert all(frac >= 0.95 and n >= 30 for frac, n in scores), scores
    assert runs[True][0].params["simulation"]["window_clock"] is True
    assert runs[False][0].params["simulation"]["window_clock"] is False


@pytest.mark.slow
def test_without_the_clock_a_window_inherits_the_previous_family(flip_runs):
    """The hysteresis the clock removes: without it, a dark-disc window that
    follows a light-disc one has its vectors pointing inwards markedly less."""
    scenes, runs = flip_runs
    without = _inward(scenes, runs[False])
    assert min(frac for frac, _ in without[1::2]) < 0.8, without


def _disc_input(ms=120.0):
    """120 ms of a disc's events (circular microsaccade) as input spikes at dt = 0.5 ms."""
    rec = image_to_events(disc(12).image, motion="circle")
    return event_spikes(rec.events[rec.events["t"] < ms * 1000], rec.sensor_size, 0.5, replay=False, t0_us=0)


def _clocked_input(window_ms=60.0):
    return _disc_input().with_clock([0, int(window_ms / 0.5)])


@pytest.mark.slow
@BRIAN2
def test_clock_spikes_are_identical_to_brian2s_and_silence_the_grouping_cells():
    """On a small network whose clock fires at 0 and 60 ms, the fast engine
    and Brian2 give the same spikes; grouping cells fire before 60 ms and
    none fires in the 10 ms after the pulse arrives."""
    inp = _clocked_input()
    net = build_network(ModelParams(levels=2), inp.shape).calibrated(inp.rate_hz)
    settings = RunSettings(duration_ms=100.0, dt_ms=net.dt_ms, instantiate="all")
    runs = {name: get_backend(name).simulate(net, inp, settings) for name in ("brian2", "fast")}
    group_times = []
    for name in runs["brian2"].populations:
        ordered = {}
        for backend in ("brian2", "fast"):
            cell, t = runs[backend].spikes[name]
            order = np.lexsort((cell, t))
            ordered[backend] = (cell[order], t[order])
        np.testing.assert_array_equal(ordered["fast"][0], ordered["brian2"][0], err_msg=name)
        np.testing.assert_allclose(ordered["fast"][1], ordered["brian2"][1], err_msg=name)
        if name.startswith("group_"):
            group_times.append(ordered["brian2"][1])
    t = np.concatenate(group_times)
    delay = net.outgoing("clock_1")[0].delay_ms
    assert np.count_nonzero((t >= 40) & (t < 60)) > 0
    # (the pulse reaches the cells after their update of the step it arrives in)
    assert np.count_nonzero((t > 60 + delay) & (t <= 70 + delay)) == 0


@pytest.mark.slow
def test_a_network_without_a_clock_ignores_clock_spikes():
    """Clock spikes given to a network without a clock change nothing."""
    inp = _clocked_input()
    net = build_network(ModelParams(levels=2), inp.shape, SpikingParams(gains=Gains(clock_inh_group=0))).calibrated(
        inp.rate_hz
    )
    settings = RunSettings(duration_ms=100.0, dt_ms=net.dt_ms)
    a, b = (get_backend("fast").simulate(net, x, settings) for x in (inp, _disc_input()))
    for name in a.populations:
        np.testing.assert_array_equal(a.counts[name], b.counts[name], err_msg=name)
    assert sum(int(a.counts[n].sum()) for n in a.populations) > 0


def test_a_repeating_input_has_no_windows_to_mark():
    rec = image_to_events(disc(12).image)
    inp = event_spikes(rec.events, rec.sensor_size, 0.5, replay=True)
    with pytest.raises(ParameterError, match="period_steps"):
        inp.with_clock([0])


@pytest.mark.slow
def test_a_frame_gives_the_same_maps_with_or_without_a_clock():
    """A frame never fires the clock: the default network (with one) gives
    the maps of the network without it, on both engines."""
    from snn_fg.events import image_to_frame
    from snn_fg.models.spiking import run_spiking

    pos, neg = image_to_frame(disc(12).image)
    for backend in ("fast", "brian2") if available_backends()["brian2"][0] else ("fast",):
        runs = [
            run_spiking(
                pos,
                neg,
                params=ModelParams(levels=2),
                spiking=SpikingParams(gains=Gains(clock_inh_group=g)),
                backend=backend,
                duration_ms=120.0,
                progress=False,
            )
            for g in (300.0, 0.0)
        ]
        assert [r.params["network"]["spiking_params"]["gains"]["clock_inh_group"] for r in runs] == [300.0, 0.0]
        for k in ("fg_x", "fg_y", "grouping"):
            np.testing.assert_array_equal(getattr(runs[0], k), getattr(runs[1], k), err_msg=f"{backend} {k}")
        assert np.abs(runs[0].fg_x).sum() > 0


@pytest.mark.slow
@pytest.mark.skipif(not available_backends()["nest"][0], reason="needs NEST (pip install -e '.[nest]')")
def test_nest_receives_the_clock_too():
    """The NEST backend wires the clock like the others: its grouping cells
    fire before the 60 ms pulse and not in the 10 ms after it arrives."""
    inp = _clocked_input()
    net = build_network(ModelParams(levels=2), inp.shape).calibrated(inp.rate_hz)
    res = get_backend("nest").simulate(net, inp, RunSettings(duration_ms=100.0, dt_ms=net.dt_ms))
    t = np.concatenate([res.spikes[n][1] for n in res.populations if n.startswith("group_")])
    delay = net.outgoing("clock_1")[0].delay_ms
    assert np.count_nonzero((t >= 40) & (t < 60)) > 0
    assert np.count_nonzero((t > 60 + delay) & (t <= 70 + delay)) == 0


def _same_maps(a, b):
    """Two lists of a recording's maps hold the same arrays and the same
    parameters (timings aside)."""
    assert len(a) == len(b)
    for x, y in zip(a, b):
        for k in ("fg_x", "fg_y", "grouping"):
            np.testing.assert_array_equal(getattr(x, k), getattr(y, k))
        assert x.extra.keys() == y.extra.keys()
        for k in x.extra:
            np.testing.assert_array_equal(x.extra[k], y.extra[k], err_msg=k)
        px, py = dict(x.params), dict(y.params)
        px.pop("timings_s"), py.pop("timings_s")
        assert px == py


@pytest.mark.slow
@pytest.mark.parametrize("backend", ["fast", pytest.param("brian2", marks=BRIAN2)])
def test_a_run_that_forgets_each_bin_once_read_gives_the_kept_runs_maps(backend):
    """``keep_run=False`` (what ``snn-fg run`` does: the backend hands each
    counting bin over and forgets it, so memory does not grow with the
    recording) gives the maps, records and parameters of the run that keeps
    every bin, with overlapping windows (each read from two bins) and the
    spike log cut between bins by the fast engine."""
    from snn_fg.models.spiking.continuous import simulate_windows, window_maps

    _, rec = flipping_disc_recording(24, windows=3, window_ms=40.0)
    windows = list(iter_windows(rec, window_ms=40.0, stride_ms=20.0))
    assert len(windows) >= 5
    kw = dict(params=ModelParams(levels=3), backend=backend, progress=False)
    kept = simulate_windows(windows, **kw)
    streamed = simulate_windows(windows, keep_run=False, **kw)
    assert kept.result.binned_counts is not None and kept.result.spikes is not None
    if backend == "fast":
        assert streamed.result.binned_counts is None and streamed.result.spikes is None
    maps = window_maps(streamed)
    _same_maps(window_maps(kept), maps)
    assert sum(int(m.extra["raster_t_ms"].size) for m in maps if "raster_t_ms" in m.extra) > 0
    for name, c in kept.result.counts.items():
        np.testing.assert_array_equal(streamed.result.counts[name], c, err_msg=name)
    assert streamed.result.stats.get("spikes") == kept.result.stats.get("spikes")


def test_a_hop_changes_what_is_read_out_not_how_the_network_runs():
    """Windows 85 ms long every 17 ms: the clock fires every 85 ms, not as each
    window starts (every 17 ms it held the grouping silent for good, and no
    window had a vector), so the windows that start on it are those of the run
    without the hop, to the bit, and those between have their vectors too."""
    from snn_fg.models.spiking.continuous import simulate_windows, window_maps

    _, rec = flipping_disc_recording(24, windows=3, window_ms=85.0)
    kw = dict(params=ModelParams(levels=3), backend="fast", progress=False)
    whole = window_maps(simulate_windows(list(iter_windows(rec, window_ms=85.0)), **kw))
    hop = window_maps(simulate_windows(list(iter_windows(rec, window_ms=85.0, stride_ms=17.0)), **kw))
    assert len(whole) == 3 and len(hop) > 10
    for k, m in enumerate(whole):
        h = hop[5 * k]
        assert h.params["simulation"]["count_from_ms"] == m.params["simulation"]["count_from_ms"]
        for a, b in ((h.fg_x, m.fg_x), (h.fg_y, m.fg_y), (h.grouping, m.grouping)):
            np.testing.assert_array_equal(a, b)
    vectors = [int(np.count_nonzero(np.hypot(m.fg_x, m.fg_y))) for m in whole + hop]
    assert min(vectors) > 0.5 * max(vectors)


def test_a_hop_run_that_stops_early_keeps_the_clock_its_last_read_out_reaches():
    """Hops cut short before the next period starts (the last of them at 153 ms, the next
    period at 170 ms): the read-out of the hop at 85 ms reaches past 170 ms, and the
    clock still fires there, as in the run without the hop. (Up to the last hop's
    start, the clock missed it, and near a stream's end a hop run's maps were not
    those of a run without the hop: on `dvs.es`, 26,089 more spikes by 870 ms.)"""
    from snn_fg.models.spiking.continuous import simulate_windows, window_maps

    _, rec = flipping_disc_recording(24, windows=3, window_ms=85.0)
    kw = dict(params=ModelParams(levels=3), backend="fast", progress=False)
    whole = window_maps(simulate_windows(list(iter_windows(rec, window_ms=85.0)), **kw))
    hops = [
        w for w in iter_windows(rec, window_ms=85.0, stride_ms=17.0) if w.t_start_us - rec.events["t"][0] <= 153_000
    ]
    hop = window_maps(simulate_windows(hops, **kw))
    assert len(hop) == 10
    for a, b in ((hop[5].fg_x, whole[1].fg_x), (hop[5].fg_y, whole[1].fg_y), (hop[5].grouping, whole[1].grouping)):
        np.testing.assert_array_equal(a, b)
