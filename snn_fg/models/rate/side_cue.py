"""The side cue of the natural-scene variant (``ModelParams.side_cue``).

On the tuning half of the labelled BSDS images, the side of a boundary with
more events within 160 px is the figure's more often than the side the
grouping chooses (``docs/model.md``, "How far local cues go"). The cue adds
that to the feedback signal of stage 8 at level 1:

    z1[o] += side_cue * Q[o],    z2[o] -= side_cue * Q[o],
    Q[o] = resize_1(D (*) h[o]),   D = rect(P_L(pos)) + rect(P_L(neg))

``D`` is the event density of pyramid level ``L = params.cue_level`` (the
rates of that level's relay cells in the spiking form), ``h[o]`` the half
disc of :func:`~snn_fg.network.kernels.side_cue_kernels` (mean density on
side 1 minus side 2, zero padding), ``resize_1`` the bilinear resize to
level 1. ``z1`` favours side 1 (``BL1``), ``z2`` side 2 (``BL2``). The
spiking form carries ``Q`` in a rectified pair of cells at level ``L``
(``side_p``, ``side_n``) that feed the level-1 feedback cells.
"""

from __future__ import annotations

import numpy as np

from ...frames.pyramid import level_shape, resize
from ...network.kernels import side_cue_kernels
from ...params import ModelParams


def side_cue_maps(pos, neg, params: ModelParams) -> np.ndarray:
    """``D (*) h[o]`` at the cue's level, ``(n_ori, h_L, w_L)``."""
    from scipy.signal import fftconvolve  # (scipy.signal takes about a second to import: only with the side cue)

    shape = level_shape(np.shape(pos), params.cue_level, params.levels_per_octave)
    density = sum(np.maximum(resize(np.asarray(a, np.float64), shape), 0.0) for a in (pos, neg))
    # correlation with h: the kernel turned round, then a convolution
    return np.stack([fftconvolve(density, k[::-1, ::-1], mode="same") for k in side_cue_kernels(params)])


def side_cue_bias(pos, neg, rows, cols, ch, params: ModelParams) -> np.ndarray:
    """What the side cue adds to the level-1 feedback signal at the entries
    ``(rows, cols, ch)`` (channels below ``n_ori``: ``z1``, above: ``z2``)."""
    if params.side_cue == 0 or len(rows) == 0:
        return np.zeros(len(rows))
    n = params.n_ori
    q = side_cue_maps(pos, neg, params)
    shape = np.shape(pos)
    up = np.stack([resize(qo, shape, "linear") for qo in q])
    hi = ch >= n
    return params.side_cue * np.where(hi, -1.0, 1.0) * up[np.where(hi, ch - n, ch), rows, cols]
