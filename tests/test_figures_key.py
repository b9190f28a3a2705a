"""What the maps figure tells its reader: which windows it shows, a colour
wheel that hides no data, and a crop drawn at its own pixel coordinates."""

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from snn_fg.cli import main
from snn_fg.results.activity import Activity, activity_figure
from snn_fg.results.figures import event_frame_rgb, maps_figure
from snn_fg.results.maps import Maps
from snn_fg.scoring.compare_figure import compare_figure
from snn_fg.scoring.metrics import compare_maps


def _windows(n, h=40, w=60):
    fx = np.zeros((n, h, w), np.float32)
    fx[:, 10, 5:50] = 1.0
    return [event_frame_rgb(fx[0] > 0, fx[0] < 0)] * n, fx, np.zeros_like(fx), fx.copy()


def _panels(fig):
    return [ax for ax in fig.axes if ax.images and ax.get_label() not in ("<colorbar>", "colour wheel")]


@pytest.mark.slow
def test_the_maps_figure_says_which_windows_it_shows():
    inputs, fx, fy, g = _windows(28)
    fig = maps_figure(inputs, fx, fy, g, [f"w{i}" for i in range(28)], hint="snn-fg plot OUT --windows I,J draws any")
    assert fig._suptitle.get_text() == (
        "6 of 28 windows shown, evenly spaced: 0, 5, 11, 16, 22, 27; snn-fg plot OUT --windows I,J draws any"
    )
    FigureCanvasAgg(fig).draw()
    note = fig._suptitle.get_window_extent()
    for ax in fig.axes:  # the note has a strip of its own, above every panel and title
        assert not note.overlaps(ax.get_tightbbox()), ax.get_title()
    titles = [ax.get_title() for ax in fig.axes if ax.get_title().startswith("input")]
    assert titles == ["input w0", "input w5", "input w11", "input w16", "input w22", "input w27"]
    fig = maps_figure(*_windows(3))
    assert fig._suptitle is None  # all shown: nothing to say
    chosen = maps_figure(inputs, fx, fy, g, [f"w{i}" for i in range(28)], rows=[3, 9])
    assert chosen._suptitle is None and [ax.get_title() for ax in _panels(chosen)][::3] == ["input w3", "input w9"]


@pytest.mark.slow
def test_the_colour_wheel_lies_outside_every_panel_and_is_an_inch_across():
    fig = maps_figure(*_windows(2))
    FigureCanvasAgg(fig).draw()
    panels = _panels(fig)
    (wheel,) = [ax for ax in fig.axes if ax.get_label() == "colour wheel"]
    box = wheel.get_window_extent()
    assert len(panels) == 6  # three panels a row
    for ax in panels:
        assert not box.overlaps(ax.get_window_extent()), ax.get_title()
    disc = wheel.images[0].get_window_extent()  # (the wheel itself, without its labels)
    assert min(disc.width, disc.height) / fig.dpi >= 0.75  # it was 0.4 inch across, beside 3.4-inch panels


def test_every_row_has_one_grouping_scale_and_its_axes_labelled():
    """A recording's figure scaled each row's grouping map to its own maximum (a colour meant
    different activity row to row) and labelled only the first row's axes."""
    inputs, fx, fy, g = _windows(3)
    g[0, 5, 5], g[1, 5, 5], g[2, 5, 5] = 1.0, 4.0, 0.5
    fig = maps_figure(inputs, fx, fy, g)
    grouping = [ax for ax in _panels(fig) if ax.get_title().startswith("grouping")]
    assert [ax.images[0].get_clim() for ax in grouping] == [(0.0, 4.0)] * 3
    assert all(ax.get_xlabel() == "x (px)" for ax in _panels(fig))
    assert [ax.get_ylabel() for ax in _panels(fig)][::3] == ["y (px, rows down)"] * 3
    (bar,) = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert "one scale for every window" in bar.get_xlabel()
    fig = maps_figure(inputs, fx, fy, g, rows=[2], grouping_max=10.0)  # a window on the recording's scale
    assert [ax.images[0].get_clim() for ax in _panels(fig) if ax.get_title().startswith("grouping")] == [(0.0, 10.0)]


def test_a_recordings_overview_is_no_taller_than_a_screen_or_two():
    """maps.png of a 12-window recording was 1760 x 4521 pixels (12 rows): the overview draws 6."""
    inputs, fx, fy, g = _windows(12, 240, 304)
    fig = maps_figure(inputs, fx, fy, g)
    w, h = fig.get_size_inches() * 110
    assert w <= 1400 and h <= 2400, (w, h)


@pytest.mark.slow
def test_a_crop_draws_that_part_at_its_own_coordinates(tmp_path):
    inputs, fx, fy, g = _windows(1)
    fig = maps_figure(inputs[0], fx[0], fy[0], g[0], crop=(5, 8, 25, 14))
    panels = _panels(fig)
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


def _record(raster):
    """A spiking record of 400 ms (counted from 200 ms) holding ``raster`` and nothing else."""
    from snn_fg.models.spiking.record import SpikingRecord

    none = np.zeros((4, 4), np.uint8)
    return SpikingRecord(
        names=[],
        counts={},
        sites={},
        raster=raster,
        input_on=none,
        input_off=none.copy(),
        count_window_ms=200.0,
        duration_ms=400.0,
        settle_ms=200.0,
        populations={},
    )


def test_the_raster_explains_every_role_and_why_feedback_cells_fire_at_2_khz():
    from snn_fg.models.spiking.figures import raster_figure
    from snn_fg.network.roles import ROLE_ORDER

    caption = "\n".join(t.get_text() for t in raster_figure(_record(raster=None)).texts)
    explained = {r for line in caption.splitlines() if ": " in line for r in line.split(": ", 1)[0].split(", ")}
    assert explained == set(ROLE_ORDER)
    assert "bo_L1, bo_L2, bo_D1, bo_D2: border-ownership cells: a light (L) or dark (D) figure" in caption
    said = " ".join(caption.split())
    # (the step is the network's: until 30 Nov the caption said 0.5 ms and 2 kHz on the compact network's 1 ms too)
    assert "a spike every step by design (up to 2 kHz at the default network's 0.5 ms step, 1 kHz at the" in said


def test_a_window_without_grouping_activity_is_drawn_dark_and_said_so():
    """An all-zero grouping map would sit at the middle of an autoscaled
    colour range (a flat mid colour that reads as activity everywhere): it
    is drawn at the bottom of the scale, and its title says there is none."""
    inputs, fx, fy, g = _windows(2)
    g[1] = 0.0
    fig = maps_figure(inputs, fx, fy, g, ["w0", "w1"])
    grouping = [ax for ax in _panels(fig) if ax.get_title().startswith("grouping")]
    assert [ax.get_title() for ax in grouping] == ["grouping w0", "grouping w1: no activity"]
    busy, silent = (ax.images[0] for ax in grouping)
    assert silent.get_clim() == (0.0, 1.0) and np.all(silent.to_rgba(silent.get_array())[..., :3] < 0.05)
    assert busy.get_clim() == (0.0, 1.0) and busy.to_rgba(np.array([[1.0]]))[0, 0, :3].max() > 0.9
    g[0] = 0.0
    first = [ax for ax in _panels(maps_figure(inputs, fx, fy, g)) if ax.get_title().startswith("grouping")][0]
    assert first.get_title() == "grouping: no activity"


def test_the_compare_figure_shows_its_whole_title_and_labels_its_axes():
    """compare --plot clipped the difference panel's title at the figure's edge and labelled no axis."""
    rng = np.random.default_rng(0)
    a, b = (Maps(*rng.normal(size=(2, 3, 40, 60)).astype(np.float32), np.zeros((3, 40, 60), np.float32)) for _ in "ab")
    fig = compare_figure(a, b, compare_maps(a, b), names=("out/run-a", "out/run-b"))
    FigureCanvasAgg(fig).draw()
    page = fig.bbox
    for ax in fig.axes:
        for text in (ax.title, ax.xaxis.label, ax.yaxis.label):
            if text.get_text():
                box = text.get_window_extent()
                assert page.x0 <= box.x0 and box.x1 <= page.x1 and box.y1 <= page.y1, text.get_text()
    panels = [ax for ax in fig.axes if ax.images and ax.get_label() != "<colorbar>" and ax.get_xlim()[1] > 2]
    assert len(panels) == 9 and all(ax.get_xlabel() == "x (px)" for ax in panels)
    assert [ax.get_ylabel() for ax in panels][::3] == ["y (px, rows down)"] * 3


def test_the_share_of_pixels_is_drawn_on_a_scale_that_shows_it():
    """``events --plot`` drew a DAVIS recording's 0.2 % on 0-100 %: it looked empty."""
    act = Activity(
        t_start_ms=np.array([0.0, 85.0]),
        t_end_ms=np.array([85.0, 170.0]),
        events=np.array([900, 1200]),
        share=np.array([0.0015, 0.002]),
        window_ms=85.0,
    )
    fig = activity_figure(act)
    share = fig.axes[1]
    assert share.get_ylim()[1] == pytest.approx(0.23)
    assert any("none saturated" in t.get_text() for t in share.texts)


def test_the_key_says_what_the_input_column_shows():
    """Every maps.png said '(or the APS frame the fbfg model ran on)', whatever it showed."""
    from snn_fg.results.figures import APS_INPUT, EVENTS_INPUT
    from snn_fg.results.overview import input_note

    fx = np.zeros((2, 8, 8), np.float32)
    events = Maps(fx, fx, fx, extra={"event_frame": np.zeros((2, 8, 8), np.int8)})
    frames = Maps(fx, fx, fx, extra={"event_frame": np.zeros((2, 8, 8), np.int8), "aps_frame": np.zeros((2, 8, 8))})
    assert input_note(events) == EVENTS_INPUT and input_note(frames) == APS_INPUT
    for note in (EVENTS_INPUT, APS_INPUT):
        texts = [t.get_text() for ax in maps_figure(*_windows(1), input_note=note).axes for t in ax.texts]
        assert note in texts and not any("APS" in t for t in texts if t != note)


def test_the_raster_caption_explains_the_roles_drawn_and_fits_on_the_page():
    """The caption was cut at the page's bottom and explained side-cue cells no network drew."""
    from types import SimpleNamespace

    from snn_fg.models.spiking.figures import raster_figure
    from snn_fg.network.roles import ROLE_ORDER

    drawn = ["simple", "bo_L1", "feedback_1p"]
    roles = np.repeat([ROLE_ORDER.index(r) for r in drawn], 5)
    raster = SimpleNamespace(row=np.arange(roles.size), role=roles, t_ms=np.linspace(0, 400, roles.size))
    fig = raster_figure(_record(raster))
    FigureCanvasAgg(fig).draw()
    (caption,) = fig.texts
    explained = [line.split(": ", 1)[0] for line in caption.get_text().splitlines() if not line.startswith(" ")]
    assert explained == ["simple", "bo_L1, bo_L2, bo_D1, bo_D2", "feedback_1p, feedback_1n, feedback_2p, feedback_2n"]
    box, page, (ax,) = caption.get_window_extent(), fig.bbox, fig.axes
    assert page.y0 <= box.y0 and box.y1 < ax.get_tightbbox().y0  # (on the page, under the axes and their labels)


def test_the_key_of_a_portrait_frame_stays_in_its_columns():
    """A portrait BSDS image (321 x 481) made panels 2.3 inches wide: the key's words ran into the
    next column's wheel and text and off the figure's right edge. Its columns are now wide enough,
    and every piece of the key's text lies inside the figure and clear of the others."""
    inputs, fx, fy, g = _windows(1, h=481, w=321)
    fig = maps_figure(inputs[0], fx[0], fy[0], g[0])
    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    whole = fig.bbox
    texts = [t for ax in fig.axes if not ax.images or ax.get_label() in ("<colorbar>",) for t in ax.texts]
    (bar,) = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    texts += [bar.title, bar.xaxis.label]
    boxes = [t.get_window_extent(renderer) for t in texts if t.get_text()]
    (wheel,) = [ax for ax in fig.axes if ax.get_label() == "colour wheel"]
    wheel_box = wheel.get_tightbbox(renderer)
    assert len(boxes) >= 4
    for b in boxes:
        assert whole.x0 <= b.x0 and b.x1 <= whole.x1 + 1, b  # (inside the figure)
        assert not b.overlaps(wheel_box), b
    for i, a in enumerate(boxes):
        for b in boxes[i + 1 :]:
            assert not a.overlaps(b), (a, b)


def test_the_figures_say_which_model_and_network_made_the_maps(tmp_path):
    """maps.png of a default and of a compact spiking run carried the same labels, and timeline.png said
    only 'the spiking model' (a new user's trial): both now name the model, its network and backend."""
    from snn_fg.results.maps import made_by

    compact = {"model": "spiking", "network": {"origin": "recipe", "recipe": "compact"}, "backend": {"name": "fast"}}
    built = {"model": "spiking", "network": {"origin": "built"}, "backend": {"name": "brian2"}}
    stored = {"model": "spiking", "network": {"origin": "/home/me/net.json"}, "backend": {"name": "nest"}}
    assert made_by(compact) == "the spiking model on the compact network (fast backend)"
    assert made_by(built) == "the spiking model on the default network (brian2 backend)"
    assert made_by(stored) == "the spiking model on the net.json network (nest backend)"
    # (the blocks are its input's: "on 3 x 3 blocks" read as maps kept on blocks, --maps-grid blocks)
    assert made_by({"model": "rate", "input_pool": 3}) == "the rate model, its input pooled in 3 x 3 blocks"
    assert made_by({"model": "rate", "input_pool": 1}) == "the rate model"
    fig = maps_figure(*_windows(2), made_by=made_by(compact))
    assert fig._suptitle.get_text() == "The spiking model on the compact network (fast backend)"
    assert main(["run", "demo", "--out", str(tmp_path / "demo"), "--no-progress"]) == 0
    assert Maps.load(tmp_path / "demo").params["model"] == "rate"


def test_the_fbfg_model_on_an_image_names_its_input_panel_the_image(tmp_path, monkeypatch):
    """Its figure's input panel is the image it read: the key said "the event frame ... white ON, black OFF"
    beside a colour photo (a new user's trial, 30 Nov); an events model's keeps the event frame's key."""
    import snn_fg.results.figures as figures
    from snn_fg.models import get_model
    from snn_fg.results.figures import IMAGE_INPUT

    said = []
    monkeypatch.setattr(figures, "save_maps_figure", lambda path, *a, **k: said.append(k.get("input_note")))
    z = np.zeros((8, 8))
    for name in ("fbfg", "rate"):
        get_model(name).write_figures(tmp_path, Maps(z, z, z, {"model": name}), [np.zeros((8, 8, 3))])
    assert said == [IMAGE_INPUT, None]  # (None: maps_figure's own, the event frame's)
    assert IMAGE_INPUT.startswith("input: the image")


def test_the_keys_words_keep_a_bracketed_phrase_whole_where_it_fits():
    """'(a window's events, or an / image's)' wrapped mid-phrase in a narrow figure (a new user's trial, 1 Dec)."""
    from snn_fg.results.figures import EVENTS_INPUT, _wrapped

    assert _wrapped(EVENTS_INPUT, 3.0).split("\n") == [
        "input: the event frame",
        "(a window's events, or an image's)",
        "white ON, black OFF, grey none",
    ]
