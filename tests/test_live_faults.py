"""Faults of the live route, each said in one line or kept as a finished run keeps it: a live run cut
short (Ctrl-C, SIGTERM) keeps its windows with the run's parameters, so that snn-fg plot and compare
read them the same, and its closing line says what is there and how its figures are made, or that
nothing was written; a DV stream served on a port in use, and a sensor size that disagrees with a
file's own, are one line each."""

import _thread
import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from snn_fg.cli.main import main
from snn_fg.cli.runner import run_recording
from snn_fg.events import iter_windows, open_recording, save_events
from snn_fg.frames.scenes import flipping_disc_recording
from snn_fg.models import get_model
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps
from snn_fg.results.store import read_attrs
from tests.conftest import earlier_run_files


class _Stream:
    """What run_recording reads of a live stream: its windows, then (``cut``) an interrupt, the hops it
    skipped for a newer one and the windows it dropped (those after the last window made too, when the
    run was cut short)."""

    def __init__(self, windows, skipped, cut: bool, dropped=()):
        self.windows, self.skipped_windows, self.cut, self.dropped_ranges = windows, skipped, cut, list(dropped)

    def __iter__(self):
        yield from self.windows
        if self.cut:
            raise KeyboardInterrupt("SIGINT")


def test_a_run_cut_short_keeps_the_parameters_of_a_finished_one(tmp_path):
    """Before the fix an interrupted run's store held the first window's parameters only: no
    ``source`` (snn-fg plot drew '0 ms windows' titled by the folder) and no ``skipped_windows``."""
    _, rec = flipping_disc_recording(24, windows=8, window_ms=40.0)
    path = save_events(tmp_path / "rec.npz", rec.events, rec.sensor_size)
    windows = [w for w in iter_windows(path, window_ms=40.0) if w.index in (0, 1, 3, 4)]
    source = {"input": "udp://127.0.0.1:9", "kind": "live", "window_ms": 40.0, "stride_ms": 40.0, "start_ms": 0.0}
    model = get_model("rate", ModelParams(levels=3))
    params = {}
    for cut in (False, True):
        out = tmp_path / f"cut{cut}"
        out.mkdir()
        skipped = [[2, 2], [5, 6]] if cut else [[2, 2]]  # (5 and 6 skipped for hop 7, which the interrupt cut)
        if cut:
            with pytest.raises(KeyboardInterrupt):
                run_recording(model, _Stream(windows, skipped, cut), out, source, figures=False)
        else:
            run_recording(model, _Stream(windows, skipped, cut), out, source, figures=False)
        params[cut] = {k: v for k, v in Maps.load(out).params.items() if k not in ("timings_s", "windows")}  # (times)
        assert read_attrs(out / "maps.zarr")["snn_fg"]["complete"] is not cut  # (ended by its stream, or not)
    assert params[True]["source"]["window_ms"] == 40.0 and params[True]["source"]["input"] == source["input"]
    # (every hop skipped before the run stopped, 5 and 6 after window 4, the last one stored, too: the
    # timeline draws the run as it went up to there)
    assert params[True].pop("skipped_windows") == [[2, 2], [5, 6]]
    assert params[False].pop("skipped_windows") == [[2, 2]]
    assert params[True] == params[False]


def test_the_timeline_of_a_run_cut_short_draws_what_it_skipped_and_dropped_before_and_after_its_windows(tmp_path):
    """A live run with 20 ms hops over 40 ms windows, cut short: hops 0 and 1 skipped before the first
    window stored (2) and windows 5-7 dropped after the last (4). timeline.png left both out (shading only
    the gaps between stored windows: the dropped ones were not even in the store), its axis ended at
    window 4 and its title did not say that the run was cut short."""
    from matplotlib.colors import to_rgba

    from snn_fg.results.overview import timeline_of
    from snn_fg.results.timeline import MISSING_COLOURS, window_rows

    _, rec = flipping_disc_recording(24, windows=8, window_ms=40.0)
    path = save_events(tmp_path / "rec.npz", rec.events, rec.sensor_size)
    windows = [w for w in iter_windows(path, window_ms=40.0, stride_ms=20.0) if w.index in (2, 3, 4)]
    source = {"input": "udp://127.0.0.1:9", "kind": "live", "window_ms": 40.0, "stride_ms": 20.0, "start_ms": 0.0}
    out = tmp_path / "run"
    out.mkdir()
    with pytest.raises(KeyboardInterrupt):
        stream = _Stream(windows, [[0, 1]], True, dropped=[[5, 7]])
        run_recording(get_model("rate", ModelParams(levels=3)), stream, out, source, figures=False)
    maps = Maps.load(out)
    assert maps.params["skipped_windows"] == [[0, 1]] and maps.params["dropped_windows"] == [[5, 7]]
    fig = timeline_of(maps, window_rows(maps), out)
    ax = fig.axes[0]
    colours = {to_rgba(c): kind for kind, c in MISSING_COLOURS.items()}
    shaded = sorted(
        (p.get_x(), p.get_width(), colours[p.get_facecolor()]) for p in ax.patches if p.get_facecolor() in colours
    )
    assert shaded == [(0.0, 40.0, "skipped"), (100.0, 60.0, "dropped")]  # (hops 0-1; windows 5-7, by their starts)
    assert ax.get_xlim()[0] <= 0.0 and ax.get_xlim()[1] >= 160.0  # (to where the run stopped)
    assert (
        fig.get_suptitle()
        == "127.0.0.1:9: the rate model, window by window up to window 7, where the run was cut short"
    )
    assert fig.axes[3].get_xlabel().startswith("time after the first event (ms); 40 ms windows, one every 20 ms")
    plain = Maps(maps.fg_x, maps.fg_y, maps.grouping, {"source": source, "model": "rate"}, maps.extra)
    title = timeline_of(plain, window_rows(plain), out).get_suptitle()  # (nothing skipped or dropped: a recording's)
    assert title.endswith("window by window up to window 4, where the run was cut short")


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _interrupted_once(folder, settle_s: float = 0.5) -> threading.Thread:
    """Ctrl-C to this process ``settle_s`` after ``folder`` appears (the live run's store: warmed up, it
    waits for its first packet then), on a thread: the live command runs on the main thread, which takes signals."""

    def go():
        t0 = time.perf_counter()
        while not folder.exists() and time.perf_counter() - t0 < 60:
            time.sleep(0.02)
        time.sleep(settle_s)
        os.kill(os.getpid(), signal.SIGINT)

    th = threading.Thread(target=go)
    th.start()
    return th


def test_the_line_of_an_interrupted_run_says_what_it_skipped_and_dropped_as_a_finished_runs_does():
    """A finished run's closing line gives the hops skipped, the windows dropped and why, with where to read
    what to try; after Ctrl-C the line named the windows kept only (a trial with --hop-ms 10 on one core:
    163 windows kept, 179 hops skipped and 70 windows dropped, said in live.json alone)."""
    from snn_fg.cli.live import _interrupted_note, _summary_text
    from snn_fg.results.publish import why_behind

    summary = {
        "windows": 163,
        "windows_dropped": 70,
        "windows_skipped": 179,
        "events_received": 2_000_000,
        "latency_ms_streaming": {"median": 30.0, "p95": 40.0, "max": 50.0},
        "per_window": [],
        **{"streamed_s": 4.0, "cpu_s": 3.9, "model_cpu_s": 3.8, "cores": 1},
    }
    summary["why_behind"] = why_behind(summary)
    said = _interrupted_note("out/live", 163, False, summary)
    why = "the run used 98% of its 1 core while the stream came: the model is slower than the stream on this machine"
    assert said == (
        "the 163 windows complete so far are in out/live/ with live.json, without figures: snn-fg plot out/live "
        f"draws them; besides them, 179 skipped for a newer hop, 70 dropped; {why} (what to try: docs/live.md, "
        "'If windows are dropped')"
    )
    finished = _summary_text(summary)  # (the same words, from the same function)
    assert finished.startswith("163 windows published, 179 skipped for a newer hop, 70 dropped, 2,000,000 events")
    assert finished.endswith(said.partition("70 dropped")[2])
    calm = {**summary, "windows_dropped": 0, "windows_skipped": 0}
    calm["why_behind"] = why_behind(calm)
    assert _interrupted_note("o", 1, False, calm).endswith("snn-fg plot o draws it; besides it, 0 dropped")


@pytest.mark.parametrize("earlier", [False, True])
def test_ctrl_c_before_the_first_window_says_that_nothing_was_written(tmp_path, capsys, earlier):
    """The line named the folder as holding the windows complete so far, when there were none and
    the folder had been removed."""
    out = tmp_path / "o"
    if earlier:  # (--force into an earlier run's folder: it is put back)
        out.mkdir()
        (out / "maps.npz").write_bytes(earlier_run_files()["maps.npz"])
    th = _interrupted_once(out / "maps.zarr")
    live = ["live", f"udp://127.0.0.1:{_free_port()}", "--out", str(out), "--sensor-size", "24x24"]
    try:
        status = main([*live, "--window-ms", "40", "--no-progress", "--levels", "3", "--wait-s", "30", "--force"])
    finally:
        th.join()
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 130
    if earlier:
        kept = f"the earlier run in {out}/ is kept"
        assert err[-1] == f"snn-fg: interrupted (Ctrl-C); no window was complete: nothing written; {kept}"
        assert [p.name for p in out.iterdir()] == ["maps.npz"]
    else:
        assert err[-1] == "snn-fg: interrupted (Ctrl-C); no window was complete: nothing written"
        assert not out.exists()


def test_a_dv_stream_served_on_a_port_in_use_is_one_line(tmp_path, capsys):
    """dv-processing's bind error came out as a traceback with Boost's source location."""
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    _, rec = flipping_disc_recording(24, windows=2, window_ms=40.0)
    path = save_events(tmp_path / "rec.npz", rec.events, rec.sensor_size)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        url = f"dv://127.0.0.1:{taken.getsockname()[1]}"
        assert main(["stream", str(path), "--to", url]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"snn-fg: error: {url}: cannot serve there: Address already in use"
    ]


def test_a_dv_server_waits_for_its_reader_as_long_as_it_is_told(tmp_path, capsys):
    """--wait-s sets how long snn-fg stream's dv:// server waits for a reader (120 s by default: it
    waited 30 s, less than a first live run's warm-up on a busy machine), and its end is one line."""
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    _, rec = flipping_disc_recording(24, windows=2, window_ms=40.0)
    path = save_events(tmp_path / "rec.npz", rec.events, rec.sensor_size)
    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        url = f"dv://127.0.0.1:{free.getsockname()[1]}"
    t = time.perf_counter()
    assert main(["stream", str(path), "--to", url, "--wait-s", "0.5"]) == 2
    assert time.perf_counter() - t < 20
    assert capsys.readouterr().err.strip().splitlines() == [f"snn-fg: error: {url}: no reader connected within 0.5 s"]


@pytest.mark.parametrize("command", ["events", "stream"])
def test_a_sensor_size_other_than_the_files_own_is_one_line(tmp_path, capsys, command):
    """snn-fg events said 'sensor: 640 x 480' of a 320 x 240 file, and snn-fg stream sent it as such,
    without a word (the check lives where files are opened: events.core.file_sensor_size)."""
    _, rec = flipping_disc_recording(24, windows=2, window_ms=40.0)
    path = save_events(tmp_path / "rec.es", rec.events, rec.sensor_size)
    w, h = rec.sensor_size[:2]
    argv = [command, str(path), "--sensor-size", f"{2 * w}x{2 * h}"]
    assert main([*argv, "--to", f"udp://127.0.0.1:{_free_port()}"] if command == "stream" else argv) == 2
    assert capsys.readouterr().err.strip().splitlines() == [
        f"snn-fg: error: {path}: the sensor size given, {2 * w} x {2 * h}, disagrees with the file's own "
        f"{w} x {h}: leave the size out for this file"
    ]


def test_a_dv_stream_that_ends_before_the_model_asks_for_it_keeps_its_events():
    """dv-processing's reader throws away what it holds untaken when the server closes: a live run
    without --sensor-size connects before its warm-up, and a short replay (its events, then a second's
    linger) had closed by the warm-up's end, so the run said 'the stream ended before any event'. The
    source now empties the reader from the connection on."""
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    from snn_fg.events.live_sources import open_source

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        url = f"dv://127.0.0.1:{s.getsockname()[1]}"
    serve = (
        "import os, numpy as np; from snn_fg.events import EVENT_DTYPE; from snn_fg.events.replay import DvSender; "
        "ev = np.zeros(1000, EVENT_DTYPE); ev['t'] = np.arange(1000) * 10; ev['x'] = np.arange(1000) % 32; "
        f"s = DvSender('{url}', (32, 24), wait_s=20); s.load(ev); s.send(ev); s.close(linger_s=0.3); os._exit(0)"
    )
    server = subprocess.Popen([sys.executable, "-c", serve])
    try:
        src = open_source(url, wait_s=20)
        server.wait(20)  # (the replay sent and closed: what the warm-up took longer than)
        time.sleep(0.2)
        got = sum(len(ev) for ev, _ in src.packets())
        src.close()
    finally:
        server.kill()
        server.wait()
    assert src.sensor_size == (32, 24) and got == 1000


def test_the_dv_servers_network_thread_gives_way_to_the_live_run_beside_it():
    """dv-processing's NetworkWriter serves from a thread that polls without pause (a core's worth of CPU,
    idle or not): beside a live run on two cores it took half their time, and the run dropped windows.
    snn-fg stream puts that thread, and only it, at the lowest priority."""
    pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    serve = (
        "import os, threading, time, dv_processing as dv; from snn_fg.events.replay import DvSender; "
        f"threading.Thread(target=lambda: (time.sleep(0.3), dv.io.NetworkReader('127.0.0.1', {port}), "
        "time.sleep(5)), daemon=True).start(); "
        "base = os.getpriority(os.PRIO_PROCESS, 0); before = set(os.listdir('/proc/self/task')); "
        f"s = DvSender('dv://127.0.0.1:{port}', (32, 24), wait_s=20); "
        "nice = {t: os.getpriority(os.PRIO_PROCESS, int(t)) for t in os.listdir('/proc/self/task')}; "
        "print(s.yielding, base, os.getpriority(os.PRIO_PROCESS, 0), *(n for t, n in nice.items() if t not in before))"
        "; os._exit(0)"
    )
    said = subprocess.run([sys.executable, "-c", serve], capture_output=True, text=True, timeout=60).stdout.split()
    yielding, base, own, new = int(said[0]), int(said[1]), int(said[2]), [int(n) for n in said[3:]]
    # one thread came with the writer and gives way (the reader's came too, at the process's own priority);
    # the sender's own thread keeps its priority (under nice 19 every thread is at 19: nothing to tell apart)
    assert yielding == 1 and own == base and new.count(19) == (1 if base < 19 else len(new))


DAVIS = Path(__file__).resolve().parent / "data" / "davis346_disc.aedat4"
#: what dv-processing says of a serial number it does not find (without its source location and stack)
NOT_FOUND = "Could not find device with given serial number"
NOT_THAT_ONE = "no camera with serial number NOSUCH1 on USB (found: DXA00093)"


def test_a_camera_on_usb_is_read_as_a_dv_stream_is(tmp_path, monkeypatch, capsys):
    """camera:// opens an iniVation camera with dv-processing, no DV software. No camera is on this machine:
    dv-processing's own reader of a DAVIS346 recording stands in for it (the camera's reader and the file's
    share dv-processing's input interface); the run ends when the reader does, with every event received
    and the rate model's maps of snn-fg run on the same file."""
    dv = pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    monkeypatch.setattr(dv.io.camera, "discover", lambda: ["a camera"])
    monkeypatch.setattr(dv.io.camera, "open", lambda *serial: dv.io.MonoCameraRecording(str(DAVIS)))
    common = ["--window-ms", "40", "--no-figures", "--no-progress", "--model", "rate"]
    live = ["live", "camera://", "--out", str(tmp_path / "live"), "--max-behind", "1000", *common]
    assert main(live) == 0
    assert main(["run", str(DAVIS), "--out", str(tmp_path / "run"), *common]) == 0
    a, b = Maps.load(tmp_path / "live"), Maps.load(tmp_path / "run")
    record = json.loads((tmp_path / "live" / "live.json").read_text())
    assert record["events_received"] == len(open_recording(DAVIS).events) and record["windows_dropped"] == 0
    assert a.fg_x.shape == b.fg_x.shape and a.fg_x.shape[0] > 1
    for x, y in ((a.fg_x, b.fg_x), (a.fg_y, b.fg_y), (a.grouping, b.grouping)):
        np.testing.assert_array_equal(x, y)


class _Failing:
    """dv-processing's reader of the DAVIS346 recording (a camera's stand-in) that fails after ``good``
    batches: with dv-processing's RuntimeError at every ask (``stopped``: and says it is no longer running),
    or once with ``error``."""

    def __init__(self, dv, good: int, error=None, stopped: bool = True):
        self.rec, self.asked, self.good, self.error, self.stopped = (
            dv.io.MonoCameraRecording(str(DAVIS)),
            0,
            good,
            error,
            stopped,
        )
        self.given = 0

    def __getattr__(self, name):
        return getattr(self.rec, name)

    def getNextEventBatch(self):  # noqa: N802 (dv-processing's name)
        self.asked += 1
        if self.asked > self.good and self.error is not None:
            error, self.error = self.error, None
            raise error
        if self.asked > self.good and self.error is None and self.stopped is not None:
            raise RuntimeError("read: Connection reset by peer [/dv-processing/network_reader.hpp:123]")
        batch = self.rec.getNextEventBatch()
        self.given += 0 if batch is None else len(batch)
        return batch

    def isRunning(self):  # noqa: N802
        return not (self.stopped and self.asked > self.good) and self.rec.isRunning()


def _live_camera(tmp_path, *size):
    """snn-fg live on camera:// (dv-processing's camera.open, patched): its exit status (130: interrupted,
    still running after 60 s)."""
    argv = ["live", "camera://", *size, "--out", str(tmp_path / "live"), "--model", "rate", "--window-ms", "10"]
    hung = threading.Timer(60, _thread.interrupt_main)
    hung.start()
    try:
        return main([*argv, "--max-behind", "1000", "--no-figures", "--no-progress"])
    finally:
        hung.cancel()


@pytest.mark.parametrize("stopped", [True, False], ids=["reader-stopped", "reader-stuck"])
def test_a_dv_stream_that_cannot_go_on_is_one_line_after_its_windows(tmp_path, monkeypatch, capsys, stopped):
    """A dv-processing reader that raises at every ask (a connection reset, a stream it cannot decode) was
    asked again without end: the run hung, its receiving thread busy. Once the reader has stopped, or after
    UNREADABLE_IN_A_ROW such packets, the run ends in one line naming the source, the problem and the event
    it came at, with the windows of the events before it kept (live.json says why it ended)."""
    dv = pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    from snn_fg.events.live_dv import UNREADABLE_IN_A_ROW

    monkeypatch.setattr(dv.io.camera, "discover", lambda: ["a camera"])
    reader = _Failing(dv, good=5, stopped=stopped)
    monkeypatch.setattr(dv.io.camera, "open", lambda *serial: reader)
    assert _live_camera(tmp_path, "--sensor-size", "346x260") == 2
    said = "the reader stopped at a packet it could not read" if stopped else (
        f"{UNREADABLE_IN_A_ROW} packets in a row could not be read"
    )  # fmt: skip
    line = f"camera://: the stream cannot go on: {said} (read: Connection reset by peer) (at event {reader.given:,})"
    assert capsys.readouterr().err.strip().splitlines()[-1] == f"snn-fg: error: {line}"
    record = json.loads((tmp_path / "live" / "live.json").read_text())
    assert record["events_received"] == reader.given > 0 and record["windows"] > 0
    assert record["ended"] == f"error: {line}"


def test_an_error_while_the_model_warms_up_is_raised_by_the_run_not_lost_with_its_thread(tmp_path, monkeypatch, capsys):
    """Without --sensor-size the camera is read from before the warm-up, on a thread of its own: an error
    there was printed as that thread's traceback, and the run went on, exit status 0, without the rest of
    the stream. It is the run's error now (here not dv-processing's RuntimeError: a fault, so a traceback)."""
    dv = pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    monkeypatch.setattr(dv.io.camera, "discover", lambda: ["a camera"])
    reader = _Failing(dv, good=0, error=ValueError("a fault in the reader"), stopped=None)
    monkeypatch.setattr(dv.io.camera, "open", lambda *serial: reader)
    with pytest.raises(ValueError, match="^a fault in the reader$"):
        _live_camera(tmp_path)
    assert "Exception in thread" not in capsys.readouterr().err


@pytest.mark.parametrize("size", [[], ["--sensor-size", "346x260"]])
def test_a_camera_run_looks_for_the_camera_and_compiles_the_packet_screen_once(tmp_path, monkeypatch, size):
    """camera:// asked dv-processing for the cameras on USB twice (before the warm-up, and again as it was
    opened), and the packet screen was prepared twice (in the warm-up, and again as the stream began): once
    each, with the size given (the camera opened after the warm-up) and without it (before)."""
    dv = pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    import snn_fg.cli.live  # noqa: F401 (every module that may call prepare_screen, loaded)
    from snn_fg.events import live_screen

    calls = {"discover": 0, "prepare_screen": 0}
    real = live_screen.prepare_screen

    def discover():
        calls["discover"] += 1
        return ["a camera"]

    def prepare_screen():
        calls["prepare_screen"] += 1
        real()

    monkeypatch.setattr(dv.io.camera, "discover", discover)
    monkeypatch.setattr(dv.io.camera, "open", lambda *serial: dv.io.MonoCameraRecording(str(DAVIS)))
    for module in list(sys.modules.values()):  # (wherever it is called from)
        if vars(module).get("prepare_screen") is real:
            monkeypatch.setattr(module, "prepare_screen", prepare_screen)
    argv = ["live", "camera://", *size, "--out", str(tmp_path / "live"), "--model", "rate", "--window-ms", "40"]
    assert main([*argv, "--max-behind", "1000", "--no-figures", "--no-progress"]) == 0
    assert calls == {"discover": 1, "prepare_screen": 1}


@pytest.mark.parametrize(
    "url, found, said",
    [
        ("camera://", [], "camera://: no iniVation camera found on this machine's USB (dv-processing looked)"),
        ("camera://NOSUCH1", ["DXA00093"], "camera://NOSUCH1: " + NOT_THAT_ONE),
    ],
)  # fmt: skip
def test_no_camera_or_not_that_one_is_one_line_before_the_warm_up(tmp_path, monkeypatch, capsys, url, found, said):
    """With --sensor-size the model warms up before the camera is opened (it sends from then on): that no
    camera is there, or not the one named, is said before the warm-up's seconds, not after them."""
    dv = pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    import snn_fg.models.live as live

    monkeypatch.setattr(dv.io.camera, "discover", lambda: [SimpleNamespace(serialNumber=s) for s in found])
    monkeypatch.setattr(live, "warm_up", lambda *a, **k: pytest.fail("warmed up before the camera was found"))
    argv = ["live", url, "--sensor-size", "346x260", "--out", str(tmp_path / "live"), "--model", "rate"]
    assert main([*argv, "--no-progress"]) == 2
    assert capsys.readouterr().err.strip().splitlines() == [f"snn-fg: error: {said}"]
    assert not (tmp_path / "live").exists()


def test_a_serial_number_dv_processing_finds_but_cannot_open_is_its_message_in_one_line(tmp_path, monkeypatch, capsys):
    dv = pytest.importorskip("dv_processing", reason="the live extra (pip install -e '.[live]')")
    monkeypatch.setattr(dv.io.camera, "discover", lambda: [SimpleNamespace(serialNumber="NOSUCH1")])
    # (dv-processing's own open() looks for the serial, does not find it, and says so with its source and stack)
    assert main(["live", "camera://NOSUCH1", "--out", str(tmp_path / "live"), "--model", "rate"]) == 2
    said = capsys.readouterr().err.strip().splitlines()
    assert said == [f"snn-fg: error: camera://NOSUCH1: cannot open the camera: {NOT_FOUND}"]


def test_the_warm_up_compiles_the_packet_screen_for_the_packets_it_will_see():
    """The receiving thread's screen (events.live_screen.screen_events) was compiled for an empty packet only,
    once connected (LiveStream), and again for the first real one, whose fields are strided views (numba's
    'A' layout): on a first run over dv:// with --sensor-size, 1.5 s of compiling after 'ready' on a busy
    machine, on the stream's time (18 of 24 demo windows dropped). The warm-up, before a dv:// stream is
    connected to, compiles both; a fresh process, since numba keeps what it has compiled."""
    probe = (
        "import numpy as np; from snn_fg.events import EVENT_DTYPE; from snn_fg.events.live_screen import "
        "screen_events; from snn_fg.models import get_model; from snn_fg.models.live import warm_up; "
        "from snn_fg.params import ModelParams; "
        "warm_up(get_model('rate', ModelParams(levels=2)), (32, 24), 40.0, windows=1); "
        "n = len(screen_events.signatures); packets = (np.zeros(k, EVENT_DTYPE) for k in (0, 1, 5)); "
        "[screen_events(ev['x'], ev['y'], ev['t'], 32, 24, 0) for ev in packets]; "
        "print(n, len(screen_events.signatures))"
    )
    assert _fresh(probe) == ["2", "2"]  # (compiled, or loaded, in the warm-up: nothing left for a packet)


def test_a_udp_source_compiles_its_packet_decoding_before_the_first_packet():
    """On a first run the receiver compiled SPIF's packet walk and its clock's unwrap at the first
    packet, on the stream's time: 22 of the demo's 24 windows dropped (a new user's trial, from Python
    and from snn-fg live alike). The source compiles them (or loads them) as it binds its port, before
    the model's warm-up; a fresh process, since numba keeps what it has compiled."""
    probe = (
        "import numpy as np; from snn_fg.events import EVENT_DTYPE, spif; "
        "from snn_fg.events.live_sources import open_source; "
        "src = open_source('udp://127.0.0.1:0', (32, 24)); "
        "n = (len(spif._walk.signatures), len(spif._unwrap.signatures)); "
        "ev = np.zeros(100, EVENT_DTYPE); ev['t'] = np.arange(100); "
        "parts = [spif.decode(spif.encode(ev[:k]), 7) for k in (1, 50, 100)]; "
        "got = np.concatenate(parts); got['t'] = spif.Unwrap()(got['t']); one = parts[0]; "
        "one['t'] = spif.Unwrap()(one['t']); src.close(); "
        "print(*n, len(spif._walk.signatures), len(spif._unwrap.signatures))"
    )
    walk, unwrap, walk_after, unwrap_after = (int(v) for v in _fresh(probe))
    assert walk >= 1 and unwrap >= 1 and (walk_after, unwrap_after) == (walk, unwrap)


def _fresh(probe: str) -> list[str]:
    """What the Python lines ``probe`` print in a fresh process (numba keeps what it has compiled), word by word."""
    said = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300)
    assert said.returncode == 0, said.stderr
    return said.stdout.split()
