"""Comparisons between maps, and scores against ground truth.

Angle maps follow the paper: the figure-ground direction on edge pixels.
Here an angle map holds ``atan2(fg_y, fg_x)`` in degrees, wrapped to
[0, 360) and divided by 360, on pixels whose vector is non-zero, and 0
elsewhere; MSE and SSIM are computed on that map (11 x 11 SSIM window).
Angle differences are always circular: ``|a - b|`` folded into [0, 180].
Grouping maps are compared by Pearson r and by SSIM after scaling each map
by its own maximum: the spiking model's grouping is in Hz, the rate model's
in its own units, and SSIM (unlike r) is not invariant to scale.
"""
from __future__ import annotations

import numpy as np
from skimage.metrics import structural_similarity

from .maps import Maps


def angle_difference_deg(ax, ay, bx, by) -> np.ndarray:
    """Absolute circular difference between two direction fields, degrees."""
    d = np.arctan2(ay, ax) - np.arctan2(by, bx)
    return np.abs(np.degrees(np.angle(np.exp(1j * d))))


def angle_map(fg_x, fg_y) -> np.ndarray:
    nz = np.hypot(fg_x, fg_y) > 0
    a = (np.degrees(np.arctan2(fg_y, fg_x)) % 360.0) / 360.0
    return np.where(nz, a, 0.0)


def _ssim(a, b):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    rng = max(float(np.ptp(a)), float(np.ptp(b)), 1e-12)
    if min(a.shape) < 11:
        return float("nan")
    return float(structural_similarity(a, b, win_size=11, data_range=rng))


def _unit(a):
    a = np.asarray(a, dtype=np.float64)
    peak = np.abs(a).max() if a.size else 0.0
    return a / peak if peak > 0 else a


def pearson(a, b) -> float:
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    if a.std() == 0 or b.std() == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def compare_frame(ax, ay, ag, bx, by, bg) -> dict:
    """Metrics between two single-frame maps (see module docstring)."""
    both = (np.hypot(ax, ay) > 0) & (np.hypot(bx, by) > 0)
    diff = angle_difference_deg(ax, ay, bx, by)[both]
    am, bm = angle_map(ax, ay), angle_map(bx, by)
    return {
        "grouping_pearson_r": pearson(ag, bg),
        "grouping_ssim": _ssim(_unit(ag), _unit(bg)),
        "angle_mse": float(np.mean((am - bm) ** 2)),
        "angle_ssim": _ssim(am, bm),
        "angle_diff_median_deg": float(np.median(diff)) if diff.size else float("nan"),
        "angle_diff_mean_deg": float(np.mean(diff)) if diff.size else float("nan"),
        "angle_within_45_frac": float(np.mean(diff <= 45)) if diff.size else float("nan"),
        "pixels_compared": int(both.sum()),
    }


def compare_maps(a: Maps, b: Maps) -> list[dict]:
    """Compare two Maps window by window; returns one dict per window."""
    if a.fg_x.shape != b.fg_x.shape:
        raise ValueError(f"maps differ in shape: {a.fg_x.shape} vs {b.fg_x.shape}")
    if a.fg_x.ndim == 2:
        return [compare_frame(a.fg_x, a.fg_y, a.grouping, b.fg_x, b.fg_y, b.grouping)]
    return [compare_frame(a.fg_x[i], a.fg_y[i], a.grouping[i], b.fg_x[i], b.fg_y[i], b.grouping[i])
            for i in range(a.fg_x.shape[0])]


def truth_scores(fg_x, fg_y, scene) -> dict:
    """Figure-ground direction against a scene's analytic ground truth.

    Scored on boundary pixels where the model vector is non-zero; ``coverage``
    is the fraction of boundary pixels that have a model vector at all.
    """
    mag = np.hypot(fg_x, fg_y)
    b = scene.boundary
    m = b & (mag > 0)
    err = angle_difference_deg(fg_x[m], fg_y[m], scene.truth_x[m], scene.truth_y[m])
    return {
        "boundary_pixels": int(b.sum()),
        "scored_pixels": int(m.sum()),
        "coverage": float(m.sum() / max(b.sum(), 1)),
        "frac_within_45": float(np.mean(err <= 45)) if err.size else float("nan"),
        "median_err_deg": float(np.median(err)) if err.size else float("nan"),
        "mean_err_deg": float(np.mean(err)) if err.size else float("nan"),
    }


def grouping_peak(grouping) -> tuple[int, int]:
    """(row, col) of the grouping maximum."""
    return tuple(int(v) for v in np.unravel_index(np.argmax(grouping), grouping.shape))


def grouping_peak_inside(grouping, scene, shape_index: int = 0) -> bool:
    """Whether the grouping maximum lies inside ``scene.shapes[shape_index]``."""
    r, c = grouping_peak(grouping)
    return bool(scene.shapes[shape_index].contains(float(r), float(c)))
