"""snn-fg compare pairs a live run's windows with snn-fg run's by the events they hold: snn-fg stream
sends the recording's own timestamps, both runs keep their clock, and windows are paired by their
start on it (snn_fg.scoring.pairing); runs stored before keep their old pairing, and a pair that
shares no window is one line."""

import json
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from snn_fg.cli.main import main
from snn_fg.errors import ParameterError
from snn_fg.events import save_events
from snn_fg.frames.scenes import DAVIS_T0_US, flipping_disc_recording
from snn_fg.results.maps import Maps
from snn_fg.results.store import read_maps
from snn_fg.scoring.metrics import compare_maps
from snn_fg.scoring.pairing import PAIR_WITHIN_US, pair_windows
from tests.test_live import _free_port, _udp_bound

#: the options every run here shares: 25 ms windows, so that 100 ms in, the stream's first window is one of a
#: whole recording's run (window 4)
COMMON = ["--window-ms", "25", "--no-figures", "--no-progress"]


def _stream_when_bound(port, path, *options):
    """``snn-fg stream path`` to the port once the live command (on the main thread) has bound it."""
    done = {}

    def go():
        t0 = time.perf_counter()
        while not _udp_bound(port) and time.perf_counter() - t0 < 60:
            time.sleep(0.02)
        url = f"udp://127.0.0.1:{port}"
        argv = [sys.executable, "-m", "snn_fg.cli", "stream", str(path), "--to", url, "--speed", "2", *options]
        done["out"] = subprocess.run(argv, capture_output=True, text=True, timeout=120)

    th = threading.Thread(target=go)
    th.start()
    return th, done


@pytest.fixture(scope="module")
def replayed(tmp_path_factory):
    """A recording stamped in Unix time (as DAVIS cameras stamp it: past 2**32 us, so that SPIF carries it
    modulo 2**32), streamed from 100 ms in by snn-fg stream into snn-fg live; and snn-fg run on it with
    --start-ms 100, without it, and with --start-ms 90 (windows 10 ms off the stream's)."""
    tmp = tmp_path_factory.mktemp("replayed")
    _, rec = flipping_disc_recording(24, windows=8, window_ms=25.0)
    ev = rec.events.copy()
    ev["t"] += DAVIS_T0_US + 4321
    path = tmp / "disc.npz"
    save_events(path, ev, rec.sensor_size)
    port = _free_port()
    th, done = _stream_when_bound(port, path, "--start-ms", "100")
    size = f"{rec.sensor_size[0]}x{rec.sensor_size[1]}"
    live = ["live", f"udp://127.0.0.1:{port}", "--out", str(tmp / "live"), "--sensor-size", size]
    assert main([*live, "--idle-s", "0.5", "--max-behind", "1000", *COMMON]) == 0
    th.join(60)
    assert done["out"].returncode == 0, done["out"].stderr
    for name, start in (("run100", ["--start-ms", "100"]), ("run", []), ("run90", ["--start-ms", "90"])):
        assert main(["run", str(path), "--out", str(tmp / name), *start, *COMMON]) == 0
    return tmp


def _compare(capsys, tmp_path, a, b):
    """``snn-fg compare a b`` (no baseline): its status, its JSON record, what it printed."""
    capsys.readouterr()
    out = tmp_path / "c.json"
    status = main(["compare", str(a), str(b), "--no-baseline", "--json", str(out), "--force"])
    said = capsys.readouterr()
    return status, json.loads(out.read_text()) if status == 0 else None, said


@pytest.mark.parametrize("run, first", [("run100", 0), ("run", 4)])
def test_a_live_run_of_a_replay_pairs_the_windows_of_snn_fg_run_that_hold_its_events(
    replayed, run, first, capsys, tmp_path
):
    """Against the run with --start-ms 100 (windows 0-3) and the run of the whole recording (its windows
    4-7): every live window is paired with the run's window of the same events, and their maps are
    equal (the rate model: no state from before). The user's report: the first was refused (no window
    start shared) and the second paired window k with window k, 100 ms apart."""
    status, record, said = _compare(capsys, tmp_path, replayed / "live", replayed / run)
    assert status == 0, said.err
    rows = record["windows"]
    assert [(r["number_a"], r["number_b"]) for r in rows] == [(k, first + k) for k in range(4)]
    assert [r["t_start_ms"] for r in rows] == [100.0 + 25 * k for k in range(4)]  # (after the recording's first event)
    lx, ly, lg, _, lextra = read_maps(replayed / "live" / "maps.zarr")
    rx, ry, rg, _, rextra = read_maps(replayed / run / "maps.zarr")
    for r in rows:
        i, k = r["window_a"], r["window_b"]
        np.testing.assert_array_equal(lextra["event_frame"][i], rextra["event_frame"][k])  # (the same events)
        for a, b in ((lx, rx), (ly, ry), (lg, rg)):
            np.testing.assert_array_equal(a[i], b[k])
    assert "windows paired by their start on the events' own clock" in said.out
    assert "different inputs" not in said.out
    assert record["options"]["paired"].startswith("windows paired by their start on the events' own clock")


def test_a_run_whose_windows_hold_other_events_than_the_live_runs_is_refused_in_one_line(replayed, capsys, tmp_path):
    """--start-ms 90: every window of the run starts 10 ms off one of the live run's: no pair, one line."""
    status, _, said = _compare(capsys, tmp_path, replayed / "live", replayed / "run90")
    assert status == 2
    err = said.err.strip().splitlines()
    assert len(err) == 1 and "share no window start on the events' own clock" in err[0], err
    assert "A's first window starts 100 ms after B's first event, B's 90 ms" in err[0]


def test_a_live_run_keeps_the_streams_clock_which_snn_fg_stream_takes_from_the_recording(replayed):
    live = Maps.load(replayed / "live").params["source"]
    run = Maps.load(replayed / "run100").params["source"]
    assert run["clock"] == "recording" and run["first_event_us"] == DAVIS_T0_US + 4321
    assert live["clock"] == "sender" and live["clock_span_us"] == 2**32
    assert live["first_event_us"] == (DAVIS_T0_US + 4321 + 100_000) % 2**32  # (SPIF's 32 bits)


def _maps(starts_us, *, first_event_us=0, **source):
    """Maps of windows starting ``starts_us`` after their first event, each window's vectors its number."""
    n = len(starts_us)
    fx = np.ones((n, 8, 8), np.float32) * np.arange(1, n + 1, dtype=np.float32)[:, None, None]
    extra = {"t_start_us": np.asarray(starts_us, np.int64)}
    return Maps(fx, fx * 0, fx, {"source": {"first_event_us": first_event_us, **source}}, extra=extra)


def test_runs_stored_before_the_clock_was_kept_are_paired_as_before_and_said_so():
    """A run without ``clock`` (stored before) against one with it: by equal starts after each run's own first
    event, 100 ms apart on the recording here, as then; the line says which run is old."""
    old = _maps([0, 25_000, 50_000], first_event_us=5_000_100_000)  # (a replay began at 0: its clock unknown)
    new = _maps([25_000 * k for k in range(6)], first_event_us=5_000_000_000, clock="recording")
    got = pair_windows(old, new)
    assert (
        got.pairs == [(0, 0), (1, 1), (2, 2)]
        and "(A was stored without the events' clock, as before snn-fg kept it" in got.how
    )
    # the same live run kept with its clock: the windows of the same events
    kept = _maps([0, 25_000, 50_000], first_event_us=5_000_100_000, clock="sender")
    assert pair_windows(kept, new).pairs == [(0, 4), (1, 5)]


def test_windows_are_paired_by_start_on_the_events_clock_within_the_tolerance_and_modulo_a_udp_span():
    run = _maps([100_000 + 25_000 * k for k in range(4)], first_event_us=DAVIS_T0_US, clock="recording")
    lag = 7  # (the stream's first event 7 us after --start-ms)
    live = _maps([0, 25_000, 50_000], first_event_us=(DAVIS_T0_US + 125_000 + lag) % 2**32, clock="sender")
    live.params["source"]["clock_span_us"] = 2**32
    got = pair_windows(live, run)
    assert got.pairs == [(0, 1), (1, 2), (2, 3)] and got.t_us == [125_000, 150_000, 175_000]
    # (the run's window 0, before the live run began, is said to be left out)
    assert got.how.endswith("starts up to 7 us apart; left out, with no partner in the other run: 1 of B's 4 windows")
    rows = compare_maps(live, run)
    assert [r["angle_diff_mean_deg"] for r in rows] == [0.0] * 3 and [r["number_b"] for r in rows] == [1, 2, 3]
    far = _maps([0], first_event_us=(DAVIS_T0_US + 125_000 + PAIR_WITHIN_US) % 2**32, clock="sender")
    far.params["source"]["clock_span_us"] = 2**32
    with pytest.raises(ParameterError, match="share no window start"):
        pair_windows(far, run)


def test_a_run_stamped_on_arrival_is_refused_in_one_line():
    run = _maps([0, 25_000], clock="recording")
    arrival = _maps([0, 25_000], clock="arrival")
    with pytest.raises(ParameterError, match="A's events were stamped as they arrived"):
        pair_windows(arrival, run)


def test_a_udp_stream_sent_without_timestamps_is_on_the_arrival_clock():
    """snn-fg stream --no-timestamps: the receiver stamps each event as it comes, a clock no other run shares."""
    import socket

    from snn_fg.events import EVENT_DTYPE, spif
    from snn_fg.events.clock import clock_keys
    from snn_fg.events.live_sources import open_source

    src = open_source("udp://127.0.0.1:0", (64, 64), wait_s=10, idle_s=0.3)
    assert clock_keys(src) == {"clock": "sender", "clock_span_us": 2**32}
    ev = np.zeros(3, EVENT_DTYPE)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        sender.sendto(spif.encode(ev, timestamps=False), src.sock.getsockname())
        try:
            assert sum(len(e) for e, _ in src.packets()) == 3
        finally:
            src.close()
    assert clock_keys(src) == {"clock": "arrival"} and clock_keys() == {"clock": "recording"}
