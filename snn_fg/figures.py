"""Figures people look at: figure-ground colour wheels and grouping heat maps.

Hue encodes the direction towards the owning object (0 deg = right, 90 deg =
up, as the paper's wheel legend); brightness encodes the vector's magnitude.
"""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.colors as mcolors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .atomic import save_figure  # noqa: E402


def fg_rgb(fg_x, fg_y) -> np.ndarray:
    """RGB image of a figure-ground field: hue = direction, value = magnitude."""
    mag = np.hypot(fg_x, fg_y)
    top = np.percentile(mag[mag > 0], 99) if (mag > 0).any() else 1.0
    hue = (np.arctan2(fg_y, fg_x) % (2 * np.pi)) / (2 * np.pi)
    val = np.clip(mag / max(top, 1e-12), 0, 1)
    val = np.where(mag > 0, 0.35 + 0.65 * val, 0.0)
    hsv = np.stack([hue, np.ones_like(hue), val], axis=-1)
    return mcolors.hsv_to_rgb(hsv)


def event_frame_rgb(pos, neg) -> np.ndarray:
    """Grey background, ON events white, OFF events black."""
    img = np.full(np.shape(pos) + (3,), 0.5)
    img[np.asarray(pos) > 0] = 1.0
    img[np.asarray(neg) > 0] = 0.0
    return img


def _wheel_inset(ax):
    inset = ax.inset_axes([0.80, 0.78, 0.2, 0.2])
    n = 101
    y, x = np.mgrid[1:-1:n * 1j, -1:1:n * 1j]
    r = np.hypot(x, y)
    rgb = mcolors.hsv_to_rgb(np.stack([(np.arctan2(y, x) % (2 * np.pi)) / (2 * np.pi),
                                       np.ones_like(r), np.ones_like(r)], -1))
    rgba = np.concatenate([rgb, (r <= 1)[..., None].astype(float)], -1)
    inset.imshow(rgba)
    inset.set_axis_off()


def plot_maps_row(axes, input_img, fg_x, fg_y, grouping, title=""):
    """Draw input / figure-ground / grouping into three axes."""
    a0, a1, a2 = axes
    if input_img.ndim == 2:
        a0.imshow(input_img, cmap="gray")
    else:
        a0.imshow(input_img)
    a0.set_title(f"input {title}".strip(), fontsize=9)
    a1.imshow(fg_rgb(fg_x, fg_y), interpolation="nearest")
    a1.set_title("figure-ground (hue = direction to object)", fontsize=9)
    _wheel_inset(a1)
    im = a2.imshow(grouping, cmap="jet")
    a2.set_title("grouping", fontsize=9)
    plt.colorbar(im, ax=a2, fraction=0.046, pad=0.02)
    for a in axes:
        a.set_xticks([])
        a.set_yticks([])


def save_maps_figure(path, inputs, fg_x, fg_y, grouping, titles=None, max_rows: int = 12):
    """Write the maps figure: one row per frame (input, figure-ground, grouping).

    ``inputs`` is a list of images (grey or RGB) matching the frames; arrays of
    ndim 2 are treated as one frame. At most ``max_rows`` frames are drawn,
    evenly spaced.
    """
    fg_x, fg_y, grouping = (np.asarray(v) for v in (fg_x, fg_y, grouping))
    if fg_x.ndim == 2:
        fg_x, fg_y, grouping = fg_x[None], fg_y[None], grouping[None]
        inputs = [inputs]
    n = fg_x.shape[0]
    idx = np.unique(np.linspace(0, n - 1, min(n, max_rows)).round().astype(int))
    h, w = fg_x.shape[1:]
    scale = 3.2 / max(h, w) * max(w, h * 1.0)
    fig, axes = plt.subplots(len(idx), 3, figsize=(3 * scale * max(w / h, 0.6) + 1, 3.0 * len(idx)),
                             squeeze=False)
    for row, i in enumerate(idx):
        t = titles[i] if titles is not None else ""
        plot_maps_row(axes[row], inputs[i], fg_x[i], fg_y[i], grouping[i], t)
    fig.tight_layout()
    try:
        save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)
    return path
