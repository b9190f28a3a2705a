"""One-pixel lines of a map stay visible in a figure whose panels have fewer screen pixels than the
map has pixels, and are drawn no thicker where a panel has room."""

import numpy as np
from PIL import Image

from snn_fg.results.atomic import save_figure
from snn_fg.results.figures import event_frame_rgb, maps_figure
from snn_fg.results.map_image import departure, pool

#: the figure's resolution in the test (save_maps_figure's)
DPI = 110


def _line_maps(h, w, row, cols):
    """Maps with one horizontal line: an ON event, a vector pointing right (pure red), grouping 1."""
    on = np.zeros((h, w), bool)
    on[row, cols] = True
    fx = on.astype(float)
    return event_frame_rgb(on, np.zeros_like(on)), fx, np.zeros_like(fx), fx.copy()


def _line_rows(tmp_path, h, w, row, cols):
    """For each panel (its title): the PNG's rows inside the panel that show the line, and the row
    where the test expects it (from the panel's box and the map's row, at the PNG's resolution)."""
    fig = maps_figure(*_line_maps(h, w, row, cols), made_by="the rate model")
    fig.set_dpi(DPI)
    path = save_figure(fig, tmp_path / "maps.png", dpi=DPI)
    png = np.asarray(Image.open(path).convert("RGB")).astype(int)
    colour = {"input": (255, 255, 255), "figure-ground": (255, 0, 0), "grouping": (252, 253, 191)}
    out = {}
    for ax in fig.axes:
        if ax.get_title() not in colour:
            continue
        box = ax.get_window_extent()
        top, left = png.shape[0] - box.y1, box.x0
        want = top + (row + 0.5) / h * box.height  # (the map's row as a PNG row)
        x0, x1 = (int(np.ceil(left + (c + 0.5) / w * box.width)) for c in (cols.start, cols.stop - 1))
        band = png[int(top) + 2 : int(top + box.height) - 2, x0:x1]  # (inside the spines)
        near = np.abs(band - colour[ax.get_title()]).sum(axis=-1) <= 12
        found = np.nonzero(near.mean(axis=1) > 0.5)[0] + int(top) + 2
        out[ax.get_title()] = found, want, box.height / h
    return out


def test_a_one_pixel_line_stays_in_a_panel_smaller_than_the_map(tmp_path):
    # (a new user's photo: a 360 x 480 map, the square's top edge on row 275, in panels of about 390 rows)
    for title, (found, want, scale) in _line_rows(tmp_path, 480, 360, 275, slice(96, 265)).items():
        assert scale < 1, title
        assert found.size, f"{title}: no line in the PNG"
        assert np.all(np.abs(found - want) <= 1.5) and found.size <= 2, (title, found, want)


def test_a_line_is_no_thicker_where_the_panel_has_room(tmp_path):
    for title, (found, want, scale) in _line_rows(tmp_path, 40, 30, 20, slice(5, 25)).items():
        assert scale > 5, title
        # (one map row: `scale` PNG rows, give or take the rows a spine or rounding takes)
        assert scale - 2 <= found.size <= scale + 1, (title, found.size, scale)
        assert abs(found.mean() - want) <= 1.5, (title, found, want)


def test_pool_keeps_each_blocks_most_salient_pixel_in_its_colour():
    grey = np.full((6, 4, 3), 0.5)
    grey[4, 1] = 0.0  # an OFF event: black on grey
    grey[1, 3] = (1.0, 0.9, 1.0)  # a paler ON event
    pooled = pool(grey, (3, 2), departure)
    want = np.full((3, 2, 3), 0.5)
    want[2, 0] = 0.0
    want[0, 1] = (1.0, 0.9, 1.0)
    assert np.array_equal(pooled, want)
    line = np.zeros((480, 360))
    line[275] = 1.0
    pooled = pool(line, (393, 294))
    assert np.nonzero(pooled.any(axis=1))[0].tolist() == [275 * 393 // 480] and pooled.all(where=pooled > 0)
    assert np.array_equal(pool(line, line.shape), line)  # (room for every pixel: nothing pooled)
