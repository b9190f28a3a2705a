"""run_live: a model on a live stream from Python, fed by your own code's event chunks (a camera
SDK, a YARP port), giving each window's maps and published line to your callback as it comes."""

import threading
import time
import warnings

import numpy as np
import pytest

from snn_fg.errors import InputError
from snn_fg.events import iter_windows
from snn_fg.events.core import as_events
from snn_fg.frames.scenes import flipping_disc_recording
from snn_fg.models import get_model, run_live
from snn_fg.params import ModelParams

#: a pyramid that fits the small frames here
SMALL = ModelParams(levels=3)


@pytest.fixture(scope="module")
def disc():
    _, rec = flipping_disc_recording(24, windows=3, window_ms=40.0)
    ev = rec.events.copy()
    ev["t"] -= ev["t"][0]
    return ev, rec.sensor_size[:2]


def _paced(ev, chunk_us=2_000):
    """The events in chunks of ``chunk_us``, each given when the wall clock reaches its end (real time)."""
    start = time.perf_counter()
    for t0 in range(0, int(ev["t"][-1]) + 1, chunk_us):
        part = ev[(ev["t"] >= t0) & (ev["t"] < t0 + chunk_us)]
        time.sleep(max(0.0, start + (t0 + chunk_us) / 1e6 - time.perf_counter()))
        yield part


@pytest.mark.parametrize("name", ["rate", "spiking"])
def test_your_own_chunks_give_each_window_the_maps_of_a_run_on_the_same_events(disc, name):
    ev, size = disc
    seen = []
    model = get_model(name, SMALL)
    summary = run_live(
        model,
        _paced(ev),
        lambda w, maps, line: seen.append((w.index, maps, line)),
        sensor_size=size,
        window_ms=40.0,
        max_behind=1000,  # (a slow machine keeps every window, later)
    )
    run = list(get_model(name, SMALL).run_windows(iter_windows(ev, sensor_size=size, window_ms=40.0)))
    assert [k for k, _, _ in seen] == [w.index for w, _ in run] == [0, 1, 2]
    for (_, live, line), (w, maps) in zip(seen, run, strict=True):
        for a, b in ((live.fg_x, maps.fg_x), (live.fg_y, maps.fg_y), (live.grouping, maps.grouping)):
            np.testing.assert_array_equal(a, b)
        assert line["window"] == w.index and line["events"] == len(w.events) and line["latency_ms"] > 0
    assert summary["windows"] == 3 and summary["windows_dropped"] == 0
    assert summary["events_received"] == len(ev) and summary["ended"] == "the sender closed the stream"
    assert summary["warm_up_s"] > 0 and [r["window"] for r in summary["per_window"]] == [0, 1, 2]
    # (a window's own time is the rate model's alone: the spiking model's timings are its whole run's, whose
    # median grew with the run and would have called a long run slower than its stream)
    assert ("model_ms_a_window" in summary) == (name == "rate")


def test_a_chunk_that_is_not_events_is_one_error_naming_the_event():
    """Times in seconds (floats) in the second chunk: the error names the stream and the event's place in it."""
    good = np.zeros(5, [("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "i1")])
    good["t"] = np.arange(5) * 1000
    bad = np.zeros(3, [("x", "i2"), ("y", "i2"), ("t", "f8"), ("p", "i1")])
    bad["t"] = [0.0051, 0.0062, 0.0073]
    with pytest.raises(InputError) as err:
        run_live(get_model("rate", SMALL), iter([good, bad]), sensor_size=(64, 48), window_ms=4.0)
    assert str(err.value).startswith("<events>: field t must hold integer microseconds") and "event 5" in str(err.value)


@pytest.mark.parametrize(
    "source, size, said",
    [
        (iter([]), None, "events handed over chunk by chunk have no sensor size of their own: give it"),
        (np.zeros(3, [("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "i1")]), (64, 48), "an iterable of event arrays"),
        (iter([]), (64, 48), "the stream ended before any event"),
    ],
)
def test_a_stream_without_a_size_or_events_or_given_as_one_array_is_one_error(source, size, said):
    with pytest.raises(InputError) as err:
        run_live(get_model("rate", SMALL), source, sensor_size=size)
    assert said in str(err.value)


def test_a_callback_slower_than_the_stream_drops_windows_and_says_so_once():
    """The windows after a slow callback are dropped by the stream's policy, said in one warning; a dropped
    window's events never came, and it is not said to be empty (its EmptyWindowWarning was noise)."""
    _, rec = flipping_disc_recording(24, windows=6, window_ms=40.0)
    ev = rec.events.copy()
    ev["t"] -= ev["t"][0]
    seen = []

    def slow(w, maps, line):
        seen.append(w.index)
        time.sleep(0.15 if w.index == 0 else 0.0)

    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        summary = run_live(get_model("rate", SMALL), _paced(ev), slow, sensor_size=rec.sensor_size[:2], window_ms=40.0)
    kinds = [type(w.message).__name__ for w in said]
    assert summary["windows_dropped"] > 0 and summary["windows"] == len(seen)
    assert len(seen) + summary["windows_dropped"] == 6
    assert kinds.count("InputWarning") == 1 and "EmptyWindowWarning" not in kinds
    # (the model waited for the callback, not for other programs: said so)
    assert summary["on_window_s"] >= 0.15 and summary["why_behind"].startswith("on_window took")


def test_a_run_says_when_it_is_ready_and_ends_where_another_thread_stops_it(disc):
    """A control loop starts its sender once the model is ready (on_ready, where snn-fg live says "ready"),
    and stops an endless stream from another thread (stop): the run ends as at the sender's end, with the
    windows before it made, and gives its summary."""
    ev, size = disc[0].copy(), disc[1]  # (its times move on as it plays again)
    said, seen, stop = [], [], threading.Event()

    def endless():
        while True:
            yield from _paced(ev)
            ev["t"] += int(ev["t"][-1]) + 1000  # (played again after itself)

    def on_window(w, maps, line):
        seen.append(w.index)
        if w.index == 2:
            stop.set()

    summary = run_live(
        get_model("rate", SMALL), endless(), on_window, sensor_size=size, window_ms=40.0, max_behind=1000,
        on_ready=lambda: said.append(len(seen)), stop=stop,
    )  # fmt: skip
    assert said == [0] and summary["ended"] == "stopped"
    assert seen[:3] == [0, 1, 2] and summary["windows"] == len(seen) and len(seen) <= 5


def test_a_chunk_that_is_not_a_structured_array_says_which_and_what_it_is():
    good = np.zeros(5, [("x", "i2"), ("y", "i2"), ("t", "i8"), ("p", "i1")])
    with pytest.raises(InputError) as err:
        run_live(get_model("rate", SMALL), iter([good, np.zeros((3, 4), np.int64)]), sensor_size=(64, 48))
    said = "<events>: chunk 1 is a int64 array of shape (3, 4), not events (fields x, y, t, p)"
    assert str(err.value) == said
    # (the check has one home, as_events, that an array read whole says too, with the array named so)
    with pytest.raises(InputError) as err:
        as_events(np.zeros((3, 4), np.int64), "<events>", what="chunk 1")
    assert str(err.value) == said


@pytest.mark.parametrize("name", ["rate", "spiking"])
def test_a_run_stopped_before_any_event_came_ends_with_its_summary(name):
    """Stopped 0.3 s in, while its own generator had given nothing yet, run_live ended in a traceback
    ('the stream ended before any event'): the caller ended it, and no window is no error then."""
    stop = threading.Event()

    def late():
        time.sleep(3)
        yield as_events(np.zeros(0, dtype=[("x", "<u2"), ("y", "<u2"), ("t", "<i8"), ("p", "u1")]))

    model = get_model(name, SMALL) if name == "rate" else get_model(name, network="compact")
    threading.Timer(0.3, stop.set).start()
    summary = run_live(model, late(), sensor_size=(32, 24), window_ms=40.0, stop=stop)
    assert summary["ended"] == "stopped" and summary["windows"] == 0
