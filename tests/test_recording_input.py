"""A recording's input made as the run needs it: spikes from events handed
over chunk by chunk, and the fast engine fed a segment of steps at a time,
give what the whole recording's input at once gives, bit for bit."""

import numpy as np
import pytest

from snn_fg.backends.fast import FastBackend
from snn_fg.events import EVENT_DTYPE, RecordingWindows, iter_windows
from snn_fg.frames.scenes import flipping_disc_recording
from snn_fg.lowering.input_spikes import event_spikes
from snn_fg.lowering.input_stream import SpikeStream
from snn_fg.models.spiking import recording_input
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
def test_the_engine_fed_segment_by_segment_gives_the_run_fed_whole(monkeypatch, adapter):
    """Overlapping windows of a recording read twice (a RecordingWindows
    over the events), the input handed over in segments of 7 steps (cut
    across windows and counting bins): the maps, spike counts, records and
    parameters are those of the engine fed the whole run's input from a
    list of the windows, with and without an input adapter (pooling and a
    refractory period: the calibration rate is then counted on its spikes)."""
    monkeypatch.setattr(recording_input, "SEGMENT_MS", 3.5)
    _, rec = flipping_disc_recording(24, windows=3, window_ms=40.0)
    opts = dict(window_ms=40.0, stride_ms=25.0)
    kw = dict(params=ModelParams(levels=3), progress=False, keep_run=False)
    if adapter != "none":
        kw.update(
            params=ModelParams(levels=3, input_pool=2), spiking=SpikingParams(input=Input(input_refractory_ms=3.0))
        )
    whole = simulate_windows(list(iter_windows(rec, **opts)), backend=_WholeInputFast(), **kw)
    fed = simulate_windows(RecordingWindows(rec, **opts), backend=FastBackend(), **kw)
    assert fed.n_windows == whole.n_windows >= 4
    assert whole.result.stats["input_spikes"] > 0
    if adapter != "none":
        assert fed.origin["calibrated"] == whole.origin["calibrated"]
    _same_runs(whole, fed)
