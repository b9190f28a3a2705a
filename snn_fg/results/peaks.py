"""The strongest proto-objects of a window's maps, for a gaze controller: the
grouping map's local maxima and the figure-ground map's mean direction around each."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

#: how far apart two peaks are at least, and the disc the direction is averaged over (px)
PEAK_RADIUS = 8


def grouping_peaks(maps, k: int = 3, radius: int = PEAK_RADIUS) -> list[dict]:
    """The ``k`` strongest local maxima of ``maps.grouping`` (strongest first,
    at least ``radius`` apart, above zero): ``x``, ``y`` (pixels, y down as in
    the map's rows), ``strength`` (the grouping value) and the mean figure-ground
    vector within ``radius`` (``fg_x``, ``fg_y``, x right, y up; ``fg_deg`` its
    direction, None where no vector lies there)."""
    g = np.nan_to_num(np.asarray(maps.grouping, dtype=np.float64))
    size = 2 * radius + 1
    top = (g == ndimage.maximum_filter(g, size=size, mode="constant")) & (g > 0)
    ys, xs = np.nonzero(top)
    order = np.argsort(-g[ys, xs], kind="stable")
    out, taken = [], []
    h, w = g.shape
    yy, xx = np.ogrid[:h, :w]
    for i in order:
        y, x = int(ys[i]), int(xs[i])
        if any((y - a) ** 2 + (x - b) ** 2 < radius**2 for a, b in taken):  # (a plateau's twins)
            continue
        taken.append((y, x))
        disc = (yy - y) ** 2 + (xx - x) ** 2 <= radius**2
        fx, fy = maps.fg_x[disc], maps.fg_y[disc]
        has = np.hypot(fx, fy) > 0
        mx, my = (float(fx[has].mean()), float(fy[has].mean())) if has.any() else (0.0, 0.0)
        deg = float(np.degrees(np.arctan2(my, mx))) if has.any() and (mx or my) else None
        out.append({"x": x, "y": y, "strength": float(g[y, x]), "fg_x": mx, "fg_y": my, "fg_deg": deg})
        if len(out) == k:
            break
    return out
