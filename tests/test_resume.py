"""A spiking run over a recording, cut short and continued: its windows are
written while the one simulation runs, the windows completed before the cut
are readable, and --resume gives the maps of a run never cut, bit for bit."""

import numpy as np
import pytest

from snn_fg.events import image_to_events, iter_windows
from snn_fg.frames.scenes import disc
from snn_fg.models import get_model
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps
from snn_fg.results.store import read_attrs

pytestmark = pytest.mark.usefixtures("warm_simulators")  # compiles the engines first (conftest)


@pytest.fixture(scope="module")
def recording():
    return image_to_events(disc(12).image, motion="circle")


def _run(rec, out, **kw):
    from snn_fg.cli.runner import run_recording

    model = get_model("spiking", ModelParams(levels=3), readout_lag_ms=10.0)
    windows = iter_windows(rec, window_ms=40, max_windows=5)
    return run_recording(model, windows, out, {"input": "disc"}, figures=False, **kw)


@pytest.mark.slow
def test_a_cut_spiking_run_keeps_its_windows_and_resume_gives_the_uncut_maps(recording, tmp_path, monkeypatch):
    from snn_fg.backends.fast.run import Run
    from snn_fg.cli import runner

    simulating = []
    real_simulate = Run.simulate

    def watched(self, *a, **k):
        simulating.append(True)
        try:
            return real_simulate(self, *a, **k)
        finally:
            simulating.append(False)

    monkeypatch.setattr(Run, "simulate", watched)
    whole = tmp_path / "whole"
    whole.mkdir()
    assert _run(recording, whole) == 5
    seen = []  # windows in the store each time a window comes out of the simulation
    real = runner._append_window

    def cut_at_the_fourth(store, w, maps):
        seen.append((store.n, simulating[-1]))
        if len(seen) == 4:
            raise KeyboardInterrupt
        real(store, w, maps)

    monkeypatch.setattr(runner, "_append_window", cut_at_the_fourth)
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(KeyboardInterrupt):
        _run(recording, out)
    # each window came out with the ones before it already in the store (readers see them at the store's next
    # flush, at most a second later, and at the interrupt, below), and while the one simulation
    # ran: at most two behind it when they are decoded on a second thread (then window k is written
    # before window k + 2 leaves the simulation)
    assert [n for n, _ in seen] == [0, 1, 2, 3]
    assert seen[0][1] and seen[1][1]
    cut = Maps.load(out)
    assert cut.fg_x.shape[0] == 3 and not read_attrs(out / "maps.zarr")["snn_fg"]["complete"]
    monkeypatch.setattr(runner, "_append_window", real)
    assert _run(recording, out, resume=True) == 5
    a, b = Maps.load(out), Maps.load(whole)
    assert read_attrs(out / "maps.zarr")["snn_fg"]["complete"]
    for key in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key))
    np.testing.assert_array_equal(a.extra["event_frame"], b.extra["event_frame"])
    assert np.count_nonzero(a.fg_x) > 0  # (equal and not empty)
    # each window's own parameters besides its timing: the same cells, rates and read-out spans
    strip = lambda p: {k: v for k, v in p.items() if k != "timings_s"}  # noqa: E731
    assert [strip(w) for w in a.params["windows"]] == [strip(w) for w in b.params["windows"]]


def test_a_spiking_run_over_a_recording_shows_the_windows_done(recording, tmp_path, monkeypatch):
    """The spiking network reads a window well before it is done with it: its bar counts the
    windows written (a bar of windows read sat at 0 while the first window ran, then vanished)."""
    from snn_fg.cli import runner
    from snn_fg.cli.runner import recording_windows, run_recording

    bars, appended = [], []
    real_append = runner.MapsStore.append  # (the maps of a window reach the store: its chunks are written later)
    monkeypatch.setattr(
        runner.MapsStore, "append", lambda self, *a, **k: appended.append(1) or real_append(self, *a, **k)
    )

    class Bar:
        def __init__(self, desc, unit, total=None, **_):
            self.desc, self.total, self.ticks, self.closed = desc, total, [], False
            bars.append(self)

        def update(self, k=1):
            self.ticks.append(len(appended))

        def close(self):
            self.closed = True

    monkeypatch.setattr(runner, "bar", Bar)
    np.save(tmp_path / "rec.npy", recording.events)
    h, w = disc(12).image.shape
    windows, _ = recording_windows(
        tmp_path / "rec.npy", sensor_size=(w, h), window_options={"window_ms": 40.0, "max_windows": 3}
    )
    out = tmp_path / "out"
    out.mkdir()
    model = get_model("spiking", ModelParams(levels=3), readout_lag_ms=10.0)
    assert run_recording(model, windows, out, {"input": "disc"}, figures=False) == 3
    assert [(b.desc, b.total, b.closed) for b in bars] == [("windows done", 3, True)]
    assert bars[0].ticks == [1, 2, 3]  # (each tick once that window's maps are written)


@pytest.mark.parametrize("stride_ms", [None, 20.0])
def test_the_last_window_of_a_run_cut_by_max_windows_is_read_out_as_in_a_longer_run(recording, tmp_path, stride_ms):
    """Its read-out span reaches the read-out lag past the cut: the network is fed the events
    there (and its window clock fires) as in a longer run, so the windows of a 3-window run
    are those of a 6-window run bit for bit (the last one's grouping and vectors differed
    while the lag ran without input)."""
    from snn_fg.cli.runner import run_recording
    from snn_fg.events import RecordingWindows

    runs = {}
    for n in (3, 6):
        out = tmp_path / f"w{n}"
        out.mkdir()
        model = get_model("spiking", ModelParams(levels=3), readout_lag_ms=20.0)
        windows = RecordingWindows(recording, window_ms=60, stride_ms=stride_ms, max_windows=n)
        assert run_recording(model, windows, out, {"input": "disc"}, figures=False) == n
        runs[n] = Maps.load(out)
    for key in ("fg_x", "fg_y", "grouping"):
        short, long = getattr(runs[3], key), getattr(runs[6], key)[:3]
        np.testing.assert_array_equal(short, long, err_msg=key)
        assert np.count_nonzero(short[2]) > 50  # (equal and not empty)
    # (read out to the window's end and 20 ms more: 180 + 20 ms, or 40 + 60 + 20 ms with the 20 ms stride)
    assert runs[3].params["windows"][2]["simulation"]["count_to_ms"] == (200.0 if stride_ms is None else 120.0)


def test_resume_with_a_larger_max_windows_goes_on_and_a_smaller_one_writes_nothing(
    recording, tmp_path, capsys, monkeypatch
):
    """A user who stopped at 3 windows and wants 5: --resume --max-windows 5 goes on from the
    store's end, and the 5 windows are those of a fresh 5-window run bit for bit (the spiking
    network, whose state runs through the windows). Fewer than the store holds: one line, nothing
    written."""
    from snn_fg.cli import runner
    from snn_fg.cli.main import main
    from snn_fg.events import save_events

    path = tmp_path / "disc.es"
    save_events(path, recording.events, recording.sensor_size)
    common = [str(path), "--model", "spiking", "--levels", "3", "--window-ms", "60", "--no-figures", "--no-progress"]
    fresh, grown = tmp_path / "fresh", tmp_path / "grown"
    assert main(["run", *common, "--out", str(fresh), "--max-windows", "5"]) == 0
    assert main(["run", *common, "--out", str(grown), "--max-windows", "3"]) == 0
    appended = []
    real = runner._append_window
    monkeypatch.setattr(
        runner, "_append_window", lambda store, w, maps: (appended.append(w.index), real(store, w, maps))
    )
    capsys.readouterr()
    # (a default typed out is the run's own: --window-ms 60 here, --start-ms 0 and a stride of the window's length,
    # not given before; until 30 Nov each was refused as "not given before, 0.0 now")
    again = ["--start-ms", "0", "--stride-ms", "60"]
    assert main(["run", *common, *again, "--out", str(grown), "--max-windows", "5", "--resume"]) == 0
    # (said where it goes on from: until 30 Nov a resumed run said nothing before its end)
    said = capsys.readouterr().out.splitlines()
    assert said[0] == f"snn-fg: the run in {grown}/ holds 3 complete windows: continuing from window 3"
    monkeypatch.setattr(runner, "_append_window", real)
    assert appended == [3, 4]  # (from where the store ended, not again from the start)
    a, b = Maps.load(grown), Maps.load(fresh)
    assert a.fg_x.shape[0] == 5 and read_attrs(grown / "maps.zarr")["snn_fg"]["complete"]
    for key in ("fg_x", "fg_y", "grouping"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    assert a.params["source"]["max_windows"] == 5
    capsys.readouterr()
    before = {p: p.read_bytes() for p in grown.rglob("*") if p.is_file()}
    assert main(["run", *common, "--out", str(grown), "--max-windows", "2", "--resume"]) == 0
    said = capsys.readouterr().out.strip()
    assert said.startswith(f"snn-fg: the run in {grown}/ holds 5 windows, more than the 2 of --max-windows: ")
    assert "nothing written" in said
    assert {p: p.read_bytes() for p in grown.rglob("*") if p.is_file()} == before
    assert main(["run", *common, "--out", str(grown), "--max-windows", "5", "--resume"]) == 0
    assert "is finished already (5 windows)" in capsys.readouterr().out


def test_resume_knows_the_recording_however_its_path_is_typed(recording, tmp_path, monkeypatch, capsys):
    """A run started as `run rec.es` and continued from another folder as `run ../rec.es`, or with
    the absolute path, was refused ("these differ: input"): a job script that runs elsewhere could
    not resume (a new user's trial, 1 Dec). The same recording is known by its sensor and first
    events, as compare knows it; another recording is still refused."""
    from snn_fg.cli.main import main
    from snn_fg.events import save_events

    save_events(tmp_path / "disc.es", recording.events, recording.sensor_size)
    save_events(tmp_path / "other.es", recording.events[100:], recording.sensor_size)
    (tmp_path / "jobs").mkdir()
    common = ["--model", "rate", "--levels", "3", "--window-ms", "40", "--no-figures", "--no-progress"]
    monkeypatch.chdir(tmp_path)
    assert main(["run", "disc.es", *common, "--out", "out", "--max-windows", "2"]) == 0
    monkeypatch.chdir(tmp_path / "jobs")
    assert main(["run", "../disc.es", *common, "--out", "../out", "--max-windows", "3", "--resume"]) == 0
    assert main(["run", str(tmp_path / "disc.es"), *common, "--out", "../out", "--max-windows", "4", "--resume"]) == 0
    assert Maps.load(tmp_path / "out").fg_x.shape[0] == 4
    capsys.readouterr()
    assert main(["run", "../other.es", *common, "--out", "../out", "--max-windows", "5", "--resume"]) == 2
    assert "these differ: input" in capsys.readouterr().err


def test_a_resumed_run_says_its_earlier_animation_shows_the_windows_before(recording, tmp_path, capsys):
    """snn-fg plot RUN --animate at 53 windows, then --resume to 183: the closing line listed maps.gif among
    what was written, still the 53-window animation."""
    from snn_fg.cli.main import main
    from snn_fg.events import save_events

    save_events(tmp_path / "disc.es", recording.events, recording.sensor_size)
    out = tmp_path / "out"
    common = [str(tmp_path / "disc.es"), "--model", "rate", "--levels", "3", "--window-ms", "40", "--no-progress"]
    assert main(["run", *common, "--no-figures", "--out", str(out), "--max-windows", "2"]) == 0
    assert main(["plot", str(out), "--animate"]) == 0
    gif = (out / "maps.gif").read_bytes()
    capsys.readouterr()
    assert main(["run", *common, "--no-figures", "--out", str(out), "--max-windows", "3", "--resume"]) == 0
    said = capsys.readouterr().out
    assert f"{out}/maps.gif shows the windows before this run: snn-fg plot {out} --animate {out}/maps.gif" in said
    assert "draws all 3" in said and "maps.gif" not in said.splitlines()[-1]  # (not among what was written)
    assert (out / "maps.gif").read_bytes() == gif  # (left as it was)
