"""A live stream in, maps and attention targets out: SPIF packets, the receiving
thread's drop policy and checks, the grouping peaks, and snn-fg live fed by
snn-fg stream's sender giving the maps of snn-fg run on the same events."""

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import matplotlib.colors as mcolors
import numpy as np
import pytest

from snn_fg.cli.main import main
from snn_fg.errors import InputWarning
from snn_fg.events import EVENT_DTYPE, save_events, spif
from snn_fg.events.live import SKIP_BEHIND, LiveStream
from snn_fg.events.replay import UdpSender, from_ms, looped, paced
from snn_fg.frames.scenes import flipping_disc_recording
from snn_fg.results.maps import Maps
from snn_fg.results.peaks import grouping_peaks
from snn_fg.results.store import read_maps


def _events(t, x=None, y=None, p=None):
    ev = np.zeros(len(t), EVENT_DTYPE)
    ev["t"] = t
    ev["x"] = np.arange(len(t)) % 7 if x is None else x
    ev["y"] = np.arange(len(t)) % 5 if y is None else y
    ev["p"] = np.arange(len(t)) % 2 if p is None else p
    return ev


def test_spif_packets_carry_the_events_and_refuse_what_is_not_whole():
    ev = _events([5, 9, 4_000_000_123], x=[0, 319, 32767], y=[239, 0, 32767], p=[1, 0, 1])
    back = spif.decode(spif.encode(ev), now_us=77)
    np.testing.assert_array_equal(back, ev)
    bare = spif.decode(spif.encode(ev, timestamps=False), now_us=77)
    assert bare["t"].tolist() == [77] * 3 and bare["x"].tolist() == [0, 319, 32767]
    data = spif.encode(ev)
    assert spif.decode(data[:-2], 0) is None  # (not whole words)
    assert spif.decode(data[:-4], 0) is None  # (a timestamped event without its time)
    unwrap = spif.Unwrap()
    assert unwrap(np.array([4_294_967_000, 4_294_967_290])).tolist() == [4_294_967_000, 4_294_967_290]
    assert unwrap(np.array([100])).tolist() == [4_294_967_396]  # (carried past 2**32)
    # a wrap inside the first batch is carried too (until 30 Nov only those after it were)
    assert spif.Unwrap()(np.array([4_294_967_290, 4])).tolist() == [4_294_967_290, 4_294_967_300]
    # a packet mixing events with and without their time words
    mixed = np.concatenate([np.frombuffer(spif.encode(ev[:1], timestamps=False), "<u4"), np.frombuffer(data, "<u4")])
    assert spif.decode(mixed.tobytes(), now_us=77)["t"].tolist() == [77, 5, 9, 4_000_000_123]


class _Packets:
    """A source whose packets are given (``arrived``: wall time of each)."""

    name, sensor_size, malformed = "test://", (20, 10), 0

    def __init__(self, packets, gate=None):
        self.list, self.gate = packets, gate

    def packets(self):
        for ev in self.list:
            if self.gate is not None:
                self.gate.wait()
            yield ev, time.perf_counter()

    def close(self):
        pass


def test_a_udp_packet_reaches_the_model_without_waiting_for_the_next():
    """Packets 20 ms apart are handed over one by one: a batch holds only the
    packets already waiting in the socket's buffer. (Until 29 Nov the socket's
    timeout made the receiver wait for one more packet before each receive:
    a batch grew to 64 packets, 160 ms of dvs.es, before the model saw any.)"""
    from snn_fg.events.live_sources import open_source

    src = open_source("udp://127.0.0.1:0", (64, 64), wait_s=10, idle_s=0.5)
    port = src.sock.getsockname()[1]
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def send():
        for k in range(10):
            sender.sendto(spif.encode(_events([1000 * k])), ("127.0.0.1", port))
            time.sleep(0.02)

    th = threading.Thread(target=send)
    th.start()
    try:
        batches = [len(ev) for ev, _ in src.packets()]
    finally:
        th.join()
        sender.close()
        src.close()
    assert sum(batches) == 10
    assert len(batches) >= 6, batches  # (one each, but where the receiving thread was held up for 20 ms)


def test_the_first_packet_is_waited_for_from_when_the_model_is_ready_not_from_the_binding():
    """A first live run's warm-up compiles the engine for up to a minute after
    the port is bound: --wait-s counts from when the receiving starts."""
    from snn_fg.events.live_sources import open_source

    src = open_source("udp://127.0.0.1:0", (64, 64), wait_s=1.0, idle_s=0.2)
    port = src.sock.getsockname()[1]
    time.sleep(1.5)  # (the warm-up: longer than wait_s)
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    threading.Timer(0.4, lambda: sender.sendto(spif.encode(_events([5])), ("127.0.0.1", port))).start()
    try:
        got = [len(ev) for ev, _ in src.packets()]
    finally:
        time.sleep(0.15)
        sender.close()
        src.close()
    assert got == [1]


def test_events_outside_the_sensor_and_back_in_time_are_dropped_counted_and_said_once():
    packets = [_events([0, 10, 20], x=[1, 25, 2]), _events([15, 30, 31]), _events([32], x=[99])]
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        stream = LiveStream(_Packets(packets), window_ms=10.0)
        got = np.concatenate(list(stream.chunks()))
    assert got["t"].tolist() == [0, 20, 30, 31]
    s = stream.stats()
    assert (s["events_received"], s["events_outside"], s["events_backwards"]) == (7, 2, 1)
    lines = [str(w.message) for w in said if issubclass(w.category, InputWarning)]
    assert len(lines) == 2 and "outside the 20 x 10 sensor" in lines[0] and "time runs backwards" in lines[1]


def test_a_model_that_falls_behind_drops_whole_windows_and_keeps_memory_bounded():
    """Nothing published: once more than max_behind windows were complete before
    a window begins, its events are dropped whole, and the queue holds at most
    max_behind + 2 windows of events (those before the first dropped: the window
    a slot's first event completes is not counted)."""
    packets = [_events(np.arange(k * 10_000, (k + 1) * 10_000, 100)) for k in range(12)]  # 12 windows of 100
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        stream = LiveStream(_Packets(packets), window_ms=10.0, max_behind=2)
        stream.thread.join(5)
    queued = sum(len(x) for x in list(stream.q.queue) if isinstance(x, np.ndarray))
    # (windows 0-3: window 4 begins with windows 0-2 complete before it and waiting, more than 2)
    assert queued == 4 * 100
    s = stream.stats()
    assert s["windows_dropped"] == 8 and s["events_dropped"] == 800
    assert s["dropped_windows"] == [[4, 11]]  # (by number, as skipped hops are: live.json lists them)
    assert sum("fell 3 windows behind" in str(w.message) for w in said) == 1
    assert stream.dropped_slots == set(range(4, 12))
    windows = list(stream)  # (the dropped ones passed over: the clock passed their events, TimePassed)
    assert [w.index for w in windows] == [0, 1, 2, 3] and stream.published == 11  # (all passed, the last at the end)


def test_once_the_model_catches_up_the_windows_are_kept_again():
    gate = threading.Event()

    class Source(_Packets):
        def packets(self):
            for k in range(12):
                if k == 6:
                    gate.wait(5)
                if k >= 6:
                    time.sleep(0.05)  # (the model keeps up from here)
                yield _events(np.arange(k * 10_000, (k + 1) * 10_000, 100)), time.perf_counter()

    stream = LiveStream(Source([]), window_ms=10.0, max_behind=2)
    while stream.slot < 5:  # (windows 0-5 arrive before the model starts: 4 and 5 are dropped)
        time.sleep(0.01)
    windows = []
    for w in stream:
        windows.append(w)
        stream.done(w)
        gate.set()
    kept = [w.index for w in windows if not stream.dropped_window(w.index) and len(w.events)]
    assert stream.stats()["windows_dropped"] == 2 and kept == [0, 1, 2, 3, 6, 7, 8, 9, 10, 11]
    assert stream.stats()["dropped_windows"] == [[4, 5]]


def test_a_model_without_read_out_lag_that_keeps_up_loses_no_window():
    """The rate model reads a window at its end: the slot whose first event completes
    a window is not dropped for that window, which no model can have had yet."""
    made = threading.Event()

    class Source(_Packets):
        def packets(self):
            made.wait(5)
            for k in range(12):
                deadline = time.perf_counter() + 5
                while stream.published < k - 2 and time.perf_counter() < deadline:  # (a stride to make its maps)
                    time.sleep(0.002)
                yield _events(np.arange(k * 10_000, (k + 1) * 10_000, 100)), time.perf_counter()

    stream = LiveStream(Source([]), window_ms=10.0, max_behind=0)
    made.set()
    kept = []
    for w in stream:
        kept.append(w.index)
        stream.done(w)
    assert stream.stats()["windows_dropped"] == 0 and kept == list(range(12))


def test_grouping_peaks_are_the_strongest_maxima_with_the_direction_around_them():
    yy, xx = np.mgrid[:40, :60]
    g = 3 * np.exp(-((xx - 15) ** 2 + (yy - 20) ** 2) / 20) + 1 * np.exp(-((xx - 45) ** 2 + (yy - 10) ** 2) / 20)
    fx, fy = np.zeros_like(g), np.zeros_like(g)
    fx[18:23, 10:14], fy[8:12, 44:47] = 1.0, -2.0
    peaks = grouping_peaks(Maps(fx.astype(np.float32), fy.astype(np.float32), g.astype(np.float32)), k=5)
    assert [(p["x"], p["y"]) for p in peaks] == [(15, 20), (45, 10)]
    assert peaks[0]["strength"] == pytest.approx(3.0) and peaks[0]["fg_deg"] == pytest.approx(0.0)
    assert peaks[1]["fg_deg"] == pytest.approx(-90.0)


def test_grouping_peaks_in_the_maps_own_float_type_and_near_the_border_are_those_in_float64():
    """The peaks are found in the grouping map's float32 and the vectors read around each peak only:
    the same peaks, values and means as in float64 over the whole frame (a peak at the border too)."""
    rng = np.random.default_rng(3)
    g = rng.random((30, 50)).astype(np.float32) ** 8 * 100
    g[0, 49] = 150.0  # (the strongest, in a corner: its disc is cut by the frame)
    fx, fy = ((rng.normal(size=g.shape) * (rng.random(g.shape) < 0.2)).astype(np.float32) for _ in range(2))
    got = grouping_peaks(Maps(fx, fy, g), k=6)
    wide = grouping_peaks(Maps(fx, fy, g.astype(np.float64)), k=6)  # (as the peaks were found before 30 Nov)
    assert got == wide and (got[0]["x"], got[0]["y"]) == (49, 0) and len(got) == 6
    yy, xx = np.mgrid[:30, :50]
    disc = (yy - 0) ** 2 + (xx - 49) ** 2 <= 8**2
    has = disc & (np.hypot(fx, fy) > 0)
    assert got[0]["fg_x"] == pytest.approx(float(fx[has].mean())) and got[0]["strength"] == 150.0


def test_a_replay_is_paced_by_the_stream_clock_and_loops_after_itself():
    ev = _events([0, 1000, 2000])
    loops = np.concatenate(list(looped(lambda: [ev], 2)))
    assert loops["t"].tolist() == [0, 1000, 2000, 3000, 4000, 5000]
    t0 = time.perf_counter()
    parts = list(paced([loops], speed=1.0))
    assert 0.004 <= time.perf_counter() - t0 < 0.5 and sum(len(p) for p in parts) == 6
    # --start-ms: each loop from that far after the recording's first event (a start-up burst left out), the
    # first at the recording's own times (until 30 Nov a replay began at 0: compare paired a live run's windows
    # with a run's 100 ms apart)
    late = np.concatenate(list(looped(lambda: from_ms([ev[:2], ev[2:]], 1.0), 2)))
    assert late["t"].tolist() == [1000, 2000, 3000, 4000]
    far = _events([2**40, 2**40 + 1000])  # (paced from its first event: not 2**40 us of waiting)
    t0 = time.perf_counter()
    assert sum(len(p) for p in paced([far], speed=1.0)) == 2 and time.perf_counter() - t0 < 0.5


def _free_port(kind=socket.SOCK_DGRAM) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _udp_bound(port: int) -> bool:
    """Whether a socket of this machine is bound to UDP ``port`` (the kernel's table: probing with a
    bind of our own could take the port from the live run at the moment it binds)."""
    tables = [Path("/proc/net", name) for name in ("udp", "udp6")]
    tables = [t.read_text().splitlines()[1:] for t in tables if t.exists()]
    if not tables:  # (not Linux: the delay alone)
        return True
    return any(int(line.split()[1].rsplit(":", 1)[1], 16) == port for lines in tables for line in lines)


def _sending(port, events, delay_s=1.0, **kw):
    """The events sent on a thread once the live command has bound ``port`` and ``delay_s`` has
    passed (the live command runs on the main thread, which handles the signals); its ``sent`` once
    joined. (A fixed delay alone lost every packet when the live command's imports took longer
    than it on a loaded machine: "no packet arrived within 30 s".)"""
    out = {}

    def go():
        time.sleep(delay_s)
        t0 = time.perf_counter()
        while not _udp_bound(port) and time.perf_counter() - t0 < 60:
            time.sleep(0.02)
        out["sent"] = _send(port, events, **kw)

    th = threading.Thread(target=go)
    th.start()
    return th, out


def _send(port, events, speed=4.0, garbage=()):
    sender = UdpSender(f"udp://127.0.0.1:{port}")
    for g in garbage:
        sender.sock.sendto(g, ("127.0.0.1", port))
    for part in paced([events], speed):
        sender.send(part)
    sender.close()
    return sender.sent


@pytest.fixture(scope="module")
def disc_file(tmp_path_factory):
    _, rec = flipping_disc_recording(24, windows=3, window_ms=40.0)
    path = tmp_path_factory.mktemp("live") / "disc.npz"
    save_events(path, rec.events, rec.sensor_size)
    ev = rec.events.copy()
    ev["t"] -= ev["t"][0]
    return path, ev, rec.sensor_size


class _Inbox:
    """Where the published lines arrive: a UDP port, or a TCP port that ``snn-fg live`` connects to."""

    def __init__(self, scheme):
        self.scheme, self.lines = scheme, []
        kind = socket.SOCK_DGRAM if scheme == "udp" else socket.SOCK_STREAM
        self.sock = socket.socket(socket.AF_INET, kind)
        self.sock.bind(("127.0.0.1", 0))
        self.url = f"{scheme}://127.0.0.1:{self.sock.getsockname()[1]}"
        self.sock.settimeout(0.5)
        if scheme == "tcp":
            self.sock.listen(1)
            self.thread = threading.Thread(target=self._accept)
            self.thread.start()

    def _accept(self):
        self.sock.settimeout(60)
        conn, _ = self.sock.accept()
        with conn, conn.makefile("r") as f:
            self.lines = [json.loads(line) for line in f]  # (until snn-fg live closes the connection)

    def read(self):
        if self.scheme == "tcp":
            self.thread.join(30)
            return self.lines
        lines = []
        while True:
            try:
                lines.append(json.loads(self.sock.recv(65536)))
            except TimeoutError:
                return lines


def test_a_dv_replay_ends_when_it_is_sent_and_the_live_run_with_it(tmp_path, disc_file, capsys):
    """snn-fg stream serving dv:// ends by itself once its events are sent, with a
    reader still connected, and the live run then ends on the closed stream with
    every event and the maps of snn-fg run (the rate model: stateless and quick)."""
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    path, ev, size = disc_file
    url = f"dv://127.0.0.1:{_free_port(socket.SOCK_STREAM)}"
    replay = [sys.executable, "-m", "snn_fg.cli", "stream", str(path), "--to", url, "--speed", "4"]
    sender = subprocess.Popen(replay, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    common = ["--window-ms", "40", "--no-figures", "--no-progress", "--model", "rate"]
    try:
        # (--sensor-size: warmed up before connecting, as docs/live.md says; warmed up after, the live run
        # reads nothing until its warm-up's imports and compiling are done, and the replay, 90 ms and a
        # second's linger, may have closed by then)
        sized = ["--sensor-size", f"{size[0]}x{size[1]}"]
        status = main(["live", url, "--out", str(tmp_path / "live"), "--max-behind", "1000", *sized, *common])
        said, err = sender.communicate(timeout=30)  # (before the fix it waited for ever on its connected reader)
    finally:
        sender.kill()
    assert status == 0 and sender.returncode == 0, err
    assert said.startswith(f"snn-fg: sent {len(ev):,} events of {path} to {url}")
    record = json.loads((tmp_path / "live" / "live.json").read_text())
    assert record["events_received"] == len(ev) and record["ended"].startswith("the sender")
    assert main(["run", str(path), "--out", str(tmp_path / "run"), *common]) == 0
    live, run = read_maps(tmp_path / "live" / "maps.zarr"), read_maps(tmp_path / "run" / "maps.zarr")
    assert len(live[0]) == len(run[0]) == 3
    for a, b in zip(live[:3], run[:3], strict=True):
        np.testing.assert_array_equal(a, b)


@pytest.mark.slow
@pytest.mark.parametrize(
    "model, publish",
    [
        (["--model", "rate"], "tcp"),
        (["--model", "spiking", "--levels", "3", "--view", "0"], "udp"),
        (["--model", "rate", "--network", "compact", "--maps-grid", "blocks", "--view", "0"], "udp"),
    ],
)
def test_live_over_udp_writes_the_maps_snn_fg_run_writes_on_the_same_events(
    tmp_path, disc_file, model, publish, capsys
):
    path, ev, size = disc_file
    port = _free_port()
    inbox = _Inbox(publish)
    common = ["--window-ms", "40", "--no-figures", "--no-progress"]
    th, out = _sending(port, ev, garbage=[b"\x01\x02\x03"])
    status = main(
        ["live", f"udp://127.0.0.1:{port}", "--out", str(tmp_path / "live"), "--sensor-size", f"{size[0]}x{size[1]}"]
        + ["--publish", inbox.url, "--max-behind", "1000", "--skip-behind", "3", "--idle-s", "0.5", *common, *model]
    )
    th.join(30)
    sent = out["sent"]
    assert status == 0
    run_model = [o for o in model if o not in ("--view", "0")]
    assert main(["run", str(path), "--out", str(tmp_path / "run"), *common, *run_model]) == 0
    live, run = read_maps(tmp_path / "live" / "maps.zarr"), read_maps(tmp_path / "run" / "maps.zarr")
    assert len(live[0]) == len(run[0]) == 3
    for a, b in zip(live[:3], run[:3], strict=True):
        np.testing.assert_array_equal(a, b)
    # (the same arrays: the live store made them from the warm-up's last window before the first came)
    assert sorted(live[4]) == sorted(run[4]) and all(live[4][k].shape == run[4][k].shape for k in run[4])
    record = json.loads((tmp_path / "live" / "live.json").read_text())
    assert record["skip_behind"] == 3
    assert record["events_received"] == sent == len(ev) and record["packets_malformed"] == 1
    assert record["windows"] == 3 and record["windows_dropped"] == 0
    assert record["ended"] == "the sender stopped: no packet for 0.5 s (--idle-s)"  # (UDP has no close of its own)
    assert record["latency_ms"]["max"] >= record["latency_ms"]["p95"] >= record["latency_ms"]["median"] > 0
    assert record["warm_up_s"] > 0 and not any(w["drop_before"] for w in record["per_window"])
    lines = inbox.read()
    assert [m["window"] for m in lines] == [0, 1, 2]
    assert [bool(m["peaks"]) for m in lines] == [bool((g > 0).any()) for g in live[2]]  # (a peak where grouping is)
    assert any(m["peaks"] for m in lines)
    said = capsys.readouterr()
    assert "malformed packet" in said.err
    ready = [x for x in said.out.splitlines() if "ready" in x]
    assert len(ready) == 1 and "warmed up in" in ready[0]
    assert ("the live page is on http://127.0.0.1:" in ready[0]) == ("--view" in model)


def test_a_udp_stream_without_a_sensor_size_is_one_line_naming_the_option(tmp_path, capsys):
    """The command line names its option, not the Python API's keyword (until 30 Nov it gave both)."""
    assert main(["live", "udp://127.0.0.1:9", "--out", str(tmp_path / "o")]) == 2
    said = capsys.readouterr().err.strip().splitlines()
    assert said == [
        "snn-fg: error: udp://127.0.0.1:9: a UDP (SPIF) stream has no sensor size of its own; give --sensor-size WxH"
    ]
    assert not (tmp_path / "o").exists()


def test_a_tcp_subscriber_that_is_not_there_is_said_in_one_line(tmp_path, capsys):
    port = _free_port()  # (nothing listens there)
    status = main(
        ["live", "udp://127.0.0.1:9", "--out", str(tmp_path / "o"), "--sensor-size", "24x24"]
        + ["--publish", f"tcp://127.0.0.1:{port}"]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and len(err) == 1
    assert err[0].startswith(f"snn-fg: error: tcp://127.0.0.1:{port}: --publish: cannot connect: ")
    assert not (tmp_path / "o").exists()


def test_no_sender_ends_with_one_line_and_no_output(tmp_path, capsys):
    port = _free_port()
    status = main(
        ["live", f"udp://127.0.0.1:{port}", "--out", str(tmp_path / "o"), "--sensor-size", "24x24"]
        + ["--wait-s", "0.3"]
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 2 and err == [
        f"snn-fg: error: udp://127.0.0.1:{port}: no packet arrived within 0.3 s; give --wait-s S to wait longer"
    ]
    assert not (tmp_path / "o").exists() or not any((tmp_path / "o").iterdir())


def test_a_live_run_into_an_earlier_runs_folder_offers_force_only(tmp_path, capsys):
    """A stream cannot be continued: the refusal names --force, not --resume (which live has not)."""
    (tmp_path / "o").mkdir()
    Maps(*(np.zeros((4, 4), np.float32) for _ in range(3)), params={}).save(tmp_path / "o" / "maps.npz")
    status = main(["live", "udp://127.0.0.1:9", "--out", str(tmp_path / "o"), "--sensor-size", "24x24"])
    err = capsys.readouterr().err.strip().splitlines()
    assert (
        status == 2 and len(err) == 1 and err[0].endswith("choose another output folder or pass --force to replace it")
    )


def test_a_udp_source_without_a_sensor_size_is_refused_in_one_line(tmp_path, capsys):
    assert main(["live", "udp://127.0.0.1:9", "--out", str(tmp_path / "o")]) == 2
    assert "give --sensor-size WxH" in capsys.readouterr().err


def test_a_dv_stream_whose_sensor_disagrees_with_the_one_given_is_refused(tmp_path, capsys):
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    port = _free_port()
    serve = (
        "from snn_fg.events.replay import DvSender; import time; "
        f"s = DvSender('dv://127.0.0.1:{port}', (32, 24), wait_s=20); time.sleep(1)"
    )
    server = subprocess.Popen([sys.executable, "-c", serve])
    try:
        status = main(["live", f"dv://127.0.0.1:{port}", "--out", str(tmp_path / "o"), "--sensor-size", "24x24"])
    finally:
        server.kill()
        server.wait()
    assert status == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"snn-fg: error: dv://127.0.0.1:{port}: --sensor-size 24x24 disagrees with the stream's 32x24"]


@pytest.mark.slow
def test_ctrl_c_ends_a_live_run_with_its_complete_windows_kept(tmp_path, disc_file):
    from snn_fg.results.store import windows_complete

    _, ev, size = disc_file
    port, out = _free_port(), tmp_path / "live"
    cmd = [sys.executable, "-m", "snn_fg.cli", "live", f"udp://127.0.0.1:{port}", "--out", str(out)]
    live = subprocess.Popen(
        cmd
        + [
            "--sensor-size",
            f"{size[0]}x{size[1]}",
            "--window-ms",
            "40",
            "--no-figures",
            "--no-progress",
            "--idle-s",
            "60",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert "ready" in live.stdout.readline()  # (bound to its port)
    th, _ = _sending(port, np.concatenate(list(looped(lambda: [ev], 20))), delay_s=0.0, speed=1.0)
    t0 = time.perf_counter()
    while windows_complete(out) < 2 and time.perf_counter() - t0 < 60:
        time.sleep(0.05)
    live.send_signal(signal.SIGINT)
    _, err = live.communicate(timeout=60)
    th.join(30)
    assert live.returncode == 130, err
    said = [x for x in err.strip().splitlines() if "interrupted" in x]
    assert said == [err.strip().splitlines()[-1]]  # (one line, the last)
    record = json.loads((out / "live.json").read_text())
    n = len(read_maps(out / "maps.zarr")[0])
    assert record["ended"] == "interrupted" and record["windows"] == n >= 2
    held = Maps.load(out).extra["window"]  # (per_window names the windows the folder holds, and only those)
    assert [r["window"] for r in record["per_window"]] == [int(w) for w in held]
    assert said[0].startswith(
        f"snn-fg: interrupted (Ctrl-C); the {n} windows complete so far are in {out}/ with live.json, "
        f"without figures: snn-fg plot {out} draws them; besides them, "  # (what was dropped: as a finished run's)
    )
    assert said[0].partition("besides them, ")[2].startswith(f"{record['windows_dropped']} dropped")  # (no hops)


@pytest.mark.parametrize(
    "argv, said",
    [
        (
            ["live", "foo://127.0.0.1:5"],
            "foo://127.0.0.1:5: source: expected udp://HOST:PORT, dv://HOST:PORT or camera://[SERIAL]",
        ),
        (
            ["live", "udp://127.0.0.1"],
            "udp://127.0.0.1: source: expected udp://HOST:PORT, dv://HOST:PORT or camera://[SERIAL]",
        ),
        (
            ["live", "udp://127.0.0.1:9", "--sensor-size", "8x8", "--publish", "http://a:1"],
            "http://a:1: --publish: expected udp://HOST:PORT or tcp://HOST:PORT",
        ),
        (["stream", "x.npz", "--to", "tcp://a:1"], "tcp://a:1: --to: expected udp://HOST:PORT or dv://HOST:PORT"),
    ],
)
def test_an_address_of_the_wrong_form_is_one_line_naming_it_and_the_option(tmp_path, capsys, disc_file, argv, said):
    if argv[0] == "stream":
        argv = ["stream", str(disc_file[0]), *argv[2:]]
    else:
        argv = [*argv, "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"snn-fg: error: {said}"]
    assert not (tmp_path / "o").exists()


def test_no_dv_server_is_one_line_without_the_librarys_source_location(tmp_path, capsys):
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    port = _free_port(socket.SOCK_STREAM)  # (nothing listens there)
    assert main(["live", f"dv://127.0.0.1:{port}", "--out", str(tmp_path / "o"), "--wait-s", "0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"snn-fg: error: dv://127.0.0.1:{port}: no DV server answered within 0.3 s (connect: Connection refused)"
    ]
    assert not (tmp_path / "o").exists()


def test_a_server_that_answers_without_a_dv_stream_ends_the_run_in_one_line(tmp_path):
    # (dv-processing's reader waits in its constructor for a DV stream's header, holding the interpreter
    # lock: a server that accepts and sends nothing held snn-fg live there for good, Ctrl-C and all)
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(8)
    port = server.getsockname()[1]
    held = []
    stop = threading.Event()

    def accept_and_say_nothing():
        server.settimeout(0.05)
        while not stop.is_set():
            try:
                held.append(server.accept()[0])
            except OSError:
                pass

    th = threading.Thread(target=accept_and_say_nothing, daemon=True)
    th.start()
    try:
        res = subprocess.run(
            [sys.executable, "-m", "snn_fg.cli", "live", f"dv://127.0.0.1:{port}", "--out", str(tmp_path / "o")]
            + ["--wait-s", "0.3"],
            capture_output=True,
            text=True,
            timeout=120,
        )
    finally:
        stop.set()
        th.join()
        for conn in held:
            conn.close()
        server.close()
    assert res.returncode == 2
    (err,) = res.stderr.strip().splitlines()
    assert err == (
        f"snn-fg: error: dv://127.0.0.1:{port}: a server answered but sent no DV event stream within 0.3 s (it "
        "never sent a DV stream header): is it a DV network writer (DV software's output, snn-fg stream --to dv://)?"
    )
    assert not (tmp_path / "o").exists()


def test_a_live_run_that_dropped_windows_numbers_the_others_as_the_stream_does(tmp_path):
    """One numbering everywhere: window k begins k windows after the stream's first; with
    windows 2 and 3 dropped, the published lines, live.json, maps.zarr, windows.csv, the figure
    titles and snn-fg plot --windows all say 0, 1, 4, 5 (the published lines and the table
    said 0, 1, 2, 3)."""
    import csv

    from snn_fg.cli.runner import run_recording
    from snn_fg.models import get_model
    from snn_fg.params import ModelParams
    from snn_fg.results.overview import window_titles
    from snn_fg.results.publish import LiveModel, LiveRecord

    _, rec = flipping_disc_recording(24, windows=6, window_ms=40.0)
    gate = threading.Event()

    class Source(_Packets):
        name, sensor_size = "test://", rec.sensor_size[:2]

    stream = LiveStream(Source([rec.events], gate), window_ms=40.0, max_behind=10**6)
    with stream.lock:  # (as a model that fell behind drops them: one slot a window)
        stream.dropped_slots |= {2, 3}
        stream.dropped_windows |= {2, 3}
    gate.set()

    class Inbox:
        lines: list = []

        def send(self, message):
            self.lines.append(message)

    inbox = Inbox()
    record = LiveRecord(stream, inbox)
    out = tmp_path / "live"
    out.mkdir()
    model = LiveModel(get_model("rate", ModelParams(levels=3)), stream, record)
    try:
        assert run_recording(model, stream, out, {"input": "test://", "window_ms": 40.0}, figures=False) == 4
    finally:
        stream.close()
    record.save(out / "live.json", "the sender closed the stream")
    kept = [0, 1, 4, 5]
    assert [m["window"] for m in inbox.lines] == kept
    assert [r["window"] for r in json.loads((out / "live.json").read_text())["per_window"]] == kept
    maps = Maps.load(out)
    assert maps.extra["window"].tolist() == kept
    assert (maps.extra["t_start_us"] == np.array(kept) * 40_000).all()  # (the number says when it began)
    with open(out / "windows.csv") as fh:
        assert [int(r["window"]) for r in csv.DictReader(fh)] == kept
    assert [t.split(":")[0] for t in window_titles(maps)] == [f"window {k}" for k in kept]
    # the overview's note on the windows it draws, and the timeline's marks, name them by number too
    from snn_fg.results.figures import maps_figure
    from snn_fg.results.overview import input_images, overview_options
    from snn_fg.results.timeline import timeline_figure, window_rows

    options = {**overview_options(maps, out), "max_rows": 3}
    fig = maps_figure(input_images(maps), maps.fg_x, maps.fg_y, maps.grouping, **options)
    assert "; 3 of 4 windows shown, evenly spaced among the 4: 0, 4, 5;" in fig._suptitle.get_text()
    timeline = timeline_figure(window_rows(maps), 40.0, shown=[0, 2, 3])
    assert [t.get_text() for t in timeline.axes[0].texts] == ["0", "4", "5"]
    # the dropped windows' time shaded on every panel (a blank before: a new user's report)
    shaded = [p.get_x() for p in timeline.axes[0].patches if p.get_facecolor()[:3] == (0.85, 0.85, 0.85)]
    assert shaded == [80.0] and "grey: windows dropped" in timeline.axes[3].get_xlabel()
    assert main(["plot", str(out), "--windows", "4-5"]) == 0
    assert sorted(p.name for p in (out / "windows").iterdir()) == ["window_0004.png", "window_0005.png"]
    assert main(["plot", str(out), "--windows", "2"]) == 2  # (dropped: not in the run)


@pytest.mark.slow
def test_the_engines_stage_messages_are_said_once_in_the_warm_up(tmp_path, disc_file, capsys):
    """The warm-up prepares the fast engine and says so; the live run on the same engine says it
    no more (its "fast engine: ... prepared" line came a second time, after "ready")."""
    import snn_fg.cli.live  # noqa: F401 - (loaded before the sender starts: the port is bound once it is)

    path, ev, size = disc_file
    port = _free_port()
    th, _ = _sending(port, ev, delay_s=2.0)
    status = main(
        ["live", f"udp://127.0.0.1:{port}", "--out", str(tmp_path / "live"), "--sensor-size", f"{size[0]}x{size[1]}"]
        + ["--model", "spiking", "--levels", "3", "--window-ms", "40", "--no-figures", "--idle-s", "0.5"]
        + ["--max-behind", "1000"]
    )
    th.join(30)
    said = capsys.readouterr()
    assert status == 0, said.err
    assert said.err.count("snn-fg: fast engine: ") == 1, said.err
    assert len(read_maps(tmp_path / "live" / "maps.zarr")[0]) == 3


def test_a_udp_replay_says_that_udp_cannot_tell_whether_anything_received_it(disc_file, capsys):
    """A new user replayed to a port nobody listened on and read 'sent ... events' as success."""
    port = _free_port()
    assert main(["stream", str(disc_file[0]), "--to", f"udp://127.0.0.1:{port}", "--speed", "20"]) == 0
    said = capsys.readouterr().out.strip()
    assert said.startswith("snn-fg: sent ") and said.endswith("; UDP does not tell whether anything received them")


def _hops_all_come_first(max_behind: int, skip_behind: int = 1) -> tuple[list, dict]:
    """10 ms hops over 40 ms windows, every event (one each 0.1 ms, to 119.9 ms) come before the
    model asks: the hops made (each passed once made) and the stream's counts (with the numbers
    of the hops skipped, ``skipped``)."""
    packets = [_events(np.arange(k * 10_000, (k + 1) * 10_000, 100)) for k in range(12)]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)  # (the one line that says a slot was dropped)
        stream = LiveStream(
            _Packets(packets), window_ms=40.0, stride_ms=10.0, max_behind=max_behind, skip_behind=skip_behind
        )
        stream.thread.join(5)
        kept = []
        for w in stream:
            kept.append(w.index)
            stream.done(w)
    return kept, {**stream.stats(), "skipped": stream.skipped_windows}


def test_hops_behind_the_stream_skip_their_read_out_for_the_newest_and_drop_nothing():
    """A hop is skipped, not dropped (the network takes its events), when the events that complete the
    read-out of the hop ``skip_behind`` later have come (the last event at 119.9 ms): with 1, hops whose
    next hop is complete too, so only hops 7 and 8 (ending at 110 and 120 ms) are made; with the default,
    2, hop 6 too, whose next hop but one (ending at 120 ms) is not complete."""
    kept, s = _hops_all_come_first(max_behind=100, skip_behind=1)
    assert kept == [7, 8] and s["windows_skipped"] == 7 and s["windows_dropped"] == 0 and s["events_dropped"] == 0
    # (by number, as ranges of consecutive ones: one entry a hop grew without end on a long --hop-ms run;
    # the timeline shades them apart from dropped ones)
    assert s["skipped"] == s["skipped_windows"] == [[0, 6]]
    kept, s = _hops_all_come_first(max_behind=100, skip_behind=SKIP_BEHIND)
    assert SKIP_BEHIND == 2 and kept == [6, 7, 8] and s["skipped_windows"] == [[0, 5]] and s["events_dropped"] == 0


def test_hops_drop_events_only_a_window_behind_and_never_skip_for_a_dropped_hop():
    """With max_behind 0 a slot is dropped once a window's worth of hops (4) wait, so from slot 8
    on (windows 5-11 hold one); hop 4 is made, since the hop after it is dropped."""
    kept, s = _hops_all_come_first(max_behind=0)
    assert s["events_dropped"] == 4 * 100 and s["windows_dropped"] == 7 and s["dropped_windows"] == [[5, 11]]
    assert kept == [4] and s["windows_skipped"] == 4


def test_the_timeline_shades_skipped_hops_apart_from_dropped_windows(tmp_path):
    """A hop skipped for a newer one (every event simulated, no read-out) is not a dropped window
    (events not simulated): the run's store keeps the skipped numbers and timeline.png shades them
    blue, the dropped grey, each named under the plot (both were grey "dropped" before)."""
    from snn_fg.cli.runner import run_recording
    from snn_fg.events import iter_windows
    from snn_fg.models import get_model
    from snn_fg.params import ModelParams
    from snn_fg.results.timeline import MISSING_COLOURS, timeline_figure, window_rows

    _, rec = flipping_disc_recording(24, windows=8, window_ms=40.0)
    path = save_events(tmp_path / "rec.npz", rec.events, rec.sensor_size)

    class Stream(list):  # (what run_recording reads of a live stream: its windows and the hops it skipped)
        skipped_windows = [[2, 2]]

    windows = Stream(w for w in iter_windows(path, window_ms=40.0) if w.index not in (2, 3, 5))
    out = tmp_path / "run"
    out.mkdir()
    run_recording(get_model("rate", ModelParams(levels=3)), windows, out, {"input": "x", "window_ms": 40.0})
    maps = Maps.load(out)
    assert maps.params["skipped_windows"] == [[2, 2]]
    grey, blue = (mcolors.to_rgba(MISSING_COLOURS[k]) for k in ("dropped", "skipped"))

    def spans(skipped):
        fig = timeline_figure(window_rows(maps), 40.0, skipped=skipped)
        drawn = [(p.get_x(), p.get_width(), tuple(p.get_facecolor())) for p in fig.axes[0].patches]
        return fig, sorted(d for d in drawn if d[2] in (grey, blue))

    fig, shaded = spans(maps.params["skipped_windows"])
    assert shaded == [(80.0, 40.0, blue), (120.0, 40.0, grey), (200.0, 40.0, grey)]
    assert spans([2])[1] == shaded  # (a run stored before 30 Nov: one number a hop)
    assert spans([[2, 3], [5, 5]])[1] == [(80.0, 80.0, blue), (200.0, 40.0, blue)]
    label = fig.axes[3].get_xlabel()
    assert "grey: windows dropped" in label and "blue: hops skipped" in label and "events not simulated" in label
    assert (out / "timeline.png").read_bytes().startswith(b"\x89PNG")


def test_a_udp_packet_without_events_is_counted_and_neither_begins_nor_prolongs_the_stream():
    """A malformed or empty datagram is no arrival: one before the sender's first packet does not start
    the --idle-s clock (an empty one ended the stream before it began), and garbage after the last packet
    does not hold the stream open (each reset the clock: a noisy port kept a finished stream going)."""
    from snn_fg.errors import InputError
    from snn_fg.events.live_sources import open_source

    src = open_source("udp://127.0.0.1:0", (64, 64), wait_s=5.0, idle_s=0.3)
    port = src.sock.getsockname()[1]
    sender = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sent = {}

    def send():
        sender.sendto(b"", ("127.0.0.1", port))  # (empty, then the real packet after more than --idle-s)
        sender.sendto(b"\x01\x02\x03", ("127.0.0.1", port))
        time.sleep(0.6)
        sent["valid"] = time.perf_counter()
        sender.sendto(spif.encode(_events([5, 6])), ("127.0.0.1", port))
        for _ in range(12):  # (garbage every 0.1 s for 1.2 s after it: longer than --idle-s 4 times over)
            time.sleep(0.1)
            sender.sendto(b"\xff" * 6, ("127.0.0.1", port))

    th = threading.Thread(target=send)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)
        th.start()
        try:
            got = [(len(ev), arrived) for ev, arrived in src.packets()]
            ended = time.perf_counter()
        finally:
            th.join()
            src.close()
    assert [n for n, _ in got] == [2]
    assert got[0][1] >= sent["valid"]  # (its arrival is the real packet's)
    assert ended - sent["valid"] < 0.3 + 0.5  # (--idle-s after the real packet, not after the garbage's 1.2 s)
    assert src.malformed >= 4  # (the empty one, the 3 bytes and the garbage before the end)

    src = open_source("udp://127.0.0.1:0", (64, 64), wait_s=0.5, idle_s=0.3)  # (only garbage: said so)
    port = src.sock.getsockname()[1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", InputWarning)
        sender.sendto(b"\x01", ("127.0.0.1", port))
        try:
            with pytest.raises(
                InputError,
                match=r"no event arrived within 0.5 s, only 1 malformed packet; pass wait_s=S to wait longer$",
            ):
                list(src.packets())
        finally:
            sender.close()
            src.close()


def test_udp_packets_the_kernel_dropped_are_counted_as_the_socket_closes():
    """UDP tells its sender nothing: packets that found the socket's buffer full were in no count
    (a new user's run received 816,221 of 1,083,594 events sent, and nothing said why)."""
    if not os.path.exists("/proc/net/udp"):
        pytest.skip("the kernel's count is read from Linux's /proc/net/udp")
    from snn_fg.events.live_sources import open_source

    src = open_source("udp://127.0.0.1:0", (64, 64), wait_s=5.0, idle_s=0.3)
    src.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # (a buffer a few packets fill)
    port = src.sock.getsockname()[1]
    data = spif.encode(_events(np.arange(1000)))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        for _ in range(50):
            sender.sendto(data, ("127.0.0.1", port))
    time.sleep(0.2)
    src.close()
    assert src.packets_lost is not None and 0 < src.packets_lost <= 50
    quiet = open_source("udp://127.0.0.1:0", (64, 64), wait_s=5.0, idle_s=0.3)
    quiet.close()
    assert quiet.packets_lost == 0


def test_live_json_keeps_only_the_windows_its_store_took_whole():
    """Cut by Ctrl-C, a live run's live.json said 52 windows and listed window 57, published as the run
    was cut, where maps.zarr held 51."""
    from snn_fg.results.publish import LiveRecord

    record = LiveRecord.__new__(LiveRecord)  # (its rows only: what keep_only reads)
    record.rows = [{"window": w, "latency_ms": 1.0} for w in (54, 55, 56, 57)]
    record.keep_only(np.array([54, 55, 56]))
    assert [r["window"] for r in record.rows] == [54, 55, 56]
