"""A DAVIS camera's APS frames: read on the events' clock, paired with the event windows, and the
frame-based model run on them (``snn-fg run REC --model fbfg``) against the event models.

The recordings of ``tests/data`` were written by iniVation's dv-processing
(``tests/data/make_davis346_disc.py``): a disc seen through the iCub's
microsaccade, whose truth the tests know.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from snn_fg.cli import main
from snn_fg.errors import InputError
from snn_fg.events import EVENT_DTYPE, iter_windows, open_recording, save_events
from snn_fg.events.aps import ApsFrame, iter_frames, open_frames, require_frames, with_frames
from snn_fg.events.frame import EventWindow
from snn_fg.events.images import as_float_image
from snn_fg.frames.scenes import APS_FIRST_US, APS_INTERVAL_US, DAVIS_T0_US, davis_disc_recording
from snn_fg.frames.still import Still
from snn_fg.models import get_model
from snn_fg.params import ModelParams
from snn_fg.results.maps import Maps
from snn_fg.scoring.compare_figure import aps_inputs, compare_figure
from snn_fg.scoring.metrics import agreement, compare_maps, frame_of, truth_scores

DATA = Path(__file__).resolve().parent / "data"
DISC = DATA / "davis346_disc.aedat4"
#: the disc recording's frames: one every 40 ms from 20 ms, for 400 ms
FRAME_TIMES = DAVIS_T0_US + APS_FIRST_US + APS_INTERVAL_US * np.arange(10)


@pytest.fixture(scope="module")
def disc_runs(tmp_path_factory):
    """The rate model's and the frame-based model's runs on the disc recording (85 ms windows;
    about 10 s each on one core)."""
    out = tmp_path_factory.mktemp("aps")
    for model in ("rate", "fbfg"):
        argv = ["run", str(DISC), "--model", model, "--out", str(out / model), "--no-progress", "--no-figures"]
        assert main(argv) == 0
    return out


def _error_line(capsys, argv) -> str:
    """The one line ``snn-fg argv`` fails with (exit status 2)."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("snn-fg: error: ") and err.count("\n") == 1, err
    return err


@pytest.mark.slow
def test_the_frames_read_are_those_the_camera_writer_wrote():
    frames = open_frames(DISC)
    assert frames.size == (346, 260)
    read = list(iter_frames(frames, (346, 260, 2)))
    made = davis_disc_recording().frames
    assert [f.t_us for f in read] == FRAME_TIMES.tolist() == [f.t_us for f in made]
    assert [f.index for f in read] == list(range(10))
    for a, b in zip(read, made, strict=True):
        assert a.image.dtype == np.uint8 and np.array_equal(a.image, b.image)
        assert a.exposure_us == b.exposure_us  # (dv-processing stamps a frame at its exposure's start)
    assert open_frames(DATA / "davis346_no_frames.aedat4") is None


def test_each_window_gets_the_last_frame_before_its_end():
    def window(k, end):
        z = np.zeros((2, 2), np.uint8)
        return EventWindow(k, end - 10, end, np.zeros(0, EVENT_DTYPE), z, z, t_first_event_us=0)

    frame = lambda k, t: ApsFrame(k, t, np.zeros((2, 2), np.uint8), (t, t))  # noqa: E731
    frames = [frame(0, 12), frame(1, 15), frame(2, 15), frame(3, 30), frame(4, 41)]
    paired = list(with_frames([window(k, end) for k, end in enumerate((10, 20, 30, 40, 60))], frames))
    # (end 10: none yet; 20: the later of the two at 15; 30: the frame at 30 is not before the end; 60: 41)
    assert [None if w.aps is None else w.aps.index for w in paired] == [None, 2, 2, 3, 4]
    assert [w.t_end_us for w in paired] == [10, 20, 30, 40, 60]


def test_events_says_how_many_frames_and_how_often(capsys, tmp_path):
    assert main(["events", str(DISC), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert (
        "APS frames: 10 frames of 346 x 260, one every 40.0 ms (25.0 per second), 19.081 to 379.081 ms after "
        "the first event"
    ) in out
    assert "skipped" not in out  # (frames are read now: the fbfg model uses them)
    assert main(["events", str(DATA / "davis346_no_frames.aedat4"), "--no-progress"]) == 0
    assert "APS frames: none (the file holds no frame stream" in capsys.readouterr().out
    assert main(["events", str(DATA / "davis346_roi_frames.aedat4"), "--no-progress"]) == 0
    assert "2 frames of 173 x 130" in (out := capsys.readouterr().out) and "another size than the event sensor" in out
    assert main(["events", str(_frames_swapped(tmp_path)), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "APS frames: unusable: APS frames out of time order: frame 1 " in out and "events:     21,197" in out


@pytest.mark.slow
def test_fbfg_runs_on_the_frames_window_by_window_aligned_with_the_event_model(disc_runs):
    rate, fbfg = Maps.load(disc_runs / "rate"), Maps.load(disc_runs / "fbfg")
    assert fbfg.fg_x.shape == rate.fg_x.shape == (5, 260, 346)
    assert np.array_equal(fbfg.extra["t_start_us"], rate.extra["t_start_us"])
    assert np.array_equal(fbfg.extra["t_end_us"], rate.extra["t_end_us"])
    # each window ran on the last frame before its end, the frame's time kept on the windows' clock
    first = int(open_recording(DISC).events["t"][0])
    ends = rate.extra["t_end_us"] + first
    expected = [int(np.flatnonzero(FRAME_TIMES < end)[-1]) for end in ends]
    assert fbfg.extra["aps_index"].tolist() == expected == [1, 3, 5, 8, 9]
    assert np.array_equal(fbfg.extra["aps_t_us"] + first, FRAME_TIMES[expected])
    frames = list(iter_frames(open_frames(DISC)))
    assert all(np.array_equal(fbfg.extra["aps_frame"][i], frames[k].image) for i, k in enumerate(expected))
    # the disc's rim is owned inward by the frame model
    scene = davis_disc_recording().scene
    for i in range(5):
        score = truth_scores(fbfg.fg_x[i], fbfg.fg_y[i], scene)
        assert score["frac_within_45"] >= 0.9 and score["scored_pixels"] > 150, (i, score)


@pytest.mark.slow
def test_compare_holds_the_event_model_against_the_frame_model_window_by_window(disc_runs, capsys):
    assert main(["compare", str(disc_runs / "rate"), str(disc_runs / "fbfg")]) == 0
    table = capsys.readouterr().out.splitlines()
    assert [line.split()[:3] for line in table[1:6]] == [[str(k), str(k), f"{85.0 * k:.1f}"] for k in range(5)]
    rows = compare_maps(Maps.load(disc_runs / "rate"), Maps.load(disc_runs / "fbfg"))
    assert [r["t_start_ms"] for r in rows] == [0.0, 85.0, 170.0, 255.0, 340.0]
    for r in rows:  # (both models see the same rim: they agree on who owns it)
        assert r["angle_within_45_frac"] >= 0.9 and r["pixels_compared"] > 200 and r["coverage_of_b"] > 0.8, r
    # B's baseline: the frame model again at 20 iterations on the APS frame window 3 read, computed here
    fbfg = Maps.load(disc_runs / "fbfg")
    still = Still(image=as_float_image(fbfg.extra["aps_frame"][3], grey=False))
    want = agreement(frame_of(fbfg, 3), get_model("fbfg", ModelParams(iterations=20)).run_still(still))
    b_within, b_r = (float(x) for x in table[4].split()[-2:])
    assert b_within == pytest.approx(want["within_45"], abs=1e-3) and b_r == pytest.approx(want["grouping_r"], abs=1e-3)
    assert "B against its own model at 20 iterations instead of 10" in " ".join(table)


@pytest.mark.slow
def test_the_compare_figure_shows_the_frame_and_the_events_beside_the_maps(disc_runs):
    rate, fbfg = Maps.load(disc_runs / "rate"), Maps.load(disc_runs / "fbfg")
    rows = compare_maps(rate, fbfg)
    assert aps_inputs(rate, rate) == []  # (two event runs: the figure as before)
    fig = compare_figure(rate, fbfg, rows, inputs=aps_inputs(rate, fbfg))
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[:4] == ["APS frame 1 (59.1 ms)", "event frame", "A window 0, 0 ms", "B window 0, 0 ms"]
    assert np.array_equal(fig.axes[0].images[0].get_array(), fbfg.extra["aps_frame"][0])
    shown = fig.axes[1].images[0].get_array()  # (the event frame: ON white, OFF black)
    assert np.array_equal(shown[..., 0] == 1.0, rate.extra["event_frame"][0] > 0)


def test_a_recording_without_frames_gets_one_line(capsys, tmp_path):
    err = _error_line(
        capsys, ["run", str(DATA / "davis346_no_frames.aedat4"), "--model", "fbfg", "--out", str(tmp_path / "o")]
    )
    assert "has no APS frames (it holds events only)" in err and "give --model rate or spiking" in err
    ev = np.zeros(3, EVENT_DTYPE)
    ev["t"] = [0, 10, 20]
    save_events(tmp_path / "r.es", ev, (4, 4))
    err = _error_line(capsys, ["run", str(tmp_path / "r.es"), "--model", "fbfg", "--out", str(tmp_path / "o")])
    assert "has no APS frames (it is .es, a format that carries no frames)" in err
    assert not (tmp_path / "o").exists()
    window = next(iter(iter_windows(DISC)))
    with pytest.raises(InputError, match="give run_windows FramedWindows\\(iter_windows\\(path, ...\\)") as said:
        get_model("fbfg").run_window(window)
    assert "ApsWindow" not in str(said.value)  # (a name the docs never give)


def test_the_way_the_fbfg_refusal_names_runs(tmp_path):
    """What the refusal above tells a script to write runs the fbfg model on a recording's frames."""
    from snn_fg.events import open_recording
    from snn_fg.events.aps import FramedWindows, require_frames

    sensor = open_recording(DISC).sensor_size
    windows = FramedWindows(iter_windows(DISC, max_windows=2), require_frames(DISC, sensor), sensor)
    done = list(get_model("fbfg").run_windows(windows))
    assert len(done) == 2 and all(int(maps.extra["aps_index"]) >= 0 for _, maps in done)


def test_frames_of_another_size_than_the_sensor_get_one_line(capsys, tmp_path):
    roi = DATA / "davis346_roi_frames.aedat4"
    err = _error_line(capsys, ["run", str(roi), "--model", "fbfg", "--out", str(tmp_path / "o")])
    assert "the frame stream is 173 x 130 pixels but the event sensor is 346 x 260" in err
    argv = ["run", str(DISC), "--model", "fbfg", "--sensor-size", "400x300", "--out", str(tmp_path / "o")]
    # (a sensor larger than the file's own, which its frames then missed, is refused as the file is opened)
    assert "the sensor size given, 400 x 300, disagrees with the file's own 346 x 260" in _error_line(capsys, argv)
    assert not (tmp_path / "o").exists()
    with pytest.raises(InputError, match=r"APS frame 0 is 173 x 130 pixels at offset \(86, 65\)"):
        next(iter_frames(require_frames(roi, (173, 130)), (173, 130)))


def _frames_swapped(tmp_path) -> Path:
    """The disc recording with its first two frame packets swapped: frames out of time order.

    An AEDAT 4 file is a header (magic, size, header) and packets, each a
    stream id and a size (little-endian int32, uint32) and that many bytes.
    """
    raw = DISC.read_bytes()
    at, frames = 18 + struct.unpack("<I", raw[14:18])[0], []
    while len(frames) < 2:
        stream, size = struct.unpack("<iI", raw[at : at + 8])
        if stream == 1:  # (the frame stream)
            frames.append((at, at + 8 + size))
        at += 8 + size
    (a0, a1), (b0, b1) = frames
    path = tmp_path / "swapped.aedat4"
    path.write_bytes(raw[:a0] + raw[b0:b1] + raw[a1:b0] + raw[a0:a1] + raw[b1:])
    return path


def test_frames_out_of_time_order_get_one_line(capsys, tmp_path):
    swapped = _frames_swapped(tmp_path)
    err = _error_line(capsys, ["run", str(swapped), "--model", "fbfg", "--out", str(tmp_path / "o"), "--no-progress"])
    t0, t1 = FRAME_TIMES[:2]
    assert f"APS frames out of time order: frame 1 ({t0} us) comes before frame 0 ({t1} us)" in err
    assert not (tmp_path / "o").exists()
