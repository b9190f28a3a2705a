"""The figure of a run against human labels (``snn-fg compare RUN LABELS --plot``): per image,
the image, the run's figure-ground map, and for each labeller the labelled directions and the
angle between them and the run's vectors (red: labelled, but the run has no vector there)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ..results.atomic import save_figure
from ..results.figures import PANEL_IN, fg_rgb, panel_width, rows_shown, shown_note, wheel_inset
from ..results.map_image import brightness, departure, show_map
from ..results.maps import has_vector
from .label_scores import pool_stats
from .metrics import angle_difference_deg

#: the colour of a labelled pixel the run has no vector on (the error's colour map, viridis, has no red)
NO_VECTOR = "tab:red"


def _image(s):
    """The image the run read (its input, else the labels' own), or None when neither can be read."""
    from ..events.images import read_image

    for path in ((s.params.get("source") or {}).get("input"), s.labels.image_path):
        if path is not None and Path(path).is_file():
            try:
                return read_image(path, grey=False)
            except Exception:  # (a figure does without the image rather than fail after the scores)
                continue
    return None


def _distinct(s) -> list[tuple[int, str]]:
    """(labeller index, name) of the labellers whose labels differ from every earlier one's."""
    out = []
    for k, fg in enumerate(s.labels.fg):
        same = next((j for j, _ in out if np.array_equal(s.labels.fg[j], fg)), None)
        if same is None:
            out.append((k, f"labeller {k + 1}"))
        else:
            out = [(j, f"{w} and {k + 1}" if j == same else w) for j, w in out]
            out = [(j, w.replace("labeller ", "labellers ", 1) if j == same else w) for j, w in out]
    return out


#: how far (px) a labelled pixel's colour is spread in the figure, so that one-pixel boundaries can be read
#: at screen size (a 5306 px wide figure of three labellers showed them as hairlines); display only
SHOWN_WIDTH_PX = 1.5


def _thick(valid: np.ndarray):
    """Where to draw a labelled pixel's colour (within :data:`SHOWN_WIDTH_PX` of one), and the nearest
    labelled pixel of each place (its row and column index arrays)."""
    from scipy import ndimage

    if not valid.any():
        return valid, None
    dist, nearest = ndimage.distance_transform_edt(~valid, return_indices=True)
    return dist <= SHOWN_WIDTH_PX, tuple(nearest)


def _spread(values: np.ndarray, near, fill):
    """``values`` (at labelled pixels) drawn at every place of ``near`` (:func:`_thick`)."""
    shown, nearest = near
    if nearest is None:
        return values
    out = np.full_like(values, fill)
    out[shown] = values[nearest][shown]
    return out


def labels_figure(scored, max_rows: int = 6) -> Figure:
    """One row per image (at most ``max_rows``, evenly spaced) of :class:`~snn_fg.cli.compare_labels.Scored`."""
    idx = rows_shown(len(scored), max_rows)  # (the images the command kept the fields of)
    h, w = np.shape(scored[idx[0]].fields[0])
    n_lab = max(len(_distinct(scored[i])) for i in idx)
    cols = 2 + 2 * n_lab
    panel_w = panel_width(w / h)
    fig = Figure(figsize=(cols * panel_w + 2.6, (PANEL_IN + 0.5) * len(idx) + 1.0), layout="constrained")
    axes = fig.subplots(len(idx), cols, squeeze=False)
    errors = []  # (the error panels: one colour bar for them all, the same 0-180 scale)
    for row, i in zip(axes, idx, strict=True):
        s = scored[i]
        img = _image(s)
        if img is None:
            row[0].text(0.5, 0.5, "image not found", ha="center", va="center", transform=row[0].transAxes)
        else:
            show_map(row[0], img, departure, cmap="gray" if np.ndim(img) == 2 else None)
        row[0].set_title(f"image {s.image_id}", fontsize=9)
        fx, fy = s.fields
        show_map(row[1], fg_rgb(fx, fy), brightness)
        row[1].set_title(f"the run's vectors ({s.params.get('model', '?')} model)", fontsize=9)
        has = has_vector(fx, fy)
        for j, (k, who) in enumerate(_distinct(s)):
            tx, ty, valid = s.truths[k]
            lab, err = row[2 + 2 * j], row[3 + 2 * j]
            near = _thick(valid)  # (each labelled pixel drawn a few pixels wide: the scores are the pixels')
            labelled = fg_rgb(np.where(valid, tx, 0), np.where(valid, ty, 0))
            show_map(lab, _spread(labelled, near, 0.0), brightness)
            lab.set_title(f"{who}: labelled direction\n(towards the figure)", fontsize=9)
            diff = np.where(valid & has, angle_difference_deg(fx, fy, tx, ty), np.nan)
            missing = np.zeros((*valid.shape, 4))
            missing[valid & ~has] = to_rgba(NO_VECTOR)
            show_map(err, _spread(missing, near, 0.0), brightness)
            im = show_map(err, _spread(diff, near, np.nan), brightness, cmap="viridis", vmin=0, vmax=180)
            errors.append(err)
            st = pool_stats([s.parts[k]])  # (the table's numbers, not a second count)
            err.set_title(
                f"{who}: error; side accuracy {st['side_accuracy']:.0%},\n"
                f"coverage {st['coverage']:.0%} of {st['n_truth']:,} labelled px",
                fontsize=8,
            )
        for ax in row[2 + 2 * len(_distinct(s)) :]:
            ax.set_axis_off()
        for ax in row:
            ax.tick_params(labelsize=7)
    if errors:
        # (one bar beside every row; a bar per panel, as tall as its axes, stood far above and below
        # a wide frame's image, and repeated the same scale for every labeller)
        bar = fig.colorbar(im, ax=errors, shrink=min(0.9, 0.5 + 0.2 * len(idx)), aspect=25 * len(idx))
        bar.set_ticks((0, 45, 90, 135, 180))
        bar.set_label("error panels: |angle difference| (deg)", fontsize=8)
        bar.ax.tick_params(labelsize=7)
    wheel_inset(axes[0][1], caption=False)  # (the title says what the hue is: no room beside these panels)
    red = Patch(
        facecolor=NO_VECTOR,
        label="error panels: labelled, but no vector from the run (white: not labelled); boundaries drawn 3 px wide",
    )
    fig.legend(handles=[red], loc="outside lower center", fontsize=8, frameon=False)
    note = shown_note(idx, len(scored), "images", [s.image_id for s in scored])
    fig.suptitle(
        "the run against the human figure/ground labels (colour wheel: the direction towards the figure, "
        "0° right, 90° up)" + (f"\n{note}" if note else ""),
        fontsize=9,
    )
    return fig


def save_labels_figure(path, scored, max_rows: int = 6) -> Path:
    """Write :func:`labels_figure` to ``path`` (atomically)."""
    return save_figure(labels_figure(scored, max_rows), path, dpi=160)  # (one-pixel contours: 110 dpi drew them faint)
