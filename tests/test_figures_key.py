"""What the maps figure tells its reader: which windows it shows, a colour
wheel that hides no data, and a crop drawn at its own pixel coordinates."""

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from snn_fg.cli import main
from snn_fg.results.figures import event_frame_rgb, maps_figure


def _windows(n, h=40, w=60):
    fx = np.zeros((n, h, w), np.float32)
    fx[:, 10, 5:50] = 1.0
    return [event_frame_rgb(fx[0] > 0, fx[0] < 0)] * n, fx, np.zeros_like(fx), fx.copy()


@pytest.mark.slow
def test_the_maps_figure_says_which_windows_it_shows():
    inputs, fx, fy, g = _windows(28)
    fig = maps_figure(inputs, fx, fy, g, [f"w{i}" for i in range(28)])
    assert fig._suptitle.get_text() == (
        "12 of 28 windows shown, evenly spaced: 0, 2, 5, 7, 10, 12, 15, 17, 20, 22, 25, 27"
    )
    FigureCanvasAgg(fig).draw()
    note = fig._suptitle.get_window_extent()
    for ax in fig.axes:  # the note has a strip of its own, above every panel and title
        assert not note.overlaps(ax.get_tightbbox()), ax.get_title()
    titles = [ax.get_title() for ax in fig.axes if ax.get_title().startswith("input")]
    assert titles == [
        "input w0",
        "input w2",
        "input w5",
        "input w7",
        "input w10",
        "input w12",
        "input w15",
        "input w17",
        "input w20",
        "input w22",
        "input w25",
        "input w27",
    ]
    fig = maps_figure(*_windows(3))
    assert fig._suptitle is None  # all shown: nothing to say


@pytest.mark.slow
def test_the_colour_wheel_lies_outside_every_panel():
    fig = maps_figure(*_windows(2))
    FigureCanvasAgg(fig).draw()
    panels = [ax for ax in fig.axes if ax.images and ax.get_label() != "<colorbar>"]
    (wheel,) = [child for ax in panels for child in ax.child_axes]
    box = wheel.get_window_extent()
    assert len(panels) == 6  # three panels a row
    for ax in panels:
        assert not box.overlaps(ax.get_window_extent()), ax.get_title()


@pytest.mark.slow
def test_a_crop_draws_that_part_at_its_own_coordinates(tmp_path):
    inputs, fx, fy, g = _windows(1)
    fig = maps_figure(inputs[0], fx[0], fy[0], g[0], crop=(5, 8, 25, 14))
    panels = [ax for ax in fig.axes if ax.images and ax.get_label() != "<colorbar>"]
    assert len(panels) == 3
    for ax in panels:
        assert ax.images[0].get_array().shape[:2] == (6, 20)
        assert ax.images[0].get_extent() == [4.5, 24.5, 13.5, 7.5]
    assert (
        main(["run", "demo", "--out", str(tmp_path / "o"), "--levels", "3", "--crop", "20,10,100,80", "--no-progress"])
        == 0
    )
    assert main(["run", "demo", "--out", str(tmp_path / "p"), "--crop", "0,0,200,10", "--no-progress"]) == 2
    assert not (tmp_path / "p").exists()


def test_the_raster_explains_every_role_and_why_feedback_cells_fire_at_2_khz():
    from snn_fg.models.spiking.figures import raster_figure
    from snn_fg.models.spiking.record import SpikingRecord
    from snn_fg.network.roles import ROLE_ORDER

    record = SpikingRecord(
        names=[],
        counts={},
        sites={},
        raster=None,
        input_on=np.zeros((4, 4), np.uint8),
        input_off=np.zeros((4, 4), np.uint8),
        count_window_ms=200.0,
        duration_ms=400.0,
        settle_ms=200.0,
        populations={},
    )
    caption = "\n".join(t.get_text() for t in raster_figure(record).texts)
    explained = {r for line in caption.splitlines() if ": " in line for r in line.split(": ", 1)[0].split(", ")}
    assert explained == set(ROLE_ORDER)
    assert "bo_L1, bo_L2, bo_D1, bo_D2: border-ownership cells: a light (L) or dark (D) figure" in caption
    assert "where z is strong they fire at up to 2 kHz, a spike every step, by design" in " ".join(caption.split())


def test_a_window_without_grouping_activity_is_drawn_dark_and_said_so():
    """An all-zero grouping map would sit at the middle of an autoscaled
    colour range (a flat mid colour that reads as activity everywhere): it
    is drawn at the bottom of the scale, and its title says there is none."""
    inputs, fx, fy, g = _windows(2)
    g[1] = 0.0
    fig = maps_figure(inputs, fx, fy, g, ["w0", "w1"])
    grouping = [ax for ax in fig.axes if ax.get_title().startswith("grouping")]
    assert [ax.get_title() for ax in grouping] == ["grouping (proto-object centres are bright)", "grouping w1: none"]
    busy, silent = (ax.images[0] for ax in grouping)
    assert silent.get_clim() == (0.0, 1.0) and np.all(silent.to_rgba(silent.get_array())[..., :3] < 0.05)
    assert busy.get_clim() == (0.0, 1.0) and busy.to_rgba(np.array([[1.0]]))[0, 0, :3].max() > 0.9
    g[0] = 0.0
    first = [ax for ax in maps_figure(inputs, fx, fy, g).axes if ax.get_title().startswith("grouping")][0]
    assert first.get_title() == "grouping: no activity"
