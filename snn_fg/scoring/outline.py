"""Object outlines from an event frame, for checking maps on real recordings.

A moving object leaves a dense blob of events; its *filled outline* is the
largest connected region after closing small gaps and filling holes. The
inward direction along that outline comes from the gradient of the smoothed
filled mask.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage as ndi

from .. import validate as check
from ..results.maps import maps_scale
from .metrics import angle_difference_deg


def filled_outline(edges: np.ndarray, close_px: int = 4, min_fraction: float = 0.0) -> np.ndarray:
    """Boolean mask of the largest filled event region of ``edges`` (H x W)."""
    m = np.asarray(edges) > 0
    if not m.any():
        return m
    st = ndi.generate_binary_structure(2, 2)
    closed = ndi.binary_closing(np.pad(m, close_px), structure=st, iterations=close_px)[
        close_px:-close_px, close_px:-close_px
    ]
    filled = ndi.binary_fill_holes(closed)
    lab, n = ndi.label(filled)
    sizes = ndi.sum(filled, lab, range(1, n + 1))
    keep = lab == (1 + int(np.argmax(sizes)))
    return keep if keep.mean() >= min_fraction else np.zeros_like(keep)


def outline_band(region: np.ndarray, band_px: int) -> np.ndarray:
    """The pixels of ``region`` within ``band_px`` of its outline."""
    return region & ~ndi.binary_erosion(region, iterations=band_px)


def event_outlines(a, b, band_px: int):
    """For comparing two maps of a recording (:func:`snn_fg.scoring.metrics.compare_maps`'s
    ``where``): ``(window_a, window_b) ->`` the pixels within ``band_px`` of
    the outline of that window's largest filled event region, from the event
    frame a run stores with its maps (A's, else B's). On a recording whose
    objects fill with events the pixels inside carry no border, and both
    maps' vectors there are noise that swamps the outline's agreement."""
    band_px = check.integer("compare_maps", "outline_px", band_px, lo=1)
    frames = [(m.extra.get("event_frame"), k, maps_scale(m.params)) for k, m in enumerate((a, b))]
    frames = [(ef, k, s) for ef, k, s in frames if ef is not None]
    if not frames:
        check.fail(
            "compare_maps",
            None,
            None,
            f"--outline {band_px} (outline_px={band_px} in Python) needs the event frame a recording's run "
            "stores with its maps; neither map has one (a still image's run stores none)",
        )
    ef, k, scale = frames[0]
    # (maps kept on blocks: the band and the closing in sensor pixels all the same)
    band, close = max(1, round(band_px / scale)), max(1, round(4 / scale))

    def where(ia, ib):
        i = (ia, ib)[k]
        frame = np.asarray(ef if i is None or np.ndim(ef) == 2 else ef[i])
        return outline_band(filled_outline(frame != 0, close), band)

    return where


def _outline_vectors(fg_x, fg_y, region, band_px, sigma):
    """Model vectors within ``band_px`` of the region's outline (inside it)
    and the inward normal there: ``(fx, fy, nx, ny)`` of the selected pixels."""
    inner = outline_band(region, band_px)
    smooth = ndi.gaussian_filter(region.astype(float), sigma)
    gy_rows, gx = np.gradient(smooth)
    nx, ny = gx, -gy_rows  # y up
    mag = np.hypot(fg_x, fg_y)
    sel = inner & (mag > 0) & (np.hypot(nx, ny) > 1e-6)
    return fg_x[sel], fg_y[sel], nx[sel], ny[sel]


def inward_score(fg_x, fg_y, region: np.ndarray, band_px: int = 3, sigma: float = 3.0) -> tuple[float, int]:
    """Fraction of figure-ground vectors within ``band_px`` of the region's
    outline (inside it) that point into the region (positive dot product with
    the inward normal). Returns ``(fraction, n_pixels)``."""
    return _inward(*_outline_vectors(fg_x, fg_y, region, band_px, sigma))


def inward_angles(fg_x, fg_y, region: np.ndarray, band_px: int = 3, sigma: float = 3.0) -> tuple[float, float]:
    """The same outline vectors as :func:`inward_score`, scored by angle:
    ``(mean absolute angle to the inward normal in degrees, fraction within
    45 degrees of it)``; ``(nan, nan)`` without vectors. Stricter than the
    sign of the dot product: a vector along the outline counts as 90 degrees off."""
    return _angles(*_outline_vectors(fg_x, fg_y, region, band_px, sigma))


def outline_scores(fg_x, fg_y, region: np.ndarray, band_px: int = 3, sigma: float = 3.0) -> dict:
    """:func:`inward_score` and :func:`inward_angles` from one pass over the
    outline vectors: ``inward`` (fraction), ``vectors`` (their count),
    ``mean_deg`` and ``within45``."""
    v = _outline_vectors(fg_x, fg_y, region, band_px, sigma)
    (inward, n), (mean_deg, within45) = _inward(*v), _angles(*v)
    return {"inward": inward, "vectors": n, "mean_deg": mean_deg, "within45": within45}


def _inward(fx, fy, nx, ny) -> tuple[float, int]:
    if not fx.size:
        return float("nan"), 0
    return float(np.mean(fx * nx + fy * ny > 0)), int(fx.size)


def _angles(fx, fy, nx, ny) -> tuple[float, float]:
    if not fx.size:
        return float("nan"), float("nan")
    diff = angle_difference_deg(fx, fy, nx, ny)
    return float(diff.mean()), float(np.mean(diff <= 45.0))
