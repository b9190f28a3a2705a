"""A live stream's dropped time costs no simulation: the stream says where the
network may go on (LiveStream.resume_at), the fast engine skips those steps
with every cell put at rest, and the windows after the gap are those of a
run that began there; a run without drops is not touched."""

import threading
import time

import numpy as np
import pytest

from snn_fg.backends.fast import FastBackend, core
from snn_fg.errors import ParameterError
from snn_fg.events.live import LiveStream
from snn_fg.frames.scenes import flipping_disc_recording
from snn_fg.models.spiking.continuous import simulate_windows
from snn_fg.models.spiking.options import READOUT_LAG_MS

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


class _Given:
    """A source of the given packets, held until ``gate`` is set."""

    name, malformed = "test://", 0

    def __init__(self, packets, sensor_size, gate):
        self.list, self.sensor_size, self.gate = packets, sensor_size, gate

    def packets(self):
        self.gate.wait(10)
        for ev in self.list:
            yield ev, time.perf_counter()

    def close(self):
        pass


def _stream(events, sensor_size, dropped=(), **options):
    """A live stream of ``events`` whose slots ``dropped`` were dropped (as a model that fell behind drops them)."""
    gate = threading.Event()
    options.setdefault("lag_ms", READOUT_LAG_MS)  # (as snn-fg live gives it: the spiking network's)
    stream = LiveStream(_Given([events], sensor_size[:2], gate), max_behind=10**6, **options)
    with stream.lock:
        stream.dropped_slots |= set(dropped)
        stream.dropped_windows |= set(dropped)  # (one slot a window: stride = window)
    gate.set()
    return stream


def test_the_stream_says_where_a_model_may_go_on_past_its_dropped_slots():
    """10 ms slots, 40 ms windows read out 20 ms late, slots 5-9 dropped (windows
    2-9 hold one): the network runs on while window 1 is still read out (to 60
    ms), then skips to each next slot while every window read out is dropped,
    and runs again at slot 10, which brings events; the time skipped is counted."""
    ended = threading.Event()
    ended.set()
    stream = LiveStream(_Given([], (8, 8), ended), window_ms=40.0, stride_ms=10.0, max_behind=10**6, lag_ms=20.0)
    with stream.lock:
        stream.dropped_slots |= {5, 6, 7, 8, 9}
        stream.dropped_windows |= set(range(2, 10))
    got = {t: stream.resume_at(t * 1000.0) / 1000 for t in (40, 50, 60, 65, 70, 80, 90, 100)}
    assert got == {40: 40, 50: 50, 60: 60, 65: 65, 70: 80, 80: 90, 90: 100, 100: 100}
    assert stream.stats()["simulated_ms_dropped"] == 30.0
    stream.published = 1  # (window 1 published: nothing reads slot 6 any more)
    assert stream.resume_at(60_000.0) == 70_000.0


def _run(stream, steps):
    """The spiking network on ``stream`` (50 steps a segment): each window's maps, published and passed."""
    maps = {}

    def published(w, m):
        maps[w.index] = m
        stream.done(w)

    simulate_windows(
        stream,
        network="compact",  # (its gains are calibrated to its input adapter's ceiling: the same in every run)
        progress=False,
        keep_run=False,
        on_window=published,
        segment_ms=5.0,
        backend=_Counting(steps),
    )
    return maps


class _Counting(FastBackend):
    """The fast engine, noting each range of steps its compiled loop simulates."""

    def __init__(self, steps):
        super().__init__()
        self.steps = steps

    def simulate(self, network, inputs, settings):
        self.steps.append(settings.dt_ms)
        return super().simulate(network, inputs, settings)


@pytest.fixture
def noted_steps(monkeypatch):
    """``[dt_ms, (n0, n1), ...]``: the steps the fast engine simulated."""
    noted = []
    run_steps = core.run_steps

    def counted(n0, n1, *rest):
        noted.append((n0, n1))
        return run_steps(n0, n1, *rest)

    monkeypatch.setattr(core, "run_steps", counted)
    return noted


def test_a_dropped_slot_is_not_simulated_and_the_network_goes_on_from_rest(noted_steps):
    """Four 85 ms windows of the compact network, the second dropped (its
    events never came): the steps from 105 ms (window 0's read-out end, 20 ms
    late) to 170 ms are never simulated and window 1 is not read out; window
    0 is that of the same events with nothing dropped (the network running on
    through the silence), and windows 2 and 3 are bit for bit those of a run
    given only their events: the network after the gap is at rest, with no
    spike of before it still on its way."""
    _, rec = flipping_disc_recording(24, windows=4, window_ms=85.0)
    ev = rec.events.copy()
    ev["t"] -= ev["t"][0]
    assert ev["t"][ev["t"] >= 170_000][0] == 170_000  # (window 2's first event starts the later run's first window)
    kept = ev[(ev["t"] < 85_000) | (ev["t"] >= 170_000)]
    steps: list = []
    gap = _run(_stream(kept, rec.sensor_size, {1}, window_ms=85.0), steps)
    dt = steps[0]
    a, b = round(105 / dt), round(170 / dt)
    ran = np.zeros(max(n1 for _, n1 in noted_steps), bool)
    for n0, n1 in noted_steps:
        assert not ran[n0:n1].any()  # (each step once)
        ran[n0:n1] = True
    assert not ran[a:b].any() and ran[:a].all() and ran[b : b + round(170 / dt)].all()
    silent = _run(_stream(kept, rec.sensor_size, window_ms=85.0), [])
    later = _run(_stream(ev[ev["t"] >= 170_000], rec.sensor_size, window_ms=85.0), [])
    assert sorted(gap) == [0, 2, 3] and sorted(silent) == [0, 1, 2, 3] and sorted(later) == [0, 1]
    for x, y in [(gap[0], silent[0]), (gap[2], later[0]), (gap[3], later[1])]:
        for k in ("fg_x", "fg_y", "grouping"):
            np.testing.assert_array_equal(getattr(x, k), getattr(y, k))
    assert np.abs(gap[2].fg_x).sum() > 0 and np.abs(gap[3].grouping).sum() > 0  # (maps, not zeros)
    assert not np.array_equal(
        gap[2].grouping, silent[2].grouping
    )  # (the network run through the gap carried its state)


def test_a_stream_cut_for_another_read_out_lag_than_the_network_reads_is_refused():
    """The stream drops windows by where their read-outs end: one told another lag
    than the network's would drop what is still read out, so it is refused."""
    _, rec = flipping_disc_recording(24, windows=2, window_ms=85.0)
    with pytest.raises(ParameterError, match="read-outs 0 ms late; the network reads them 20 ms late"):
        _run(_stream(rec.events, rec.sensor_size, window_ms=85.0, lag_ms=0.0), [])


def test_hops_behind_the_stream_skip_read_outs_only_and_the_hops_made_are_a_runs():
    """10 ms hops over 85 ms windows, every event received before the network starts: each hop
    whose next hop's read-out is complete too is skipped (not decoded), the network simulates
    every step (nothing dropped, nothing skipped), and the hops made equal, bit for bit, those
    of the same events run as a recording with the same hop."""
    from snn_fg.events.window import iter_windows

    _, rec = flipping_disc_recording(24, windows=2, window_ms=85.0)
    ev = rec.events.copy()
    ev["t"] -= ev["t"][0]
    stream = _stream(ev, rec.sensor_size, window_ms=85.0, stride_ms=10.0)
    stream.thread.join(5)
    live = _run(stream, [])
    whole = {}
    simulate_windows(
        list(iter_windows(rec, window_ms=85.0, stride_ms=10.0)),
        network="compact",
        progress=False,
        keep_run=False,
        on_window=lambda w, m: whole.__setitem__(w.index, m),
        segment_ms=5.0,
    )
    s = stream.stats()
    assert s["windows_dropped"] == 0 and s["simulated_ms_dropped"] == 0 and s["windows_skipped"] > 0
    assert len(live) + s["windows_skipped"] == len(whole) and len(live) < len(whole)
    assert sorted(live) == list(range(len(whole) - len(live), len(whole)))  # (the newest hops: 6-9 of 10)
    for k, m in live.items():
        for name in ("fg_x", "fg_y", "grouping"):
            np.testing.assert_array_equal(getattr(m, name), getattr(whole[k], name))
    assert any(np.abs(m.fg_x).sum() > 0 for m in live.values())  # (maps, not zeros)
