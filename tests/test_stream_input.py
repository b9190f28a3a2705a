"""A recording's input made as the run needs it, read once: spikes from events handed
over chunk by chunk, and the fast engine fed a segment of steps at a time,
give what the whole recording's input at once gives, bit for bit; a run laid
out ahead of its stream and stopped at its end gives the maps of a run that
knew the windows beforehand, and asks for no event before the step it simulates."""

import numpy as np
import pytest

from snn_fg.backends.fast import FastBackend
from snn_fg.events import EVENT_DTYPE, RecordingWindows, iter_windows
from snn_fg.frames.scenes import flipping_disc_recording
from snn_fg.lowering.input_spikes import event_spikes
from snn_fg.lowering.input_stream import SegmentedInput, SpikeStream
from snn_fg.models.spiking.continuous import simulate_windows, window_maps
from snn_fg.network import Input, SpikingParams
from snn_fg.params import ModelParams

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


def _events(n=4000, w=9, h=7, span_us=40_000, seed=3):
    rng = np.random.default_rng(seed)
    ev = np.zeros(n, EVENT_DTYPE)
    ev["x"], ev["y"] = rng.integers(0, w, n), rng.integers(0, h, n)
    ev["t"] = np.sort(rng.integers(0, span_us, n))
    ev["p"] = rng.integers(0, 2, n)
    return ev


@pytest.mark.parametrize("refractory_ms", [0.0, 2.0])
def test_spikes_of_events_added_in_chunks_are_those_of_all_the_events_at_once(refractory_ms):
    """Chunks cut inside a step (two events of one source in that step
    merge across the cut) and spikes taken at other points than the cuts:
    the refractory period carries over, and the spikes, their order and the
    merged count are event_spikes' on the whole."""
    ev = _events()
    whole = event_spikes(ev, (9, 7), 0.5, replay=False, t0_us=0, refractory_ms=refractory_ms)
    stream = SpikeStream((7, 9), 0.5, 0, refractory_ms)
    cuts = [0, 1, 997, 998, 2500, 3999, 4000]
    assert ev["t"][997] // 500 == ev["t"][996] // 500 or ev["t"][998] // 500 == ev["t"][997] // 500
    parts = []
    for a, b in zip(cuts, cuts[1:]):
        stream.add(ev[a:b])
        complete = int(ev["t"][b - 1] // 500)  # (later events may still fall in this step)
        parts.append(stream.take_until(complete - 3))
    parts.append(stream.take_until(10**9))
    idx, steps = (np.concatenate([p[k] for p in parts]) for k in (0, 1))
    np.testing.assert_array_equal(idx, whole.indices)
    np.testing.assert_array_equal(steps, whole.steps)
    assert stream.merged == whole.merged
    assert whole.merged > 0 if refractory_ms == 0 else idx.size < len(ev) - 1000  # (each case does something)
    np.testing.assert_array_equal(stream.on, whole.on)
    np.testing.assert_array_equal(stream.off, whole.off)


class _WholeInputFast(FastBackend):
    """The fast engine handed the whole run's input at once, as before it streamed it."""

    streams_input = False


def _same_runs(a, b):
    ma, mb = window_maps(a), window_maps(b)
    assert len(ma) == len(mb)
    for x, y in zip(ma, mb):
        for k in ("fg_x", "fg_y", "grouping"):
            np.testing.assert_array_equal(getattr(x, k), getattr(y, k))
        for k in x.extra:
            np.testing.assert_array_equal(x.extra[k], y.extra[k], err_msg=k)
        px, py = dict(x.params), dict(y.params)
        px.pop("timings_s"), py.pop("timings_s")
        px["backend"].pop("name", None), py["backend"].pop("name", None)
        assert px == py
    for name, c in a.result.counts.items():
        np.testing.assert_array_equal(b.result.counts[name], c, err_msg=name)


@pytest.mark.slow
@pytest.mark.parametrize("adapter", ["none", "pool and refractory"])
def test_the_engine_fed_segment_by_segment_gives_the_run_fed_whole(adapter):
    """Overlapping windows of a recording read once as it streams (a
    RecordingWindows over the events), the input handed over in segments of
    7 steps (cut across windows and counting bins): the maps, spike counts,
    records and parameters are those of the engine fed the whole run's
    input from a list of the windows, with and without an input adapter
    (pooling and a refractory period: the gains are then calibrated to its
    ceiling)."""
    _, rec = flipping_disc_recording(24, windows=3, window_ms=40.0)
    opts = dict(window_ms=40.0, stride_ms=25.0)
    kw = dict(params=ModelParams(levels=3), progress=False, keep_run=True)
    if adapter != "none":
        kw.update(
            params=ModelParams(levels=3, input_pool=2), spiking=SpikingParams(input=Input(input_refractory_ms=3.0))
        )
    whole = simulate_windows(list(iter_windows(rec, **opts)), backend=_WholeInputFast(), **kw)
    fed = simulate_windows(RecordingWindows(rec, **opts), backend=FastBackend(), segment_ms=3.5, **kw)
    assert fed.n_windows == whole.n_windows >= 4
    assert whole.result.stats["input_spikes"] > 0
    if adapter != "none":
        assert fed.origin["calibrated"] == whole.origin["calibrated"]
        assert fed.origin["calibrated"]["to_hz"] == pytest.approx(1000 / 3.0)
    _same_runs(whole, fed)


class _Chunks:
    """A recording's events in chunks of ``n``, noting how far they have been read."""

    def __init__(self, events, n):
        self.events, self.n, self.read_to = events, n, -1

    def __iter__(self):
        for i in range(0, len(self.events), self.n):
            chunk = self.events[i : i + self.n]
            self.read_to = int(chunk["t"][-1])
            yield chunk


class _Stream:
    """A stream cut as it is read (what a live source gives the spiking model)."""

    def __init__(self, rec, chunks, **options):
        from snn_fg.events.cutter import WindowCutter

        self.chunks, self.cutter = chunks, WindowCutter(rec.sensor_size, **options)

    def cut(self):
        return self.chunks, self.cutter


@pytest.mark.slow
def test_a_run_laid_out_ahead_of_its_stream_reads_it_causally_and_ends_with_it():
    """A stream of unknown length (laid out for an hour, stopped once its last
    window is read): the maps of every window, the last included, are those
    of the run over the list of its windows (whose clock fires for those
    windows only), bit for bit; and after the first window (which calibrates
    a network without an input refractory period) each segment of input is
    asked for when the stream has been read to that segment's end and at
    most two chunks further (one read ahead on a thread): the events arrive
    as the network needs them, not a window ahead."""
    _, rec = flipping_disc_recording(24, windows=4, window_ms=40.0)
    kw = dict(params=ModelParams(levels=3), progress=False, window_ms=40.0) | {}
    listed = window_maps(
        simulate_windows(
            list(iter_windows(rec, window_ms=40.0)), params=ModelParams(levels=3), progress=False, keep_run=True
        )
    )
    chunks = _Chunks(rec.events, 50)
    asked = []
    streamed = []
    stream = _Stream(rec, chunks, window_ms=kw.pop("window_ms"))
    run = simulate_windows(
        stream,
        keep_run=False,
        on_window=lambda w, m: streamed.append(m),
        segment_ms=2.0,
        backend=_Noting(asked, chunks),
        **kw,
    )
    assert run.n_windows == len(listed) == len(streamed) == 4 and len(run.spans) > 1000  # (stopped early)
    for a, b in zip(listed, streamed, strict=True):
        for k in ("fg_x", "fg_y", "grouping"):
            np.testing.assert_array_equal(getattr(a, k), getattr(b, k))
    t0, ev_t = int(rec.events["t"][0]), rec.events["t"]
    # (a network without an input refractory period is calibrated on the first window: none runs before it is read)
    assert all(read_to >= t0 + 40_000 for _, read_to in asked)
    later = [(s, r) for s, r in asked[:-5] if t0 + s * 500 > t0 + 40_000 + 2 * 500 * 4]
    assert len(later) > 50
    for end_step, read_to in later:
        end_us = t0 + end_step * 500  # (0.5 ms steps)
        assert read_to >= min(end_us, ev_t[-1])  # every event before the segment's end was read
        assert np.count_nonzero((ev_t >= end_us) & (ev_t <= read_to)) <= 2 * 50  # (one chunk past it, one read ahead)


class _Noting(FastBackend):
    """The fast engine, noting how far the stream had been read as each segment of input was asked for."""

    def __init__(self, asked, chunks):
        super().__init__()
        self.asked, self.chunks = asked, chunks

    def simulate(self, network, inputs, settings):
        segment = inputs.segment

        def noted(j):
            out = segment(j)
            self.asked.append(((j + 1) * inputs.segment_steps, self.chunks.read_to))
            return out

        inputs.segment = noted
        return super().simulate(network, inputs, settings)


def test_the_whole_input_of_a_drained_stream_marks_the_sources_that_fire():
    """A backend that takes the run's input whole gets it once the stream has
    ended: its ``fired`` marks the sources that fire then (so that such a
    backend can create only the cells their spikes reach), while ``on`` and
    ``off`` stay the sources the run was laid out with (every one, as for the
    fast engine: they make the edge masks)."""
    ev = _events(n=600, w=5)  # (events on the 5 left columns of a 7 x 9 grid)
    stream = SpikeStream((7, 9), 0.5, 0, 2.0)
    stream.add(ev)
    every = np.ones((7, 9), bool)
    inp = SegmentedInput((7, 9), every, every.copy(), 200.0, 0, 10, stream.take_until, np.array([0, 40]))
    whole = inp.whole()
    on, off = np.zeros((7, 9), bool), np.zeros((7, 9), bool)
    on[ev["y"][ev["p"] == 1], ev["x"][ev["p"] == 1]] = True
    off[ev["y"][ev["p"] == 0], ev["x"][ev["p"] == 0]] = True
    np.testing.assert_array_equal(whole.fired[0], on)
    np.testing.assert_array_equal(whole.fired[1], off)
    assert not on[:, 5:].any() and on.sum() + off.sum() > 40
    np.testing.assert_array_equal(whole.on, every)
    np.testing.assert_array_equal(whole.off, every)
    assert np.count_nonzero(whole.indices == whole.clock_index) == 2


def test_a_read_ahead_closed_before_its_end_does_not_wait_for_its_reading_thread():
    """A run stopped part way (bad input further on) leaves its read-ahead unfinished; the garbage
    collector closes it whenever it runs, inside threading's own locks too, where waiting for the
    reading thread deadlocked (a test run hung in Thread.start). Closing it returns at once; the
    reading thread ends once its read is done."""
    import threading

    from snn_fg.models.spiking.continuous import read_ahead

    gate = threading.Event()

    def slow():
        yield 1
        gate.wait(timeout=30)  # (the second read: held until the test lets it go)
        yield 2

    ahead = read_ahead(slow())
    assert next(ahead) == 1  # (the reading thread is now held in the second read)
    closing = threading.Thread(target=ahead.close)
    closing.start()
    closing.join(timeout=5)
    held = closing.is_alive()
    gate.set()
    closing.join()
    assert not held


@pytest.mark.parametrize("gap", [0, 3])
def test_the_compiled_passes_of_a_stream_give_what_the_sorts_give(gap):
    """A segment's spikes, its clock's put in place and its cell numbers are made in
    compiled passes where the spikes come in order: each equals numpy's sorted result,
    and out-of-order input takes the sorting route to the same answer."""
    from snn_fg.backends.fast.feed import input_events
    from snn_fg.lowering.input_spikes import step_spikes
    from snn_fg.lowering.input_stream import _in_order_spikes, _with_clock

    rng = np.random.default_rng(gap)
    n_src = 50
    step = np.sort(rng.integers(0, 40, 3000)).astype(np.int64)
    idx = rng.integers(0, n_src, step.size).astype(np.int64)
    last_a, last_b = (np.full(n_src, -max(gap, 1), np.int64) for _ in range(2))
    fired = np.zeros(n_src, bool)
    want_i, want_s, want_m = step_spikes(step, idx, n_src, gap, last_a)
    got_i, got_s, got_m = _in_order_spikes(step, idx, gap, last_b, fired)
    np.testing.assert_array_equal(got_i, want_i)
    np.testing.assert_array_equal(got_s, want_s)
    assert got_m == want_m and (want_m > 0) == (gap == 0)
    np.testing.assert_array_equal(last_b, last_a)
    np.testing.assert_array_equal(np.flatnonzero(fired), np.unique(want_i))
    assert _in_order_spikes(step[::-1].copy(), idx, gap, last_b, fired)[2] == -1  # (steps that decrease)

    clock = np.array([0, 7, 7, 39, 45], np.int64)
    merged = _with_clock(want_i, want_s, clock, n_src)
    both_i, both_s = np.concatenate([want_i, np.full(clock.size, n_src)]), np.concatenate([want_s, clock])
    order = np.lexsort((both_i, both_s))
    np.testing.assert_array_equal(merged[0], both_i[order])
    np.testing.assert_array_equal(merged[1], both_s[order])
    assert _with_clock(want_i[::-1].copy(), want_s[::-1].copy(), clock, n_src) is None

    cells = np.concatenate([np.arange(100, 100 + n_src), [-1]])  # (the clock: no cell)
    for i, s in ((merged[0], merged[1]), (merged[0][::-1].copy(), merged[1][::-1].copy())):
        ptr, ids = input_events(cells, i, s, 30, 5)  # (steps 5-34; the rest and the clock left out)
        keep = (s >= 5) & (s < 35) & (i < n_src)
        ids_want = (cells[i[keep]]).astype(np.int32)
        order = np.lexsort((ids_want, s[keep]))
        np.testing.assert_array_equal(ids, ids_want[order])
        np.testing.assert_array_equal(ptr, np.searchsorted(s[keep][order] - 5, np.arange(31)))
