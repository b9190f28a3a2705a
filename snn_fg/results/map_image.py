"""Maps drawn so that one-pixel lines stay visible on a panel smaller than the map.

Matplotlib draws an image that has more pixels than its panel has screen pixels by sampling it
(``interpolation="nearest"``: one map pixel per screen pixel, the others skipped) or averaging it
(antialiased), so a one-pixel edge of a figure-ground map vanishes or fades. :func:`show_map`
pools the map for the screen pixels its panel has when it is drawn: each screen pixel shows the
most salient of the map pixels it covers (:func:`brightness` for the figure-ground and grouping
maps, :func:`departure` where the background is not dark). Where the panel has a screen pixel per
map pixel or more, or when zoomed in, nothing is pooled: no line is drawn thicker than it is.
"""

from __future__ import annotations

import matplotlib.colors as mcolors
import numpy as np
from matplotlib.image import AxesImage


def brightness(image) -> np.ndarray:
    """Salience of a dark-ground map: a scalar map's value, an RGB map's largest channel (its HSV
    value), an RGBA map's opacity."""
    image = np.asarray(image, dtype=float)
    if image.ndim == 2:
        return image
    return image[..., 3] if image.shape[-1] == 4 else image[..., :3].max(axis=-1)


def departure(image) -> np.ndarray:
    """Salience of a map on a ground of any colour (an event frame's grey, a white page): how far each
    pixel lies from the map's median colour, which the ground has."""
    image = np.asarray(image, dtype=float)
    ground = np.nanmedian(image, axis=(0, 1))
    far = np.abs(image - ground)
    return far if image.ndim == 2 else far.sum(axis=-1)


def _pool_axis(image, score, n: int, axis: int):
    """``image`` and ``score`` with ``axis`` cut into ``n`` runs of whole pixels, each run kept as
    its most salient pixel."""
    size = score.shape[axis]
    starts = (np.arange(n) * size) // n  # (n <= size: no run is empty)
    best = np.maximum.reduceat(score, starts, axis=axis)
    run = np.repeat(np.arange(n), np.diff(np.append(starts, size)))
    place = np.arange(size).reshape((-1, 1) if axis == 0 else (1, -1))
    at = np.where(score == np.take(best, run, axis=axis), place, size)
    first = np.minimum.reduceat(at, starts, axis=axis)  # (the first of equally salient pixels)
    pick = first[..., None] if image.ndim == 3 else first
    return np.take_along_axis(image, pick, axis=axis), np.take_along_axis(score, first, axis=axis)


def pool(image, shape, salience=brightness) -> np.ndarray:
    """``image`` (rows x columns, grey or with colour channels) reduced to ``shape`` (no larger than
    it): each output pixel is the most salient (by ``salience``, NaN least) of the input pixels it
    covers, its colour kept whole."""
    image = np.asarray(image)
    score = np.nan_to_num(np.asarray(salience(image), dtype=float), nan=-np.inf)
    rows, cols = shape
    image, score = _pool_axis(image, score, rows, 0)
    image, _ = _pool_axis(image, score, cols, 1)
    return image


class _MapImage(AxesImage):
    """An image that is pooled (:func:`pool`) for the screen pixels it covers each time it is drawn."""

    def __init__(self, ax, data, salience=brightness, **kwargs):
        super().__init__(ax, **kwargs)
        self.map = np.asarray(data)
        self.salience = salience
        self.set_data(self.map)

    def draw(self, renderer):
        box = self.get_window_extent(renderer)
        h, w = self.map.shape[:2]
        shape = (max(1, min(h, int(abs(box.height)))), max(1, min(w, int(abs(box.width)))))
        if shape != self.get_array().shape[:2]:
            self.set_data(self.map if shape == (h, w) else pool(self.map, shape, self.salience))
        super().draw(renderer)


def show_map(ax, data, salience=brightness, *, extent=None, cmap=None, norm=None, vmin=None, vmax=None) -> AxesImage:
    """Draw ``data`` into ``ax`` as ``imshow`` with ``interpolation="nearest"`` would (``extent``,
    ``cmap``, ``norm`` or ``vmin``/``vmax`` as it takes them; a grey map's scale by default its
    whole range), pooled by ``salience`` where the panel is smaller than the map."""
    data = np.asarray(data)
    if data.ndim == 2 and norm is None:
        finite = data[np.isfinite(data)]
        low = vmin if vmin is not None else (float(finite.min()) if finite.size else 0.0)
        high = vmax if vmax is not None else (float(finite.max()) if finite.size else 1.0)
        norm = mcolors.Normalize(low, high)
    image = _MapImage(ax, data, salience, cmap=cmap, norm=norm, interpolation="nearest")
    image.set_clip_path(ax.patch)
    image.set_extent(extent if extent is not None else image.get_extent())
    ax.add_image(image)
    ax.set_aspect("equal")
    return image
