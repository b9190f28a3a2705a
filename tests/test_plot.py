"""What a recording's run gives a researcher beside its maps: a table window by window
(windows.csv), the run over time (timeline.png), and ``snn-fg plot``: chosen windows one figure
each, an animation, the overview again."""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest
from PIL import Image

from snn_fg.cli.main import main
from snn_fg.events import image_to_events, save_events
from snn_fg.frames.scenes import disc
from snn_fg.results.maps import Maps
from snn_fg.results.timeline import COLUMNS, window_rows


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A disc seen by a camera moving in a circle (64 x 64, 6 windows of 60 ms), run by the rate model."""
    rec = image_to_events(disc(8).image, motion="circle")
    path = tmp_path_factory.mktemp("rec") / "disc.es"
    save_events(path, rec.events, rec.sensor_size)
    out = tmp_path_factory.mktemp("runs") / "o"
    assert main(["run", str(path), "--out", str(out), "--window-ms", "60", "--levels", "3", "--no-progress"]) == 0
    return out


def test_a_recordings_run_writes_a_table_and_a_timeline_beside_its_maps(run):
    assert sorted(p.name for p in run.iterdir()) == ["maps.png", "maps.zarr", "timeline.png", "windows.csv"]
    m = Maps.load(run)
    with open(run / "windows.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == COLUMNS and len(rows) == m.fg_x.shape[0] == 6
    for i, r in enumerate(rows):
        has = (m.fg_x[i] != 0) | (m.fg_y[i] != 0)
        events = m.extra["event_frame"][i] != 0
        assert int(r["window"]) == i and int(r["events"]) == int(m.extra["event_count"][i])
        assert float(r["t_start_ms"]) == m.extra["t_start_us"][i] / 1000
        assert float(r["pixel_share"]) == pytest.approx(events.mean(), abs=1e-6)
        assert int(r["fg_pixels"]) == int(has.sum())
        # the rate model gives every event pixel a vector, and nothing else one: its share would be 1
        # by construction, so the table leaves it empty
        assert np.array_equal(has, events) and r["fg_coverage"] == ""
        assert float(r["grouping_peak"]) == pytest.approx(float(m.grouping[i].max()), rel=1e-4)
        y, x = np.unravel_index(np.argmax(m.grouping[i]), m.grouping[i].shape)
        assert (int(r["peak_x"]), int(r["peak_y"])) == (x, y)
    w, h = Image.open(run / "timeline.png").size
    assert 900 <= w <= 1100 and h <= 900


def test_plot_draws_chosen_windows_one_figure_each_on_one_scale(run, capsys):
    assert main(["plot", str(run), "--windows", "1,4-5"]) == 0
    assert sorted(p.name for p in (run / "windows").iterdir()) == [
        "window_0001.png",
        "window_0004.png",
        "window_0005.png",
    ]
    assert main(["plot", str(run), "--windows", "1"]) == 2  # it exists
    assert "window_0001.png: exists; pass --force to replace it" in capsys.readouterr().err
    assert main(["plot", str(run), "--windows", "6"]) == 2
    assert "--windows 6: the run has 6 windows, 0 to 5" in capsys.readouterr().err
    assert main(["plot", str(run / "maps.png"), "--windows", "1"]) == 2
    assert "snn-fg plot draws a recording's run" in capsys.readouterr().err
    assert main(["plot", str(run / "nothere")]) == 2
    assert capsys.readouterr().err.strip().endswith("nothere: no such folder")
    # a crop off the sensor: one line naming the run and the option (until 30 Nov: the figure's function)
    assert main(["plot", str(run), "--windows", "2", "--crop", "10,10,100,50"]) == 2
    said = capsys.readouterr().err.strip().splitlines()
    assert said == [
        f"snn-fg: error: {run}: --crop: crop x0,y0,x1,y1 = 10,10,100,50 must satisfy 0 <= x0 < x1 <= 64 "
        "and 0 <= y0 < y1 <= 64 (the frame is 64 x 64)"
    ]
    assert not (run / "windows" / "window_0002.png").exists()


def test_a_window_figure_says_which_model_made_it_and_from_which_recording(run):
    """A window's figure, sent on its own, named neither (until 30 Nov: only its panels' times)."""
    from snn_fg.results.overview import window_figure

    fig = window_figure(Maps.load(run), 2, grouping_label="grouping", grouping_max=1.0)
    assert fig._suptitle is not None
    assert fig._suptitle.get_text() == "The rate model: disc.es"  # (made_from: the model and the input)


@pytest.mark.parametrize("name", ["maps.gif", "maps.mp4"])
def test_plot_animates_the_maps_one_frame_per_window(run, tmp_path, name):
    out = tmp_path / name
    assert main(["plot", str(run), "--animate", str(out), "--fps", "5"]) == 0
    if name.endswith(".gif"):
        gif = Image.open(out)
        assert gif.n_frames == 6 and gif.info["duration"] == 200
    else:
        video = cv2.VideoCapture(str(out))
        assert int(video.get(cv2.CAP_PROP_FRAME_COUNT)) == 6 and video.get(cv2.CAP_PROP_FPS) == 5
    assert [p.name for p in tmp_path.iterdir()] == [name]  # (no part file left)


def test_plot_draws_the_overview_of_a_run_made_without_figures(run, tmp_path, capsys):
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "maps.zarr").symlink_to(run / "maps.zarr", target_is_directory=True)
    assert main(["plot", str(bare)]) == 0
    assert sorted(p.name for p in bare.iterdir()) == ["maps.png", "maps.zarr", "timeline.png", "windows.csv"]
    assert (bare / "windows.csv").read_text() == (run / "windows.csv").read_text()


def test_plot_draws_the_figures_of_a_run_made_with_no_figures_keeping_its_table(run, tmp_path, capsys):
    """A run made with --no-figures writes windows.csv: plot alone refused it ('exists; pass --force'),
    where usage.md says plot draws such a run's overview (a new user's trial, 1 Dec)."""
    import shutil

    bare = tmp_path / "nofig"
    bare.mkdir()
    (bare / "maps.zarr").symlink_to(run / "maps.zarr", target_is_directory=True)
    shutil.copy2(run / "windows.csv", bare / "windows.csv")
    before = (bare / "windows.csv").stat().st_mtime_ns
    assert main(["plot", str(bare)]) == 0
    assert sorted(p.name for p in bare.iterdir()) == ["maps.png", "maps.zarr", "timeline.png", "windows.csv"]
    assert (bare / "windows.csv").stat().st_mtime_ns == before  # (kept as the run wrote it)
    assert "windows.csv" not in capsys.readouterr().out


def test_a_saturated_window_neither_sets_the_grouping_scale_nor_flattens_the_timeline():
    """dvs.es's first window is a sensor-wide burst: its grouping (830) set the one colour scale and
    dimmed every scene (430-630), and its 106,494 events flattened the other windows' bars."""
    from snn_fg.results.activity import Activity, activity_figure
    from snn_fg.results.overview import grouping_top, window_titles

    g = np.zeros((3, 4, 4), np.float32)
    g[0, 1, 1], g[1, 1, 1], g[2, 1, 1] = 830.0, 430.0, 630.0
    extra = {"pixel_share": np.array([1.0, 0.09, 0.1]), "t_start_us": np.array([0, 85_000, 170_000])}
    extra["t_end_us"] = extra["t_start_us"] + 85_000
    maps = Maps(g, g, g, extra=extra)
    assert grouping_top(maps) == 630.0
    assert window_titles(maps)[:2] == ["window 0: 0-85 ms, saturated", "window 1: 85-170 ms"]
    act = Activity(
        t_start_ms=np.array([0.0, 85.0, 170.0]),
        t_end_ms=np.array([85.0, 170.0, 255.0]),
        events=np.array([106_494, 32_000, 36_000]),
        share=extra["pixel_share"],
        window_ms=85.0,
    )
    events, share = activity_figure(act).axes
    assert events.get_ylim()[1] == pytest.approx(1.5 * 36_000)
    assert any("clipped (largest 106,494)" in t.get_text() for t in events.texts)
    assert share.get_ylim()[1] == pytest.approx(15.0)


def test_the_coverage_is_the_share_of_event_pixels_with_a_vector_where_a_model_can_leave_them_blank(run):
    m = Maps.load(run)
    blanked = m.fg_x.copy()
    blanked[0][m.extra["event_frame"][0] != 0] *= np.arange(np.count_nonzero(m.extra["event_frame"][0])) % 4 != 0
    m.fg_x, m.fg_y = blanked, np.where(blanked != 0, m.fg_y, 0)
    rows = window_rows(m)
    events = m.extra["event_frame"][0] != 0
    assert rows[0]["fg_coverage"] == pytest.approx(((blanked[0] != 0) & events).sum() / events.sum(), abs=1e-4)
    assert 0.7 < rows[0]["fg_coverage"] < 0.8 and rows[1]["fg_coverage"] == 1.0
    assert all(r["fg_coverage"] is None for r in window_rows(m, coverage=False))


def test_the_overview_drawn_again_leaves_the_rate_model_s_coverage_empty(run, tmp_path):
    import shutil

    again = tmp_path / "again"
    shutil.copytree(run, again)
    assert main(["plot", str(again), "--force"]) == 0
    with open(again / "windows.csv") as fh:
        assert {r["fg_coverage"] for r in csv.DictReader(fh)} == {""}


def test_window_titles_tell_short_windows_apart():
    """--start-ms 998.9 --window-ms 0.05: two windows were both titled '999-999 ms' in maps.png."""
    from snn_fg.results.overview import window_titles

    g = np.zeros((3, 4, 4), np.float32)
    extra = {"pixel_share": np.full(3, 0.1), "t_start_us": np.array([998_900, 998_950, 999_000])}
    extra["t_end_us"] = extra["t_start_us"] + 50
    titles = window_titles(Maps(g, g, g, extra=extra))
    assert titles == ["window 0: 998.9-998.95 ms", "window 1: 998.95-999 ms", "window 2: 999-999.05 ms"]
    assert len(set(titles)) == 3
