"""live.json's latency says which windows waited for the end of the stream: the last window is
completed by no later event, only by the stream ending (udp://: --idle-s without a packet), so its
latency holds that wait; it is marked, and the summary is given also without it."""

import json
import time

import numpy as np

from snn_fg.cli.live import _summary_text
from snn_fg.cli.runner import run_recording
from snn_fg.events.live import LiveStream
from snn_fg.frames.scenes import flipping_disc_recording
from snn_fg.models import get_model
from snn_fg.params import ModelParams
from snn_fg.results.publish import END_OF_STREAM, LiveModel, LiveRecord, why_behind

#: how long the source stays silent after its last packet before it ends (as --idle-s would)
IDLE_S = 0.4


class _Source:
    """A window's events a packet, sent at once, then IDLE_S of silence before the stream ends."""

    name, malformed = "test://", 0

    def __init__(self, rec, window_us):
        self.sensor_size = rec.sensor_size[:2]
        t = rec.events["t"] - rec.events["t"][0]
        self.list = [rec.events[t // window_us == k] for k in range(int(t[-1] // window_us) + 1)]

    def packets(self):
        for ev in self.list:
            yield ev, time.perf_counter()
        time.sleep(IDLE_S)

    def close(self):
        pass


def test_the_window_the_end_of_the_stream_completes_is_marked_and_left_out_of_the_streaming_latency(tmp_path):
    _, rec = flipping_disc_recording(24, windows=4, window_ms=40.0)
    stream = LiveStream(_Source(rec, 40_000), window_ms=40.0, max_behind=10**6)
    record = LiveRecord(stream)
    out = tmp_path / "live"
    out.mkdir()
    model = LiveModel(get_model("rate", ModelParams(levels=3)), stream, record)
    try:
        n = run_recording(model, stream, out, {"input": "test://", "window_ms": 40.0}, figures=False)
    finally:
        stream.close()
    record.save(out / "live.json", "the sender closed the stream")
    live = json.loads((out / "live.json").read_text())
    rows = live["per_window"]
    assert n == len(rows) == 4
    assert [r["completed_by"] for r in rows] == ["the stream's events"] * 3 + [END_OF_STREAM]
    waited, others = rows[-1]["latency_ms"], [r["latency_ms"] for r in rows[:-1]]
    assert waited >= IDLE_S * 1000  # (the last window's latency holds the silence)
    assert live["latency_ms"]["max"] == max(waited, *others)  # (the key as it was: every window)
    assert live["latency_ms_streaming"]["max"] == max(others)
    assert live["latency_ms_streaming"]["median"] == float(np.median(others))
    assert live["windows_completed_by_end"] == 1
    for stats in (live["latency_ms"], live["latency_ms_streaming"]):  # (to 0.01 ms: 281.02610000000055 was said)
        assert all(v == round(v, 2) for v in stats.values()), stats
    assert live["dropped_windows"] == [] and live["why_behind"] is None
    said = _summary_text(live)
    assert f"max {max(others):.1f} ms" in said and f"not counted: {waited:.1f} ms" in said
    assert said.startswith("4 windows published, 0 dropped, ")
    # (with --hop-ms the end completes the last few hops: said as many, with the longest wait)
    hops = [*rows[:1], *({**r, "completed_by": END_OF_STREAM} for r in rows[1:])]
    said = _summary_text({**live, "per_window": hops})
    longest = max(r["latency_ms"] for r in hops[1:])
    assert f"(the last 3 windows, completed by the end of the stream, not counted: up to {longest:.1f} ms)" in said


def test_a_window_the_next_events_complete_is_not_marked():
    """The criterion: an event past the window's read-out (and, for a spiking run, the segment it
    is read in) came, so the window did not wait for the end."""

    class W:
        t_end_us = 40_000

    stream = LiveStream(_Source(flipping_disc_recording(24, windows=2, window_ms=40.0)[1], 40_000), lag_ms=20.0)
    stream.thread.join(5)
    stream.last_t = 59_999
    assert not stream.completed_by_end(W)  # (the stream goes on: its next events will complete it)
    stream.end_seen = True
    assert stream.completed_by_end(W)
    stream.last_t = 60_000
    assert not stream.completed_by_end(W)
    stream.segment_ms = 5.0
    assert stream.completed_by_end(W) and (setattr(stream, "last_t", 65_000) or not stream.completed_by_end(W))


def test_the_closing_line_says_what_the_sensor_check_dropped():
    """Events outside the sensor (a wrong --sensor-size) or back in time were warned about once, at
    the start; the closing line says how many there were in all."""
    summary = {
        "windows": 11,
        "windows_dropped": 0,
        "events_received": 361_198,
        "events_outside": 230_303,
        "events_backwards": 0,
        "latency_ms_streaming": {"median": 30.0, "p95": 40.0, "max": 50.0},
        "per_window": [],
    }
    said = _summary_text(summary)
    assert said.startswith("11 windows published, 0 dropped, 361,198 events received (230,303 outside the sensor, ")
    assert "back in time" not in said and _summary_text({**summary, "events_outside": 0}).count("(") == 0
    reach = _summary_text({**summary, "events_outside_reach": {"x": 319, "y": 239}})
    assert "(they reach x=319, y=239: is --sensor-size right?)" in reach


def test_the_closing_line_says_whether_the_model_or_the_machine_fell_behind():
    """A new user on a busy machine saw windows dropped and could not tell a slow model from a crowded
    machine: the closing line says which, from the run's CPU while the stream came."""
    summary = {
        "windows": 2,
        "windows_dropped": 10,
        "events_received": 473_225,
        "events_outside": 0,
        "events_backwards": 0,
        "latency_ms_streaming": {"median": 1678.1, "p95": 1752.2, "max": 1760.5},
        "per_window": [],
        "streamed_s": 10.0,
        "cores": 2,
    }

    def closing(**cpu):  # (the closing line, and live.json's why_behind, which the same function makes)
        s = {**summary, **cpu}
        s["why_behind"] = why_behind(s)
        return _summary_text(s), s["why_behind"]

    crowded, verdict = closing(cpu_s=3.0, model_cpu_s=2.5)
    assert verdict == (
        "the run used 15% of its 2 cores while the stream came: other programs had the rest, "
        "and the model waited for them"
    )
    assert crowded.endswith(f"; {verdict} (what to try: docs/live.md, 'If windows are dropped')")
    slow, verdict = closing(cpu_s=12.0, model_cpu_s=9.5)
    assert verdict == (
        "the run used 60% of its 2 cores while the stream came: the model is slower than the stream on this machine"
    )
    assert f"; {verdict} (what to try" in slow
    kept, verdict = closing(windows_dropped=0, cpu_s=3.0, model_cpu_s=2.5)
    assert verdict is None and "while the stream came" not in kept  # (nothing fell behind: nothing to explain)
    assert closing(windows_dropped=0, windows_skipped=3, cpu_s=3.0, model_cpu_s=2.5)[1] is not None  # (hops)
    # the stream's first windows fell behind (dvs.es from its start, its start-up burst): a share of the CPU over
    # the whole stream called other programs the cause (a new user's trial, 30 Nov); said as what it is
    start = {"windows_dropped": 0, "windows_skipped": 17, "skipped_windows": [[0, 16]], "cpu_s": 9.2, "model_cpu_s": 7}
    assert closing(**start)[1] == (
        "only the stream's first windows fell behind (0-16), and the model kept up after them (the run used 46% of "
        "its 2 cores while the stream came): a recording's start-up burst, events on most of the sensor, does this "
        "(--start-ms past it)"
    )
    # the default rate model works on threads of its own and leaves the cores idle while windows are dropped: its
    # thread's CPU and the run's share said "other programs" on an idle machine (a new user's trial, 1 Dec); a
    # model that makes each window on its own says its time for one, and that decides
    rate = {"cpu_s": 3.0, "model_cpu_s": 0.5, "model_ms_a_window": 160.0, "stride_ms": 85.0}
    assert closing(**rate)[1] == (
        "the model took 160 ms a window (the median) against the stream's 85 ms: it is slower than the stream on "
        "this machine (--network compact needs less)"
    )
    assert "other programs had the rest" in closing(**{**rate, "model_ms_a_window": 30.0})[1]
    later = {**start, "windows_skipped": 19, "skipped_windows": [[1, 16], [40, 40]], "dropped_windows": [[17, 17]]}
    assert closing(**later)[1] == (
        "the run used 46% of its 2 cores while the stream came: other programs had the rest, and the model waited "
        "for them; 17 of them at the stream's start (windows 1-17)"
    )


class _Early(_Source):
    """Packets that came before the warm-up ended, as a dv:// stream's do when its size is not given (connected
    to first, to learn it): each stamped with its arrival then, handed over once the model asks."""

    def __init__(self, rec, window_us, warm_up_s):
        super().__init__(rec, window_us)
        self.arrived = time.perf_counter()
        time.sleep(warm_up_s)  # (the warm-up, on the stream's time)

    def packets(self):
        for ev in self.list:
            yield ev, self.arrived


def test_a_warm_up_on_the_streams_time_is_named_as_why_windows_were_dropped(tmp_path):
    """Without --sensor-size a dv:// run learns the size from the stream, so it is built and warmed up after
    the stream began (0.5 s of it for the demo): its first windows were dropped, and the closing line blamed
    'other programs' (the run used 26% of its 2 cores) for what was its own warm-up. It says so, with the
    warm-up's seconds on the stream's time (live.json: warm_up_on_stream_s); a stream that came whole during
    a first run's minute of compiling, with no stream time after it, said nothing at all."""
    _, rec = flipping_disc_recording(24, windows=6, window_ms=40.0)
    stream = LiveStream(_Early(rec, 40_000, warm_up_s=0.3), window_ms=40.0, max_behind=0)
    record = LiveRecord(stream)
    record.cores = 2
    out = tmp_path / "live"
    out.mkdir()
    model = LiveModel(get_model("rate", ModelParams(levels=3)), stream, record)
    try:
        run_recording(model, stream, out, {"input": "test://", "window_ms": 40.0}, figures=False)
    finally:
        stream.close()
    live = record.summary("the sender closed the stream")
    assert live["windows_dropped"] > 0 and 0.3 <= live["warm_up_on_stream_s"] < 1.0
    assert live["why_behind"].startswith(
        f"the model was built and warmed up after the stream's first event came, for "
        f"{live['warm_up_on_stream_s']:.1f} s of the stream's time, which its first windows waited for"
    )
    for cpu in ({"streamed_s": 0.0, "cpu_s": 0.0, "model_cpu_s": 0.0}, {"cpu_s": 0.1, "model_cpu_s": 0.1}):
        assert why_behind({**live, **cpu}) == live["why_behind"]  # (all came meanwhile; an idle CPU)
    on_time = {**live, "warm_up_on_stream_s": 0.0, "streamed_s": 1.0, "cpu_s": 0.1, "model_cpu_s": 0.1}
    assert "other programs had the rest" in why_behind(on_time)  # (a warm-up before the stream: the CPU's verdict)


def test_the_cpu_share_is_measured_over_the_stream_and_stays_within_its_cores():
    """cpu_s and model_cpu_s are measured over streamed_s (the first packet's arrival to the last's),
    not from the warm-up to the summary: the model's work after the last packet (the last windows,
    the wait for the end) made a live run say it "used 119% of its 1 core". Here the model's thread
    works 0.6 s after a 0.2 s stream; that work is not the stream's."""
    import os

    class Paced(_Source):
        def packets(self):
            for ev in self.list:
                time.sleep(0.02)  # (a sender paced by the clock: the run idles between packets)
                yield ev, time.perf_counter()

    _, rec = flipping_disc_recording(24, windows=10, window_ms=20.0)
    stream = LiveStream(Paced(rec, 20_000), window_ms=20.0, max_behind=10**6)
    record = LiveRecord(stream)
    record.cores = len(os.sched_getaffinity(0))
    try:
        got = sum(len(c) for c in stream.chunks() if isinstance(c, np.ndarray))
        busy = time.thread_time() + 0.6
        while time.thread_time() < busy:  # (the model's thread at work after the stream)
            pass
    finally:
        stream.close()
    assert got == len(rec.events)
    live = record.summary("the sender closed the stream")
    wall, cores = live["streamed_s"], live["cores"]
    assert wall >= 0.1  # (the ten packets' 0.18 s, paced, to within the receiver's 10 ms sampling)
    assert live["model_cpu_s"] <= wall + 0.002  # (one thread: no more CPU than wall time)
    assert live["cpu_s"] <= wall * cores + 0.002
    assert live["why_behind"] is None  # (nothing dropped or skipped)
    share = int(why_behind({**live, "windows_dropped": 1}).split("the run used ")[1].split("%")[0])
    assert share <= 100


def test_each_published_line_says_when_it_was_sent_and_its_span_on_the_streams_own_clock(tmp_path):
    """A controller matches a window to its robot's pose by the wall clock the line was sent at (Unix
    seconds) or by the camera's own timestamps (here a DAVIS-like clock in Unix microseconds), not only
    by t_start_us, which counts from the stream's first event."""
    _, rec = flipping_disc_recording(24, windows=3, window_ms=40.0)
    camera_t0 = 1_700_000_000_000_000
    rec.events["t"] += camera_t0 - rec.events["t"][0]
    lines = []

    class Inbox:
        def send(self, message):
            lines.append(json.loads(json.dumps(message)))  # (as a subscriber reads it)

    class Page:  # (the live page: given each line with the run's counts so far, /state.json)
        shown: list = []

        def show(self, w, maps, state):
            self.shown.append(state)

    stream = LiveStream(_Source(rec, 40_000), window_ms=40.0, start_ms=5.0, max_behind=10**6)
    record = LiveRecord(stream, Inbox(), view=Page())
    out = tmp_path / "live"
    out.mkdir()
    before = time.time()
    try:
        run_recording(LiveModel(get_model("rate", ModelParams(levels=3)), stream, record), stream, out, {})
    finally:
        stream.close()
    after = time.time()
    assert [m["window"] for m in lines] == [0, 1, 2]
    for k, m in enumerate(lines):
        assert m["t_start_us"] == 5_000 + 40_000 * k  # (from the first event, 5 ms on)
        assert m["stream_t_start_us"] == camera_t0 + m["t_start_us"]  # (the events' own times)
        assert m["stream_t_end_us"] == camera_t0 + m["t_end_us"]
        assert before <= m["published_unix_s"] <= after
        assert m["latency_ms"] == round(m["latency_ms"], 2)
    assert lines[0]["published_unix_s"] <= lines[1]["published_unix_s"] <= lines[2]["published_unix_s"]
    counts = [(s["windows"], s["windows_dropped"], s["windows_skipped"]) for s in Page.shown]
    assert counts == [(1, 0, 0), (2, 0, 0), (3, 0, 0)]
    assert [{k: v for k, v in s.items() if k in m} for s, m in zip(Page.shown, lines, strict=True)] == lines
