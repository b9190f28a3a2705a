"""CORF push-pull contour operator (Azzopardi & Petkov 2012; Azzopardi et al. 2014), the edge
stage of the frame-based model of Hu et al. (2019).

A CORF simple cell combines LGN-like sub-units, each a half-wave rectified
Difference-of-Gaussians (DoG) response of one polarity (centre-on or
centre-off) seen at a point (rho, phi) of the receptive field:

1. **DoG** of the image (rescaled to [0, 1]) with outer sigma ``sigma`` and inner
   ``sigma * SIGMA_RATIO``; centre-on = rectified (inner - outer), centre-off =
   rectified (outer - inner);
2. **configuration** on a synthetic step edge (light on the left of the
   receptive-field centre): on circles of radii ``RHO[sigma]`` the local
   maxima of max(on, off) give one sub-unit each, with the polarity that wins
   there;
3. **response** of a cell preferring direction psi: each sub-unit's rectified DoG
   is blurred by a Gaussian whose size grows with rho (radius
   ``round((SIGMA0 + ALPHA * rho) / 2)``, sd a third of it), raised to the weight
   ``exp(-rho^2 / (2 sigma_w^2))`` (``sigma_w`` = max rho / 3), shifted by
   the sub-unit's position rotated to psi, and all are combined by a weighted
   geometric mean;
4. **push-pull**: the pull cell is the push cell with every sub-unit's polarity
   inverted and moved ``BETA`` px further from the centre along the edge
   normal; the output is ``[push - INHIBITION * pull]+``, which silences the
   responses to texture and noise that a lone push cell gives.

The edge strength of a pixel is the largest response over the 16 directions
(22.5 degrees apart), its direction that one, the **light side** of the edge (x
right, y up), the same convention as :func:`snn_fg.models.rate.fbfg.image_edges`.
Like Hu et al.'s use of it, the responses are not thinned.

Parameters are those of Hu et al.'s FBFG (``sigma`` 2.2, ``BETA`` 4 px,
``INHIBITION`` 1.8) and of the published CORF configuration (inner/outer
sigma ratio 0.5, ``SIGMA0`` 2, ``ALPHA`` 0.9, radii for sigma 2.2).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import ndimage as ndi

#: DoG outer sigma (px) of Hu et al.'s FBFG.
SIGMA = 2.2
#: inner / outer sigma of the DoG.
SIGMA_RATIO = 0.5
#: Radii (px) of the sub-unit circles for outer sigma in (2, 2.4) (the published configuration).
RHO = (19.18, 9.369, 4.5128, 2.1325)
#: Blur of a sub-unit: radius round((SIGMA0 + ALPHA * rho) / 2).
SIGMA0, ALPHA = 2.0, 0.9
#: Pull sub-units lie this many px further out along the edge normal.
BETA = 4.0
#: Weight of the pull (antiphase) cell.
INHIBITION = 1.8
#: Directions per turn.
N_DIRECTIONS = 16
#: Responses below this (of the step edge's peak) do not make a sub-unit.
_PEAK_FLOOR = 0.01
#: Samples per turn when looking for sub-units on a circle.
_CIRCLE_SAMPLES = 720
_EDGE_HALF = 60


def _rectified_dog(image, sigma):
    """(on, off): rectified centre-on and centre-off DoG responses."""
    dog = ndi.gaussian_filter(image, sigma * SIGMA_RATIO, mode="reflect") - ndi.gaussian_filter(
        image, sigma, mode="reflect"
    )
    return np.maximum(dog, 0.0), np.maximum(-dog, 0.0)


def _circle_peaks(values):
    """Indices (fractional, the middle of a plateau) of the local maxima of a circular sequence."""
    n = len(values)
    peaks = []
    for i in range(n):
        v = values[i]
        if v <= 0 or v < values[i - 1]:
            continue
        j = i
        while values[(j + 1) % n] == v and j - i < n:
            j += 1
        if values[(j + 1) % n] < v and values[i - 1] < v:
            peaks.append(((i + j) / 2) % n)
    return peaks


@lru_cache(maxsize=4)
def configuration(sigma: float = SIGMA, rho=RHO) -> tuple:
    """Sub-units ``(polarity, x, y)`` of the push cell preferring a light side on the left
    (direction 180 degrees); polarity 1 = centre-on, 0 = centre-off; x right, y up, px."""
    side = 2 * _EDGE_HALF + 1
    edge = np.zeros((side, side))
    edge[:, : _EDGE_HALF + 1] = 1.0  # light up to and including the centre column
    on, off = _rectified_dog(edge, sigma)
    top = max(on.max(), off.max())
    units = []
    ang = 2 * np.pi * np.arange(_CIRCLE_SAMPLES) / _CIRCLE_SAMPLES
    for r in rho:
        cols = np.round(_EDGE_HALF + r * np.cos(ang)).astype(int)
        rows = np.round(_EDGE_HALF - r * np.sin(ang)).astype(int)
        best = np.maximum(on[rows, cols], off[rows, cols])
        best = np.round(np.where(best < _PEAK_FLOOR * top, 0.0, best), 3 + int(-np.log10(top)))
        for k in _circle_peaks(best):
            a = 2 * np.pi * k / _CIRCLE_SAMPLES
            x, y = r * np.cos(a), r * np.sin(a)
            rr, cc = int(round(_EDGE_HALF - y)), int(round(_EDGE_HALF + x))
            units.append((int(on[rr, cc] >= off[rr, cc]), float(x), float(y)))
    return tuple(units)


def _pull(units, beta=BETA):
    """The antiphase cell: polarities inverted, sub-units moved ``beta`` px outwards along x."""
    return tuple((1 - p, x + (beta if x >= 0 else -beta), y) for p, x, y in units)


class _Blurred:
    """Blurred, weighted sub-unit responses, computed once per (polarity, rho) and padded by
    ``pad`` px (edges replicated) so that a shifted copy is a slice."""

    def __init__(self, on, off, weight_sigma, pad):
        self.maps = (off, on)
        self.weight_sigma = weight_sigma
        self.pad = pad
        self.cache = {}

    def weight(self, rho):
        return float(np.exp(-(rho**2) / (2 * self.weight_sigma**2)))

    def shifted(self, polarity, rho, dx, dy):
        """The map seen ``dx`` px right and ``dy`` px up of every pixel."""
        key = (polarity, round(rho, 3))
        if key not in self.cache:
            radius = int(round((SIGMA0 + ALPHA * rho) / 2))
            m = self.maps[polarity]
            if radius > 0:
                m = ndi.gaussian_filter(m, radius / 3, mode="nearest", truncate=3.0)
            self.cache[key] = np.pad(np.maximum(m, 0.0) ** self.weight(rho), self.pad, mode="edge")
        h, w = self.maps[0].shape
        r0, c0 = self.pad - dy, self.pad + dx
        return self.cache[key][r0 : r0 + h, c0 : c0 + w]


def _cell(blurred, units, psi):
    """Weighted geometric mean of the sub-units rotated by ``psi`` from the 180-degree cell."""
    turn = psi - np.pi
    c, s = np.cos(turn), np.sin(turn)
    out, total = None, 0.0
    for p, x, y in units:
        rho = np.hypot(x, y)
        dx, dy = x * c - y * s, x * s + y * c
        part = blurred.shifted(p, rho, int(np.trunc(dx)), int(np.trunc(dy)))
        out = part.copy() if out is None else np.multiply(out, part, out=out)
        total += blurred.weight(rho)
    return out ** (1.0 / total)


def corf_responses(
    image, sigma: float = SIGMA, beta: float = BETA, inhibition: float = INHIBITION, n_directions: int = N_DIRECTIONS
) -> np.ndarray:
    """Push-pull responses (n_directions, H, W) of a grey image; direction k prefers a light side at
    ``2 pi k / n_directions`` (x right, y up). The image is rescaled to [0, 1] first."""
    img = np.asarray(image, dtype=np.float64)
    lo, hi = img.min(), img.max()
    img = (img - lo) / (hi - lo) if hi > lo else np.zeros_like(img)
    push = configuration(sigma)
    pull = _pull(push, beta)
    weight_sigma = max(np.hypot(x, y) for _, x, y in push + pull) / 3
    pad = int(np.ceil(max(np.hypot(x, y) for _, x, y in push + pull))) + 1
    blurred = _Blurred(*_rectified_dog(img, sigma), weight_sigma, pad)
    out = np.empty((n_directions,) + img.shape)
    for k in range(n_directions):
        psi = 2 * np.pi * k / n_directions
        out[k] = np.maximum(_cell(blurred, push, psi) - inhibition * _cell(blurred, pull, psi), 0.0)
    return out


def corf_edges(image, sigma: float = SIGMA) -> tuple[np.ndarray, np.ndarray]:
    """Edge strength (H, W) and light-side direction in radians (x right, y up) of a grey image.

    Examples
    --------
    >>> import numpy as np
    >>> img = np.zeros((48, 48)); img[:, :24] = 1.0            # light on the left
    >>> strength, direction = corf_edges(img)
    >>> c = int(np.argmax(strength[24]))
    >>> 21 <= c <= 26, round(float(np.degrees(direction[24, c])))
    (True, 180)
    """
    resp = corf_responses(image, sigma)
    best = np.argmax(resp, axis=0)
    strength = np.take_along_axis(resp, best[None], axis=0)[0]
    return strength, 2 * np.pi * best / resp.shape[0]
