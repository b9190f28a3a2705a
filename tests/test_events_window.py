"""iter_windows edge cases and streaming behaviour."""

import warnings
from pathlib import Path

import numpy as np
import pytest

from snn_fg.errors import InputError, ParameterError
from snn_fg.events import EVENT_DTYPE, EmptyWindowWarning, events_to_frame, iter_windows, save_events


def ev_at(times, xs=None, ys=None, ps=None):
    n = len(times)
    ev = np.zeros(n, EVENT_DTYPE)
    ev["t"] = times
    ev["x"] = xs if xs is not None else np.arange(n) % 8
    ev["y"] = ys if ys is not None else 0
    ev["p"] = ps if ps is not None else 1
    return ev


def test_windows_partition_events_and_frames_match():
    rng = np.random.default_rng(0)
    t = np.sort(rng.integers(0, 1_000_000, 5000)) + 123
    ev = ev_at(t, rng.integers(0, 16, 5000), rng.integers(0, 8, 5000), rng.integers(0, 2, 5000))
    wins = list(iter_windows(ev, window_ms=85, sensor_size=(16, 8), chunk_events=333))
    assert [w.index for w in wins] == list(range(len(wins)))
    assert wins[0].t_start_us == t[0] and all(w.t_end_us - w.t_start_us == 85_000 for w in wins[:-1])
    # the last window ends with the recording, one microsecond after its last event
    assert wins[-1].t_end_us == t[-1] + 1 and wins[-1].t_end_us - wins[-1].t_start_us <= 85_000
    assert len(wins) == int(np.ceil((t[-1] - t[0] + 1) / 85_000))
    np.testing.assert_array_equal(np.concatenate([w.events for w in wins]), ev)
    for w in wins:
        assert ((w.events["t"] >= w.t_start_us) & (w.events["t"] < w.t_end_us)).all()
        pos, neg = events_to_frame(w.events, (16, 8))
        np.testing.assert_array_equal(w.pos, pos)
        np.testing.assert_array_equal(w.neg, neg)


def test_start_stride_and_max_windows():
    ev = ev_at(np.arange(0, 100_000, 10))
    wins = list(iter_windows(ev, window_ms=10, start_ms=20, stride_ms=25, max_windows=3, sensor_size=(8, 1)))
    assert [(w.t_start_us, w.t_end_us) for w in wins] == [(20_000, 30_000), (45_000, 55_000), (70_000, 80_000)]
    assert all(len(w.events) == 1000 for w in wins)
    over = list(iter_windows(ev, window_ms=10, stride_ms=5, sensor_size=(8, 1), max_windows=4))
    assert [len(w.events) for w in over] == [1000] * 4  # overlapping windows share events


def test_empty_window_warns_and_is_all_zero():
    ev = ev_at([0, 1000, 300_000, 300_500])
    with pytest.warns(EmptyWindowWarning, match="no events"):
        wins = list(iter_windows(ev, window_ms=100, sensor_size=(8, 1)))
    assert len(wins) == 4
    assert [len(w.events) for w in wins] == [2, 0, 0, 2]
    assert not wins[1].pos.any() and not wins[1].neg.any() and wins[1].pos.shape == (1, 8)


def test_window_longer_than_recording_gives_one_window():
    ev = ev_at(np.arange(50) * 100)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        wins = list(iter_windows(ev, window_ms=10_000, sensor_size=(8, 1)))
    assert len(wins) == 1
    assert len(wins[0].events) == 50 and wins[0].t_end_us == 49 * 100 + 1  # not 10 s past the data


def test_backwards_timestamp_names_event_index():
    ev = ev_at([0, 10, 20, 15, 30])
    with pytest.raises(InputError, match="backwards.*event 3"):
        list(iter_windows(ev, window_ms=1, sensor_size=(8, 1)))
    # also across chunk boundaries
    with pytest.raises(InputError, match="event 3"):
        list(iter_windows(ev, window_ms=1, sensor_size=(8, 1), chunk_events=3))


def test_out_of_sensor_names_event_index():
    ev = ev_at([0, 10, 20, 30], xs=[0, 1, 9, 2])
    with pytest.raises(InputError, match="outside.*event 2"):
        list(iter_windows(ev, sensor_size=(8, 1)))


def test_empty_recording_and_late_start_are_errors(tmp_path):
    with pytest.raises(InputError, match="no events"):
        list(iter_windows(np.zeros(0, EVENT_DTYPE), sensor_size=(8, 1)))
    with pytest.raises(InputError, match="after the last event") as late:
        list(iter_windows(ev_at([0, 10]), start_ms=5, sensor_size=(8, 1)))
    assert str(late.value).endswith(
        "the start, 5 ms, lies after the last event (0.01 ms after the first); pass start_ms below 0.01"
    )
    with pytest.raises(InputError, match=r"the start, 99,999,999 ms, lies after"):  # (it said 1e+08 ms)
        list(iter_windows(ev_at([0, 10]), start_ms=99_999_999, sensor_size=(8, 1)))
    assert late.value.for_command_line().endswith("; give --start-ms below 0.01")  # (the option, not the keyword)
    for bad in (
        {"window_ms": 0},
        {"window_ms": -1},
        {"start_ms": -1},
        {"window_ms": float("nan")},
        {"max_windows": 0},
        {"max_windows": "2"},
        {"stride_ms": "x"},
        {"denoise_us": "5"},
        {"refractory_us": -1},
    ):
        with pytest.raises(ParameterError):
            list(iter_windows(ev_at([0, 10]), sensor_size=(8, 1), **bad))


@pytest.mark.slow  # reads through tonic, whose import brings torch (3 s on an idle core)
def test_denoise_and_refractory_filters_use_tonic():
    # tonic's Denoise is causal: an event survives if a 4-neighbour fired within filter_time
    # before it, so isolated events and the first event of a cluster are dropped
    t = [20_000, 50_000, 50_010, 50_020, 90_000]
    ev = ev_at(t, xs=[0, 4, 5, 4, 7], ys=[0, 3, 3, 4, 7])
    w = next(iter(iter_windows(ev, window_ms=100, sensor_size=(8, 8), denoise_us=1000)))
    assert w.events["t"].tolist() == [50_010, 50_020]
    # RefractoryPeriod: dropped events also restart the pixel's refractory clock
    burst = ev_at([1000, 1010, 1020, 1090, 6000], xs=[1, 1, 1, 1, 1])
    w = next(iter(iter_windows(burst, window_ms=100, sensor_size=(8, 1), refractory_us=100)))
    assert w.events["t"].tolist() == [1000, 6000]


def test_file_input_streams(tmp_path):
    rng = np.random.default_rng(2)
    ev = ev_at(np.sort(rng.integers(0, 500_000, 3000)), rng.integers(0, 8, 3000))
    save_events(tmp_path / "r.es", ev, (8, 1))
    wins = list(iter_windows(tmp_path / "r.es", window_ms=50, chunk_events=100))
    np.testing.assert_array_equal(np.concatenate([w.events for w in wins]), ev)


def test_shared_dvs_es_windows(dataset):
    wins = list(iter_windows(dataset("events", "dvs.es"), window_ms=85, start_ms=1, chunk_events=50_000))
    assert sum(len(w.events) for w in wins) == 396_440  # everything after the 1 ms reset burst
    assert all(w.pos.shape == (240, 320) for w in wins)
    assert all((w.pos | w.neg).any() for w in wins)


@pytest.mark.slow
def test_streaming_memory_experiment_small(tmp_path):
    import json
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[1]
    report = tmp_path / "r.json"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "experiments.bench.events_streaming_memory",
            "--events",
            "200000",
            "--duration-s",
            "2",
            "--report",
            str(report),
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=root,
    )
    assert res.returncode == 0, res.stderr
    out = json.loads(report.read_text())
    assert out["events_streamed"] == 200_000
    assert out["windows"] == 24  # ceil(2 s / 85 ms)
    assert out["within_target"] and out["peak_rss_mb"] < 1024


def test_a_stream_chunk_held_whole_is_passed_on_uncopied_and_pooled_exactly():
    """The cutter passes a chunk every window holds on as it is (no copy), and one
    with events before the first window or in a hop's gap as its held events only;
    pooling puts each event on its block without touching the chunk."""
    from snn_fg.events.cutter import WindowCutter
    from snn_fg.frames.pool import pool_events

    ev = np.zeros(6, EVENT_DTYPE)
    ev["t"], ev["x"], ev["y"], ev["p"] = [0, 10, 20, 30, 40, 50], [0, 5, 8, 9, 17, 31], [1, 2, 3, 4, 5, 6], [1, 0] * 3
    cut = WindowCutter((32, 8), "test", window_ms=0.02, start_ms=0.015)
    cut.add(ev[:1])
    assert cut.held_events(ev[1:]).tolist() == ev[2:].tolist()  # (10 us lies before the first window, at 15)
    later = ev[2:]
    assert cut.held_events(later) is later
    gaps = WindowCutter((32, 8), "test", window_ms=0.01, stride_ms=0.02)  # (windows [0, 10), [20, 30), ...)
    gaps.add(ev[:1])
    assert gaps.held_events(ev)["t"].tolist() == [0, 20, 40]
    before = ev.copy()
    pooled = pool_events(ev, 3)
    assert pooled["x"].tolist() == [0, 1, 2, 3, 5, 10] and pooled["y"].tolist() == [0, 0, 1, 1, 1, 2]
    assert pooled["t"].tolist() == ev["t"].tolist() and pooled["p"].tolist() == ev["p"].tolist()
    assert ev.tolist() == before.tolist()


def test_a_window_handed_out_is_not_kept_while_its_chunk_yields_the_rest():
    """A chunk of events can complete thousands of short windows at once; a window whose frames were
    read must go when its reader lets it go, not when the chunk's last window is handed out
    (`snn-fg events --window-ms 0.001` held every window's frames: 24 GB, a new user's trial, 1 Dec)."""
    import gc
    import weakref

    ev = ev_at(np.arange(1000) * 10)  # (one chunk of 1000 events, a window every 10 us of a 1 us window grid)
    windows = iter_windows(ev, window_ms=0.01, sensor_size=(8, 1), chunk_events=10_000)
    first = next(windows)
    assert first.pos.any()  # (its frames made)
    gone = weakref.ref(first)
    del first
    next(windows)
    gc.collect()
    assert gone() is None


def test_a_stream_of_many_events_within_a_millisecond_is_warned_of_as_times_in_milliseconds():
    """40,000 events with times in ms made one window of 0.1 ms, without a word (a new user's trial, 1 Dec)."""
    from snn_fg.errors import InputWarning

    ev = ev_at(np.arange(2000) // 2, np.arange(2000) % 8)  # (1000 "ms" read as 1000 us)
    with pytest.warns(InputWarning, match="all 2,000 events lie within 999 us.*milliseconds"):
        assert len(list(iter_windows(ev, sensor_size=(8, 1)))) == 1
    with warnings.catch_warnings():
        warnings.simplefilter("error", InputWarning)  # (the same events in microseconds: 1 ms of them, no word)
        list(iter_windows(ev_at(np.arange(2000) * 1000 // 2, np.arange(2000) % 8), sensor_size=(8, 1)))
