"""Human figure/ground ground truth (BSDS, Fowlkes, Martin & Malik 2007) and scores against it.

* :func:`load_bsds_fg` reads one image's labels from ``bsds-fg/labels/<id>.npz``
  (``fg``: int8, one map per labeller; +1 on the figure side and -1 on the
  ground side of every labelled boundary); :func:`load_labels` one such file by its path.
* :func:`boundary_directions` turns one such map into a direction per figure
  pixel, the paper's conversion: fit a line to the +1 pixels in a 5 x 5 window
  centred on the pixel (grown by 2 up to 21 x 21 while the fit is
  degenerate), take its normal and orient it towards the figure, i.e. away
  from the -1 pixels on the perpendicular. The fit is a total least-squares line
  (principal axis of the +1 pixels), so vertical lines need no special case.
* :func:`score_directions` compares a model's figure-ground field with those
  directions pixel by pixel: the mean *signed* difference (the number the
  paper reports), and the mean absolute difference, median, fraction within
  45 degrees (the numbers that show the error) and the side accuracy: the
  fraction within 90 degrees, i.e. with the figure on the labelled side.

Directions are unit vectors, x right and y up, like the models' ``fg_x``,
``fg_y``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import ndimage as ndi

from ..errors import InputError
from ..frames.still import read_npz_arrays
from ..results.maps import has_vector

#: Window sides tried in turn for the line fit (the paper: 5 x 5 grown to 21 x 21).
WINDOWS = tuple(range(5, 22, 2))
#: Fewest +1 pixels a line is fitted to.
MIN_POINTS = 3
#: A fit is degenerate when the spread across the line reaches this fraction of the spread along it.
MAX_ANISOTROPY = 0.5
#: Angle error (degrees) counted as "right" in :func:`score_directions`.
WITHIN_DEG = 45.0
#: Angle errors below this (degrees) put the figure on the labelled side: the
#: occlusion-boundary literature's binary side accuracy (a vector exactly
#: along the boundary names no side and counts as wrong).
SIDE_DEG = 90.0


@dataclass(frozen=True, kw_only=True)
class GroundTruth:
    """One image's labels: ``fg`` (n_labellers, H, W) int8 in {-1, 0, 1} and the labellers' ids."""

    image_id: str
    fg: np.ndarray
    labellers: tuple
    image_path: Path | None = None


def bsds_ids(root) -> list[str]:
    """Image ids with labels under ``root`` (the ``bsds-fg`` folder), sorted numerically."""
    return sorted((p.stem for p in Path(root, "labels").glob("*.npz")), key=int)


def load_bsds_fg(root, image_id) -> GroundTruth:
    """Labels of ``image_id`` from ``root/labels/<id>.npz`` (and the image path if present).

    Examples
    --------
    >>> gt = load_bsds_fg(datasets.require("bsds-fg"), "12003")   # doctest: +SKIP
    >>> gt.fg.shape                                              # doctest: +SKIP
    (2, 321, 481)
    """
    image = Path(root, "images", f"{image_id}.jpg")
    return load_labels(Path(root, "labels", f"{image_id}.npz"), image if image.exists() else None, str(image_id))


def load_labels(path, image=None, image_id: str | None = None) -> GroundTruth:
    """Labels from one ``.npz`` file in the bsds-fg format (``fg``, optional ``labellers``), checked:
    a missing or unreadable file, another key set, values other than -1/0/1 or maps of another
    size than ``image`` (a path, when given) are an :class:`InputError` naming ``path``.
    ``image_id``: the file's stem unless given."""
    path = Path(path)
    arrays = read_npz_arrays(path, ("fg",), ("labellers",), what="figure/ground label file (bsds-fg format)")
    fg = _checked_fg(path, arrays["fg"], image)
    labellers = tuple(int(v) for v in np.ravel(arrays.get("labellers", ())))
    if labellers and len(labellers) != fg.shape[0]:
        raise InputError(path, f"'labellers' names {len(labellers)} labellers but 'fg' holds {fg.shape[0]} maps")
    return GroundTruth(
        image_id=path.stem if image_id is None else image_id,
        fg=fg,
        labellers=labellers,
        image_path=None if image is None else Path(image),
    )


def _checked_fg(path, fg, image) -> np.ndarray:
    """``fg`` as (labellers, H, W) int8, or an :class:`InputError` naming ``path``: every caller
    scores the maps pixel by pixel against a model's field made from ``image``, so a wrong shape
    would otherwise surface deep in a worker as a numpy broadcast error that names no file."""
    if fg.dtype.kind not in "biu":  # float maps could hold 0.5s that np.isin rounds nowhere near
        raise InputError(path, f"'fg' must be an integer array (int8), not {fg.dtype}")
    if fg.ndim == 2:
        fg = fg[None]
    if fg.ndim != 3 or 0 in fg.shape:
        raise InputError(path, f"'fg' must be (labellers, H, W); got shape {fg.shape}")
    if not np.isin(fg, (-1, 0, 1)).all():
        raise InputError(
            path, f"'fg' must hold only -1, 0 and 1; found {[int(v) for v in np.setdiff1d(fg, (-1, 0, 1))[:5]]}"
        )
    if image is not None:
        from ..events.images import read_image

        shape = read_image(image).shape[:2]
        if fg.shape[1:] != shape:
            raise InputError(
                path,
                f"'fg' maps are {fg.shape[1]} x {fg.shape[2]} but the image {image.name} is {shape[0]} x {shape[1]}",
            )
    return fg.astype(np.int8)


def _window_sums(mask, side):
    """Per pixel, over the side x side window: count, sum of dx, dy, dx^2, dy^2, dx*dy of ``mask`` pixels."""
    h, w = mask.shape
    r, c = np.mgrid[0:h, 0:w].astype(np.float64)
    m = mask.astype(np.float64)
    box = lambda a: ndi.uniform_filter(a, side, mode="constant") * side * side  # noqa: E731 - a window sum
    n, sr, sc = box(m), box(m * r), box(m * c)
    srr, scc, src = box(m * r * r), box(m * c * c), box(m * r * c)
    # moments about the window's centre pixel (dx right, dy down)
    dx, dy = sc - n * c, sr - n * r
    dxx = scc - 2 * c * sc + n * c * c
    dyy = srr - 2 * r * sr + n * r * r
    dxy = src - r * sc - c * sr + n * r * c
    return n, dx, dy, dxx, dyy, dxy


def _fit_normals(fig, side):
    """Unit normals (nx right, ny down) of the line fitted to ``fig`` in ``side`` windows (unoriented),
    and where the fit is usable."""
    n, dx, dy, dxx, dyy, dxy = _window_sums(fig, side)
    with np.errstate(invalid="ignore", divide="ignore"):
        mx, my = dx / n, dy / n
        cxx, cyy, cxy = dxx / n - mx * mx, dyy / n - my * my, dxy / n - mx * my
        # eigenvalues of the 2 x 2 scatter; the normal is the eigenvector of the smaller one
        half_tr = (cxx + cyy) / 2
        root = np.sqrt(np.maximum(((cxx - cyy) / 2) ** 2 + cxy**2, 0))
        big, small = half_tr + root, half_tr - root
        tangent = 0.5 * np.arctan2(2 * cxy, cxx - cyy)
    ok = (n >= MIN_POINTS) & (big > 0) & (small <= MAX_ANISOTROPY * big)
    return -np.sin(tangent), np.cos(tangent), ok


def _ground_side(ground, rows, cols, nx, ny, half):
    """Per pixel (rows, cols): sum of the normal offsets of the ground pixels lying on the
    perpendicular (within 1 px of it) up to ``half`` px away. > 0: the ground lies along +normal."""
    pad = np.pad(ground, half)
    total = np.zeros(len(rows))
    for dy in range(-half, half + 1):
        for dx in range(-half, half + 1):
            if dx == 0 and dy == 0:
                continue
            along = dx * nx + dy * ny
            across = np.abs(dx * ny - dy * nx)
            hit = pad[rows + half + dy, cols + half + dx] & (across <= 1.0)
            total += np.where(hit, along, 0.0)
    return total


def boundary_directions(fg_map) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Figure direction at every figure (+1) pixel of one labeller's map.

    Parameters
    ----------
    fg_map : (H, W) array
        +1 figure side, -1 ground side of the labelled boundaries, 0 elsewhere.

    Returns
    -------
    (x, y, valid)
        Unit vectors (x right, y up) towards the figure, zero where ``valid``
        is False (not a +1 pixel, or no usable fit up to 21 x 21).

    Notes
    -----
    The normal is oriented away from the -1 pixels found on the perpendicular
    through the pixel (within the window), as the paper's conversion does; a
    centroid of all the window's -1 pixels would cancel out at convex corners.

    Examples
    --------
    >>> import numpy as np
    >>> fg = np.zeros((20, 20), np.int8)
    >>> fg[10, :] = 1; fg[11, :] = -1         # figure above the line
    >>> x, y, ok = boundary_directions(fg)
    >>> round(float(x[10, 10]), 3), round(float(y[10, 10]), 3), bool(ok[10, 10])
    (0.0, 1.0, True)
    """
    fg_map = np.asarray(fg_map)
    fig, ground = fg_map > 0, fg_map < 0
    out_x = np.zeros(fg_map.shape)
    out_y = np.zeros(fg_map.shape)
    todo = fig.copy()
    for side in WINDOWS:
        if not todo.any():
            break
        nx, ny, ok = _fit_normals(fig, side)
        rows, cols = np.nonzero(todo & ok)
        nx, ny = nx[rows, cols], ny[rows, cols]
        g = _ground_side(ground, rows, cols, nx, ny, side // 2)
        keep = g != 0
        rows, cols, flip = rows[keep], cols[keep], np.where(g[keep] > 0, -1.0, 1.0)
        out_x[rows, cols] = nx[keep] * flip
        out_y[rows, cols] = -ny[keep] * flip  # rows grow downwards; y points up
        todo[rows, cols] = False
    return out_x, out_y, fig & ~todo


def signed_angle_deg(ax, ay, bx, by) -> np.ndarray:
    """Signed angle from b to a, degrees in (-180, 180]."""
    d = np.degrees(np.arctan2(ay, ax) - np.arctan2(by, bx))
    return 180.0 - (180.0 - d) % 360.0


def angle_errors(fg_x, fg_y, truth_x, truth_y, valid) -> np.ndarray:
    """Signed errors (degrees) of the model field at the valid truth pixels where the model has a vector."""
    fg_x, fg_y = np.asarray(fg_x, np.float64), np.asarray(fg_y, np.float64)
    m = valid & has_vector(fg_x, fg_y)
    return signed_angle_deg(fg_x[m], fg_y[m], truth_x[m], truth_y[m])


def summarise_errors(signed) -> dict:
    """Mean signed and absolute error, median absolute error, fraction within 45 degrees,
    side accuracy (fraction below :data:`SIDE_DEG`), pixel count."""
    signed = np.asarray(signed, np.float64)
    if not signed.size:
        nan = float("nan")
        return {
            "mean_signed_deg": nan,
            "mean_abs_deg": nan,
            "median_abs_deg": nan,
            "within45": nan,
            "side_accuracy": nan,
            "n_pixels": 0,
        }
    a = np.abs(signed)
    return {
        "mean_signed_deg": float(signed.mean()),
        "mean_abs_deg": float(a.mean()),
        "median_abs_deg": float(np.median(a)),
        "within45": float(np.mean(a <= WITHIN_DEG)),
        "side_accuracy": float(np.mean(a < SIDE_DEG)),
        "n_pixels": int(signed.size),
    }


def score_directions(fg_x, fg_y, truth) -> dict:
    """Scores of a field against ``truth`` = ``(x, y, valid)`` of :func:`boundary_directions`, plus
    ``coverage``: the fraction of valid truth pixels where the model has a vector."""
    tx, ty, valid = truth
    signed = angle_errors(fg_x, fg_y, tx, ty, valid)
    return {**summarise_errors(signed), "coverage": float(signed.size / max(int(valid.sum()), 1))}


def labeller_agreement(gt: GroundTruth) -> dict:
    """The human ceiling: labeller 2's directions scored against labeller 1's where both label a figure pixel."""
    if gt.fg.shape[0] < 2:
        raise InputError(gt.image_id, "needs two labellers")
    a, b = (boundary_directions(m) for m in gt.fg[:2])
    return score_directions(np.where(b[2], b[0], 0), np.where(b[2], b[1], 0), a)
