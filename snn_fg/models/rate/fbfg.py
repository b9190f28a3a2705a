"""Frame-based figure-ground model (FBFG, Hu et al. 2019) on a grey or RGB image.

Stages 5-9 are those of the event model (shared code in :mod:`.edfg`); only
the simple cells differ. Two edge operators feed them (``edge_operator``):

* ``"corf"``: the CORF push-pull contour operator that Hu et al. use
  (:mod:`.corf`), unthinned as in their code;
* ``"gaussian"`` (default): a cheaper stand-in, described here.

Both see the same channels and the same normalisation (strengths divided by
the level-1 maximum, values below ``params.fbfg_edge_floor`` zeroed). The
Gaussian-derivative operator:

* channels: intensity (mean of R, G, B) and two colour-opponent channels
  (R - G, B - (R + G)/2), weighted 0.8 / 0.2 as in the original;
* edge strength and direction from Gaussian-derivative filters
  (``params.fbfg_edge_sigma``, 1 px),
  i.e. the steerable odd-symmetric response at the best of 16 directions;
* non-maximum suppression along the gradient, so contours are one pixel wide
  (CORF's output is likewise thin);
* strengths are divided by the level-1 maximum and values below
  ``params.fbfg_edge_floor`` (10 %) are zeroed.

Differences from CORF: no push-pull inhibition (CORF suppresses responses
to textures with the opposite-polarity response), no DoG sub-unit geometry, a
fixed scale. The direction index is the quantised gradient direction (towards
the brighter side) shifted by a quarter turn, the same convention stage 4 gives
for events, so that the border-ownership families receive the same polarity.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage as ndi

from ... import validate
from ...frames import check as check_input
from ...frames.pyramid import check_levels, pyramid
from ...params import EDGE_OPERATORS, ModelParams
from ...results.maps import Maps
from .corf import corf_edges
from .edfg import border_ownership_grouping, readout


def _channels(image: np.ndarray) -> list[tuple[float, np.ndarray]]:
    img = np.asarray(image, dtype=np.float64)
    if img.ndim == 2:
        return [(1.0, img)]
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    return [(0.8, (r + g + b) / 3), (0.1, r - g), (0.1, b - (r + g) / 2)]


def _nonmax(mag, gr, gc):
    """Keep pixels whose magnitude is a maximum along the gradient direction."""
    ang = np.arctan2(gr, gc)
    dr = np.round(np.sin(ang)).astype(int)
    dc = np.round(np.cos(ang)).astype(int)
    h, w = mag.shape
    r, c = np.mgrid[0:h, 0:w]
    p1 = mag[np.clip(r + dr, 0, h - 1), np.clip(c + dc, 0, w - 1)]
    p2 = mag[np.clip(r - dr, 0, h - 1), np.clip(c - dc, 0, w - 1)]
    return mag * ((mag >= p1) & (mag >= p2))


def _gaussian_channel(ch, sigma):
    """(strength, row gradient, column gradient) of one channel."""
    gr = ndi.gaussian_filter(ch, sigma, order=(1, 0))
    gc = ndi.gaussian_filter(ch, sigma, order=(0, 1))
    return np.hypot(gr, gc), gr, gc


def image_edges(image, sigma: float = 1.0, operator: str = "gaussian") -> tuple[np.ndarray, np.ndarray]:
    """Edge strength (H, W) and direction in radians (x right, y up) towards the light side.

    Channel strengths are added with the channel weights; the direction is
    that of the channel with the strongest weighted response. The Gaussian
    operator's edges are thinned by non-maximum suppression; CORF's are not.
    """
    validate.choice("image_edges", "operator", operator, EDGE_OPERATORS)
    strength = best = direction = None
    gr_i = gc_i = None
    for weight, ch in _channels(image):
        if operator == "corf":
            mag, ang = corf_edges(ch)
            gr = gc = None
        else:
            mag, gr, gc = _gaussian_channel(ch, sigma)
            ang = np.arctan2(-gr, gc)  # rows grow downwards; y points up
        mag = weight * mag
        if strength is None:
            strength, best, direction, gr_i, gc_i = mag, mag, ang, gr, gc
            continue
        strength = strength + mag
        take = mag > best
        direction = np.where(take, ang, direction)
        if gr is not None:
            gr_i, gc_i = np.where(take, gr, gr_i), np.where(take, gc, gc_i)
        best = np.maximum(best, mag)
    if operator == "gaussian":
        strength = _nonmax(strength, gr_i, gc_i)
    return strength, direction


def frame_simple_cells(image, params: ModelParams = ModelParams(), edge_operator: str = "gaussian"):
    """S maps per level from an image: strength where the direction index equals o."""
    img = np.asarray(image, dtype=np.float64)
    levels = pyramid(img, params.levels, params.levels_per_octave)
    n_dir = params.n_dir
    norm = None
    s_levels = []
    for lvl in levels:
        strength, direction = image_edges(lvl, params.fbfg_edge_sigma, edge_operator)
        if norm is None:
            norm = strength.max() if strength.max() > 0 else 1.0
        strength = strength / norm
        strength[strength < params.fbfg_edge_floor] = 0.0
        k = np.round(direction / (2 * np.pi) * n_dir).astype(int)
        index = (k + n_dir // 4) % n_dir
        s_levels.append(strength[None] * (index[None] == np.arange(n_dir)[:, None, None]))
    return s_levels


def run_fbfg(image, params: ModelParams = ModelParams(), progress=None, edge_operator: str = "gaussian") -> Maps:
    """Grey (H, W) or RGB (H, W, 3) image in [0, 1] -> figure-ground and grouping maps.

    Parameters
    ----------
    image : array
        Grey (H, W) or RGB (H, W, 3), floats in [0, 1].
    params : ModelParams
        Model parameters (the paper's by default).
    progress : callable, optional
        Wraps the iterations in a progress bar.
    edge_operator : {"gaussian", "corf"}
        The simple cells' edge operator: the Gaussian-derivative stand-in, or
        Hu et al.'s CORF push-pull (:mod:`snn_fg.models.rate.corf`, several times slower).

    Returns
    -------
    Maps
        The grouping map is normalised to [0, 1] and values below
        ``params.grouping_floor`` are zeroed, as the frame-based model does;
        ``params["edge_operator"]`` records the operator.

    Examples
    --------
    >>> from snn_fg.frames.scenes import disc
    >>> maps = run_fbfg(disc(radius=12).image, edge_operator="corf")
    >>> maps.params["edge_operator"], maps.fg_x.shape
    ('corf', (64, 64))
    """
    check_input.image("run_fbfg", image)
    img = np.asarray(image, dtype=np.float64)
    if params.input_pool != 1:
        validate.fail(
            "run_fbfg",
            "params.input_pool",
            params.input_pool,
            "must be 1: input pooling is a stage of the event models, not of the frame-based one",
        )
    check_levels(img.shape[:2], params.levels, "<image>", params.levels_per_octave)
    s_levels = frame_simple_cells(img, params, edge_operator)
    g = border_ownership_grouping(s_levels, params, progress)
    fg_x, fg_y, grouping = readout(g, params, img.shape[:2])
    top = grouping.max()
    if top > 0:
        grouping = grouping / top
    grouping[grouping < params.grouping_floor] = 0.0
    return Maps(
        fg_x.astype(np.float32),
        fg_y.astype(np.float32),
        grouping.astype(np.float32),
        params={"model": "fbfg", "edge_operator": edge_operator, **params.to_dict()},
    )
